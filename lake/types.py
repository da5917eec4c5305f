"""Topic field types: their names in the config, Trino types, and value checks.

One table of types serves the Emitter (validation before writing), ingestion
(validation) and the catalog (Trino column types); `schema` gives their Arrow types.
"""

from __future__ import annotations

import json
import math
import re
from numbers import Integral, Real
from typing import Any

#: Field type names accepted in a topic schema, with aliases resolved.
FIELD_TYPES = ("int", "float", "boolean", "string", "status", "image", "video", "string[]", "metric[]")
TYPE_ALIASES = {"bigint": "int"}

#: Kinds of attached metric in a `metric[]` field, and the documented keys of a metric object.
#: Any other key (ReSim: "the contents are flexible", e.g. `unit`) is kept in the object's
#: `extra` field: a JSON object text of those keys, NULL when there are none.
METRIC_KINDS = ("scalar", "text", "image", "plotly")
METRIC_REQUIRED_KEYS = ("name", "type", "value")
METRIC_OPTIONAL_KEYS = ("description", "status")
METRIC_FIELDS = ("name", "description", "status", "type", "value", "extra")

_TRINO = {
    "int": "bigint",
    "float": "double",
    "boolean": "boolean",
    "string": "varchar",
    "status": "varchar",
    "image": "varchar",
    "video": "varchar",
    "string[]": "array(varchar)",
    "metric[]": "array(row(" + ", ".join(f"{name} varchar" for name in METRIC_FIELDS) + "))",
}


INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1

#: Limits of one emissions line (JSON text, newline excluded), the same for the Emitter and ingestion:
#: a longer or deeper line is refused. Far above what real records need (a Plotly figure is ~10 deep).
MAX_LINE_BYTES = 16 << 20
MAX_JSON_DEPTH = 256
# a JSON string (skipped whole), an opening bracket (group 1), or a closing one
_JSON_NESTING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"|([\[{])|[\]}]')


def json_too_deep(text: str, limit: int = MAX_JSON_DEPTH) -> bool:
    """Whether JSON `text` nests arrays and objects deeper than `limit`, found without parsing it."""
    if text.count("[") + text.count("{") <= limit:
        return False
    depth = 0
    for token in _JSON_NESTING.finditer(text):
        if token.group(1):
            depth += 1
            if depth > limit:
                return True
        elif token.group()[0] != '"':
            depth -= 1
    return False


class FieldError(ValueError):
    """A value does not fit its field type; the message says what was expected and got."""


def canonical_type(name: str) -> str | None:
    """The canonical field type for a config type name, or None when unknown."""
    name = TYPE_ALIASES.get(name, name)
    return name if name in _TRINO else None


def trino_type(field_type: str) -> str:
    """The Trino type name under which queries see a field of this type."""
    return _TRINO[field_type]


def _describe(value: Any) -> str:
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{type(value).__name__} {text}"


def is_utf8(text: str) -> bool:
    """False if `text` holds a lone surrogate (U+D800-U+DFFF), which UTF-8 (and so Parquet) cannot store."""
    if text.isascii():
        return True
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _text(value: str, where: str = "") -> str:
    if not is_utf8(value):
        raise FieldError(f"{where}string holds a lone surrogate (U+D800-U+DFFF), which is not valid Unicode text")
    return value


def _as_str_list(value: Any) -> list[str]:
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        value = value.tolist()
    if not isinstance(value, (list, tuple)):
        raise FieldError(f"expected a list of strings, got {_describe(value)}")
    for i, item in enumerate(value):
        if not isinstance(item, str):
            raise FieldError(f"expected a list of strings, got {_describe(item)} at position {i}")
        _text(item, f"position {i}: ")
    return list(value)


def _metric_value_text(kind: str, value: Any) -> str:
    if kind in ("scalar", "text"):
        if isinstance(value, bool) or not isinstance(value, (str, Real)):
            raise FieldError(f"metric of type {kind} needs a string or number value, got {_describe(value)}")
        return value if isinstance(value, str) else json.dumps(value.item() if hasattr(value, "item") else value)
    if kind == "image":
        return json.dumps(_as_str_list([value] if isinstance(value, str) else value))
    # plotly: a JSON text (fig.to_json()) or the decoded object
    if isinstance(value, str):
        try:
            json.loads(value)
        except ValueError as exc:
            raise FieldError(f"metric of type plotly needs a JSON text, got invalid JSON ({exc})") from None
        return value
    if isinstance(value, dict):
        return json.dumps(value, allow_nan=False)
    raise FieldError(f"metric of type plotly needs a JSON text or object, got {_describe(value)}")


def _metric_extra(item: dict, where: str) -> str | None:
    """The object's undocumented keys as a JSON object text (None when it has none)."""
    extra = {key: value for key, value in item.items() if key not in METRIC_REQUIRED_KEYS + METRIC_OPTIONAL_KEYS}
    if not extra:
        return None
    keys = f"{where}: key(s) {', '.join(map(repr, extra))}"
    try:
        text = json.dumps(extra, allow_nan=False, ensure_ascii=False)
    except (ValueError, TypeError) as exc:
        raise FieldError(f"{keys}: cannot be stored as JSON: {exc}") from None
    return _text(text, f"{keys}: ")


def _metric(item: Any, index: int) -> dict[str, str | None]:
    where = f"metric {index}"
    if not isinstance(item, dict):
        raise FieldError(f"{where}: expected an object, got {_describe(item)}")
    missing = [k for k in METRIC_REQUIRED_KEYS if k not in item]
    if missing:
        raise FieldError(f"{where}: missing key(s) {', '.join(missing)}")
    for key in ("name", "type", *METRIC_OPTIONAL_KEYS):
        if key in item and item[key] is not None and not isinstance(item[key], str):
            raise FieldError(f"{where}: {key} must be a string, got {_describe(item[key])}")
    kind = item["type"]
    if kind not in METRIC_KINDS:
        raise FieldError(f"{where}: type must be one of {', '.join(METRIC_KINDS)}, got {kind!r}")
    metric = {
        "name": item["name"],
        "description": item.get("description"),
        "status": item.get("status"),
        "type": kind,
        "value": _metric_value_text(kind, item["value"]),
        "extra": _metric_extra(item, where),
    }
    for key, text in metric.items():
        if text is not None:
            _text(text, f"{where}: {key}: ")
    return metric


def check_value(field_type: str, value: Any) -> Any:
    """Return `value` as stored for `field_type` (numpy scalars become Python ones), or raise FieldError.

    Rules: int takes integers (not bool); float takes integers or finite floats (not
    bool); boolean only bool; string/status/image/video a str; string[] a list of str;
    metric[] a list of metric objects (name, type scalar|text|image|plotly, value,
    optional description and status; other keys are kept as JSON text in `extra`). None is never
    accepted, nor a string holding a lone surrogate (it has no UTF-8 form).
    """
    if field_type == "int":
        if isinstance(value, bool) or not isinstance(value, Integral):
            raise FieldError(f"expected int, got {_describe(value)}")
        number = int(value)
        if not INT64_MIN <= number <= INT64_MAX:
            raise FieldError(f"int out of the 64-bit range: {number}")
        return number
    if field_type == "float":
        if isinstance(value, bool) or not isinstance(value, Real) or type(value).__name__ == "bool_":
            raise FieldError(f"expected float, got {_describe(value)}")
        try:
            number = float(value)
        except OverflowError:
            raise FieldError(f"float out of range: {_describe(value)}") from None
        if not math.isfinite(number):
            raise FieldError(f"expected a finite float, got {number!r}")
        return number
    if field_type == "boolean":
        if isinstance(value, bool):
            return value
        if type(value).__name__ == "bool_":
            return bool(value)
        raise FieldError(f"expected boolean, got {_describe(value)}")
    if field_type in ("string", "status", "image", "video"):
        if not isinstance(value, str):
            raise FieldError(f"expected {field_type} (a string), got {_describe(value)}")
        return _text(value)
    if field_type == "string[]":
        return _as_str_list(value)
    if field_type == "metric[]":
        if not isinstance(value, (list, tuple)):
            raise FieldError(f"expected a list of metric objects, got {_describe(value)}")
        return [_metric(item, i) for i, item in enumerate(value)]
    raise FieldError(f"unknown field type {field_type!r}")
