"""Post-hoc import of robot logs: the messages of an MCAP file become topic rows, through the Emitter.

A mapping file (YAML) says, per MCAP topic, which lakegate topic its messages fill and how:

```yaml
/odom:
  topic: odom_linear_velocity            # a topic of the metrics config
  fields:                                # topic field: path in the message
    x: twist.twist.linear.x
    y: twist.twist.linear.y
  timestamp: header.stamp                # log_time (default), publish_time, or a message path
  decimate: 10                           # optional: keep one message in 10
```

A path is attribute or key names joined by dots, with `[i]` for an element of a list
(`poses[0].position.x`). A timestamp path names a ROS time (`sec` and `nanosec`) or an integer of
nanoseconds. Messages are decoded with `mcap-ros2-support` (ROS 2 messages with a `ros2msg`
schema; no ROS installation needed), `mcap-protobuf-support` (protobuf messages with their
descriptors) or as JSON (message encoding `json`). Every row goes through
the `Emitter`, so it is checked against the config exactly as emitted rows are. Errors name the
mapping file, line and column, and the message (topic, index, log time) with the field path.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from operator import attrgetter
from pathlib import Path
from typing import Any

from mcap.decoder import DecoderFactory
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory
from ruamel.yaml.nodes import MappingNode

from lakegate.lake.config import Location, Topic
from lakegate.lake.config_schema import Key, Section
from lakegate.lake.config_yaml import FileReader, RawProblem
from lakegate.lake.emitter import Emitter, ValidationError

#: Where a message's timestamp comes from when the mapping does not say: the MCAP log time.
LOG_TIME, PUBLISH_TIME = "log_time", "publish_time"
_STEP = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)")
_INDEX = re.compile(r"\[(\d+)\]")

MAPPING = Section(
    "mapping",
    {
        "topic": Key("string", "The lakegate topic the messages fill.", required=True),
        "fields": Key("data", "Topic field -> path in the message.", required=True),
        "timestamp": Key("string", "log_time (default), publish_time, or a path in the message."),
        "decimate": Key("threshold", "Keep one message in this many (an integer >= 1)."),
    },
)


class MappingError(ValueError):
    """The mapping file is wrong; `problems` are `file:line:col: message` lines."""

    def __init__(self, problems: list[str]):
        self.problems = problems
        super().__init__("\n".join(problems))


class McapImportError(ValueError):
    """A message cannot become a row; the message names the mapping's place and the message."""


@dataclass(frozen=True)
class MessagePath:
    """A path in a message (`twist.linear.x`, `poses[0].x`) and where the mapping wrote it."""

    text: str
    steps: tuple[str | int, ...]
    location: Location
    #: For a path of names only: one C-level lookup of the attributes (decoded ROS 2 and protobuf messages).
    attributes: Callable[[Any], Any] | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        names_only = all(isinstance(step, str) for step in self.steps)
        object.__setattr__(self, "attributes", attrgetter(self.text) if names_only else None)

    def get(self, message: Any) -> Any:
        """The value at this path; KeyError naming the first step that is not there."""
        if self.attributes is not None and not isinstance(message, dict):
            try:
                return self.attributes(message)
            except AttributeError:
                pass  # the walk below names the missing step
        value = message
        for step in self.steps:
            try:
                if isinstance(step, int):
                    value = value[step]
                elif isinstance(value, dict):
                    value = value[step]
                else:
                    value = getattr(value, step)
            except (KeyError, IndexError, AttributeError, TypeError):
                raise KeyError(step) from None
        return value


@dataclass(frozen=True)
class TopicMapping:
    """How the messages of one MCAP topic become rows of one lakegate topic."""

    source: str  # the MCAP topic
    topic: str
    fields: dict[str, MessagePath]
    timestamp: str | MessagePath  # LOG_TIME, PUBLISH_TIME or a path
    decimate: int
    location: Location


def parse_path(text: str, location: Location) -> MessagePath | None:
    """A message path, or None when `text` is not one."""
    steps: list[str | int] = []
    for part in text.split("."):
        match = _STEP.fullmatch(part)
        if match is None:
            return None
        steps.append(match.group(1))
        steps += [int(i) for i in _INDEX.findall(match.group(2))]
    return MessagePath(text, tuple(steps), location)


def load_mapping(path: Path, topics: dict[str, Topic]) -> list[TopicMapping]:
    """Read and check a mapping file against the config's `topics`; MappingError lists every problem."""
    raw: list[RawProblem] = []
    reader = FileReader(str(path), raw)  # no warnings: unknown keys are errors in lakegate's own format
    root = reader.compose()
    mappings = []
    if root is not None and not isinstance(root, MappingNode):
        reader.error(root, "the mapping file must map MCAP topics to mappings (/odom: {topic: ..., fields: ...})")
    elif root is not None:
        for key, node in reader.items(root, "MCAP topic", " in the mapping"):
            at = Location(str(path), *reader.position(key))
            entries = reader.section(node, MAPPING, f"mapping of '{key.value}'", key)
            if "topic" in entries and "fields" in entries:
                mapping = _mapping(reader, key.value, entries, topics, at)
                if mapping is not None:
                    mappings.append(mapping)
    if raw:
        problems = sorted(raw, key=lambda p: (p[1], p[2]))
        raise MappingError([f"{p}:{line}:{column}: {message}" for p, line, column, message in problems])
    return mappings


def _mapping(
    reader: FileReader, source: str, entries: dict, topics: dict[str, Topic], at: Location
) -> TopicMapping | None:
    def where(node: Any) -> Location:
        return Location(reader.path, *reader.position(node))

    before = len(reader.problems)
    name = entries["topic"].value
    topic = topics.get(name)
    if topic is None:
        reader.error(entries["topic"].node, f"'{source}' maps to topic '{name}', which the config does not declare")
        return None
    keys = reader.plain_keys(entries["fields"].node)
    fields: dict[str, MessagePath] = {}
    for field_name, text in entries["fields"].value.items():
        node = keys.get(field_name, entries["fields"].node)
        path = parse_path(text, where(node)) if isinstance(text, str) else None
        if field_name not in topic.fields:
            reader.error(node, f"topic '{name}' has no field '{field_name}' (its fields: {', '.join(topic.fields)})")
        elif path is None:
            reader.error(
                node, f"field '{field_name}': {text!r} is not a message path (like twist.linear.x or poses[0].x)"
            )
        else:
            fields[field_name] = path
    missing = [f for f in topic.fields if f not in entries["fields"].value]
    if missing:
        reader.error(entries["fields"].node, f"topic '{name}' needs its fields {', '.join(missing)} mapped too")
    timestamp: str | MessagePath = LOG_TIME
    if "timestamp" in entries:
        text = entries["timestamp"].value
        parsed = text if text in (LOG_TIME, PUBLISH_TIME) else parse_path(text, where(entries["timestamp"].node))
        if parsed is None:
            reader.error(entries["timestamp"].node, f"timestamp {text!r} is not log_time, publish_time or a path")
        timestamp = parsed or LOG_TIME
    decimate = entries["decimate"].value if "decimate" in entries else 1
    if isinstance(decimate, bool) or not isinstance(decimate, int) or decimate < 1:
        reader.error(entries["decimate"].node, f"decimate must be an integer >= 1, got {decimate!r}")
    if len(reader.problems) > before:
        return None
    return TopicMapping(source, name, fields, timestamp, decimate, at)


class _JsonDecoderFactory(DecoderFactory):
    """Messages with encoding `json`: their bytes are a JSON text."""

    def decoder_for(self, message_encoding: str, schema: Schema | None) -> Callable[[bytes], Any] | None:
        return json.loads if message_encoding == "json" else None


@dataclass
class ImportReport:
    """What an import read and wrote."""

    messages: int = 0  # messages of the mapped topics read
    rows: dict[str, int] = field(default_factory=dict)  # lakegate topic -> rows emitted


def message_count(mcap_path: Path, sources: set[str]) -> int | None:
    """The number of messages on `sources` from the file's summary (None without one)."""
    with open(mcap_path, "rb") as stream:
        try:
            summary = make_reader(stream).get_summary()
        except McapError as error:
            raise _unreadable(mcap_path, error) from None
    if summary is None or summary.statistics is None:
        return None
    counts = summary.statistics.channel_message_counts
    return sum(counts.get(cid, 0) for cid, channel in summary.channels.items() if channel.topic in sources)


def import_mcap(
    mcap_path: Path,
    mappings: list[TopicMapping],
    emitter: Emitter,
    *,
    on_message: Callable[[], None] | None = None,
) -> ImportReport:
    """Emit one row per kept message of the mapped topics; McapImportError on the first message that
    does not fit (the mapping's place, the MCAP topic, message index and log time, the field path)."""
    by_source = {m.source: m for m in mappings}
    seen = dict.fromkeys(by_source, 0)
    report = ImportReport(rows=dict.fromkeys((m.topic for m in mappings), 0))
    for mapping, message, decoded in _messages(mcap_path, by_source):
        index = seen[mapping.source]
        seen[mapping.source] += 1
        report.messages += 1
        if on_message is not None:
            on_message()
        if index % mapping.decimate:
            continue
        where = f"{mapping.source} message {index} (log time {message.log_time})"
        row = {name: _value(path, decoded, where, _plain) for name, path in mapping.fields.items()}
        timestamp = _timestamp(mapping, message, decoded, where)
        try:
            emitter.emit(mapping.topic, row, timestamp)
        except ValidationError as error:
            path = mapping.fields.get(error.field or "")
            place = path.location if path is not None else mapping.location
            via = f" ({path.text})" if path is not None else ""
            raise McapImportError(f"{place}: {where}: field '{error.field}'{via}: {error.reason}") from None
        report.rows[mapping.topic] += 1
    return report


def _messages(mcap_path: Path, by_source: dict[str, TopicMapping]) -> Iterator[tuple[TopicMapping, Any, Any]]:
    factories = [Ros2DecoderFactory(), ProtobufDecoderFactory(), _JsonDecoderFactory()]
    with open(mcap_path, "rb") as stream:
        try:
            reader = make_reader(stream, decoder_factories=factories)
            messages = reader.iter_decoded_messages(topics=list(by_source), log_time_order=False)  # file order: no heap
            for _, channel, message, decoded in messages:
                yield by_source[channel.topic], message, decoded
        except McapError as error:
            raise _unreadable(mcap_path, error) from None


def _unreadable(mcap_path: Path, error: McapError) -> McapImportError:
    """The error for a file the mcap reader refuses (not MCAP, cut short, unknown compression...)."""
    why = str(error) or f"{type(error).__name__} (an empty or cut-short file)"
    return McapImportError(f"{mcap_path}: cannot decode the MCAP file: {why}")


def _value(path: MessagePath, decoded: Any, where: str, convert: Callable[[Any], Any]) -> Any:
    try:
        return convert(path.get(decoded))
    except KeyError as error:
        raise McapImportError(f"{path.location}: {where}: path {path.text} has no '{error.args[0]}'") from None


def _plain(value: Any) -> Any:
    """Arrays of a message (lists, array.array, bytes, protobuf repeated fields) as lists; other
    values as they are."""
    if isinstance(value, (str, int, float, dict)) or not hasattr(value, "__len__"):
        return value
    return list(value)


def _timestamp(mapping: TopicMapping, message: Any, decoded: Any, where: str) -> int:
    if mapping.timestamp == LOG_TIME:
        return message.log_time
    if mapping.timestamp == PUBLISH_TIME:
        return message.publish_time
    path = mapping.timestamp
    value = _value(path, decoded, where, lambda v: v)
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    seconds = value.get("sec") if isinstance(value, dict) else getattr(value, "sec", None)
    nanos = value.get("nanosec") if isinstance(value, dict) else getattr(value, "nanosec", None)
    if isinstance(seconds, int) and isinstance(nanos, int):
        return seconds * 1_000_000_000 + nanos
    raise McapImportError(
        f"{path.location}: {where}: timestamp {path.text} is neither a ROS time (sec, nanosec) nor "
        f"integer nanoseconds, got {type(value).__name__}"
    )
