"""Properties of the lake, checked on generated inputs (hypothesis):

- ingest accepts a line, and stores its values, exactly when `check_line` does (its fast paths only save time);
- a branch name's directory is one safe path segment that `decode_branch` turns back into the name.
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lakegate.lake import paths
from lakegate.lake.catalog import Catalog
from lakegate.lake.config import Config, load_config
from lakegate.lake.ingest import check_line, ingest_job

SLOW = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
FAST = settings(max_examples=300, deadline=None)

#: topic -> field -> type; `t` has one field of each type the fast paths read, `u` a status.
TOPICS = {
    "t": {"i": "int", "f": "float", "b": "boolean", "s": "string", "l": "string[]"},
    "u": {"st": "status"},
}
CONFIG = "version: 1\ntopics:\n" + "".join(
    f"  {name}:\n    schema: {json.dumps(fields)}\n" for name, fields in TOPICS.items()
)

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=3), inner, max_size=3),
    max_leaves=5,
)
#: valid values of each field type, including its edges
valid_values = {
    "int": st.integers(-(2**63), 2**63 - 1) | st.sampled_from([0, -(2**63), 2**63 - 1]),
    "float": st.floats(allow_nan=False, allow_infinity=False) | st.integers(-(2**70), 2**70),
    "boolean": st.booleans(),
    "string": st.text(max_size=8),
    "status": st.sampled_from(["PASSED", "FAILED", ""]) | st.text(max_size=4),
    "string[]": st.lists(st.text(max_size=4), max_size=3),
}
#: values just outside each field type
near_values = {
    "int": st.sampled_from([2**63, -(2**63) - 1, 1.0, True, "1", None]),
    "float": st.sampled_from([math.nan, math.inf, -math.inf, True, "1.5", None, 10**400]),
    "boolean": st.sampled_from([0, 1, "true", None]),
    "string": st.sampled_from([1, None, ["a"], "\ud800", "a\udfff"]),
    "status": st.sampled_from([1, None, "\udfff"]),
    "string[]": st.sampled_from([["a", None], "a", [1], [["a"]], ["\ud800"], None]),
}
BAD_TIMESTAMPS = [-1, 1.5, "1", 2**63, None, True]


@st.composite
def emission_lines(draw: st.DrawFn, timestamp: int) -> bytes:
    """One emissions line: usually good, in the Emitter's layout or another, else broken in one place."""
    topic = draw(st.sampled_from(list(TOPICS)))
    fields = TOPICS[topic]
    data = {name: draw(valid_values[kind]) for name, kind in fields.items()}
    metadata: dict[str, Any] = {"topic": topic, "timestamp": timestamp}
    field, kind = draw(st.sampled_from(list(fields.items())))
    flaw = draw(st.sampled_from(["none"] * 6 + ["near", "any", "missing", "extra", "timestamp", "topic"]))
    if flaw == "near":
        data[field] = draw(near_values[kind])
    elif flaw == "any":
        data[field] = draw(json_values)
    elif flaw == "missing":
        del data[field]
    elif flaw == "extra":
        data["extra"] = 1
    elif flaw == "timestamp":
        metadata["timestamp"] = draw(st.sampled_from(BAD_TIMESTAMPS))
    elif flaw == "topic":
        metadata["topic"] = draw(st.sampled_from(["nope", "T", 1]))
    record = {"$metadata": metadata, "$data": data}
    if draw(st.booleans()):
        record = {"$data": data, "$metadata": metadata}  # not the Emitter's key order
    separators = draw(st.sampled_from([(", ", ": "), (",", ":")]))
    text = json.dumps(record, separators=separators, ensure_ascii=draw(st.booleans()))
    return text.encode("utf-8", "surrogatepass")  # a lone surrogate becomes invalid UTF-8, as in a broken file


@pytest.fixture(scope="module")
def config(tmp_path_factory) -> Config:
    path = tmp_path_factory.mktemp("config") / "config.resim.yaml"
    path.write_text(CONFIG)
    return load_config(path)


def checked(raw: bytes, config: Config) -> tuple[str, int, list[Any]] | None:
    """What `check_line` decides: (topic, timestamp, values) or None when it refuses the line."""
    try:
        return check_line(raw, config.topics)
    except ValueError:
        return None


def same(a: Any, b: Any) -> bool:
    """Equal values of equal types; floats by their bits (-0.0 is not 0.0)."""
    if isinstance(a, float) or isinstance(b, float):
        return type(a) is type(b) and math.copysign(1, a) == math.copysign(1, b) and a == b
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


@SLOW
@given(data=st.data())
def test_ingest_accepts_and_stores_exactly_what_check_line_does(tmp_path, config, data):
    lines = [data.draw(emission_lines(timestamp=n)) for n in range(data.draw(st.integers(1, 12)))]
    decisions = [checked(raw, config) for raw in lines]
    with tempfile.TemporaryDirectory(dir=tmp_path) as folder:
        emissions = Path(folder) / "emissions.jsonl"
        emissions.write_bytes(b"".join(raw + b"\n" for raw in lines))
        lake = Path(folder) / "lake"
        report = ingest_job(lake, "main", "b1", "j1", [emissions], config=config, skip_bad_lines=True)
        assert report.bad_lines == decisions.count(None)
        connection = Catalog(lake).connect("main")
        for topic, fields in TOPICS.items():
            want = [(stamp, *values) for name, stamp, values in filter(None, decisions) if name == topic]
            assert report.rows.get(topic, 0) == len(want)
            if want:
                columns = ", ".join(f'"{name}"' for name in fields)
                got = connection.execute(f"SELECT timestamp, {columns} FROM {topic} ORDER BY timestamp").fetchall()
                assert all(same(list(g), list(w)) for g, w in zip(got, want, strict=True)), (got, want)


branch_names = st.text(st.characters(blacklist_categories=["Cs"]), min_size=1, max_size=40)


@FAST
@given(name=branch_names)
def test_branch_names_round_trip_through_one_safe_path_segment(name):
    try:
        segment = paths.encode_branch(name)
    except paths.LakePathError as error:  # only a name too long for one segment (each byte is at most %XX)
        assert "too long" in str(error) and 3 * len(name.encode()) > 240
        return
    assert paths.decode_branch(segment) == name
    assert "/" not in segment and "\\" not in segment and "\0" not in segment
    assert segment not in (".", "..") and not segment.startswith((".", "_"))
    assert segment.isascii() and segment.isprintable()


@FAST
@given(segment=st.text(st.characters(codec="ascii"), min_size=1, max_size=12))
def test_only_encoded_names_decode(segment):
    try:
        name = paths.decode_branch(segment)
    except paths.LakePathError:
        return
    assert paths.encode_branch(name) == segment  # one name, one directory: no two spellings of a branch


def test_a_name_with_a_lone_surrogate_is_refused_clearly():
    with pytest.raises(paths.LakePathError, match="not valid Unicode"):
        paths.encode_branch("a\ud800")
