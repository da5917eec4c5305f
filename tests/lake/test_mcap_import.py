"""`lakegate import mcap`: real MCAP files written with the mcap writers (ROS 2 messages with a
schema, and JSON messages), imported by the real CLI; every row is checked."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from google.protobuf.type_pb2 import Field, Type
from mcap_protobuf.writer import Writer as ProtobufWriter
from mcap_ros2.writer import Writer as Ros2Writer

from lakegate.lake.catalog import Catalog
from lakegate.lake.config import load_config
from lakegate.lake.mcap_import import MappingError, load_mapping

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
CONFIG = """\
version: 1
topics:
  odom_linear_velocity:
    schema: {x: float, y: float, z: float}
  odom_frame:
    schema: {frame: string, first_sample: float}
  battery:
    schema: {percent: float, charging: boolean, cell: int}
"""
ODOM_MSGDEF = """\
builtin_interfaces/Time stamp
string frame
demo_msgs/Twist twist
float64[] samples
================================================================================
MSG: demo_msgs/Twist
demo_msgs/Vector3 linear
================================================================================
MSG: demo_msgs/Vector3
float64 x
float64 y
float64 z
"""
MAPPING = """\
/odom:
  topic: odom_linear_velocity
  fields: {x: twist.linear.x, y: twist.linear.y, z: twist.linear.z}
  timestamp: stamp
/odom_copy:
  topic: odom_frame
  fields:
    frame: frame
    first_sample: samples[0]
  decimate: 3
/battery:
  topic: battery
  fields: {percent: state.percent, charging: state.charging, cell: "cells[1]"}
  timestamp: publish_time
"""
BASE_NS = 1_700_000_000 * 10**9


def odom(i: int) -> dict:
    """The i-th odometry message (stamp 10 ms apart, log time 1 ms later)."""
    stamp = BASE_NS + i * 10_000_000
    return {
        "stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9},
        "frame": f"base_{i % 2}",
        "twist": {"linear": {"x": i * 0.5, "y": -i / 4, "z": 0.125}},
        "samples": [i + 0.25, 9.0],
    }


def battery(i: int) -> dict:
    return {"state": {"percent": 100.0 - i, "charging": i % 2 == 0}, "cells": [3700 + i, 3800 - i]}


def write_mcap(path: Path, count: int) -> Path:
    """ROS 2 odometry on /odom and /odom_copy, JSON battery messages on /battery, interleaved."""
    with open(path, "wb") as stream:
        ros = Ros2Writer(stream)
        schema = ros.register_msgdef("demo_msgs/Odom", ODOM_MSGDEF)
        raw = ros._writer  # the same file: JSON channels beside the ROS 2 ones
        json_schema = raw.register_schema("Battery", "jsonschema", json.dumps({"type": "object"}).encode())
        channel = raw.register_channel("/battery", "json", json_schema)
        for i in range(count):
            log_time = BASE_NS + i * 10_000_000 + 1_000_000
            ros.write_message("/odom", schema, odom(i), log_time=log_time)
            ros.write_message("/odom_copy", schema, odom(i), log_time=log_time)
            raw.add_message(channel, log_time, json.dumps(battery(i)).encode(), publish_time=log_time + 5, sequence=i)
        ros.finish()
    return path


def lakegate(*args, check=True):
    result = subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=300)
    if check:
        assert result.returncode == 0, result.stderr
    return result


@pytest.fixture
def files(tmp_path):
    config = tmp_path / "config.resim.yaml"
    config.write_text(CONFIG)
    mapping = tmp_path / "map.yaml"
    mapping.write_text(MAPPING)
    return config, mapping, write_mcap(tmp_path / "run.mcap", 10)


def expected_rows(count: int) -> dict[str, list[tuple]]:
    """Every row the mapping makes of `count` messages, computed from the messages written."""
    rows: dict[str, list[tuple]] = {"odom_linear_velocity": [], "odom_frame": [], "battery": []}
    for i in range(count):
        message, log_time = odom(i), BASE_NS + i * 10_000_000 + 1_000_000
        stamp = message["stamp"]["sec"] * 10**9 + message["stamp"]["nanosec"]
        linear = message["twist"]["linear"]
        rows["odom_linear_velocity"].append((stamp, linear["x"], linear["y"], linear["z"]))
        if i % 3 == 0:  # decimate: 3
            rows["odom_frame"].append((log_time, message["frame"], message["samples"][0]))
        state, cells = battery(i)["state"], battery(i)["cells"]
        rows["battery"].append((log_time + 5, state["percent"], state["charging"], cells[1]))
    return rows


def test_import_to_an_emissions_file_then_ingest_gives_every_row(files, tmp_path):
    config, mapping, log = files
    output = tmp_path / "emissions.resim.jsonl"
    result = lakegate("import", "mcap", log, "--mapping", mapping, "--output", output, "--metrics-config-path", config)
    assert "wrote 24 rows from 30 messages" in result.stdout
    lines = [json.loads(line) for line in output.read_text().splitlines()]
    by_topic: dict[str, list[tuple]] = {}
    for line in lines:
        data, topic = line["$data"], line["$metadata"]["topic"]
        by_topic.setdefault(topic, []).append((line["$metadata"]["timestamp"], *data.values()))
    assert by_topic == expected_rows(10)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".lakegate-import-")]  # no scratch left


def test_import_straight_into_a_job(files, tmp_path):
    config, mapping, log = files
    lake = tmp_path / "lake"
    result = lakegate(
        "import", "mcap", log, "--mapping", mapping, "--metrics-config-path", config,
        "--lake", lake, "--batch", "b1", "--job", "run-1", "--build-version", "2.0",
    )  # fmt: skip
    assert "ingested job 'run-1' of batch 'b1'" in result.stdout
    con = Catalog(lake).connect("main")
    for topic, rows in expected_rows(10).items():
        columns = ", ".join(load_config(config).topics[topic].fields)
        assert con.execute(f"SELECT timestamp, {columns} FROM {topic} ORDER BY timestamp").fetchall() == rows
    assert con.execute("SELECT DISTINCT build_version, job_id FROM battery").fetchall() == [("2.0", "run-1")]


def test_a_file_that_is_not_mcap_or_cut_short_is_one_clear_line(files, tmp_path):
    """Garbage, an empty file and a recording killed midway (its first half) fail with one line naming
    the file, write nothing to the output and leave no traceback."""
    config, mapping, log = files
    data = log.read_bytes()
    cases = {"garbage.mcap": bytes(range(256)) * 8, "empty.mcap": b"", "cut.mcap": data[: len(data) // 2]}
    for name, content in cases.items():
        path, output = tmp_path / name, tmp_path / f"{name}.jsonl"
        path.write_bytes(content)
        result = lakegate(
            "import", "mcap", path, "--mapping", mapping, "--output", output, "--metrics-config-path", config,
            check=False,
        )  # fmt: skip
        assert result.returncode == 1, (name, result.stderr)
        assert result.stderr.startswith(f"lakegate: {path}: cannot decode the MCAP file: "), (name, result.stderr)
        assert "Traceback" not in result.stderr and not output.exists(), name


def test_mapping_errors_name_the_mapping_file_line_and_column(files, tmp_path):
    config, _, log = files
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        textwrap.dedent(
            """\
            /odom:
              topic: odom_linear_velocity
              fields: {x: twist.linear.x, y: "twist..y", w: twist.linear.z}
              decimate: 0
            /battery:
              topic: batery
              fields: {percent: state.percent}
              every: 2
            """
        )
    )
    with pytest.raises(MappingError) as caught:
        load_mapping(bad, load_config(config).topics)
    assert caught.value.problems == [
        f"{bad}:3:11: topic 'odom_linear_velocity' needs its fields z mapped too",
        f"{bad}:3:31: field 'y': 'twist..y' is not a message path (like twist.linear.x or poses[0].x)",
        f"{bad}:3:46: topic 'odom_linear_velocity' has no field 'w' (its fields: x, y, z)",
        f"{bad}:4:13: decimate must be an integer >= 1, got 0",
        f"{bad}:6:10: '/battery' maps to topic 'batery', which the config does not declare",
        f"{bad}:8:3: unknown key 'every' in mapping of '/battery'",
    ]
    result = lakegate("import", "mcap", log, "--mapping", bad, "--output", tmp_path / "o.jsonl",
                      "--metrics-config-path", config, check=False)  # fmt: skip
    assert result.returncode == 1 and "the mapping has 6 problem(s)" in result.stderr
    assert not (tmp_path / "o.jsonl").exists()


def test_a_message_that_does_not_fit_names_the_mapping_place_and_the_message(files, tmp_path):
    config, _, log = files
    mapping = tmp_path / "wrong.yaml"
    mapping.write_text(
        "/odom:\n  topic: odom_frame\n  fields: {frame: frame, first_sample: 'samples[5]'}\n"
        "/battery:\n  topic: odom_frame\n  fields: {frame: state.percent, first_sample: 'cells[0]'}\n"
    )
    result = lakegate("import", "mcap", log, "--mapping", mapping, "--output", tmp_path / "o.jsonl",
                      "--metrics-config-path", config, check=False)  # fmt: skip
    log_time = BASE_NS + 1_000_000
    assert result.returncode == 1
    assert result.stderr.strip() == (
        f"lakegate: {mapping}:3:26: /odom message 0 (log time {log_time}): path samples[5] has no '5'"
    )
    only_battery = tmp_path / "battery.yaml"
    only_battery.write_text(
        "/battery:\n  topic: odom_frame\n  fields: {frame: state.percent, first_sample: 'cells[0]'}\n"
    )
    result = lakegate("import", "mcap", log, "--mapping", only_battery, "--output", tmp_path / "o.jsonl",
                      "--metrics-config-path", config, check=False)  # fmt: skip
    assert result.stderr.strip() == (
        f"lakegate: {only_battery}:3:12: /battery message 0 (log time {log_time}): field 'frame' (state.percent): "
        "expected string (a string), got float 100.0"
    )
    assert not (tmp_path / "o.jsonl").exists()


def test_progress_bar_on_stderr_when_asked(files, tmp_path):
    config, mapping, log = files
    result = lakegate("import", "mcap", log, "--mapping", mapping, "--output", tmp_path / "o.jsonl",
                      "--metrics-config-path", config, "--progress")  # fmt: skip
    assert "30/30" in result.stderr and "msg" in result.stderr
    quiet = lakegate("import", "mcap", log, "--mapping", mapping, "--output", tmp_path / "o.jsonl",
                     "--metrics-config-path", config)  # fmt: skip
    assert quiet.stderr == "" and os.path.getsize(tmp_path / "o.jsonl") > 0


def test_protobuf_messages_with_nested_and_repeated_fields(tmp_path):
    """Protobuf messages (google.protobuf.Type: a name, repeated messages, repeated strings)."""
    config = tmp_path / "config.resim.yaml"
    config.write_text("version: 1\ntopics:\n  types:\n    schema: {label: string, n: int, tags: 'string[]'}\n")
    mapping = tmp_path / "map.yaml"
    mapping.write_text("/types:\n  topic: types\n  fields: {label: name, n: 'fields[1].number', tags: oneofs}\n")
    messages = [
        Type(name=f"t{i}", fields=[Field(name="a", number=1), Field(name="b", number=10 + i)], oneofs=["x"] * i)
        for i in range(4)
    ]
    log = tmp_path / "proto.mcap"
    with open(log, "wb") as stream, ProtobufWriter(stream) as writer:
        for i, message in enumerate(messages):
            writer.write_message("/types", message, log_time=1000 + i, publish_time=1000 + i)
    output = tmp_path / "out.jsonl"
    lakegate("import", "mcap", log, "--mapping", mapping, "--output", output, "--metrics-config-path", config)
    rows = [json.loads(line) for line in output.read_text().splitlines()]
    assert [(r["$metadata"]["timestamp"], r["$data"]) for r in rows] == [
        (1000 + i, {"label": m.name, "n": m.fields[1].number, "tags": list(m.oneofs)}) for i, m in enumerate(messages)
    ]
