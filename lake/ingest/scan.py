"""Ingestion scan: emissions files read in blocks of whole lines, each topic's lines turned into an
Arrow table by the fast paths (Arrow's JSON reader) or, for what they do not certainly accept,
by `rules.check_line`'s exact check (the package docstring says how)."""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.json as pj
from numpy.lib.stride_tricks import sliding_window_view

from lakegate.lake import paths, platform_tables
from lakegate.lake.config import Config, Topic
from lakegate.lake.ingest.rules import BadLine, IngestError, LineProblem, parse_line, too_long, topic_of
from lakegate.lake.schema import (
    JOB_COLUMNS,
    RESERVED_FIELDS,
    field_arrow_type,
    file_schema,
    job_columns,
    topic_columns,
)
from lakegate.lake.types import INT64_MAX, MAX_LINE_BYTES

BLOCK_SIZE = 16 << 20
THREADS = 2
LINE = "_line"  # line number column of intermediate tables
#: The columns of an events file that hold the same value on every row of a job (`job_id` too).
JOB_FILE_COLUMNS = (*(name for name, _ in JOB_COLUMNS), "job_id")


class Plan:
    """How one topic's lines are read and stored."""

    def __init__(self, index: int, topic: Topic):
        self.index = index
        self.topic = topic
        self.name = topic.name
        self.file_schema = file_schema(topic.name, topic_columns(topic))
        #: the columns of its file that hold the same value on every row of a job (`job_id` too)
        self.job_file_columns = (*(name for name, _ in job_columns(topic)), "job_id")
        self.schema = pa.schema([field for field in self.file_schema if field.name not in self.job_file_columns])
        # metric[] values are normalised by check_value; a topic without fields has no Arrow struct
        self.fast = bool(topic.fields) and "metric[]" not in topic.fields.values()
        if self.fast:
            meta = pa.struct([("topic", pa.string()), ("timestamp", pa.int64()), ("event", pa.bool_())])
            data = pa.struct([(f, field_arrow_type(t)) for f, t in topic.fields.items()])
            self.line_options = pj.ParseOptions(
                explicit_schema=pa.schema([("$metadata", meta), ("$data", data)]), unexpected_field_behavior="error"
            )
            self.data_options = pj.ParseOptions(
                explicit_schema=pa.schema(list(data)), unexpected_field_behavior="error"
            )
        # how the topic's name may be written between quotes in a line
        self.spellings = sorted(
            {json.dumps(self.name)[1:-1].encode(), json.dumps(self.name, ensure_ascii=False)[1:-1].encode()}
        )


def topic_plans(config: Config) -> list[Plan]:
    """The plans of the config's topics and of the platform tables (`lake.platform_tables`)."""
    plans = []
    for index, topic in enumerate([*config.topics.values(), *platform_tables.TOPICS.values()]):
        paths.check_table_name(topic.name)
        clash = RESERVED_FIELDS.intersection(topic.fields)
        if clash:
            raise IngestError(
                f"topic {topic.name!r} declares field {sorted(clash)[0]!r}, a column lakegate adds "
                "to every topic row; rename the field"
            )
        plans.append(Plan(index, topic))
    return plans


# -- reading blocks of lines -----------------------------------------------------------------


@dataclass
class Block:
    path: str
    first_line: int  # number of the block's first line (1-based)
    data: bytes  # whole lines, each ending with a newline
    offsets: np.ndarray  # line i is data[offsets[i]:offsets[i+1]]
    unterminated: int  # line number of a last line that had no newline, else 0
    too_long: dict[int, int] = field(default_factory=dict)  # line i -> its size, when above MAX_LINE_BYTES

    def line_bytes(self, i: int) -> bytes:
        """Line i of the block, without its newline."""
        return self.data[self.offsets[i] : self.offsets[i + 1] - 1]


def read_blocks(path: Path) -> Iterator[Block]:
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
                data, rest = data[: end + 1], data[end + 1 :]
            block = _block(str(path), first, data, unterminated, max_line)
            if skipped:
                block.too_long[0], skipped = skipped, 0
            yield block
            first += len(block.offsets) - 1


def _block(path: str, first: int, data: bytes, unterminated: bool, max_line: int) -> Block:
    """A block of the whole lines in `data` (which ends with a newline), its overlong lines noted."""
    array = np.frombuffer(data, np.uint8)
    newlines = np.flatnonzero(array == 10)
    offsets = np.empty(len(newlines) + 1, np.int64)
    offsets[0] = 0
    offsets[1:] = newlines + 1
    count = len(newlines)
    sizes = np.diff(offsets) - 1
    too_long = {int(i): int(sizes[i]) for i in np.flatnonzero(sizes > max_line)}
    return Block(path, first, data, offsets, first + count - 1 if unterminated else 0, too_long)


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


class Hinter:
    """Guesses each line's topic from its text, as an index into the plans (-1: check it exactly).

    A guess is only a hint: the fast paths check the topic, so a wrong guess costs time,
    never correctness. For lines that start as the Emitter writes them
    (`{"$metadata": {"topic": "NAME"`) it also gives where the topic's closing quote ends.
    """

    PREFIX = b'{"$metadata": {"topic": "'
    LOOSE = r'^[ \t\r]*\{.*?"topic"\s*:\s*"(?P<t>[^"\\]*)"'

    def __init__(self, plans: list[Plan]):
        spelled = sorted((spelling + b'"', plan.index) for plan in plans if plan.fast for spelling in plan.spellings)
        self.width = max((len(s) for s, _ in spelled), default=0)
        self.keys = np.array([s for s, _ in spelled], dtype=f"S{max(self.width, 1)}")
        self.codes = np.array([i for _, i in spelled], np.int16)
        self.names = pa.array([s[:-1] for s, _ in spelled], pa.large_binary())

    def codes_of(self, block: Block, lines: pa.Array) -> tuple[np.ndarray, np.ndarray]:
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
_DATA_KEYS = (
    (b'}, "$data": ', False),
    (b', "event": true}, "$data": ', True),
    (b', "event": false}, "$data": ', False),
)


def _emitter_layout(
    block: Block, lines: np.ndarray, after: np.ndarray, event_topic: bool
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
    texts = pa.Array.from_buffers(
        pa.large_binary(), len(offsets) - 1, [None, pa.py_buffer(offsets), pa.py_buffer(scratch)]
    )
    return _gather(texts, np.arange(0, len(offsets) - 1, 2))


# -- turning blocks into tables --------------------------------------------------------------


@dataclass
class Result:
    """What a part of a block gave: per plan index a table (with line numbers), and problems."""

    tables: dict[int, pa.Table] = field(default_factory=dict)
    problems: list[LineProblem] = field(default_factory=list)


def _slow(plans: list[Plan], topics: dict[str, Topic], block: Block, lines: Sequence[int]) -> Result:
    """Check the given lines (indexes into the block) one by one with `check_line`."""
    rows: dict[str, list[tuple[int, int, list[Any]]]] = {}
    result = Result()
    for i in lines:
        number = block.first_line + int(i)
        raw = block.line_bytes(int(i))
        try:
            if int(i) in block.too_long:
                raise too_long(block.too_long[int(i)])
            checked = parse_line(raw, topics, unterminated=number == block.unterminated)
        except BadLine as exc:
            text = raw[: 1000 if int(i) in block.too_long else None].decode("utf-8", "surrogateescape")
            result.problems.append(LineProblem(block.path, number, str(exc), text, topic_of(text, topics)))
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
        result.tables[plan.index] = pa.Table.from_arrays(columns, schema=pa.schema([(LINE, pa.int64()), *plan.schema]))
    return result


def _gather(texts: pa.Array, indexes: np.ndarray) -> pa.Buffer:
    """The given elements of a binary array, one after the other, as one buffer."""
    taken = texts.take(pa.array(indexes))
    offsets = np.frombuffer(taken.buffers()[1], np.int64)[taken.offset : taken.offset + len(taken) + 1]
    return taken.buffers()[2].slice(int(offsets[0]), int(offsets[-1] - offsets[0]))


def _parse(buffer: pa.Buffer, options: pj.ParseOptions, rows: int) -> pa.Table | None:
    """Arrow's strict parse of newline-separated JSON objects; None unless it gives exactly `rows` rows."""
    try:
        parsed = pj.read_json(
            pa.BufferReader(buffer),
            parse_options=options,
            read_options=pj.ReadOptions(use_threads=False, block_size=max(buffer.size + 1, 1 << 16)),
        )
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError, pa.ArrowTypeError):
        return None
    if parsed.num_rows != rows or parsed.schema != options.explicit_schema:
        return None
    return parsed


def _valid_values(plan: Plan, values: Sequence[pa.Array], good: pa.Array) -> pa.Array:
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


def _accept(
    plan: Plan, numbers: np.ndarray, timestamp: pa.Array, values: Sequence[pa.Array], good: pa.Array
) -> tuple[pa.Table, np.ndarray]:
    """(table of the good rows, with line numbers; positions of the other rows)."""
    good = _valid_values(plan, values, good)
    table = pa.Table.from_arrays(
        [pa.array(numbers, pa.int64()), timestamp, *values], schema=pa.schema([(LINE, pa.int64()), *plan.schema])
    )
    if good.null_count == 0 and pc.all(good).as_py():
        return table, np.array([], np.int64)
    return table.filter(good), np.flatnonzero(~good.to_numpy(zero_copy_only=False))


def _fast_lines(plan: Plan, buffer: pa.Buffer, numbers: np.ndarray) -> tuple[pa.Table | None, np.ndarray]:
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


def _fast_payloads(
    plan: Plan, buffer: pa.Buffer, numbers: np.ndarray, timestamps: np.ndarray
) -> tuple[pa.Table | None, np.ndarray]:
    """The `$data` objects of lines in the Emitter's layout parsed by Arrow: as `_fast_lines`."""
    parsed = _parse(buffer, plan.data_options, len(numbers))
    if parsed is None:
        return None, np.arange(len(numbers))
    values = [column.combine_chunks() for column in parsed.columns]
    return _accept(plan, numbers, pa.array(timestamps, pa.int64()), values, pa.repeat(True, len(numbers)))


def process_block(
    plans: list[Plan], topics: dict[str, Topic], block: Block, pool: ThreadPoolExecutor, hinter: Hinter
) -> list[Future[Result]]:
    """Start the work of one block; its futures give _Results."""
    count = len(block.offsets) - 1
    lines = pa.Array.from_buffers(
        pa.large_binary(), count, [None, pa.py_buffer(block.offsets), pa.py_buffer(block.data)]
    )
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
        futures.append(pool.submit(_slow, plans, topics, block, order[: bounds[1]]))
    for plan in plans:
        group = order[bounds[plan.index + 1] : bounds[plan.index + 2]]
        if len(group):
            futures.append(pool.submit(_check_group, plans, topics, block, plan, lines, group, after[group], scratch))
    return futures


def _check_group(
    plans: list[Plan],
    topics: dict[str, Topic],
    block: Block,
    plan: Plan,
    lines: pa.Array,
    group: np.ndarray,
    after: np.ndarray,
    scratch: bytearray | None,
) -> Result:
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
    results = [Result({plan.index: t}) for t in parts if t is not None and t.num_rows]
    refused_lines = np.sort(np.concatenate(refused)) if refused else np.array([], np.int64)
    if len(refused_lines):  # a refused line may even be another topic's
        results.append(_slow(plans, topics, block, refused_lines))
    if len(results) == 1:
        return results[0]
    return Result(merge_results(results), [p for r in results for p in r.problems])


def merge_results(results: Sequence[Result]) -> dict[int, pa.Table]:
    """Per plan index, the tables of several results as one, in line order."""
    pieces: dict[int, list[pa.Table]] = {}
    for result in results:
        for index, table in result.tables.items():
            pieces.setdefault(index, []).append(table)
    return {
        index: tables[0] if len(tables) == 1 else pa.concat_tables(tables).sort_by(LINE)
        for index, tables in pieces.items()
    }
