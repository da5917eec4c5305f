"""Ingestion rules: whether one emissions line is accepted, exactly (the Emitter's rules, `types.check_value`)."""
from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from lakegate.lake.config import Topic
from lakegate.lake.config_yaml import did_you_mean
from lakegate.lake.types import INT64_MAX, MAX_JSON_DEPTH, MAX_LINE_BYTES, FieldError, check_value, json_too_deep

#: How many problems an IngestError keeps (the total is always counted).
MAX_PROBLEMS = 100


@dataclass(frozen=True)
class LineProblem:
    """One bad line: where it is and why it was refused."""

    path: str
    line: int
    reason: str
    text: str = ""

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.reason}"


class IngestError(ValueError):
    """The job was not ingested (nothing of it was written); `problems` lists bad lines.

    `total` counts every bad line found, even beyond the `MAX_PROBLEMS` kept.
    """

    def __init__(self, message: str, problems: Sequence[LineProblem] = (), total: int = 0):
        self.problems = list(problems)
        self.total = total
        self.summary = message
        super().__init__("\n".join([message, *(str(p) for p in self.problems)]))


# -- checking one line exactly --------------------------------------------------------------


class BadLine(Exception):
    """A line is refused; the message is the reason."""


def _reject_constant(name: str) -> Any:
    raise BadLine(f"bad JSON: {name} is not valid JSON (JSON has no NaN or Infinity)")


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    result = dict(pairs)
    if len(result) != len(pairs):
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise BadLine(f"bad JSON: duplicate key {key!r}")
            seen.add(key)
    return result


_DECODER = json.JSONDecoder(parse_constant=_reject_constant, object_pairs_hook=_unique_keys)


def _what(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, float) else repr(value)
    return f"{type(value).__name__} {text[:40]}{'...' if len(text) > 40 else ''}"


def check_line(raw: bytes, topics: dict[str, Topic], *, unterminated: bool = False
               ) -> tuple[str, int, list[Any]] | None:
    """Check one emissions line: (topic, timestamp, field values as stored), or None if blank.

    Raises ValueError with the reason when the line is refused. `unterminated` says the
    line is the file's last and has no newline (a bad one is reported as truncated).
    """
    try:
        return parse_line(raw, topics, unterminated)
    except BadLine as exc:
        raise ValueError(str(exc)) from None


def too_long(size: int) -> BadLine:
    return BadLine(f"line too long: {size:,} bytes, more than the limit of {MAX_LINE_BYTES:,} bytes of an emissions line")


def parse_line(raw: bytes, topics: dict[str, Topic], unterminated: bool) -> tuple[str, int, list[Any]] | None:
    if len(raw) > MAX_LINE_BYTES:
        raise too_long(len(raw))
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise BadLine(f"invalid UTF-8 at byte {exc.start + 1} of the line") from None
    if not text.strip(" \t\r\n"):
        return None
    if json_too_deep(text):
        raise BadLine(f"nested too deep: more than {MAX_JSON_DEPTH} levels of arrays and objects, the limit of an "
                   "emissions line")
    try:
        record = _DECODER.decode(text)
    except json.JSONDecodeError as exc:
        reason = f"bad JSON at column {exc.colno}: {exc.msg}"
        if unterminated:
            reason = f"truncated last line (no newline at the end of the file): {reason}"
        raise BadLine(reason) from None
    if not isinstance(record, dict):
        raise BadLine(f"expected a JSON object with $metadata and $data, got {_what(record)}")
    for key in ("$metadata", "$data"):
        if key not in record:
            raise BadLine(f"missing {key}")
    extra = [k for k in record if k not in ("$metadata", "$data")]
    if extra:
        raise BadLine(f"unexpected key {extra[0]!r} (a line has only $metadata and $data)")
    meta = record["$metadata"]
    if not isinstance(meta, dict):
        raise BadLine(f"$metadata must be an object, got {_what(meta)}")
    extra = [k for k in meta if k not in ("topic", "timestamp", "event")]
    if extra:
        raise BadLine(f"unexpected key {extra[0]!r} in $metadata (expected topic, timestamp, event)")
    if "topic" not in meta:
        raise BadLine("$metadata has no topic")
    name = meta["topic"]
    if not isinstance(name, str):
        raise BadLine(f"topic must be a string, got {_what(name)}")
    topic = topics.get(name)
    if topic is None:
        raise BadLine(f"unknown topic {name!r}{did_you_mean(name, topics)}")
    if "timestamp" not in meta:
        raise BadLine(f"topic {name!r}: bad timestamp: $metadata has no timestamp")
    timestamp = meta["timestamp"]
    if type(timestamp) is not int or not 0 <= timestamp <= INT64_MAX:
        raise BadLine(f"topic {name!r}: bad timestamp: expected an integer number of nanoseconds "
                   f"from 0 to 2^63-1, got {_what(timestamp)}")
    event = meta.get("event")
    if event is not None and not isinstance(event, bool):
        raise BadLine(f"topic {name!r}: event must be true or false, got {_what(event)}")
    if event and not topic.event:
        raise BadLine(f"topic {name!r} is not an event topic (declare it with event: true)")
    data = record["$data"]
    if not isinstance(data, dict):
        raise BadLine(f"topic {name!r}: $data must be an object, got {_what(data)}")
    missing = [f for f in topic.fields if f not in data]
    if missing:
        raise BadLine(f"topic {name!r}: missing field{'s' if len(missing) > 1 else ''} {', '.join(map(repr, missing))}")
    extra = [f for f in data if f not in topic.fields]
    if extra:
        raise BadLine(f"topic {name!r}: unexpected field{'s' if len(extra) > 1 else ''} {', '.join(map(repr, extra))}"
                   f"{did_you_mean(extra[0], topic.fields)}")
    values = []
    for field_name, field_type in topic.fields.items():
        try:
            value = check_value(field_type, data[field_name])
        except FieldError as exc:
            raise BadLine(f"topic {name!r}, field {field_name!r}: {exc}") from None
        values.append(value)
    return name, timestamp, values
