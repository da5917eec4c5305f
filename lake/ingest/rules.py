"""Ingestion rules: whether one emissions line is accepted, exactly (the Emitter's rules, `types.check_value`)."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
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
    topic: str | None = None  # the declared topic the line names, if it names one

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.reason}"


@dataclass
class BadLines:
    """Every bad line of a job by cause: the first line of each distinct reason and how many share
    it, and per topic how many lines a skip would drop (None: lines naming no declared topic)."""

    causes: dict[str, tuple[LineProblem, int]] = field(default_factory=dict)
    dropped: Counter[str | None] = field(default_factory=Counter)

    def add(self, problem: LineProblem) -> None:
        first, count = self.causes.get(problem.reason, (problem, 0))
        self.causes[problem.reason] = (first, count + 1)
        self.dropped[problem.topic] += 1

    def what_skipping_drops(self, topics: dict[str, Topic]) -> str:
        """`2 rows of topic 'a', 109 events of event topic 'goal_reached' (with their metrics)`."""
        parts = []
        for name, count in self.dropped.most_common():
            if name is None:
                parts.append(f"{count} line{'s' if count > 1 else ''} naming no declared topic")
            elif topics[name].event:
                parts.append(f"{count} event{'s' if count > 1 else ''} of event topic {name!r} (with their metrics)")
            else:
                parts.append(f"{count} row{'s' if count > 1 else ''} of topic {name!r}")
        return ", ".join(parts)


class IngestError(ValueError):
    """The job was not ingested (nothing of it was written); `problems` lists bad lines.

    `total` counts every bad line found, even beyond the `MAX_PROBLEMS` kept.
    """

    def __init__(
        self, message: str, problems: Sequence[LineProblem] = (), total: int = 0, bad_lines: BadLines | None = None
    ):
        self.problems = list(problems)
        self.total = total
        self.bad_lines = bad_lines or BadLines()
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


def check_line(
    raw: bytes, topics: dict[str, Topic], *, unterminated: bool = False
) -> tuple[str, int, list[Any]] | None:
    """Check one emissions line: (topic, timestamp, field values as stored), or None if blank.

    Raises ValueError with the reason when the line is refused. `unterminated` says the
    line is the file's last and has no newline (a bad one is reported as truncated).
    """
    try:
        return parse_line(raw, topics, unterminated)
    except BadLine as exc:
        raise ValueError(str(exc)) from None


def topic_of(text: str, topics: dict[str, Topic]) -> str | None:
    """The declared topic a (bad) line names, if it can be read."""
    try:
        name = json.loads(text)["$metadata"]["topic"]
    except (ValueError, TypeError, KeyError, RecursionError):
        return None
    return name if isinstance(name, str) and name in topics else None


def too_long(size: int) -> BadLine:
    return BadLine(
        f"line too long: {size:,} bytes, more than the limit of {MAX_LINE_BYTES:,} bytes of an emissions line"
    )


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
        raise BadLine(
            f"nested too deep: more than {MAX_JSON_DEPTH} levels of arrays and objects, the limit of an emissions line"
        )
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
        raise BadLine(
            f"topic {name!r}: bad timestamp: expected an integer number of nanoseconds "
            f"from 0 to 2^63-1, got {_what(timestamp)}"
        )
    event = meta.get("event")
    if event is not None and not isinstance(event, bool):
        raise BadLine(f"topic {name!r}: event must be true or false, got {_what(event)}")
    if event and not topic.event:
        raise BadLine(f"topic {name!r} is not an event topic (declare it with event: true)")
    data = record["$data"]
    if not isinstance(data, dict):
        raise BadLine(f"topic {name!r}: $data must be an object, got {_what(data)}")
    values, problems = _check_data(topic, data)
    if problems:
        raise BadLine(f"topic {name!r}{', ' if problems[0].startswith('field ') else ': '}" + "; ".join(problems))
    return name, timestamp, values


def _check_data(topic: Topic, data: dict[str, Any]) -> tuple[list[Any], list[str]]:
    """The field values as stored, and every problem of `$data` (missing, unexpected and bad fields)."""
    problems = []
    missing = [f for f in topic.fields if f not in data]
    if missing:
        problems.append(f"missing field{'s' if len(missing) > 1 else ''} {', '.join(map(repr, missing))}")
    unexpected = [f for f in data if f not in topic.fields]
    problems += [f"unexpected field {f!r}{did_you_mean(f, missing or topic.fields)}" for f in unexpected]
    values = []
    for field_name, field_type in topic.fields.items():
        if field_name in data:
            try:
                values.append(check_value(field_type, data[field_name]))
            except FieldError as exc:
                problems.append(f"field {field_name!r}: {exc}")
    return values, problems
