"""The Emitter: writes typed records to an emissions file (JSON lines), validated against the config.

Drop-in for the reference `resim.metrics.python.emissions.Emitter` (same constructor plus
`flush_interval`, same method names and parameters, `ReSimValidationError` as an alias of
`ValidationError`), with these differences:

- every line is standard JSON (no NaN/Infinity tokens) and carries a timestamp: a missing,
  non-integer, negative or > 2**63-1 timestamp raises `ValidationError` (the reference writes
  a line without timestamp, which the lake cannot store as a BIGINT row);
- validation follows `lakegate.lake.types.check_value` (the same rules ingestion applies),
  including the contents of `metric[]` values, and rejects NaN/inf in float fields;
- one Emitter may be shared by many threads, and lines are buffered and written in chunks
  (see `Emitter` for the flush policy; `flush()` writes now);
- in a forked child (`os.fork`, `multiprocessing` with the fork start method) every emit
  is written before it returns, so the child's lines survive `os._exit` and SIGTERM;
- a failed write (disk full, I/O error) raises `OSError` to the caller on its next emit,
  flush or close, and never leaves part of a line in the file;
- a line longer than 16 MiB or nested deeper than 256 levels raises `ValidationError`
  (ingestion refuses such lines: `lakegate.lake.types.MAX_LINE_BYTES`, `MAX_JSON_DEPTH`);
- a string holding a lone surrogate (`"\\ud800"`), in any position, raises `ValidationError`
  (UTF-8 and Parquet cannot store it);
- emitting on a closed Emitter raises ValueError (the reference silently appends to its
  default path).

As in the reference, `emit()` and `emit_series()` on an event topic write plain rows
(no `"event": true`); only `emit_event()` marks a line as an event, and with a config it
must name an event topic.
"""

from __future__ import annotations

import atexit
import contextlib
import difflib
import json
import os
import sys
import threading
import warnings
import weakref
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from itertools import groupby, repeat, starmap
from json.encoder import encode_basestring_ascii as _json_str
from pathlib import Path
from types import TracebackType
from typing import Any

import orjson

from lakegate.lake.config import Topic, load_config
from lakegate.lake.series_lines import SeriesLines, rows_text
from lakegate.lake.types import MAX_JSON_DEPTH, MAX_LINE_BYTES, check_value, is_utf8, json_too_deep

DEFAULT_OUTPUT_PATH = Path("/tmp/resim/outputs/emissions.resim.jsonl")
DEFAULT_FLUSH_INTERVAL = 0.5  # seconds
MAX_TIMESTAMP = 2**63 - 1  # timestamps are BIGINT nanoseconds
# This many queued lines are written by the emitting thread at once: a chunk this small is encoded and
# written while its records are still in the CPU's cache, which costs about a fifth less CPU per
# record than handing chunks of 8192 to the flusher thread (whose wake-up also waits for the GIL).
_CHUNK_LINES = 1024
_WRITEV_ITEMS = 64  # up to this many queued items are written by one os.writev, more are joined first


class ValidationError(ValueError, TypeError):
    """An emission does not fit its topic; the message names topic, field and (series) index.

    Also a TypeError, like the reference's `ReSimValidationError`, so code written for the
    reference catches it unchanged.
    """

    def __init__(self, reason: str, *, topic: Any = None, field: str | None = None, index: int | None = None):
        self.reason, self.topic, self.field, self.index = reason, topic, field, index
        where = []
        if topic is not None:
            where.append(f"topic {topic!r}")
        if field is not None:
            where.append(f"field {field!r}")
        if index is not None:
            where.append(f"index {index}")
        super().__init__(f"{', '.join(where)}: {reason}" if where else reason)

    def at(self, index: int) -> ValidationError:
        """The same error located at position `index` of a series."""
        return ValidationError(self.reason, topic=self.topic, field=self.field, index=index)


#: The reference's name for the error, for drop-in compatibility.
ReSimValidationError = ValidationError


def _plain(value: Any) -> Any:
    """json.dumps `default`: numpy scalars and arrays become Python values."""
    tolist = getattr(value, "tolist", None)
    if tolist is None:
        raise TypeError(f"{type(value).__name__} is not JSON serializable")
    return tolist()


def _dumps(value: Any) -> str:
    """Standard JSON text for a Python value (numpy accepted; NaN/inf rejected with ValueError)."""
    return json.dumps(value, allow_nan=False, default=_plain)


def _describe(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 60 else text[:57] + '...'}"


def _check_timestamp(topic: Any, timestamp: Any) -> int:
    """The timestamp as an int in [0, 2**63), or ValidationError."""
    if timestamp is None:
        raise ValidationError("a timestamp (int nanoseconds >= 0) is required", topic=topic)
    try:
        value = check_value("int", timestamp)
    except ValueError:
        reason = f"timestamp must be an int (nanoseconds), got {_describe(timestamp)}"
        raise ValidationError(reason, topic=topic) from None
    if not 0 <= value <= MAX_TIMESTAMP:
        raise ValidationError(f"timestamp must be between 0 and 2**63-1 nanoseconds, got {value}", topic=topic)
    return value


def _checked(topic: str, field: str, field_type: str, value: Any) -> Any:
    """`check_value(field_type, value)`, its errors as ValidationError naming topic and field."""
    try:
        return check_value(field_type, value)
    except (ValueError, TypeError, OverflowError) as exc:
        raise ValidationError(str(exc), topic=topic, field=field) from None
    except RecursionError:  # a metric's Plotly object nested far too deep
        raise ValidationError(_TOO_DEEP, topic=topic, field=field) from None


def _json_text(topic: str, field: str, field_type: str, value: Any) -> str:
    """JSON text of a `string[]` or `metric[]` value, checked by `check_value`."""
    stored = _checked(topic, field, field_type, value)
    try:
        # metric[] is written as given: check_value's normal form is for storage, not re-reading.
        text = _dumps(value if field_type == "metric[]" else stored)
    except (ValueError, TypeError) as exc:
        raise ValidationError(f"not standard JSON: {exc}", topic=topic, field=field) from None
    except RecursionError:
        raise ValidationError(_TOO_DEEP, topic=topic, field=field) from None
    if json_too_deep(text, MAX_JSON_DEPTH - 2):  # the line and $data objects hold it
        raise ValidationError(_TOO_DEEP, topic=topic, field=field)
    return text


_TOO_DEEP = f"nested too deep: an emissions line has at most {MAX_JSON_DEPTH} levels of arrays and objects"


def _check_length(topic: str, line: bytes) -> None:
    """ValidationError if `line` (with its newline) is longer than ingestion accepts."""
    if len(line) > MAX_LINE_BYTES + 1:
        raise ValidationError(
            f"the record's line would be {len(line) - 1:,} bytes, more than the limit of "
            f"{MAX_LINE_BYTES:,} bytes of an emissions line",
            topic=topic,
        )


# Per field type: the test under which `check_value` certainly accepts the value @ as it is,
# the expression of its JSON text (bytes) then, and the expression of its JSON text otherwise
# (which calls check_value, so accept/reject is always check_value's decision). Floats are
# written by orjson (shortest round-trip digits, as Python's repr) except below 1e-4 in
# magnitude, where orjson's notation differs from repr's ("0.00001", "1e-7" vs "1e-05", "1e-07").
_FAST = {
    "float": (
        "type(@) is float and (@ >= 1e-4 or @ <= -1e-4 or @ == 0.0) and -1e999 < @ < 1e999",  # NaN compares false
        "_orjson(@)",
        "_float_json(TOPIC, NAME, @)",
    ),
    "int": ("type(@) is int and -0x8000000000000000 <= @ <= 0x7FFFFFFFFFFFFFFF", "b'%d' % @", None),
    "boolean": ("@ is True or @ is False", "(b'true' if @ else b'false')", None),
    # other text: check_value finds lone surrogates
    "string": ("type(@) is str and @.isascii()", "_json_str(@).encode()", None),
}
_FAST.update({t: _FAST["string"] for t in ("status", "image", "video")})
_TIMESTAMP_CHECK = "if type(ts) is not int or not 0 <= ts <= 0x7FFFFFFFFFFFFFFF: ts = _check_timestamp(TOPIC, ts)"
_PLAIN_END = b'}, "$data": '
_EVENT_END = b', "event": true}, "$data": '


def _float_json(topic: str, field: str, value: Any) -> bytes:
    """JSON text of a float field's value (Python's repr, as json.dumps writes it), checked by `check_value`."""
    return repr(_checked(topic, field, "float", value)).encode()


# Per field type of a row (`_Codec.row`): the test under which the value @ goes to orjson as it
# is (its text is then the same as `_FAST`'s), and the checked item otherwise.
_ROW = {
    "float": (
        "type(@) is float and (1e-4 <= @ < 1e999 or -1e999 < @ <= -1e-4 or @ == 0.0)",  # NaN compares false
        "_fragment(_float_json(TOPIC, NAME, @))",
    ),
    "int": (_FAST["int"][0], "_checked(TOPIC, NAME, 'int', @)"),
    "boolean": (_FAST["boolean"][0], "_checked(TOPIC, NAME, 'boolean', @)"),
}


def _percent(text: str) -> bytes:
    """ASCII text as the literal part of a bytes %-format."""
    return text.replace("%", "%%").encode()


class _Codec:
    """A topic compiled into functions that validate records and return their JSON lines.

    `line(data, timestamp, end)` takes one record as a dict and returns its line (bytes);
    `row(data, timestamp)`, made for topics of float, int and boolean fields only (else None),
    checks it the same way and returns the row that `rows_text` turns into the same line;
    `series(end, timestamps, *columns)` takes one list per field, in schema order, and returns
    the list of lines (an error names the index). `end` closes `$metadata`: `_PLAIN_END` or
    `_EVENT_END`. The code is generated (as dataclasses do) so that the common case runs
    without per-field loops or calls. `blocks(stamps, columns)` builds a whole series column by
    column (`SeriesLines.encode`), or returns None for `series` to check it record by record.
    """

    __slots__ = ("topic", "fields", "layout", "line", "series", "row", "blocks")

    def __init__(self, topic: Topic):
        self.topic = topic
        self.fields = tuple(topic.fields)
        self.layout = SeriesLines(topic.name, topic.fields)
        self.line, self.series, self.row = self._compile()
        self.blocks = self.layout.encode

    def _record(self, indent: str) -> list[str]:
        """Source lines that check `ts` and `v0`, `v1`, ... and build the JSON line `text`."""
        checks = [_TIMESTAMP_CHECK]
        template = _percent(f'{{"$metadata": {{"topic": {_json_str(self.topic.name)}, "timestamp": ') + b"%d%b{"
        texts = ["ts", "end"]
        for i, (name, field_type) in enumerate(self.topic.fields.items()):
            v, t = f"v{i}", f"t{i}"
            if field_type in _FAST:
                test, fast, slow = (
                    part and part.replace("@", v).replace("NAME", repr(name)) for part in _FAST[field_type]
                )
                if slow is None:
                    checks.append(f"if not ({test}): {v} = _checked(TOPIC, {name!r}, {field_type!r}, {v})")
                    checks.append(f"{t} = {fast}")
                else:
                    checks.append(f"{t} = {fast} if {test} else {slow}")
            else:
                checks.append(f"{t} = _json_text(TOPIC, {name!r}, {field_type!r}, {v}).encode()")
            texts.append(t)
            template += _percent(("" if i == 0 else ", ") + _json_str(name) + ": ") + b"%b"
        template += b"}}\n"
        checks.append(f"text = {template!r} % ({', '.join(texts)})")
        checks.append("if len(text) > MAX_TEXT: _check_length(TOPIC, text)")
        return [indent + check for check in checks]

    def _unpack(self) -> list[str]:
        """Source lines that check the field names of `data` and set `v0`, `v1`, ... to its values."""
        names = "".join(f"v{i}, " for i in range(len(self.fields)))
        get = f"{names}= {''.join(f'data[{f!r}], ' for f in self.fields)}" if names else "pass"
        unpack = f"{names}= _fields_of(data)" if names else "_fields_of(data)"
        return [
            f"    if type(data) is dict and len(data) == {len(self.fields)}:",
            "        try:",
            f"            {get}",
            "        except KeyError:",
            f"            {unpack}",
            "    else:",
            f"        {unpack}",
        ]

    def _row(self) -> list[str]:
        """Source of `row`, or nothing if a field type has no row form or a line could be too long."""
        types = self.topic.fields.values()
        longest = self.layout.constant_length + 24 * (len(types) + 1)  # 24: the longest number text
        if not all(t in _ROW for t in types) or longest > MAX_LINE_BYTES + 1:
            return []
        source = ["def row(data, ts):", *self._unpack(), "    " + _TIMESTAMP_CHECK]
        items = ["P0", "ts"]
        for i, (name, field_type) in enumerate(self.topic.fields.items()):
            test, slow = (part.replace("@", f"v{i}").replace("NAME", repr(name)) for part in _ROW[field_type])
            source.append(f"    if not ({test}): v{i} = {slow}")
            items += [f"P{i + 1}", f"v{i}"]
        items.append(f"P{len(types) + 1}")
        return [*source, f"    return ({', '.join(items)})"]

    def _compile(
        self,
    ) -> tuple[Callable[..., bytes], Callable[..., list[bytes]], Callable[..., tuple[Any, ...]] | None]:
        names = "".join(f"v{i}, " for i in range(len(self.fields)))
        columns = "".join(f"c{i}, " for i in range(len(self.fields)))
        source = [
            "def line(data, ts, end=PLAIN_END):",
            *self._unpack(),
            *self._record("    "),
            "    return text",
            f"def series(end, stamps, {columns}):",
            "    lines = []",
            "    append = lines.append",
            "    try:",
            f"        for ts, {names}in zip(stamps, {columns}):",
            *self._record("            "),
            "            append(text)",
            "    except ValidationError as exc:",
            "        raise exc.at(len(lines)) from None",
            "    return lines",
            *self._row(),
        ]
        namespace: dict[str, Any] = {
            "_json_str": _json_str,
            "_orjson": orjson.dumps,
            "_float_json": _float_json,
            "_checked": _checked,
            "_json_text": _json_text,
            "ValidationError": ValidationError,
            "_check_timestamp": _check_timestamp,
            "_fields_of": self.fields_of,
            "TOPIC": self.topic.name,
            "PLAIN_END": _PLAIN_END,
            "MAX_TEXT": MAX_LINE_BYTES + 1,
            "_check_length": _check_length,
            "_fragment": orjson.Fragment,
            **{f"P{i}": part for i, part in enumerate(self.layout.parts)},
        }
        exec("\n".join(source), namespace)  # noqa: S102 - names and templates are repr()'d
        return namespace["line"], namespace["series"], namespace.get("row")

    def fields_of(self, data: Any) -> list[Any]:
        """The values of `data` in schema order, or ValidationError for a non-mapping or wrong keys."""
        if not isinstance(data, Mapping):
            raise ValidationError(f"data must be a dict of field values, got {_describe(data)}", topic=self.topic.name)
        check_field_names(self.topic, data.keys())
        return [data[name] for name in self.fields]


def check_field_names(topic: Topic, names: Iterable[Any]) -> None:
    """ValidationError naming the first missing or unknown field of `topic`, if any."""
    names = list(names)
    declared = f"the topic has {', '.join(map(repr, topic.fields))}" if topic.fields else "the topic has no fields"
    missing = [f for f in topic.fields if f not in names]
    if missing:
        raise ValidationError(
            f"missing field(s) {', '.join(map(repr, missing))}; {declared}", topic=topic.name, field=missing[0]
        )
    extra = [n for n in names if n not in topic.fields]
    if extra:
        hint = difflib.get_close_matches(str(extra[0]), list(topic.fields), n=1)
        raise ValidationError(
            f"unknown field(s) {', '.join(map(repr, extra))}; " + (f"did you mean {hint[0]!r}?" if hint else declared),
            topic=topic.name,
            field=str(extra[0]),
        )


def _plain_data_json(topic: Any, data: Any) -> str:
    """`$data` JSON text without a config: any JSON-able dict (numpy accepted), standard JSON only."""
    if not isinstance(topic, str) or not topic or not is_utf8(topic):
        raise ValidationError(f"topic must be a non-empty string of valid Unicode text, got {_describe(topic)}")
    if not isinstance(data, Mapping):
        raise ValidationError(f"data must be a dict of field values, got {_describe(data)}", topic=topic)
    try:
        text = _dumps(dict(data))
    except RecursionError:
        raise ValidationError(_TOO_DEEP, topic=topic) from None
    except (ValueError, TypeError) as exc:
        error: Exception = exc
    else:
        if json_too_deep(text, MAX_JSON_DEPTH - 1):  # the line's object holds it
            raise ValidationError(_TOO_DEEP, topic=topic)
        if "\\ud" not in text or _utf8_everywhere(data):  # \\ud...: an escaped surrogate, maybe a lone one
            return text
        error = ValueError(_LONE_SURROGATE)
    for name, value in data.items():  # find the field to blame
        if not isinstance(name, str) or not is_utf8(name):
            raise ValidationError(
                f"field names must be strings of valid Unicode text, got {_describe(name)}", topic=topic
            )
        try:
            _dumps(value)
            if not _utf8_everywhere(value):
                raise ValueError(_LONE_SURROGATE)
        except (ValueError, TypeError) as exc:
            error = exc
            break
    else:
        name = None
    reason = str(error)
    if reason.startswith("Out of range float values"):
        reason = "NaN and infinity are not standard JSON"
    if reason != _LONE_SURROGATE:
        reason = f"not standard JSON: {reason}"
    raise ValidationError(reason, topic=topic, field=name)


_LONE_SURROGATE = "a string holds a lone surrogate (U+D800-U+DFFF), which is not valid Unicode text"


def _utf8_everywhere(value: Any) -> bool:
    """False if a string anywhere in `value` (dict keys included) holds a lone surrogate."""
    if isinstance(value, str):
        return is_utf8(value)
    if isinstance(value, Mapping):
        return all(_utf8_everywhere(k) and _utf8_everywhere(v) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return all(_utf8_everywhere(v) for v in value)
    tolist = getattr(value, "tolist", None)  # numpy arrays of str
    return _utf8_everywhere(tolist()) if tolist is not None and not isinstance(value, (int, float)) else True


def _as_column(topic: str, field: str, values: Any) -> list[Any]:
    if isinstance(values, list):
        return values
    if isinstance(values, (tuple, range)):
        return list(values)
    tolist = getattr(values, "tolist", None)  # numpy arrays
    column = tolist() if tolist is not None else None
    if not isinstance(column, list):
        raise ValidationError(
            f"emit_series needs a list or 1-D array per field, got {_describe(values)}", topic=topic, field=field
        )
    return column


#: Emitters not yet closed, flushed and closed at interpreter exit (weakly held: GC still works).
_LIVE: weakref.WeakSet[Emitter] = weakref.WeakSet()


class Emitter:
    """Writes emissions as JSON lines to `output_path`, validated when a config is given.

    `config_path` is one path or a list of paths to config files (`load_config` merges them).
    As in the reference, files that do not exist are skipped with a warning, and validation
    is off when none exists or the merged config declares no topics; an invalid config
    raises `ConfigError`. Lines are appended to `output_path` (parent folders are created).

    Flush policy: validated lines are queued in memory and appended to the file in
    whole-line chunks, in emission order (a record of a topic whose fields are all float, int
    or boolean is queued as its checked values, which are immutable, and becomes its line
    when written): by the emitting thread itself as soon as 1024 lines are queued (or when one
    `emit_series` call brings 1024 or more), by a daemon flusher thread every `flush_interval`
    seconds, and on `flush()`, `close()`,
    garbage collection and interpreter exit (atexit).
    So a crash of the emitting process, even SIGKILL, loses at most the lines of the last
    `flush_interval`; a record with an error raises before anything of it is queued (for
    `emit_series`, before any of its records is). Data is handed to the OS, not synced to
    disk: a machine crash may lose more.

    Write errors (a full disk): only whole lines reach the file (after a short write the
    partial line is cut off again); the lines not written stay queued, in order, for the
    next flush. `flush()` and `close()` raise the `OSError`; a failure of the flusher thread,
    or of a chunk written by `emit`, is raised by the next `emit`, `flush` or `close` call (an
    `emit` that raises it has not queued its record). `close()` raises when lines remain unwritten: they are lost.

    Threads: one Emitter may be shared; lines of different threads never interleave and each
    thread's lines keep their order (the queue's appends are atomic; one lock orders the
    writes). Close it only after the emitting threads are done: a line emitted while
    `close()` runs may be lost.

    Forked children (`os.fork`, `multiprocessing` Process and Pool with the fork start
    method): the lines queued before the fork are left to the parent to write; the child
    writes its own lines to the same file (appending whole lines in one write each, so
    lines of the processes never interleave) before each emit returns, so they survive
    every way a child ends, `os._exit` and a Pool's SIGTERM included. No exit hook could
    do that: `os._exit` and signals run none.
    """

    def __init__(
        self,
        config_path: str | os.PathLike[str] | Iterable[str | os.PathLike[str]] | None = None,
        output_path: str | os.PathLike[str] = DEFAULT_OUTPUT_PATH,
        flush_interval: float = DEFAULT_FLUSH_INTERVAL,
    ):
        if not flush_interval > 0:
            raise ValueError(f"flush_interval must be > 0 seconds, got {flush_interval!r}")
        self._closed = True  # until the file is open, so that __del__ and close() are no-ops
        if config_path is None:
            self.config_paths: list[Path] = []
        elif isinstance(config_path, (str, os.PathLike)):
            self.config_paths = [Path(config_path)]
        else:
            self.config_paths = [Path(p) for p in config_path]
        self.output_path = Path(output_path)
        self.flush_interval = float(flush_interval)
        self.topics: dict[str, Topic] = self._load_topics()
        self.validation_enabled = bool(self.topics)
        self._codecs = {name: _Codec(topic) for name, topic in self.topics.items()}
        # emit() queues a row where the topic has one (made into lines when written), else a line
        self._emits = {name: codec.row or codec.line for name, codec in self._codecs.items()}
        self.output_path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(self.output_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)  # not inherited by exec
        self._closed = False
        self._start(_CHUNK_LINES)
        _LIVE.add(self)

    def _load_topics(self) -> dict[str, Topic]:
        present = []
        for path in self.config_paths:
            if path.is_file():
                present.append(path)
            else:
                warnings.warn(f"metrics config {path} not found: emissions are not validated against it", stacklevel=3)
        return load_config(present).topics if present else {}

    def _start(self, chunk_lines: int) -> None:
        """Fresh queue and lock, and the flusher thread unless every emit writes (`chunk_lines` 1)."""
        # lines, blocks of lines and rows; appends and pops are atomic: emitting threads take no lock
        self._queue: deque[bytes | tuple[Any, ...]] = deque()
        self._write_lock = threading.Lock()  # held while lines are taken and written: keeps their order
        self._wake = threading.Event()  # set once closed: the flusher thread should stop
        self._chunk_lines = chunk_lines  # a queue this long is written by the emitting thread
        self._error: OSError | None = None  # a write error of the flusher thread, not yet raised
        self._stopped = False  # closed, or _error set: emit must look before queuing
        if chunk_lines > 1:
            threading.Thread(
                target=_flush_periodically,
                args=(weakref.ref(self), self._wake, self.flush_interval),
                name=f"emitter-flush {self.output_path.name}",
                daemon=True,
            ).start()

    # --- emitting -----------------------------------------------------------------------

    def emit(self, topic_name: str, data: dict[str, Any], timestamp: int | None = None) -> None:
        """Emit one record of `topic_name` at `timestamp` (int nanoseconds, required)."""
        encode = self._emits.get(topic_name)
        if encode is not None:
            item = encode(data, timestamp)
        else:
            item = self._unvalidated_line(topic_name, data, timestamp, _PLAIN_END)
        if self._stopped:
            self._raise_stopped()
        queue = self._queue
        queue.append(item)
        if len(queue) >= self._chunk_lines:
            self._write_chunk()

    def emit_event(self, topic_name: str, data: dict[str, Any], timestamp: int) -> None:
        """Emit one event (a line with `"event": true`); with a config, the topic must be an event topic."""
        codec = self._codecs.get(topic_name)
        if codec is not None:
            if not codec.topic.event:
                raise ValidationError("not an event topic (add `event: true` to it, or use emit())", topic=topic_name)
            line = codec.line(data, timestamp, _EVENT_END)
        else:
            line = self._unvalidated_line(topic_name, data, timestamp, _EVENT_END)
        self._append([line])

    def emit_series(self, topic_name: str, data: dict[str, list[Any]], timestamps: Iterable[int] | None = None) -> None:
        """Emit one record per position of the equally long lists (or 1-D arrays) in `data`.

        Equivalent to `emit(topic_name, {k: v[i] for k, v in data.items()}, timestamps[i])`
        for each i, except that nothing is written unless every record is valid.
        """
        if timestamps is None:
            raise ValidationError(
                "emit_series needs timestamps (int nanoseconds >= 0), one per value", topic=topic_name
            )
        if not isinstance(data, Mapping):
            raise ValidationError(f"data must be a dict of lists, got {_describe(data)}", topic=topic_name)
        columns = {name: _as_column(topic_name, name, values) for name, values in data.items()}
        stamps = _as_column(topic_name, "timestamps", timestamps)
        wrong = [name for name, column in columns.items() if len(column) != len(stamps)]
        if wrong:
            shown = ", ".join(f"{name!r}: {len(column)}" for name, column in columns.items())
            raise ValidationError(
                f"series differ in length: {len(stamps)} timestamps, {shown}", topic=topic_name, field=wrong[0]
            )
        codec = self._codecs.get(topic_name)
        if codec is not None:
            check_field_names(codec.topic, columns)
            ordered = [columns[name] for name in codec.fields]
            blocks = codec.blocks(stamps, ordered) if stamps else None
            if blocks is not None:
                self._append_blocks(blocks, len(stamps))
                return
            lines = codec.series(_PLAIN_END, stamps, *ordered)
        else:
            lines = []
            try:
                for i, stamp in enumerate(stamps):
                    record = {name: column[i] for name, column in columns.items()}
                    lines.append(self._unvalidated_line(topic_name, record, stamp, _PLAIN_END))
            except ValidationError as exc:
                raise exc.at(len(lines)) from None
        self._append(lines)

    def _unvalidated_line(self, topic_name: Any, data: Any, timestamp: Any, end: bytes) -> bytes:
        if self.validation_enabled:
            hint = difflib.get_close_matches(str(topic_name), list(self.topics), n=1)
            known = f"did you mean {hint[0]!r}?" if hint else f"the config declares {', '.join(map(repr, self.topics))}"
            raise ValidationError(f"unknown topic; {known}", topic=topic_name)
        body = _plain_data_json(topic_name, data)
        timestamp = _check_timestamp(topic_name, timestamp)
        line = (
            f'{{"$metadata": {{"topic": {_json_str(topic_name)}, "timestamp": {timestamp}'.encode()
            + end
            + f"{body}}}\n".encode()
        )
        _check_length(topic_name, line)
        return line

    # --- buffering and writing ----------------------------------------------------------

    def _append(self, lines: list[bytes]) -> None:
        if self._stopped:
            self._raise_stopped()
        self._queue.extend(lines)
        if len(self._queue) >= self._chunk_lines:
            self._write_chunk()

    def _append_blocks(self, blocks: list[bytes], count: int) -> None:
        """Queue `count` lines given as blocks of whole lines; a chunk or more is written now."""
        if self._stopped:
            self._raise_stopped()
        if count < self._chunk_lines:
            self._append(b"".join(blocks).splitlines(keepends=True))  # JSON text holds no raw \r or \n
            return
        self._queue.extend(blocks)
        self._write_chunk()

    def _raise_stopped(self) -> None:
        """ValueError once closed; else the flusher thread's pending write error (raised once)."""
        if self._closed:
            raise ValueError("emit on a closed Emitter")
        error, self._error, self._stopped = self._error, None, False
        if error is not None:
            raise error

    def _fail(self, error: OSError) -> None:
        """Keep a write error for the next emit, flush or close to raise."""
        self._error, self._stopped = error, True

    def _write_chunk(self) -> None:
        """Write the queued lines from the emitting thread; a write error is kept for the next call."""
        try:
            self.flush()
        except OSError as exc:
            self._fail(exc)

    def _write_queued(self) -> None:
        """Append the queued lines to the file; call with _write_lock held.

        Each run of queued rows (of `emit`) becomes one block of their lines. A few items
        (blocks of whole lines of `emit_series` or rows) are handed to `os.writev` as they are;
        many (single lines) are joined into one buffer first. Only whole lines stay in the file:
        after a short write the partial line is cut off. On OSError the lines not written go
        back to the front of the queue.
        """
        queue = self._queue
        items: list[bytes] = []
        for kind, run in groupby(starmap(queue.popleft, repeat((), len(queue))), type):
            if kind is tuple:
                items.append(rows_text(list(run)))
            else:
                items.extend(run)
        if len(items) > _WRITEV_ITEMS:
            items = [b"".join(items)]
        done = 0
        data = b""
        try:
            done = os.writev(self._fd, items)
            size = sum(map(len, items))
            if done < size:  # a short write: the rest goes byte-exactly, or fails
                data = b"".join(items)
                while done < size:
                    done += os.write(self._fd, memoryview(data)[done:])
        except OSError as exc:
            self._write_failed(exc, data or b"".join(items), done)

    def _write_failed(self, exc: OSError, data: bytes, done: int) -> None:
        """Cut off a partial line after `done` bytes of `data`, requeue the lines not written, raise."""
        partial = done - (data.rfind(b"\n", 0, done) + 1)
        if partial:
            with contextlib.suppress(OSError):  # with O_APPEND the file offset is where our write ended
                os.ftruncate(self._fd, os.lseek(self._fd, 0, os.SEEK_CUR) - partial)
        unwritten = data[done - partial :]
        self._queue.appendleft(unwritten)
        count = unwritten.count(b"\n")
        raise OSError(
            exc.errno,
            f"the Emitter could not write {self.output_path}: {exc.strerror} ({count} line(s) not written)",
        ) from exc

    def flush(self) -> None:
        """Append every queued line to the file now; OSError if that fails (the lines stay queued)."""
        with self._write_lock:
            if self._closed:
                return
            error, self._error, self._stopped = self._error, None, False
            if self._queue:
                self._write_queued()
            elif error is not None:
                raise error

    def close(self) -> None:
        """Write the queued lines and close the file; later calls do nothing.

        OSError if lines could not be written (they are lost).
        """
        with self._write_lock:
            if self._closed:
                return
            self._closed = self._stopped = True
            self._wake.set()
            try:
                if self._queue:
                    self._write_queued()
            finally:
                self._queue.clear()
                os.close(self._fd)
                _LIVE.discard(self)

    def _after_fork_in_child(self) -> None:
        if not self._closed:
            self._start(1)  # every emit writes; the parent writes what was queued before the fork

    def __enter__(self) -> Emitter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - nothing can be reported from a finalizer
            pass


def _flush_periodically(ref: weakref.ref[Emitter], wake: threading.Event, interval: float) -> None:
    """The flusher thread: flush every `interval` seconds until closed (which wakes it) or garbage-collected."""
    while True:
        wake.wait(interval)
        wake.clear()
        emitter = ref()
        if emitter is None or emitter._closed:
            return
        try:
            emitter.flush()
        except OSError as exc:  # e.g. disk full: the lines stay queued, the emitting thread gets the error
            emitter._fail(exc)
        del emitter


@atexit.register
def _close_all_at_exit() -> None:
    for emitter in list(_LIVE):
        try:
            emitter.close()
        except OSError as exc:  # nobody to raise it to: say it on standard error, once, without a traceback
            print(f"lakegate: {exc}", file=sys.stderr)


def _restart_in_forked_child() -> None:
    for emitter in list(_LIVE):
        emitter._after_fork_in_child()


os.register_at_fork(after_in_child=_restart_in_forked_child)
