"""Ingestion: emissions files (JSON lines) of one job -> Parquet files in the lake.

`ingest_job` validates every line against the branch's topics and writes one Parquet file
per topic (columns `timestamp`, the declared fields, `experience_name`, `build_version`),
the job's `events` and its `metadata` row, under the Hive layout of `lake.paths`. Files are
written to `_staging/` and, once the whole job is good, made the job's tables all at once
by one commit of the branch's record (`lake.record`); a bad
line fails the job (nothing written) unless `skip_bad_lines`, which keeps the good rows
and writes the bad lines with their reasons to a quarantine file.

How lines are checked (fast and exact):

* Files are read in blocks of whole lines (memory stays bounded), worked on by a few
  threads. A line longer than `MAX_LINE_BYTES` (16 MiB) is refused without being held
  whole, and one nested deeper than `MAX_JSON_DEPTH` (256) before it is parsed. Each line's topic is guessed from its text (`{"$metadata": {"topic": "NAME"`
  as the Emitter writes it, or a looser pattern), and lines are grouped by topic.
* Lines exactly in the Emitter's layout (`{"$metadata": {"topic": T, "timestamp": DIGITS},
  "$data": {...}}`, checked with numpy on the bytes) only need their `$data` object
  parsed; other lines are parsed whole. Either way Arrow's JSON reader parses a topic's
  group with the topic's exact schema. That reader is strict where lakegate is strict
  (standard JSON only, no extra or duplicate keys, no `1.0` for an int, no number for a
  string ...); what it lets through is then checked column by column (row count, topic,
  timestamp, nulls, finite floats, event flag).
* Every line the fast paths do not certainly accept -- and every line of topics with
  `metric[]` fields -- is decided by `check_line`, which applies `lake.types.check_value`
  (the Emitter's rules) to the parsed JSON. So a line is accepted exactly when
  `check_line` accepts it; the fast paths only save time (tests check they agree).
"""
from __future__ import annotations

import json
import sys
import time
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.json as pj
import pyarrow.parquet as pq
from numpy.lib.stride_tricks import sliding_window_view
from tqdm import tqdm

from lakegate.lake import paths
from lakegate.lake.config import Config, Topic
from lakegate.lake.config_yaml import did_you_mean
from lakegate.lake.metadata import build_metadata_row, metadata_table, write_metadata_file
from lakegate.lake.record import Change
from lakegate.lake.registry import BranchConfigs
from lakegate.lake.schema import (EVENTS_COLUMNS, JOB_COLUMNS, RESERVED_FIELDS, TIMESTAMP, field_arrow_type, file_schema,
                                  topic_columns)
from lakegate.lake.types import INT64_MAX, MAX_JSON_DEPTH, MAX_LINE_BYTES, FieldError, check_value, json_too_deep

BLOCK_SIZE = 16 << 20
#: Rows buffered per topic before they are written as (part of) a row group.
ROWS_PER_WRITE = 128 * 1024
#: How many problems an IngestError keeps (the total is always counted).
MAX_PROBLEMS = 100
THREADS = 2

EVENTS_SCHEMA = file_schema(paths.EVENTS_TABLE, EVENTS_COLUMNS)
#: events column -> field types of an event topic that fill it (other types leave it NULL).
EVENT_FIELDS = {
    "name": ("string", "status", "image", "video"),
    "description": ("string", "status", "image", "video"),
    "status": ("string", "status", "image", "video"),
    "tags": ("string[]",),
    "metrics": ("metric[]",),
}
_LINE = "_line"  # line number column of intermediate tables


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


@dataclass
class IngestReport:
    """What one ingest did."""

    branch: str
    batch_id: str
    job_id: str
    rows: dict[str, int]  # every declared topic -> rows written (0 if none)
    events: int
    lines: int
    bad_lines: int
    quarantine: Path | None
    seconds: float
    config_version: int
    files: list[Path] = field(default_factory=list)
    problems: list[LineProblem] = field(default_factory=list)  # the first MAX_PROBLEMS, when skipped


# -- checking one line exactly --------------------------------------------------------------


class _Bad(Exception):
    """A line is refused; the message is the reason."""


def _reject_constant(name: str) -> Any:
    raise _Bad(f"bad JSON: {name} is not valid JSON (JSON has no NaN or Infinity)")


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    result = dict(pairs)
    if len(result) != len(pairs):
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise _Bad(f"bad JSON: duplicate key {key!r}")
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
        return _check_line(raw, topics, unterminated)
    except _Bad as exc:
        raise ValueError(str(exc)) from None


def _too_long(size: int) -> _Bad:
    return _Bad(f"line too long: {size:,} bytes, more than the limit of {MAX_LINE_BYTES:,} bytes of an emissions line")


def _check_line(raw: bytes, topics: dict[str, Topic], unterminated: bool) -> tuple[str, int, list[Any]] | None:
    if len(raw) > MAX_LINE_BYTES:
        raise _too_long(len(raw))
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _Bad(f"invalid UTF-8 at byte {exc.start + 1} of the line") from None
    if not text.strip(" \t\r\n"):
        return None
    if json_too_deep(text):
        raise _Bad(f"nested too deep: more than {MAX_JSON_DEPTH} levels of arrays and objects, the limit of an "
                   "emissions line")
    try:
        record = _DECODER.decode(text)
    except json.JSONDecodeError as exc:
        reason = f"bad JSON at column {exc.colno}: {exc.msg}"
        if unterminated:
            reason = f"truncated last line (no newline at the end of the file): {reason}"
        raise _Bad(reason) from None
    if not isinstance(record, dict):
        raise _Bad(f"expected a JSON object with $metadata and $data, got {_what(record)}")
    for key in ("$metadata", "$data"):
        if key not in record:
            raise _Bad(f"missing {key}")
    extra = [k for k in record if k not in ("$metadata", "$data")]
    if extra:
        raise _Bad(f"unexpected key {extra[0]!r} (a line has only $metadata and $data)")
    meta = record["$metadata"]
    if not isinstance(meta, dict):
        raise _Bad(f"$metadata must be an object, got {_what(meta)}")
    extra = [k for k in meta if k not in ("topic", "timestamp", "event")]
    if extra:
        raise _Bad(f"unexpected key {extra[0]!r} in $metadata (expected topic, timestamp, event)")
    if "topic" not in meta:
        raise _Bad("$metadata has no topic")
    name = meta["topic"]
    if not isinstance(name, str):
        raise _Bad(f"topic must be a string, got {_what(name)}")
    topic = topics.get(name)
    if topic is None:
        raise _Bad(f"unknown topic {name!r}{did_you_mean(name, topics)}")
    if "timestamp" not in meta:
        raise _Bad(f"topic {name!r}: bad timestamp: $metadata has no timestamp")
    timestamp = meta["timestamp"]
    if type(timestamp) is not int or not 0 <= timestamp <= INT64_MAX:
        raise _Bad(f"topic {name!r}: bad timestamp: expected an integer number of nanoseconds "
                   f"from 0 to 2^63-1, got {_what(timestamp)}")
    event = meta.get("event")
    if event is not None and not isinstance(event, bool):
        raise _Bad(f"topic {name!r}: event must be true or false, got {_what(event)}")
    if event and not topic.event:
        raise _Bad(f"topic {name!r} is not an event topic (declare it with event: true)")
    data = record["$data"]
    if not isinstance(data, dict):
        raise _Bad(f"topic {name!r}: $data must be an object, got {_what(data)}")
    missing = [f for f in topic.fields if f not in data]
    if missing:
        raise _Bad(f"topic {name!r}: missing field{'s' if len(missing) > 1 else ''} {', '.join(map(repr, missing))}")
    extra = [f for f in data if f not in topic.fields]
    if extra:
        raise _Bad(f"topic {name!r}: unexpected field{'s' if len(extra) > 1 else ''} {', '.join(map(repr, extra))}"
                   f"{did_you_mean(extra[0], topic.fields)}")
    values = []
    for field_name, field_type in topic.fields.items():
        try:
            value = check_value(field_type, data[field_name])
        except FieldError as exc:
            raise _Bad(f"topic {name!r}, field {field_name!r}: {exc}") from None
        values.append(value)
    return name, timestamp, values


# -- topics as plans -------------------------------------------------------------------------


class _Plan:
    """How one topic's lines are read and stored."""

    def __init__(self, index: int, topic: Topic):
        self.index = index
        self.topic = topic
        self.name = topic.name
        self.file_schema = file_schema(topic.name, topic_columns(topic))
        self.schema = pa.schema([field for field in self.file_schema if field.name not in JOB_COLUMNS])
        # metric[] values are normalised by check_value; a topic without fields has no Arrow struct
        self.fast = bool(topic.fields) and "metric[]" not in topic.fields.values()
        if self.fast:
            meta = pa.struct([("topic", pa.string()), ("timestamp", pa.int64()), ("event", pa.bool_())])
            data = pa.struct([(f, field_arrow_type(t)) for f, t in topic.fields.items()])
            self.line_options = pj.ParseOptions(explicit_schema=pa.schema([("$metadata", meta), ("$data", data)]),
                                                unexpected_field_behavior="error")
            self.data_options = pj.ParseOptions(explicit_schema=pa.schema(list(data)), unexpected_field_behavior="error")
        # how the topic's name may be written between quotes in a line
        self.spellings = sorted({json.dumps(self.name)[1:-1].encode(), json.dumps(self.name, ensure_ascii=False)[1:-1].encode()})


def _plans(config: Config) -> list[_Plan]:
    plans = []
    for index, topic in enumerate(config.topics.values()):
        paths.check_table_name(topic.name)
        clash = RESERVED_FIELDS.intersection(topic.fields)
        if clash:
            raise IngestError(f"topic {topic.name!r} declares field {sorted(clash)[0]!r}, a column lakegate adds "
                              "to every topic row; rename the field")
        plans.append(_Plan(index, topic))
    return plans


# -- reading blocks of lines -----------------------------------------------------------------


@dataclass
class _Block:
    path: str
    first_line: int  # number of the block's first line (1-based)
    data: bytes  # whole lines, each ending with a newline
    offsets: np.ndarray  # line i is data[offsets[i]:offsets[i+1]]
    unterminated: int  # line number of a last line that had no newline, else 0
    too_long: dict[int, int] = field(default_factory=dict)  # line i -> its size, when above MAX_LINE_BYTES

    def line_bytes(self, i: int) -> bytes:
        """Line i of the block, without its newline."""
        return self.data[self.offsets[i]:self.offsets[i + 1] - 1]


def _blocks(path: Path) -> Iterator[_Block]:
    """The file's lines in blocks of whole lines, about BLOCK_SIZE bytes each.

    A line longer than `MAX_LINE_BYTES` that would have to be held whole across blocks is
    skipped instead: it is an empty line of the block, with its size in `too_long`.
    """
    max_line = MAX_LINE_BYTES
    first = 1
    rest = b""
    skipped = 0  # bytes of an overlong line being skipped
    with open(path, "rb") as handle:
        while True:
            chunk = handle.read(BLOCK_SIZE)
            if skipped and chunk:
                end = chunk.find(b"\n")
                if end < 0:
                    skipped += len(chunk)
                    continue
                skipped += end
                chunk = chunk[end:]  # its newline ends the skipped line, an empty line here
            unterminated = False
            if not chunk:
                if not rest and not skipped:
                    return
                data, rest, unterminated = rest + b"\n", b"", True
            else:
                data = rest + chunk if rest else chunk
                end = data.rfind(b"\n")
                if end < 0:
                    rest, skipped = (b"", len(data)) if len(data) > max_line else (data, 0)
                    continue
                data, rest = data[:end + 1], data[end + 1:]
            block = _block(str(path), first, data, unterminated, max_line)
            if skipped:
                block.too_long[0], skipped = skipped, 0
            yield block
            first += len(block.offsets) - 1


def _block(path: str, first: int, data: bytes, unterminated: bool, max_line: int) -> _Block:
    """A block of the whole lines in `data` (which ends with a newline), its overlong lines noted."""
    array = np.frombuffer(data, np.uint8)
    newlines = np.flatnonzero(array == 10)
    offsets = np.empty(len(newlines) + 1, np.int64)
    offsets[0] = 0
    offsets[1:] = newlines + 1
    count = len(newlines)
    sizes = np.diff(offsets) - 1
    too_long = {int(i): int(sizes[i]) for i in np.flatnonzero(sizes > max_line)}
    return _Block(path, first, data, offsets, first + count - 1 if unterminated else 0, too_long)


def _window(data: np.ndarray, starts: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """The `width` bytes of `data` at each start, and which starts had that many bytes."""
    if len(data) < width:
        return np.zeros((len(starts), width), np.uint8), np.zeros(len(starts), bool)
    whole = (starts >= 0) & (starts <= len(data) - width)
    return sliding_window_view(data, width)[np.where(whole, starts, 0)], whole


def _equals_at(data: np.ndarray, starts: np.ndarray, literal: bytes) -> np.ndarray:
    """Whether `literal` is at each start."""
    window, whole = _window(data, starts, len(literal))
    return whole & (np.ascontiguousarray(window).view(f"S{len(literal)}").ravel() == literal)


class _Hinter:
    """Guesses each line's topic from its text, as an index into the plans (-1: check it exactly).

    A guess is only a hint: the fast paths check the topic, so a wrong guess costs time,
    never correctness. For lines that start as the Emitter writes them
    (`{"$metadata": {"topic": "NAME"`) it also gives where the topic's closing quote ends.
    """

    PREFIX = b'{"$metadata": {"topic": "'
    LOOSE = r'^[ \t\r]*\{.*?"topic"\s*:\s*"(?P<t>[^"\\]*)"'

    def __init__(self, plans: list[_Plan]):
        spelled = sorted((spelling + b'"', plan.index) for plan in plans if plan.fast for spelling in plan.spellings)
        self.width = max((len(s) for s, _ in spelled), default=0)
        self.keys = np.array([s for s, _ in spelled], dtype=f"S{max(self.width, 1)}")
        self.codes = np.array([i for _, i in spelled], np.int16)
        self.names = pa.array([s[:-1] for s, _ in spelled], pa.large_binary())

    def codes_of(self, block: _Block, lines: pa.Array) -> tuple[np.ndarray, np.ndarray]:
        """(plan index or -1, position after the topic's closing quote or -1) of each line."""
        codes = np.full(len(lines), -1, np.int16)
        after = np.full(len(lines), -1, np.int64)
        if not len(self.keys) or not len(lines):
            return codes, after
        standard = pc.starts_with(lines, pattern=self.PREFIX.decode()).to_numpy(zero_copy_only=False)
        # the `width` bytes after the prefix, cut after the first quote, looked up among the spellings
        name_at = block.offsets[:-1] + len(self.PREFIX)
        window, whole = _window(np.frombuffer(block.data, np.uint8), name_at, self.width)
        window = window.copy()
        quote = (window == ord('"')).argmax(axis=1)
        window[np.arange(self.width) > quote[:, None]] = 0
        keys = window.view(f"S{self.width}").ravel()
        where = np.minimum(np.searchsorted(self.keys, keys), len(self.keys) - 1)
        hit = standard & whole & (self.keys[where] == keys)
        codes[hit] = self.codes[where[hit]]
        after[hit] = name_at[hit] + quote[hit] + 1
        others = np.flatnonzero(~standard)
        if len(others):
            text = lines.take(pa.array(others)).cast(pa.large_string())
            names = pc.extract_regex(text, self.LOOSE).field("t").cast(pa.large_binary())
            found = pc.fill_null(pc.index_in(names, value_set=self.names), -1).to_numpy()
            hit = found >= 0
            codes[others[hit]] = self.codes[found[hit]]
        return codes, after


_TIMESTAMP_KEY = b', "timestamp": '
#: What may follow the timestamp's digits in the Emitter's layout, and whether it makes the line an event.
_DATA_KEYS = ((b'}, "$data": ', False), (b', "event": true}, "$data": ', True), (b', "event": false}, "$data": ', False))


def _emitter_layout(block: _Block, lines: np.ndarray, after: np.ndarray, event_topic: bool
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Which of the given lines are exactly `{"$metadata": {"topic": T, "timestamp": N[, "event": B]}, "$data": X}`.

    `after` is where each line's topic name ends (-1: not this layout); `"event": true` is
    only this layout for an event topic. Returns (mask, timestamps, where X starts, where
    the line's closing brace is). Such a line is valid JSON with exactly that meaning if
    and only if X is a valid JSON object, so only X needs parsing (`_payloads`).
    """
    data = np.frombuffer(block.data, np.uint8)
    width = len(_TIMESTAMP_KEY)
    window, ok = _window(data, after, width + 20)
    ok &= np.ascontiguousarray(window[:, :width]).view(f"S{width}").ravel() == _TIMESTAMP_KEY
    digits = window[:, width:] - np.uint8(ord("0"))
    count = (digits < 10).argmin(axis=1)  # leading digits (0 also when all 20 are)
    ok &= (count > 0) & ((count == 1) | (digits[:, 0] != 0))  # JSON has no leading zeros
    digits_end = after + width + count
    value = np.zeros(len(lines), np.uint64)
    for position in range(int(count[ok].max(initial=0))):  # Horner, digit by digit
        value = np.where(position < count, value * np.uint64(10) + digits[:, position], value)
    ok &= value <= np.uint64(INT64_MAX)
    start = np.full(len(lines), -1, np.int64)
    for key, event in _DATA_KEYS:
        left = np.flatnonzero(ok & (start < 0))
        if len(left) and (event_topic or not event):
            hit = left[_equals_at(data, digits_end[left], key)]
            start[hit] = digits_end[hit] + len(key)
    ok &= start >= 0
    # X starts with '{' and the line ends with X's '}' and the line's '}' (then '\r'?, '\n')
    newline = block.offsets[lines + 1] - 1
    close = newline - 1 - (data[np.maximum(newline - 1, 0)] == ord("\r"))
    ok &= (close - 1 > start) & (data[np.clip(start, 0, len(data) - 1)] == ord("{"))
    ok &= (data[np.maximum(close, 0)] == ord("}")) & (data[np.maximum(close - 1, 0)] == ord("}"))
    return ok, value.astype(np.int64), start, close


def _payloads(scratch: bytearray, start: np.ndarray, close: np.ndarray) -> pa.Buffer:
    """The X of each line (from `start` to the line's closing brace at `close`), each on its own line.

    The closing braces in `scratch` (a copy of the block) become newlines; lines are in order.
    """
    data = np.frombuffer(scratch, np.uint8)
    data[close] = ord("\n")
    offsets = np.empty(2 * len(start), np.int64)
    offsets[0::2] = start
    offsets[1::2] = close + 1
    texts = pa.Array.from_buffers(pa.large_binary(), len(offsets) - 1, [None, pa.py_buffer(offsets), pa.py_buffer(scratch)])
    return _gather(texts, np.arange(0, len(offsets) - 1, 2))


# -- turning blocks into tables --------------------------------------------------------------


@dataclass
class _Result:
    """What a part of a block gave: per plan index a table (with line numbers), and problems."""

    tables: dict[int, pa.Table] = field(default_factory=dict)
    problems: list[LineProblem] = field(default_factory=list)


def _slow(plans: list[_Plan], topics: dict[str, Topic], block: _Block, lines: Sequence[int]) -> _Result:
    """Check the given lines (indexes into the block) one by one with `check_line`."""
    rows: dict[str, list[tuple[int, int, list[Any]]]] = {}
    result = _Result()
    for i in lines:
        number = block.first_line + int(i)
        raw = block.line_bytes(int(i))
        try:
            if int(i) in block.too_long:
                raise _too_long(block.too_long[int(i)])
            checked = _check_line(raw, topics, unterminated=number == block.unterminated)
        except _Bad as exc:
            text = raw[:1000 if int(i) in block.too_long else None].decode("utf-8", "surrogateescape")
            result.problems.append(LineProblem(block.path, number, str(exc), text))
            continue
        if checked is not None:
            name, timestamp, values = checked
            rows.setdefault(name, []).append((number, timestamp, values))
    by_name = {plan.name: plan for plan in plans}
    for name, topic_rows in rows.items():
        plan = by_name[name]
        columns = [pa.array([r[0] for r in topic_rows], pa.int64()), pa.array([r[1] for r in topic_rows], pa.int64())]
        for j, (_, kind) in enumerate(plan.topic.fields.items()):
            columns.append(pa.array([r[2][j] for r in topic_rows], field_arrow_type(kind)))
        result.tables[plan.index] = pa.Table.from_arrays(columns, schema=pa.schema([(_LINE, pa.int64()), *plan.schema]))
    return result


def _gather(texts: pa.Array, indexes: np.ndarray) -> pa.Buffer:
    """The given elements of a binary array, one after the other, as one buffer."""
    taken = texts.take(pa.array(indexes))
    offsets = np.frombuffer(taken.buffers()[1], np.int64)[taken.offset:taken.offset + len(taken) + 1]
    return taken.buffers()[2].slice(int(offsets[0]), int(offsets[-1] - offsets[0]))


def _parse(buffer: pa.Buffer, options: pj.ParseOptions, rows: int) -> pa.Table | None:
    """Arrow's strict parse of newline-separated JSON objects; None unless it gives exactly `rows` rows."""
    try:
        parsed = pj.read_json(pa.BufferReader(buffer), parse_options=options,
                              read_options=pj.ReadOptions(use_threads=False, block_size=max(buffer.size + 1, 1 << 16)))
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError, pa.ArrowTypeError):
        return None
    if parsed.num_rows != rows or parsed.schema != options.explicit_schema:
        return None
    return parsed


def _valid_values(plan: _Plan, values: Sequence[pa.Array], good: pa.Array) -> pa.Array:
    """`good` narrowed to rows whose field values are all storable: present, finite, no null in lists."""
    for kind, column in zip(plan.topic.fields.values(), values):
        good = pc.and_(good, column.is_valid())
        if kind == "float":
            good = pc.and_(good, pc.fill_null(pc.is_finite(column), False))
        elif kind == "string[]" and column.values.null_count:
            flat_nulls = pc.is_null(pc.list_flatten(column)).to_numpy(zero_copy_only=False)
            holders = np.unique(pc.list_parent_indices(column).to_numpy()[flat_nulls])
            mask = np.ones(len(column), bool)
            mask[holders] = False
            good = pc.and_(good, pa.array(mask))
    return good


def _accept(plan: _Plan, numbers: np.ndarray, timestamp: pa.Array, values: Sequence[pa.Array],
            good: pa.Array) -> tuple[pa.Table, np.ndarray]:
    """(table of the good rows, with line numbers; positions of the other rows)."""
    good = _valid_values(plan, values, good)
    table = pa.Table.from_arrays([pa.array(numbers, pa.int64()), timestamp, *values],
                                 schema=pa.schema([(_LINE, pa.int64()), *plan.schema]))
    if good.null_count == 0 and pc.all(good).as_py():
        return table, np.array([], np.int64)
    return table.filter(good), np.flatnonzero(~good.to_numpy(zero_copy_only=False))


def _fast_lines(plan: _Plan, buffer: pa.Buffer, numbers: np.ndarray) -> tuple[pa.Table | None, np.ndarray]:
    """Whole lines of one topic parsed by Arrow: (table of the certainly good rows, positions of the others)."""
    parsed = _parse(buffer, plan.line_options, len(numbers))
    if parsed is None:
        return None, np.arange(len(numbers))
    meta = parsed.column("$metadata").combine_chunks()
    data = parsed.column("$data").combine_chunks()
    topic, timestamp, event = meta.flatten()
    good = pc.and_(meta.is_valid(), data.is_valid())
    good = pc.and_(good, pc.fill_null(pc.equal(topic, plan.name), False))
    good = pc.and_(good, pc.fill_null(pc.greater_equal(timestamp, 0), False))
    if not plan.topic.event:
        good = pc.and_(good, pc.invert(pc.fill_null(event, False)))
    return _accept(plan, numbers, timestamp, data.flatten(), good)


def _fast_payloads(plan: _Plan, buffer: pa.Buffer, numbers: np.ndarray, timestamps: np.ndarray
                   ) -> tuple[pa.Table | None, np.ndarray]:
    """The `$data` objects of lines in the Emitter's layout parsed by Arrow: as `_fast_lines`."""
    parsed = _parse(buffer, plan.data_options, len(numbers))
    if parsed is None:
        return None, np.arange(len(numbers))
    values = [column.combine_chunks() for column in parsed.columns]
    return _accept(plan, numbers, pa.array(timestamps, pa.int64()), values, pa.repeat(True, len(numbers)))


def _process(plans: list[_Plan], topics: dict[str, Topic], block: _Block, pool: ThreadPoolExecutor,
             hinter: _Hinter) -> list[Future[_Result]]:
    """Start the work of one block; its futures give _Results."""
    count = len(block.offsets) - 1
    lines = pa.Array.from_buffers(pa.large_binary(), count, [None, pa.py_buffer(block.offsets), pa.py_buffer(block.data)])
    try:
        lines.cast(pa.large_string())  # validates UTF-8 of the whole block
        codes, after = hinter.codes_of(block, lines)
    except pa.ArrowInvalid:
        codes, after = np.full(count, -1, np.int16), np.full(count, -1, np.int64)  # invalid UTF-8: check exactly
    if block.too_long:
        codes[list(block.too_long)] = -1  # check_line refuses them
    scratch = bytearray(block.data) if (after >= 0).any() else None
    order = np.argsort(codes, kind="stable")
    bounds = np.searchsorted(codes[order], np.arange(-1, len(plans) + 1))
    futures = []
    if bounds[1]:
        futures.append(pool.submit(_slow, plans, topics, block, order[:bounds[1]]))
    for plan in plans:
        group = order[bounds[plan.index + 1]:bounds[plan.index + 2]]
        if len(group):
            futures.append(pool.submit(_check_group, plans, topics, block, plan, lines, group, after[group], scratch))
    return futures


def _check_group(plans: list[_Plan], topics: dict[str, Topic], block: _Block, plan: _Plan, lines: pa.Array,
                 group: np.ndarray, after: np.ndarray, scratch: bytearray | None) -> _Result:
    """Check one topic's lines of a block: Arrow for what it certainly accepts, check_line for the rest."""
    parts, refused = [], []
    layout, timestamps, start, close = _emitter_layout(block, group, after, plan.topic.event)
    if layout.any():
        texts = _payloads(scratch, start[layout], close[layout])
        table, bad = _fast_payloads(plan, texts, block.first_line + group[layout], timestamps[layout])
        parts.append(table)
        refused.append(group[layout][bad])
    others = group[~layout]
    if len(others):
        table, bad = _fast_lines(plan, _gather(lines, others), block.first_line + others)
        parts.append(table)
        refused.append(others[bad])
    results = [_Result({plan.index: t}) for t in parts if t is not None and t.num_rows]
    refused_lines = np.sort(np.concatenate(refused)) if refused else np.array([], np.int64)
    if len(refused_lines):  # a refused line may even be another topic's
        results.append(_slow(plans, topics, block, refused_lines))
    if len(results) == 1:
        return results[0]
    return _Result(_merge_results(results), [p for r in results for p in r.problems])


def _merge_results(results: Sequence[_Result]) -> dict[int, pa.Table]:
    """Per plan index, the tables of several results as one, in line order."""
    pieces: dict[int, list[pa.Table]] = {}
    for result in results:
        for index, table in result.tables.items():
            pieces.setdefault(index, []).append(table)
    return {index: tables[0] if len(tables) == 1 else pa.concat_tables(tables).sort_by(_LINE)
            for index, tables in pieces.items()}


# -- writing ---------------------------------------------------------------------------------


class _JobWriter:
    """Buffers each topic's rows and writes them to Parquet files in the staging directory."""

    def __init__(self, scratch: Path, plans: list[_Plan], job_values: dict[str, str | None]):
        self.scratch = scratch
        self.plans = plans
        self.job_values = job_values
        self.buffers: dict[int, list[pa.Table]] = {}
        self.buffered: dict[int, int] = {}
        self.writers: dict[str, pq.ParquetWriter] = {}
        self.rows = {plan.name: 0 for plan in plans}
        self.events = 0
        self.enabled = True

    def add(self, index: int, table: pa.Table) -> None:
        plan = self.plans[index]
        self.rows[plan.name] += table.num_rows
        if not self.enabled:
            return
        self.buffers.setdefault(index, []).append(table)
        self.buffered[index] = self.buffered.get(index, 0) + table.num_rows
        if self.buffered[index] >= ROWS_PER_WRITE:
            self._flush(index)

    def _constants(self, count: int) -> list[pa.Array]:
        return [pa.repeat(pa.scalar(self.job_values.get(name), pa.string()), count) for name in JOB_COLUMNS]

    def _flush(self, index: int) -> None:
        tables = self.buffers.pop(index, [])
        self.buffered[index] = 0
        if not tables:
            return
        plan = self.plans[index]
        table = pa.concat_tables(tables).drop_columns([_LINE])
        table = pa.Table.from_arrays([*table.columns, *self._constants(table.num_rows)], schema=plan.file_schema)
        self._write(plan.name, table)
        if plan.topic.event:
            self._write_events(plan, table)

    def _write_events(self, plan: _Plan, table: pa.Table) -> None:
        count = table.num_rows
        columns = [table.column(TIMESTAMP), pa.repeat(pa.scalar(plan.name, pa.string()), count)]
        for name, kinds in EVENT_FIELDS.items():
            if plan.topic.fields.get(name) in kinds:
                columns.append(table.column(name))
            else:
                columns.append(pa.nulls(count, EVENTS_SCHEMA.field(name).type))
        columns += self._constants(count)
        self.events += count
        self._write(paths.EVENTS_TABLE, pa.Table.from_arrays(columns, schema=EVENTS_SCHEMA))

    def _write(self, name: str, table: pa.Table) -> None:
        writer = self.writers.get(name)
        if writer is None:
            strings = [f.name for f in table.schema if pa.types.is_string(f.type)]  # numbers rarely repeat
            writer = pq.ParquetWriter(self.scratch / f"{name}.parquet", table.schema, compression="zstd",
                                      use_dictionary=strings)
            self.writers[name] = writer
        writer.write_table(table, row_group_size=1 << 20)

    def close(self) -> dict[str, Path]:
        """Write what is buffered and close the files; table name -> staged file."""
        if self.enabled:
            for index in list(self.buffers):
                self._flush(index)
        for writer in self.writers.values():
            writer.close()
        return {name: self.scratch / f"{name}.parquet" for name in self.writers}


# -- the job ---------------------------------------------------------------------------------


def ingest_job(
    lake: Path,
    branch: str,
    batch_id: str,
    job_id: str,
    emissions: Sequence[Path],
    *,
    config: Config,
    metadata: dict[str, Any] | None = None,
    skip_bad_lines: bool = False,
    progress: bool = False,
) -> IngestReport:
    """Ingest the emissions files of one job into the lake (replacing an earlier ingest of it).

    Raises IngestError (nothing written) when a line is bad and `skip_bad_lines` is off,
    MetadataError for bad metadata, LakePathError for names the lake cannot hold.
    """
    started = time.perf_counter()
    lake = Path(lake)
    paths.encode_branch(branch)
    paths.check_segment(batch_id, "batch id")
    paths.check_segment(job_id, "job id")
    plans = _plans(config)
    files = [Path(p) for p in emissions]
    for path in files:
        if not path.is_file():
            raise IngestError(f"emissions file {str(path)!r} does not exist or is not a file")
    row = build_metadata_row(metadata or {}, lake=lake, branch=branch, batch_id=batch_id, job_id=job_id)
    problems: list[LineProblem] = []
    bad = 0
    lines = 0
    with paths.job_lock(lake, branch, batch_id, job_id), paths.staging(lake, branch) as scratch:
        writer = _JobWriter(scratch, plans, {c: row[c] for c in JOB_COLUMNS})
        quarantine = scratch / "quarantine.jsonl"
        with open(quarantine, "w", encoding="utf-8") as bad_lines, \
                ThreadPoolExecutor(THREADS, thread_name_prefix="lakegate-ingest") as pool, \
                tqdm(total=sum(p.stat().st_size for p in files), unit="B", unit_scale=True, desc="ingest",
                     disable=not progress, file=sys.stderr, dynamic_ncols=True) as bar:
            pending: deque[tuple[_Block, list[Future[_Result]]]] = deque()

            def collect() -> None:
                nonlocal bad, lines
                block, futures = pending.popleft()
                results = [f.result() for f in futures]
                found = sorted((p for r in results for p in r.problems), key=lambda p: p.line)
                if found:
                    bad += len(found)
                    problems.extend(found[:max(0, MAX_PROBLEMS - len(problems))])
                    if skip_bad_lines:
                        bad_lines.writelines(json.dumps({"file": p.path, "line": p.line, "reason": p.reason,
                                                         "text": p.text}) + "\n" for p in found)
                    else:
                        writer.enabled = False  # the job fails: keep counting problems, write nothing
                for index, table in _merge_results(results).items():
                    writer.add(index, table)
                lines += len(block.offsets) - 1
                bar.update(len(block.data) - (1 if block.unterminated else 0))
                bar.set_postfix(lines=f"{lines:,}", refresh=False)

            topics = {plan.name: plan.topic for plan in plans}
            hinter = _Hinter(plans)
            for path in files:
                for block in _blocks(path):
                    pending.append((block, _process(plans, topics, block, pool, hinter)))
                    while len(pending) > 2:
                        collect()
            while pending:
                collect()
        if bad and not skip_bad_lines:
            writer.close()
            raise IngestError(f"{bad} bad line{'s' if bad > 1 else ''} in the emissions of job {job_id!r}; nothing "
                              "was written (use --skip-bad-lines to keep the good rows)", problems, bad)
        staged = writer.close()
        metadata_file = scratch / "metadata.parquet"
        write_metadata_file(metadata_table(row), metadata_file)
        staged[paths.METADATA_TABLE] = metadata_file
        version = BranchConfigs(lake, branch).store_config(config)
        published = _publish(lake, branch, batch_id, job_id, staged)
        quarantine_target = paths.quarantine_file(lake, branch, batch_id, job_id)
        if bad:
            paths.publish(quarantine, quarantine_target)
        else:
            quarantine_target.unlink(missing_ok=True)
    return IngestReport(
        branch=branch, batch_id=batch_id, job_id=job_id, rows=writer.rows, events=writer.events, lines=lines,
        bad_lines=bad, quarantine=quarantine_target if bad else None, seconds=time.perf_counter() - started,
        config_version=version, files=published, problems=problems if bad else [],
    )


def _publish(lake: Path, branch: str, batch_id: str, job_id: str, staged: dict[str, Path]) -> list[Path]:
    """Make the staged files the job's tables, all at once (one record commit); the old files go."""
    change = Change(lake, branch)
    for name, file in staged.items():
        change.add(name, batch_id, job_id, file)
    change.replace_job(batch_id, job_id)
    return change.commit(f"ingest {batch_id}/{job_id}")
