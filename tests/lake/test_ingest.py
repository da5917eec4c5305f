"""Ingestion: real emissions files -> real Parquet -> real DuckDB queries."""

from __future__ import annotations

import json
import math
import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from lakegate.lake import paths
from lakegate.lake.catalog import Catalog
from lakegate.lake.config import Config, Topic, load_config
from lakegate.lake.emitter import Emitter
from lakegate.lake.ingest import IngestError, check_line, ingest_job, rules, scan
from lakegate.lake.record import current_file
from lakegate.lake.types import FieldError, check_value

CONFIG = """\
version: 1
topics:
  odom:
    schema: {x: float, y: float, z: float}
  sample:
    schema: {i: int, f: float, b: boolean, s: string, st: status, im: image, vi: video, tags: "string[]",
             metrics: "metric[]"}
  plain:
    schema: {i: int, f: float, b: boolean, s: string, tags: "string[]"}
  goal_reached:
    event: true
    schema: {name: string, description: string, status: status, tags: "string[]", metrics: "metric[]"}
  stop:
    event: true
    schema: {name: string, speed: float}
  never:
    schema: {v: float, w: "string[]"}
"""


@pytest.fixture
def config_path(tmp_path):
    path = tmp_path / "config.resim.yaml"
    path.write_text(CONFIG)
    return path


@pytest.fixture
def config(config_path):
    return load_config(config_path)


def line(topic, timestamp, data, event=False):
    meta = {"topic": topic, "timestamp": timestamp, **({"event": True} if event else {})}
    return json.dumps({"$metadata": meta, "$data": data})


def odom(i):
    return line("odom", i * 1000, {"x": i + 0.5, "y": -i * 0.25, "z": 0.0})


def write_lines(path, lines, end="\n"):
    path.write_text("".join(text + end for text in lines), encoding="utf-8")
    return path


def query(lake, sql, branch="main"):
    return Catalog(lake).connect(branch).execute(sql).fetchall()


def count(lake, table, branch="main"):
    return query(lake, f'SELECT COUNT(*) FROM "{table}"', branch)[0][0]


GOAL = {"name": "g", "description": "d", "status": "PASSED", "tags": []}
#: A stored metric object's fields, all NULL.
NO_METRIC_KEYS = dict.fromkeys(("name", "description", "status", "type", "value", "extra"))


def bits(value):
    return struct.pack("<d", value)


# -- round trip --------------------------------------------------------------------------


def test_round_trip_of_every_field_type_through_emitter_ingest_and_duckdb(tmp_path, config_path, config):
    emissions = tmp_path / "emissions.resim.jsonl"
    record = {
        "i": -(2**63),
        "f": 3,
        "b": True,
        "s": 'ünï "q" \\ 🚀\n',
        "st": "PASSED",
        "im": "a.png",
        "vi": "v.mp4",
        "tags": ["a", "b"],
        "metrics": [
            {"name": "m", "type": "scalar", "value": 2.5, "unit": "m/s", "limits": [0, 3.5]},
            {"name": "t", "type": "text", "value": "hi", "description": "d", "status": "PASSED"},
            {"name": "img", "type": "image", "value": ["1.png", "2.png"]},
            {"name": "p", "type": "plotly", "value": {"data": [], "layout": {}}},
        ],
    }
    second = {**record, "i": 2**63 - 1, "f": -0.0, "b": False, "s": "", "tags": [], "metrics": []}
    with Emitter(config_path=config_path, output_path=emissions) as emitter:
        emitter.emit("sample", record, timestamp=5)
        emitter.emit("sample", second, timestamp=6)
        plain = {k: record[k] for k in ("i", "f", "b", "s", "tags")}
        emitter.emit("plain", plain, timestamp=5)
        emitter.emit("plain", {k: second[k] for k in ("i", "f", "b", "s", "tags")}, timestamp=6)
        emitter.emit_event(
            "goal_reached",
            {
                "name": "Goal 1",
                "description": "reached",
                "status": "PASSED",
                "tags": ["nav"],
                "metrics": record["metrics"][:1],
            },
            timestamp=7,
        )
        emitter.emit_series(
            "odom",
            {"x": [0.1, 1e-300, 1.7976931348623157e308], "y": [1, 2, 3], "z": [0.5, 0.25, -4.0]},
            timestamps=[1, 2, 3],
        )
    report = ingest_job(
        tmp_path / "lake",
        "main",
        "b1",
        "j1",
        [emissions],
        config=config,
        metadata={"experience_name": "sunny", "build_version": "1.2.3"},
    )
    assert report.rows == {"odom": 3, "sample": 2, "plain": 2, "goal_reached": 1, "stop": 0, "never": 0}
    assert report.bad_lines == 0 and report.events == 1
    lake = tmp_path / "lake"
    expected_metrics = [
        # keys beyond the documented ones are kept, as a JSON object text in `extra`
        {
            **NO_METRIC_KEYS,
            "name": "m",
            "type": "scalar",
            "value": "2.5",
            "extra": '{"unit": "m/s", "limits": [0, 3.5]}',
        },
        {**NO_METRIC_KEYS, "name": "t", "description": "d", "status": "PASSED", "type": "text", "value": "hi"},
        {**NO_METRIC_KEYS, "name": "img", "type": "image", "value": '["1.png", "2.png"]'},
        {**NO_METRIC_KEYS, "name": "p", "type": "plotly", "value": '{"data": [], "layout": {}}'},
    ]
    rows = query(
        lake,
        "SELECT timestamp, i, f, b, s, st, im, vi, tags, metrics, experience_name, build_version, batch_id, "
        "job_id FROM sample ORDER BY timestamp",
    )
    assert rows == [
        (
            5,
            -(2**63),
            3.0,
            True,
            'ünï "q" \\ 🚀\n',
            "PASSED",
            "a.png",
            "v.mp4",
            ["a", "b"],
            expected_metrics,
            "sunny",
            "1.2.3",
            "b1",
            "j1",
        ),
        (6, 2**63 - 1, -0.0, False, "", "PASSED", "a.png", "v.mp4", [], [], "sunny", "1.2.3", "b1", "j1"),
    ]
    assert bits(rows[1][2]) == bits(-0.0)
    types = query(
        lake,
        "SELECT typeof(timestamp), typeof(i), typeof(f), typeof(b), typeof(s), typeof(st), typeof(tags), "
        "typeof(metrics), typeof(experience_name), typeof(batch_id) FROM sample LIMIT 1",
    )[0]
    assert types[:7] == ("BIGINT", "BIGINT", "DOUBLE", "BOOLEAN", "VARCHAR", "VARCHAR", "VARCHAR[]")
    assert (
        types[7].replace('"', "")
        == "STRUCT(name VARCHAR, description VARCHAR, status VARCHAR, type VARCHAR, value VARCHAR, extra VARCHAR)[]"
    )
    assert types[8:] == ("VARCHAR", "VARCHAR")
    # the fast path (no metric[] field) gives exactly the same values and types
    assert query(lake, "SELECT timestamp, i, f, b, s, tags FROM plain ORDER BY timestamp") == [
        r[:5] + (r[8],) for r in rows
    ]
    assert query(lake, "SELECT typeof(i), typeof(f), typeof(b), typeof(s), typeof(tags) FROM plain LIMIT 1")[0] == (
        "BIGINT",
        "DOUBLE",
        "BOOLEAN",
        "VARCHAR",
        "VARCHAR[]",
    )
    floats = query(lake, "SELECT x, y FROM odom ORDER BY timestamp")
    assert floats == [(0.1, 1.0), (1e-300, 2.0), (1.7976931348623157e308, 3.0)]
    events = query(
        lake, "SELECT timestamp, topic, name, description, status, tags, metrics, experience_name FROM events"
    )
    assert events == [(7, "goal_reached", "Goal 1", "reached", "PASSED", ["nav"], expected_metrics[:1], "sunny")]
    metadata = query(lake, "SELECT batch_id, job_id, experience_name, build_version, job_status FROM metadata")
    assert metadata == [("b1", "j1", "sunny", "1.2.3", "SUCCEEDED")]


def test_parquet_files_have_the_contract_columns_and_zstd(tmp_path, config):
    emissions = write_lines(
        tmp_path / "e.jsonl", [odom(1), line("stop", 9, {"name": "halt", "speed": 0.5}, event=True)]
    )
    ingest_job(tmp_path / "lake", "main", "b1", "j1", [emissions], config=config)
    topic_file = current_file(tmp_path / "lake", "main", "odom", "b1", "j1")
    schema = pq.read_schema(topic_file)
    assert schema.names == [
        "timestamp",
        *("x", "y", "z"),
        *("experience_name", "build_version", "project_id", "run_counter", "job_id"),
    ]
    assert str(schema.field("timestamp").type) == "int64"
    assert pq.ParquetFile(topic_file).metadata.row_group(0).column(1).compression == "ZSTD"
    events_file = current_file(tmp_path / "lake", "main", "events", "b1", "j1")
    assert pq.read_schema(events_file).names == [
        "timestamp",
        "topic",
        "name",
        "description",
        "status",
        "tags",
        "metrics",
        "experience_name",
        "build_version",
        "project_id",
        "run_counter",
        "job_id",
    ]
    # an event topic without description/status/tags/metrics fields leaves them NULL in events
    assert query(tmp_path / "lake", "SELECT topic, name, description, tags, metrics FROM events") == [
        ("stop", "halt", None, None, None)
    ]
    assert query(tmp_path / "lake", "SELECT name, speed FROM stop") == [("halt", 0.5)]


# -- bad lines ---------------------------------------------------------------------------

BAD = [
    # (line text, reason fragment)
    ('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": }}', "bad JSON at column"),
    ("[1, 2]", "expected a JSON object with $metadata and $data, got list"),
    ('{"$data": {"x": 1.0, "y": 2.0, "z": 3.0}}', "missing $metadata"),
    ('{"$metadata": {"topic": "odom", "timestamp": 1}}', "missing $data"),
    (line("odometry", 1, {"x": 1.0, "y": 2.0, "z": 3.0}), "unknown topic 'odometry' (did you mean 'odom'?)"),
    (line("odom", 1, {"x": "1.5", "y": 2.0, "z": 3.0}), "topic 'odom', field 'x': expected float, got str"),
    (
        line("plain", 1, {"i": 1.0, "f": 1.0, "b": True, "s": "", "tags": []}),
        "topic 'plain', field 'i': expected int, got float",
    ),
    (line("plain", 1, {"i": 1, "f": 1.0, "b": 1, "s": "", "tags": []}), "field 'b': expected boolean, got int"),
    (
        line("plain", 1, {"i": 1, "f": 1.0, "b": True, "s": "", "tags": ["a", 2]}),
        "field 'tags': expected a list of strings",
    ),
    (line("plain", 1, {"i": 2**63, "f": 1.0, "b": True, "s": "", "tags": []}), "int out of the 64-bit range"),
    (line("odom", 1, {"x": 1.0, "y": 2.0}), "topic 'odom': missing field 'z'"),
    (line("odom", 1, {"x": 1.0, "y": 2.0, "z": 3.0, "w": 4.0}), "topic 'odom': unexpected field 'w'"),
    # every problem of a line, each unexpected field with the likeliest missing one
    (
        line("odom", 1, {"x": "1", "y": 2.0, "zz": 3.0, "w": 4.0}),
        "topic 'odom': missing field 'z'; unexpected field 'zz' (did you mean 'z'?); unexpected field 'w'; "
        "field 'x': expected float, got str",
    ),
    (line("odom", -1, {"x": 1.0, "y": 2.0, "z": 3.0}), "bad timestamp: expected an integer number of nanoseconds"),
    (line("odom", 1.5, {"x": 1.0, "y": 2.0, "z": 3.0}), "bad timestamp"),
    (line("odom", "5", {"x": 1.0, "y": 2.0, "z": 3.0}), "bad timestamp"),
    (
        '{"$metadata": {"topic": "odom"}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}',
        "bad timestamp: $metadata has no timestamp",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": NaN, "y": 2.0, "z": 3.0}}',
        "NaN is not valid JSON",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1e400, "y": 2.0, "z": 3.0}}',
        "expected a finite float, got inf",
    ),
    ('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0,}}', "bad JSON"),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "x": 2.0, "y": 2.0, "z": 3.0}}',
        "duplicate key 'x'",
    ),
    (line("odom", 1, {"x": 1.0, "y": 2.0, "z": 3.0}, event=True), "topic 'odom' is not an event topic"),
    (line("plain", 1, {"i": 1, "f": 1.0, "b": True, "s": "\ud800", "tags": []}), "lone surrogate"),
    (
        line(
            "goal_reached",
            1,
            {**GOAL, "metrics": [{"name": "m", "type": "text", "value": "v", "unit": "\ud800"}]},
            True,
        ),
        "field 'metrics': metric 0: key(s) 'unit': string holds a lone surrogate",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1, "colour": "red"}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}',
        "unexpected key 'colour' in $metadata",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}, "extra": 1}',
        "unexpected key 'extra'",
    ),
    ('{"$metadata": {"topic": "odom", "timestamp": 007}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}', "bad JSON"),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 9223372036854775808}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}',
        "bad timestamp",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0} {"x": 1.0}}',
        "bad JSON",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}, "w": {}}',
        "unexpected key 'w'",
    ),
    ('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}}', "bad JSON"),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": "}\\n{\\"x\\": 1"}}',
        "field 'z': expected float",
    ),
    (
        line(
            "sample",
            1,
            {
                "i": 1,
                "f": 1.0,
                "b": True,
                "s": "",
                "st": "",
                "im": "",
                "vi": "",
                "tags": [],
                "metrics": [{"name": "m", "type": "chart", "value": 1}],
            },
        ),
        "field 'metrics': metric 0: type must be one of",
    ),
]


def bad_file(tmp_path):
    """Good odom lines with every kind of bad line between them, an invalid UTF-8 line and a truncated last line."""
    texts, expected = [], []
    for number, (text, reason) in enumerate(BAD):
        texts += [odom(number), text]
        expected.append((2 * number + 2, reason))
    data = (
        "".join(t + "\n" for t in texts).encode()
        + b'{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": "\xff"}}\n'
    )
    expected.append((len(texts) + 1, "invalid UTF-8 at byte"))
    data += (odom(99) + "\n").encode() + b'{"$metadata": {"topic": "odom", "times'
    expected.append((len(texts) + 3, "truncated last line (no newline at the end of the file): bad JSON"))
    path = tmp_path / "bad.jsonl"
    path.write_bytes(data)
    return path, expected, len(BAD) + 1


def test_every_bad_line_is_reported_with_file_line_and_reason_and_nothing_is_written(tmp_path, config):
    path, expected, good = bad_file(tmp_path)
    with pytest.raises(IngestError) as caught:
        ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config)
    error = caught.value
    assert [(p.line, p.path) for p in error.problems] == [(n, str(path)) for n, _ in expected]
    for problem, (number, reason) in zip(error.problems, expected):
        assert reason in problem.reason, (number, problem.reason)
        assert str(problem).startswith(f"{path}:{number}: ")
    assert error.total == len(expected)
    assert "nothing was written" in str(error) and "--skip-bad-lines" in str(error)
    lake_branch = paths.branch_dir(tmp_path / "lake", "main")
    assert not list(lake_branch.glob("*/batch_id=*/job_id=*/*.parquet"))
    assert not paths.quarantine_file(tmp_path / "lake", "main", "b1", "j1").exists()


def test_a_failed_ingest_leaves_the_earlier_ingest_of_the_job_intact(tmp_path, config):
    lake = tmp_path / "lake"
    good = write_lines(tmp_path / "good.jsonl", [odom(i) for i in range(10)])
    ingest_job(lake, "main", "b1", "j1", [good], config=config, metadata={"experience_name": "first"})
    path, _, _ = bad_file(tmp_path)
    with pytest.raises(IngestError):
        ingest_job(lake, "main", "b1", "j1", [path], config=config, metadata={"experience_name": "second"})
    assert count(lake, "odom") == 10
    assert query(lake, "SELECT experience_name FROM metadata") == [("first",)]


def test_skip_bad_lines_keeps_good_rows_and_quarantines_the_rest(tmp_path, config):
    lake = tmp_path / "lake"
    path, expected, good = bad_file(tmp_path)
    report = ingest_job(lake, "main", "b1", "j1", [path], config=config, skip_bad_lines=True)
    assert report.bad_lines == len(expected) and report.rows["odom"] == good
    assert count(lake, "odom") == good
    assert report.quarantine == paths.quarantine_file(lake, "main", "b1", "j1")
    kept = [json.loads(t) for t in report.quarantine.read_text().splitlines()]
    assert [(k["file"], k["line"]) for k in kept] == [(str(path), n) for n, _ in expected]
    assert all(reason in k["reason"] for k, (_, reason) in zip(kept, expected))
    raw_lines = path.read_bytes().split(b"\n")
    for k in kept:  # the bad line itself, byte for byte (invalid UTF-8 as surrogate escapes)
        assert k["text"].encode("utf-8", "surrogateescape") == raw_lines[k["line"] - 1]
    # a clean re-ingest of the job removes its quarantine file
    clean = write_lines(tmp_path / "clean.jsonl", [odom(1)])
    assert ingest_job(lake, "main", "b1", "j1", [clean], config=config).quarantine is None
    assert not report.quarantine.exists()


def test_many_blocks_many_files_and_long_lines_keep_line_numbers(tmp_path, config, monkeypatch):
    monkeypatch.setattr(scan, "BLOCK_SIZE", 700)  # a few lines per block; some lines are longer than a block
    long_tags = [f"tag{i}" for i in range(200)]
    first = write_lines(
        tmp_path / "a.jsonl",
        [odom(i) for i in range(40)]
        + [line("odom", 1, {"x": 1})]
        + [line("plain", i, {"i": i, "f": 0.5, "b": False, "s": "x" * 1500, "tags": long_tags}) for i in range(5)],
    )
    second = write_lines(
        tmp_path / "b.jsonl", [odom(i) for i in range(30)] + ['{"broken'] + [odom(i) for i in range(3)]
    )
    with pytest.raises(IngestError) as caught:
        ingest_job(tmp_path / "lake", "main", "b1", "j1", [first, second], config=config)
    assert [(Path(p.path).name, p.line) for p in caught.value.problems] == [("a.jsonl", 41), ("b.jsonl", 31)]
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [first, second], config=config, skip_bad_lines=True)
    assert report.rows["odom"] == 73 and report.rows["plain"] == 5 and report.lines == 80
    assert query(tmp_path / "lake", "SELECT COUNT(*), MIN(length(s)), MAX(len(tags)) FROM plain") == [(5, 1500, 200)]
    # rows keep the order of the lines within a topic
    xs = [r[0] for r in query(tmp_path / "lake", "SELECT x FROM odom")]
    assert xs == [i + 0.5 for i in range(40)] + [i + 0.5 for i in range(30)] + [i + 0.5 for i in range(3)]


def test_other_json_layouts_blank_lines_and_crlf_are_read_the_same(tmp_path, config):
    texts = [
        '{"$metadata":{"topic":"odom","timestamp":1},"$data":{"x":1,"y":2.5,"z":-3e2}}',
        '{"$data": {"z": 0.0, "y": 1.0, "x": 2.0}, "$metadata": {"timestamp": 2, "topic": "odom"}}',
        '   {  "$metadata" : { "timestamp" : 3 , "topic" : "odom" } , "$data" : { "x" : 3 , "y" : 3 , "z" : 3 } }   ',
        "",
        "  \t ",
        '{"$metadata": {"topic": "od\\u006fm", "timestamp": 4}, "$data": {"x": 4, "y": 4, "z": 4}}',
        '{"$metadata": {"event": false, "topic": "odom", "timestamp": 5}, "$data": {"x": 5, "y": 5, "z": 5}}',
        '{"$metadata": {"topic": "odom", "timestamp": 6, "event": null}, "$data": {"x": 6, "y": 6, "z": 6}}',
        '{"$metadata": {"topic": "stop", "timestamp": 7}, "$data": {"name": "no event flag", "speed": 1}}',
    ]
    path = tmp_path / "layouts.jsonl"
    path.write_bytes("".join(t + "\r\n" for t in texts).encode())
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config)
    assert report.bad_lines == 0 and report.rows["odom"] == 6 and report.rows["stop"] == 1
    assert query(tmp_path / "lake", "SELECT timestamp, x, y, z FROM odom ORDER BY timestamp") == [
        (1, 1.0, 2.5, -300.0),
        (2, 2.0, 1.0, 0.0),
        (3, 3.0, 3.0, 3.0),
        (4, 4.0, 4.0, 4.0),
        (5, 5.0, 5.0, 5.0),
        (6, 6.0, 6.0, 6.0),
    ]


# -- the fast path and check_value agree ----------------------------------------------------

VALUES = {
    "int": [
        "0",
        "-0",
        "1",
        "-1",
        "9223372036854775807",
        "-9223372036854775808",
        "9223372036854775808",
        "-9223372036854775809",
        "1.0",
        "1e3",
        "1E2",
        "1.5",
        "true",
        "false",
        "null",
        '"1"',
        "[1]",
        '{"a": 1}',
        "NaN",
        "Infinity",
        "00",
        "-",
        "+1",
    ],
    "float": [
        "0",
        "1",
        "-1",
        "0.1",
        "-0.0",
        "1e308",
        "1e309",
        "-1e309",
        "1e-400",
        "4.9e-324",
        "2.2250738585072014e-308",
        "123456789012345678901234567890",
        "9007199254740993",
        "0.30000000000000004",
        "1.7976931348623157e308",
        "1.5e+10",
        "1E-5",
        "true",
        "null",
        '"1.5"',
        "NaN",
        "-Infinity",
        "[1.0]",
        ".5",
        "1.",
        "01.5",
    ],
    "boolean": ["true", "false", "0", "1", '"true"', "null", "[true]", "True"],
    "string": [
        '""',
        '"x"',
        '"\u00fcn\u00ef"',
        '"\\u00fc"',
        '"\\ud83d\\ude80"',
        '"\\ud800"',
        '"a\\"b"',
        '"tab\\t"',
        '"\\u0000"',
        "5",
        "true",
        "null",
        '["x"]',
        '{"a": "b"}',
        '"raw\ttab"',
        '"\\x"',
        "'single'",
    ],
    "status": ['"PASSED"', "1", "null"],
    "image": ['"a.png"', "[]"],
    "string[]": [
        "[]",
        '["a"]',
        '["a", "b"]',
        "[1]",
        '["a", null]',
        "null",
        '"a"',
        '[["a"]]',
        "[true]",
        '["\\ud800"]',
        '["a",]',
        "[ ]",
    ],
}


def expected_decision(field_type, literal):
    """What the rules say: standard JSON only, then check_value, then what Parquet can hold."""

    def refuse(token):
        raise ValueError(token)

    try:
        value = json.loads(literal, parse_constant=refuse)
        stored = check_value(field_type, value)
    except (ValueError, FieldError):
        return False, None
    try:
        json.dumps(stored, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError:
        return False, None
    return True, stored


def fast_paths(plans, raw):
    """Run one line through both fast paths: whole lines, and `$data` objects of lines in the Emitter's layout."""
    block = scan.Block("test", 1, raw + b"\n", np.array([0, len(raw) + 1]), 0)
    lines = pa.Array.from_buffers(pa.large_binary(), 1, [None, pa.py_buffer(block.offsets), pa.py_buffer(block.data)])
    codes, after = scan.Hinter(plans).codes_of(block, lines)
    plan = plans[codes[0]]
    layout, timestamps, start, close = scan._emitter_layout(block, np.array([0]), after, plan.topic.event)
    assert layout[0], "the cases are written in the Emitter's layout"
    payloads = scan._payloads(bytearray(block.data), start, close)
    return {
        "lines": scan._fast_lines(plan, pa.py_buffer(block.data), np.array([1])),
        "payloads": scan._fast_payloads(plan, payloads, np.array([1]), timestamps),
    }


def test_fast_path_and_exact_checks_agree_on_a_table_of_values(tmp_path):
    names = {t: "t_" + t.replace("[]", "_list") for t in VALUES}
    config_path = tmp_path / "c.yaml"
    config_path.write_text(
        "version: 1\ntopics:\n" + "".join(f"  {names[t]}:\n    schema: {{v: {json.dumps(t)}}}\n" for t in VALUES)
    )
    config = load_config(config_path)
    cases = [(t, literal) for t, literals in VALUES.items() for literal in literals]
    texts = [
        f'{{"$metadata": {{"topic": "{names[t]}", "timestamp": {n}}}, "$data": {{"v": {literal}}}}}'
        for n, (t, literal) in enumerate(cases)
    ]
    path = tmp_path / "cases.jsonl"
    path.write_bytes("".join(t + "\n" for t in texts).encode("utf-8", "surrogatepass"))
    plans = scan.topic_plans(config)
    for (field_type, literal), text in zip(cases, texts):
        accept, stored = expected_decision(field_type, literal)
        raw = text.encode("utf-8", "surrogatepass")
        # the exact check
        try:
            checked = check_line(raw, config.topics)
        except ValueError:
            checked = None
        assert (checked is not None) == accept, (field_type, literal)
        if accept:
            assert checked[2] == [stored]
        # each fast path alone, on this one line: the same decision and the same value
        for route, (table, refused) in fast_paths(plans, raw).items():
            assert (not len(refused)) == accept, (route, "decided otherwise", field_type, literal)
            if accept:
                value = table.column("v")[0].as_py()
                assert value == stored and type(value) is type(stored), (route, field_type, literal, value, stored)
                if field_type == "float":
                    assert bits(value) == bits(stored)
    # and end to end
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config, skip_bad_lines=True)
    accepted = {(t, lit) for t, lit in cases if expected_decision(t, lit)[0]}
    assert report.bad_lines == len(cases) - len(accepted)
    for field_type in VALUES:
        rows = query(tmp_path / "lake", f"SELECT timestamp, v FROM {names[field_type]} ORDER BY timestamp")
        want = [
            (n, expected_decision(t, lit)[1])
            for n, (t, lit) in enumerate(cases)
            if t == field_type and (t, lit) in accepted
        ]
        assert [r[0] for r in rows] == [w[0] for w in want]
        for (_, got), (_, value) in zip(rows, want):
            assert got == value and (field_type != "float" or bits(got) == bits(value))
    assert any(math.isclose(v, 1.2345678901234568e29) for (v,) in query(tmp_path / "lake", "SELECT v FROM t_float"))


# -- replacing a job ------------------------------------------------------------------------


def test_reingesting_a_job_replaces_it_and_never_duplicates(tmp_path, config):
    lake = tmp_path / "lake"
    both = write_lines(
        tmp_path / "both.jsonl", [odom(i) for i in range(5)] + [line("stop", 1, {"name": "x", "speed": 1.0}, True)]
    )
    for _ in range(2):
        ingest_job(lake, "main", "b1", "j1", [both], config=config)
        assert count(lake, "odom") == 5 and count(lake, "stop") == 1 and count(lake, "events") == 1
        assert count(lake, "metadata") == 1
    ingest_job(lake, "main", "b1", "j2", [both], config=config)
    assert count(lake, "odom") == 10 and count(lake, "metadata") == 2
    only_odom = write_lines(tmp_path / "odom.jsonl", [odom(i) for i in range(3)])
    ingest_job(lake, "main", "b1", "j1", [only_odom], config=config)
    # j1's stop rows and events are gone, j2's stay
    assert query(lake, "SELECT job_id, COUNT(*) FROM odom GROUP BY 1 ORDER BY 1") == [("j1", 3), ("j2", 5)]
    assert query(lake, "SELECT job_id FROM stop") == [("j2",)] and query(lake, "SELECT job_id FROM events") == [("j2",)]
    assert not (paths.table_dir(lake, "main", "stop") / "batch_id=b1" / "job_id=j1").exists()


def test_names_the_lake_cannot_hold_are_refused_before_anything_is_written(tmp_path, config):
    emissions = write_lines(tmp_path / "e.jsonl", [odom(1)])
    for batch, job in (("a/b", "j"), ("b", "*"), ("..", "j"), ("b", "")):
        with pytest.raises(paths.LakePathError):
            ingest_job(tmp_path / "lake", "main", batch, job, [emissions], config=config)
    clash = Config(topics={"odom": Topic("odom", {"timestamp": "int"})})  # configs built in code are checked too
    with pytest.raises(IngestError, match="declares field 'timestamp', a column lakegate adds"):
        ingest_job(tmp_path / "lake", "main", "b", "j", [emissions], config=clash)
    for name in ("metadata", "events", "_configs", "a*b"):
        with pytest.raises(paths.LakePathError, match="topic name"):
            ingest_job(
                tmp_path / "lake",
                "main",
                "b",
                "j",
                [emissions],
                config=Config(topics={name: Topic(name, {"x": "int"})}),
            )
    with pytest.raises(IngestError, match="does not exist"):
        ingest_job(tmp_path / "lake", "main", "b", "j", [tmp_path / "missing.jsonl"], config=config)
    assert not (tmp_path / "lake").exists() or not list((tmp_path / "lake").glob("*/*/batch_id=*"))


def test_ingest_stores_its_config_and_reports_the_version(tmp_path, config, config_path):
    emissions = write_lines(tmp_path / "e.jsonl", [odom(1)])
    first = ingest_job(tmp_path / "lake", "main", "b1", "j1", [emissions], config=config)
    again = ingest_job(tmp_path / "lake", "main", "b1", "j2", [emissions], config=config)
    assert first.config_version == again.config_version == 1
    config_path.write_text(CONFIG + "  later:\n    schema: {n: int}\n")
    third = ingest_job(tmp_path / "lake", "main", "b1", "j3", [emissions], config=load_config(config_path))
    assert third.config_version == 2 and third.rows["later"] == 0


def test_progress_bar_goes_to_stderr_only_when_asked(tmp_path, config, capsys):
    emissions = write_lines(tmp_path / "e.jsonl", [odom(i) for i in range(100)])
    ingest_job(tmp_path / "lake", "main", "b1", "j1", [emissions], config=config)
    assert capsys.readouterr().err == ""
    ingest_job(tmp_path / "lake", "main", "b1", "j1", [emissions], config=config, progress=True)
    err = capsys.readouterr().err
    assert "ingest" in err and "lines=100" in err and "B/s" in err


# -- crash safety ---------------------------------------------------------------------------

CRASH_SCRIPT = """
import sys
from pathlib import Path
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job, scan, write
scan.BLOCK_SIZE, write.ROWS_PER_WRITE = 1 << 20, 20_000  # small blocks and writes: a file is open early
ingest_job(Path(sys.argv[1]), "main", "b1", "j1", [Path(sys.argv[3])], config=load_config(sys.argv[2]))
"""


def big_emissions(path, count):
    template = '{"$metadata": {"topic": "odom", "timestamp": %d}, "$data": {"x": %d.25, "y": -%d.5, "z": 0.125}}\n'
    with open(path, "w") as handle:
        for start in range(0, count, 10000):
            handle.write("".join(template % (i, i, i) for i in range(start, min(count, start + 10000))))
    return path


def visible_files(lake):
    return sorted(p.relative_to(lake) for p in Path(lake).glob("*/*/batch_id=*/job_id=*/*"))


@pytest.mark.parametrize("moment", ["reading", "writing"])
def test_kill_9_during_ingest_leaves_nothing_partial_and_a_rerun_succeeds(tmp_path, config_path, config, moment):
    lake = tmp_path / "lake"
    small = write_lines(tmp_path / "small.jsonl", [odom(i) for i in range(7)])
    ingest_job(lake, "main", "b1", "j1", [small], config=config)
    before = visible_files(lake)
    lines = 200_000
    big = big_emissions(tmp_path / "big.jsonl", lines)
    staging = paths.branch_dir(lake, "main") / paths.STAGING
    process = subprocess.Popen([sys.executable, "-c", CRASH_SCRIPT, str(lake), str(config_path), str(big)])
    try:
        deadline, reached = time.monotonic() + 60, False
        while not reached and time.monotonic() < deadline and process.poll() is None:
            scratch = list(staging.glob(f"{process.pid}-*"))
            reached = bool(scratch) and (moment == "reading" or bool(list(scratch[0].glob("*.parquet"))))
            time.sleep(0.002)
        assert reached and process.poll() is None, "the ingest finished before it could be killed"
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait()
    assert process.returncode == -signal.SIGKILL
    # readers see exactly the earlier version of the job, and every visible file is whole
    assert visible_files(lake) == before
    for relative in before:
        pq.read_metadata(lake / relative)
    assert count(lake, "odom") == 7
    # a re-run succeeds, cleans the dead writer's scratch, and counts match
    report = ingest_job(lake, "main", "b1", "j1", [big], config=config)
    assert report.rows["odom"] == lines and count(lake, "odom") == lines
    assert not list(staging.glob(f"{process.pid}-*"))


# --- line limits: length and nesting depth ---------------------------------------------------


def test_deeply_nested_line_is_a_bad_line_not_a_crash(tmp_path, config):
    """100k `[` used to raise RecursionError out of ingest, even with skip_bad_lines."""
    deep = line("plain", 2, {"i": 1, "f": 1.0, "b": True, "s": "x", "tags": []}).replace(
        '"tags": []', '"tags": ' + "[" * 100_000
    )
    path = write_lines(tmp_path / "deep.jsonl", [odom(1), deep, odom(3)])
    with pytest.raises(IngestError) as caught:
        ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config)
    assert [(p.line, p.reason) for p in caught.value.problems] == [
        (2, "nested too deep: more than 256 levels of arrays and objects, the limit of an emissions line")
    ]
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config, skip_bad_lines=True)
    assert report.rows["odom"] == 2 and report.bad_lines == 1


@pytest.mark.parametrize("depth", [252, 253])
def test_emitter_and_ingest_agree_on_the_depth_limit(tmp_path, config_path, config, depth):
    """A Plotly object `depth` deep in a metric makes a line depth + 4 deep: both accept 256, refuse 257."""
    figure: dict = {}
    for _ in range(depth - 1):
        figure = {"a": figure}
    record = {
        "name": "g",
        "description": "d",
        "status": "PASSED",
        "tags": [],
        "metrics": [{"name": "m", "type": "plotly", "value": figure}],
    }
    raw = line("goal_reached", 1, record, event=True).encode()
    with Emitter(config_path, tmp_path / "emissions.jsonl") as em:
        if depth == 252:
            assert check_line(raw, config.topics) is not None
            em.emit_event("goal_reached", record, 1)
        else:
            with pytest.raises(ValueError, match="nested too deep"):
                check_line(raw, config.topics)
            with pytest.raises(ValueError, match="nested too deep"):
                em.emit_event("goal_reached", record, 1)


def test_overlong_lines_are_refused_without_being_held_whole(tmp_path, config, monkeypatch):
    monkeypatch.setattr(scan, "BLOCK_SIZE", 256)
    for module in (rules, scan):  # the limit of the exact check and of the block reader
        monkeypatch.setattr(module, "MAX_LINE_BYTES", 150)
    long_in_a_block = line("plain", 1, {"i": 1, "f": 1.0, "b": True, "s": "y" * 120, "tags": []})  # 190 bytes
    across_blocks = line("plain", 2, {"i": 1, "f": 1.0, "b": True, "s": "z" * 2000, "tags": []})
    path = write_lines(tmp_path / "long.jsonl", [odom(1), long_in_a_block, odom(3), across_blocks, odom(5)])
    with path.open("a") as handle:
        handle.write(across_blocks)  # and one more as the last line, without a newline
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config, skip_bad_lines=True)
    assert report.rows["odom"] == 3 and report.rows["plain"] == 0 and report.lines == 6
    assert [(p.line, p.reason) for p in report.problems] == [
        (2, f"line too long: {len(long_in_a_block):,} bytes, more than the limit of 150 bytes of an emissions line"),
        (4, f"line too long: {len(across_blocks):,} bytes, more than the limit of 150 bytes of an emissions line"),
        (6, f"line too long: {len(across_blocks):,} bytes, more than the limit of 150 bytes of an emissions line"),
    ]
    assert [x for (x,) in query(tmp_path / "lake", "SELECT x FROM odom")] == [1.5, 3.5, 5.5]


def test_metric_objects_of_old_files_without_extra_read_with_new_ones_in_either_order(tmp_path, config):
    """Files written before metric objects had `extra` hold a 5-field struct; a query over them and
    newer files together gives each row its own `extra` (NULL for the old ones), also when an old one is read first."""
    lake = tmp_path / "lake"
    unit = {"name": "speed", "type": "scalar", "value": 1.5, "unit": "m/s"}
    plain = {"name": "speed", "type": "scalar", "value": 2.5}
    for job_id in ("a", "b", "c"):
        metric = plain if job_id == "a" else unit
        path = write_lines(tmp_path / f"{job_id}.jsonl", [line("goal_reached", 1, {**GOAL, "metrics": [metric]}, True)])
        ingest_job(lake, "main", "b1", job_id, [path], config=config)
    # job a (read first) as an earlier version wrote it: the struct without `extra`, in place (same file, same links)
    old = pa.struct([(name, pa.string()) for name in ("name", "description", "status", "type", "value")])
    for table in ("goal_reached", "events"):
        path = current_file(lake, "main", table, "b1", "a")
        stored = pq.read_table(path)
        metrics = stored.column("metrics").to_pylist()
        assert metrics == [[{**NO_METRIC_KEYS, "name": "speed", "type": "scalar", "value": "2.5"}]]
        narrowed = [[{k: v for k, v in m.items() if k != "extra"} for m in ms] for ms in metrics]
        index = stored.schema.get_field_index("metrics")
        stored = stored.set_column(index, "metrics", pa.array(narrowed, pa.list_(old)))
        pq.write_table(stored, path)
    expected = [
        ("a", "2.5", None),
        ("b", "1.5", '{"unit": "m/s"}'),
        ("c", "1.5", '{"unit": "m/s"}'),
    ]
    for table in ("goal_reached", "events"):
        rows = query(lake, f"SELECT job_id, metrics[1].value, metrics[1].extra FROM {table} ORDER BY job_id")
        assert rows == expected, table
    # the old job alone reads too
    con = Catalog(lake).connect("main")
    assert con.execute("SELECT metrics[1].extra FROM events WHERE job_id = 'a'").fetchall() == [(None,)]
