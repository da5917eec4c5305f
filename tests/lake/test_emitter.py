"""The Emitter: line format, every validation rule, numpy inputs, threads, and the flush policy."""

from __future__ import annotations

import gc
import gzip
import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from lakegate.lake.config import ConfigError
from lakegate.lake.emitter import Emitter, ValidationError
from lakegate.lake.types import FIELD_TYPES, check_value

FIXTURE_CONFIG = Path(__file__).resolve().parents[2] / "fixtures" / "config.resim.yaml"
ODOM = "odom_linear_velocity"

GOAL = {
    "name": "Goal 1 Reached",
    "description": "Robot reached goal 1",
    "status": "PASSED",
    "tags": ["navigation"],
    "metrics": [{"name": "Stereo View", "type": "image", "value": ["goal_1.png"], "status": "PASSED"}],
}


def strict_loads(line: str) -> dict:
    """json.loads that refuses the non-standard NaN/Infinity tokens."""

    def refuse(token: str) -> None:
        raise ValueError(f"non-standard JSON token {token}")

    return json.loads(line, parse_constant=refuse)


def read_lines(path: Path) -> list[dict]:
    return [strict_loads(line) for line in path.read_text().splitlines()]


def write_config(path: Path, topics: dict) -> Path:
    path.write_text(yaml.safe_dump({"version": 1, "topics": topics}, allow_unicode=True, sort_keys=False))
    return path


@pytest.fixture
def out(tmp_path: Path) -> Path:
    return tmp_path / "out" / "emissions.resim.jsonl"


@pytest.fixture
def emitter(out: Path):
    with Emitter(config_path=FIXTURE_CONFIG, output_path=out) as em:
        yield em


def rejected(emitter: Emitter, *args, method: str = "emit") -> ValidationError:
    with pytest.raises(ValidationError) as info:
        getattr(emitter, method)(*args)
    return info.value


# --- line format ------------------------------------------------------------------------


def test_lines_are_the_documented_json(emitter: Emitter, out: Path):
    emitter.emit(ODOM, {"x": 1.0, "y": 2.0, "z": 3.0}, timestamp=0)
    emitter.emit(ODOM, {"z": 0.0, "y": 1.9, "x": 1.1}, timestamp=500000000)  # key order does not matter
    emitter.close()
    assert out.read_text().splitlines() == [
        '{"$metadata": {"topic": "odom_linear_velocity", "timestamp": 0}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}',
        '{"$metadata": {"topic": "odom_linear_velocity", "timestamp": 500000000}, '
        '"$data": {"x": 1.1, "y": 1.9, "z": 0.0}}',
    ]


def test_every_field_type_serializes_like_json_dumps(out: Path, tmp_path: Path):
    config = write_config(
        tmp_path / "c.yaml",
        {
            "all": {
                "schema": {
                    "i": "int",
                    "f": "float",
                    "b": "boolean",
                    "s": "string",
                    "st": "status",
                    "im": "image",
                    "v": "video",
                    "ss": "string[]",
                    "m": "metric[]",
                }
            }
        },
    )
    data = {
        "i": -(2**63),
        "f": 1e-300,
        "b": False,
        "s": 'quote " backslash \\ newline \n é ✓',
        "st": "PASSED",
        "im": "a.png",
        "v": "b.mp4",
        "ss": ["x", "ÿ"],
        "m": [
            {"name": "n", "type": "scalar", "value": 2.5, "description": None},
            {"name": "p", "type": "plotly", "value": {"data": []}},
        ],
    }
    with Emitter(config, out) as em:
        em.emit("all", data, timestamp=2**63 - 1)
    expected = {"$metadata": {"topic": "all", "timestamp": 2**63 - 1}, "$data": data}
    assert out.read_text() == json.dumps(expected) + "\n"


def test_odd_topic_and_field_names_are_escaped(out: Path, tmp_path: Path):
    topic, field = 'it\'s "odd" é', "f'{x}\"\\"  # a topic name is a table folder: no braces or backslash
    config = write_config(tmp_path / "c.yaml", {topic: {"schema": {field: "string", "n": "float"}}})
    with Emitter(config, out) as em:
        em.emit(topic, {field: "{v}", "n": 1}, timestamp=3)
    assert read_lines(out) == [{"$metadata": {"topic": topic, "timestamp": 3}, "$data": {field: "{v}", "n": 1.0}}]


def test_odd_names_of_a_numeric_topic_are_escaped(out: Path, tmp_path: Path):
    """Records of float, int and boolean fields are queued as rows and joined into lines later: names holding
    JSON punctuation and non-ASCII characters come out as json.dumps writes them."""
    topic = 'odd, "topic" é'  # a table folder: no brackets
    fields = {'a, [b] "c": 0.00001': "float", "],[": "int", "é ✓ 😀": "boolean", "e-5": "float"}
    config = write_config(tmp_path / "c.yaml", {topic: {"schema": fields}})
    records = [dict(zip(fields, values)) for values in [(1e-5, -(2**63), True, -0.0), (2.5, 2**63 - 1, False, 1e22)]]
    with Emitter(config, out) as em:
        for i, record in enumerate(records):
            em.emit(topic, record, timestamp=i)
    expected = [json.dumps({"$metadata": {"topic": topic, "timestamp": i}, "$data": r}) for i, r in enumerate(records)]
    assert out.read_text().splitlines() == expected


def test_output_is_appended_and_folders_created(out: Path):
    for ts in (1, 2):
        with Emitter(FIXTURE_CONFIG, out) as em:
            em.emit("robot_speed", {"speed": 0.5}, ts)
    assert [line["$metadata"]["timestamp"] for line in read_lines(out)] == [1, 2]


# --- validation rules -------------------------------------------------------------------

# Values tried against every field type: the Emitter must accept exactly what check_value accepts.
VALUE_TABLE = [
    0,
    1,
    -7,
    2**63 - 1,
    -(2**63),
    2**63,
    2**80,
    True,
    False,
    0.0,
    -0.0,
    1.5,
    1e308,
    float("nan"),
    float("inf"),
    -float("inf"),
    "",
    "text",
    "NaN",
    b"bytes",
    None,
    [],
    ["a", "b"],
    ["a", 1],
    ("a",),
    {"a": 1},
    object(),
    np.int8(3),
    np.int64(-4),
    np.uint64(2**64 - 1),
    np.float32(1.25),
    np.float64(2.5),
    np.float64("nan"),
    np.float32("inf"),
    np.bool_(True),
    np.str_("np"),
    np.array(["a", "b"]),
    np.array([1.0, 2.0]),
    [{"name": "m", "type": "scalar", "value": 1.5}],
    [{"name": "m", "type": "text", "value": "ok", "description": "d", "status": "PASSED"}],
    [{"name": "m", "type": "image", "value": ["1.jpg", "2.jpg"]}],
    [{"name": "m", "type": "plotly", "value": '{"data": []}'}],
    [{"name": "m", "type": "plotly", "value": "{not json"}],
    [{"name": "m", "type": "bar", "value": 1}],
    [{"name": "m", "type": "scalar"}],
    [{"name": "m", "type": "scalar", "value": 1, "extra": 1}],
    [{"name": 5, "type": "scalar", "value": 1}],
    [{"name": "m", "type": "scalar", "value": True}],
    [{"name": "m", "type": "scalar", "value": np.float64(3.5)}],
    ["not a metric"],
    # text that is not valid Unicode (a lone surrogate) in every string position, and valid non-ASCII text
    "\ud800",
    "a\udfffb",
    np.str_("\udc00"),
    "é ✓ \U0001f600",
    ["ok", "\ud800"],
    np.array(["ok", "\ud800"]),
    [{"name": "\ud800", "type": "scalar", "value": 1}],
    [{"name": "m", "type": "text", "value": "\udbff"}],
    [{"name": "m", "type": "scalar", "value": 1, "description": "\ud800"}],
    [{"name": "m", "type": "scalar", "value": 1, "status": "\ud800"}],
    [{"name": "m", "type": "image", "value": ["\ud800.png"]}],
    [{"name": "m", "type": "image", "value": "\ud800.png"}],
]


def check_value_accepts(field_type, value) -> bool:
    try:
        check_value(field_type, value)
    except (ValueError, TypeError, OverflowError):
        return False
    return True


@pytest.mark.parametrize("field_type", FIELD_TYPES)
def test_accepts_exactly_what_check_value_accepts(field_type: str, out: Path, tmp_path: Path):
    config = write_config(tmp_path / "c.yaml", {"t": {"schema": {"v": field_type}}})
    with Emitter(config, out) as em:
        for i, value in enumerate(VALUE_TABLE):
            expected = check_value_accepts(field_type, value)
            try:
                em.emit("t", {"v": value}, timestamp=i)
                accepted = True
            except ValidationError as exc:
                accepted = False
                assert "topic 't', field 'v'" in str(exc)
            assert accepted == expected, f"{field_type} {value!r}: emitter {accepted}, check_value {expected}"
            if accepted and field_type != "metric[]":
                em.flush()
                written = read_lines(out)[-1]["$data"]["v"]
                assert json.dumps(written) == json.dumps(check_value(field_type, value))  # same value and JSON type


def test_a_rejected_record_writes_nothing(emitter: Emitter, out: Path):
    rejected(emitter, ODOM, {"x": 1.0, "y": 2.0, "z": "up"}, 1)
    rejected(emitter, ODOM, {"x": 1.0, "y": 2.0}, 1)
    emitter.close()
    assert out.read_text() == ""


def test_wrong_type_names_topic_and_field(emitter: Emitter):
    error = rejected(emitter, ODOM, {"x": "left", "y": "right", "z": "up"}, 1000000000)
    assert isinstance(error, ValueError)
    assert str(error).startswith("topic 'odom_linear_velocity', field 'x': expected float, got str 'left'")
    assert (error.topic, error.field, error.index) == (ODOM, "x", None)


@pytest.mark.parametrize("bad", [True, False, np.bool_(False)])
def test_bool_is_not_a_number(emitter: Emitter, bad):
    assert rejected(emitter, "robot_speed", {"speed": bad}, 1).field == "speed"
    record = {"error_m": 1.0, "sigma_m": 1.0, "within_1_sigma": bad}
    assert rejected(emitter, "covariance_accuracy", record, 1).field == "within_1_sigma"


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf"), np.float32("nan")])
def test_non_finite_float_is_rejected(emitter: Emitter, bad):
    error = rejected(emitter, "robot_speed", {"speed": bad}, 1)
    assert "topic 'robot_speed', field 'speed'" in str(error) and "finite" in str(error)


def test_missing_field(emitter: Emitter):
    error = rejected(emitter, ODOM, {"x": 1.0, "y": 2.0}, 1)
    assert error.field == "z" and "missing field(s) 'z'" in str(error) and "topic 'odom_linear_velocity'" in str(error)


def test_extra_field_with_did_you_mean(emitter: Emitter):
    error = rejected(emitter, "robot_speed", {"speed": 1.0, "sped": 2.0}, 1)
    assert error.field == "sped" and "unknown field(s) 'sped'" in str(error) and "did you mean 'speed'" in str(error)
    assert rejected(emitter, "robot_speed", {"sped": 2.0}, 1).field == "speed"  # missing is reported first


def test_data_must_be_a_mapping(emitter: Emitter):
    assert "data must be a dict" in str(rejected(emitter, "robot_speed", [("speed", 1.0)], 1))


def test_unknown_topic(emitter: Emitter):
    error = rejected(emitter, "robot_sped", {"speed": 1.0}, 1)
    assert error.topic == "robot_sped" and "unknown topic" in str(error) and "did you mean 'robot_speed'" in str(error)
    assert "unknown topic" in str(rejected(emitter, "robot_sped", {"speed": [1.0]}, [1], method="emit_series"))
    assert "unknown topic" in str(rejected(emitter, "nope", GOAL, 1, method="emit_event"))


@pytest.mark.parametrize("bad", [None, 1.0, 1.5, "5", True, np.float64(3.0), -1, np.int64(-1), 2**63])
def test_timestamp_must_be_a_non_negative_int64(emitter: Emitter, bad):
    error = rejected(emitter, "robot_speed", {"speed": 1.0}, bad)
    assert error.topic == "robot_speed" and "timestamp" in str(error)
    assert "timestamp" in str(rejected(emitter, "goal_reached", GOAL, bad, method="emit_event"))
    assert rejected(emitter, "robot_speed", {"speed": [1.0, 2.0]}, [0, bad], method="emit_series").index == 1


def test_numpy_integer_timestamps_are_accepted(emitter: Emitter, out: Path):
    emitter.emit("robot_speed", {"speed": 1.0}, np.int64(7))
    emitter.emit("robot_speed", {"speed": 1.0}, np.uint32(8))
    emitter.close()
    assert [line["$metadata"]["timestamp"] for line in read_lines(out)] == [7, 8]


def test_validation_error_is_one_value_error():
    assert issubclass(ValidationError, ValueError)


# --- series -----------------------------------------------------------------------------


def test_series_is_equivalent_to_single_emits(out: Path, tmp_path: Path):
    series = {"x": [1.0, 1.1, 1.1, 1.2], "y": [2.0, 1.9, 1.8, 1.7], "z": [3, 3.0, 3.0, 3.0]}
    stamps = [0, 500000000, 1000000000, 1500000000]
    with Emitter(FIXTURE_CONFIG, out) as em:
        em.emit_series(ODOM, series, timestamps=stamps)
        em.emit_series("goal_status", {"state": np.array(["WAITING", "REACHED"])}, timestamps=np.array([1, 2]))
    singles = tmp_path / "singles.jsonl"
    with Emitter(FIXTURE_CONFIG, singles) as em:
        for i, ts in enumerate(stamps):
            em.emit(ODOM, {k: v[i] for k, v in series.items()}, timestamp=ts)
        em.emit("goal_status", {"state": "WAITING"}, 1)
        em.emit("goal_status", {"state": "REACHED"}, 2)
    assert out.read_bytes() == singles.read_bytes()
    assert len(read_lines(out)) == 6


def test_series_accepts_tuples_ranges_and_arrays(emitter: Emitter, out: Path):
    emitter.emit_series("robot_speed", {"speed": (0.5, 1.5)}, timestamps=range(10, 12))
    emitter.emit_series("robot_speed", {"speed": np.array([2.5])}, timestamps=np.array([12], dtype=np.uint64))
    emitter.close()
    assert [(r["$metadata"]["timestamp"], r["$data"]["speed"]) for r in read_lines(out)] == [
        (10, 0.5),
        (11, 1.5),
        (12, 2.5),
    ]


def test_series_of_unequal_length(emitter: Emitter, out: Path):
    error = rejected(emitter, ODOM, {"x": [1.0, 2.0], "y": [1.0], "z": [1.0, 2.0]}, [0, 1], method="emit_series")
    assert error.topic == ODOM and error.field == "y" and "differ in length" in str(error)
    error = rejected(emitter, ODOM, {"x": [1.0], "y": [1.0], "z": [1.0]}, [0, 1], method="emit_series")
    assert "2 timestamps" in str(error)
    emitter.close()
    assert out.read_text() == ""


def test_series_error_names_index_and_writes_nothing(emitter: Emitter, out: Path):
    error = rejected(
        emitter,
        ODOM,
        {"x": [1.0, 2.0, 3.0], "y": [1.0, float("nan"), 1.0], "z": [0.0] * 3},
        [0, 1, 2],
        method="emit_series",
    )
    assert (error.topic, error.field, error.index) == (ODOM, "y", 1)
    assert str(error).startswith("topic 'odom_linear_velocity', field 'y', index 1: ")
    emitter.close()
    assert out.read_text() == ""


def test_series_needs_lists_timestamps_and_the_topic_fields(emitter: Emitter):
    assert rejected(emitter, "robot_speed", {"speed": 1.0}, [0], method="emit_series").field == "speed"
    assert "needs timestamps" in str(rejected(emitter, "robot_speed", {"speed": [1.0]}, None, method="emit_series"))
    assert rejected(emitter, ODOM, {"x": [1.0], "y": [1.0]}, [0], method="emit_series").field == "z"


# --- events -----------------------------------------------------------------------------


def test_event_lines_carry_event_true(emitter: Emitter, out: Path):
    emitter.emit_event("goal_reached", GOAL, timestamp=1750000000)
    emitter.close()
    (line,) = read_lines(out)
    assert line == {"$metadata": {"topic": "goal_reached", "timestamp": 1750000000, "event": True}, "$data": GOAL}


def test_emit_event_on_a_non_event_topic(emitter: Emitter):
    error = rejected(emitter, "robot_speed", {"speed": 1.0}, 5, method="emit_event")
    assert error.topic == "robot_speed" and "not an event topic" in str(error)


def test_emit_on_an_event_topic_writes_a_plain_row_like_the_reference(emitter: Emitter, out: Path):
    emitter.emit("goal_reached", GOAL, 5)
    emitter.close()
    assert read_lines(out)[0]["$metadata"] == {"topic": "goal_reached", "timestamp": 5}


def test_event_fields_are_validated(emitter: Emitter):
    bad_metric = {**GOAL, "metrics": [{"name": "m", "type": "gauge", "value": 1}]}
    error = rejected(emitter, "goal_reached", bad_metric, 5, method="emit_event")
    assert error.field == "metrics" and "gauge" in str(error)
    assert rejected(emitter, "goal_reached", {**GOAL, "tags": "navigation"}, 5, method="emit_event").field == "tags"
    nan_metric = {**GOAL, "metrics": [{"name": "m", "type": "scalar", "value": float("nan")}]}
    assert "not standard JSON" in str(rejected(emitter, "goal_reached", nan_metric, 5, method="emit_event"))


# --- numpy ------------------------------------------------------------------------------


def test_numpy_values(emitter: Emitter, out: Path):
    emitter.emit(ODOM, {"x": np.float64(0.1), "y": np.float32(0.5), "z": np.int16(2)}, np.int64(1))
    emitter.emit("covariance_accuracy", {"error_m": np.float64(0.2), "sigma_m": 0.3, "within_1_sigma": np.int64(1)}, 2)
    emitter.emit("goal_status", {"state": np.str_("REACHED")}, 3)
    event = {
        **GOAL,
        "tags": np.array(["a", "b"]),
        "metrics": [
            {"name": "s", "type": "scalar", "value": np.float64(2.5)},
            {"name": "i", "type": "image", "value": np.array(["1.png"])},
        ],
    }
    emitter.emit_event("goal_reached", event, 4)
    emitter.emit_series(
        ODOM, {"x": np.arange(3, dtype=np.float32), "y": np.zeros(3), "z": np.arange(3)}, timestamps=np.arange(5, 8)
    )
    emitter.close()
    lines = read_lines(out)
    assert lines[0]["$data"] == {"x": 0.1, "y": 0.5, "z": 2.0}
    assert lines[1]["$data"]["within_1_sigma"] == 1 and lines[2]["$data"] == {"state": "REACHED"}
    assert lines[3]["$data"]["tags"] == ["a", "b"]
    assert [m["value"] for m in lines[3]["$data"]["metrics"]] == [2.5, ["1.png"]]
    assert [(line["$metadata"]["timestamp"], line["$data"]["z"]) for line in lines[4:]] == [
        (5, 0.0),
        (6, 1.0),
        (7, 2.0),
    ]


def test_numpy_bool_is_boolean_only(emitter: Emitter, tmp_path: Path, out: Path):
    config = write_config(tmp_path / "c.yaml", {"flags": {"schema": {"ok": "boolean"}}})
    with Emitter(config, out) as em:
        em.emit_series("flags", {"ok": np.array([True, False])}, [0, 1])
        assert rejected(em, "flags", {"ok": np.int64(1)}, 2).field == "ok"
    assert [line["$data"]["ok"] for line in read_lines(out)] == [True, False]


# --- without a config -------------------------------------------------------------------


def test_without_config_anything_json_is_written(out: Path):
    with Emitter(output_path=out) as em:
        assert not em.validation_enabled
        em.emit("anything", {"a": np.float32(1.5), "b": [1, "x"], "c": {"d": None}, "e": np.arange(2)}, 1)
        em.emit_series("s", {"v": [1, 2]}, [2, 3])
        em.emit_event("ev", {"name": "x"}, 4)
    lines = read_lines(out)
    assert lines[0]["$data"] == {"a": 1.5, "b": [1, "x"], "c": {"d": None}, "e": [0, 1]}
    assert [line["$data"] for line in lines[1:3]] == [{"v": 1}, {"v": 2}]
    assert lines[3]["$metadata"] == {"topic": "ev", "timestamp": 4, "event": True}


def test_without_config_standard_json_and_timestamps_are_still_required(out: Path):
    with Emitter(output_path=out) as em:
        error = rejected(em, "t", {"ok": 1.0, "bad": float("nan")}, 1)
        assert (error.topic, error.field) == ("t", "bad") and "NaN" in str(error)
        assert rejected(em, "t", {"deep": [1.0, float("inf")]}, 1).field == "deep"
        assert rejected(em, "t", {"obj": object()}, 1).field == "obj"
        assert "timestamp" in str(rejected(em, "t", {"a": 1}, None))
        assert "timestamp" in str(rejected(em, "t", {"a": 1}, -5))
        assert rejected(em, "t", {"a": [1, float("nan")]}, [0, 1], method="emit_series").index == 1
        assert "data must be a dict" in str(rejected(em, "t", 5, 1))
    assert out.read_text() == ""


def test_missing_config_file_disables_validation_with_a_warning(out: Path, tmp_path: Path):
    with pytest.warns(UserWarning, match="not found"):
        em = Emitter(tmp_path / "absent.yaml", out)
    assert not em.validation_enabled
    em.emit("any", {"x": "y"}, 1)
    em.close()
    assert len(read_lines(out)) == 1


def test_invalid_config_raises_config_error(out: Path, tmp_path: Path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("version: 1\ntopics:\n  t:\n    schema: {x: flaot}\n")
    with pytest.raises(ConfigError, match="bad.yaml:4"):
        Emitter(bad, out)


def test_config_path_list_is_merged(out: Path, tmp_path: Path):
    first = write_config(tmp_path / "a.yaml", {"a": {"schema": {"x": "int"}}})
    second = write_config(tmp_path / "b.yaml", {"b": {"schema": {"y": "string"}}})
    with Emitter([first, str(second)], out) as em:
        em.emit("a", {"x": 1}, 1)
        em.emit("b", {"y": "z"}, 2)
        assert rejected(em, "a", {"x": "1"}, 3).field == "x"
    assert len(read_lines(out)) == 2


# --- lifecycle, threads and flushing ----------------------------------------------------


def test_close_is_idempotent_and_emit_after_close_raises(out: Path):
    em = Emitter(FIXTURE_CONFIG, out)
    em.close()
    em.close()
    with pytest.raises(ValueError, match="closed"):
        em.emit("robot_speed", {"speed": 1.0}, 1)


def test_flush_interval_must_be_positive(out: Path):
    with pytest.raises(ValueError, match="flush_interval"):
        Emitter(output_path=out, flush_interval=0)


def wait_for_lines(path: Path, count: int) -> int:
    deadline = time.monotonic() + 10
    while len(path.read_bytes().splitlines()) < count and time.monotonic() < deadline:
        time.sleep(0.01)
    return len(read_lines(path))


def test_lines_reach_the_file_every_flush_interval(out: Path):
    with Emitter(FIXTURE_CONFIG, out, flush_interval=0.05) as em:
        em.emit("robot_speed", {"speed": 1.0}, 1)
        assert wait_for_lines(out, 1) == 1


def test_a_full_chunk_is_written_without_waiting_for_the_interval(out: Path):
    with Emitter(FIXTURE_CONFIG, out, flush_interval=3600) as em:
        em.emit_series("robot_speed", {"speed": [1.0] * 10_000}, list(range(10_000)))
        assert wait_for_lines(out, 10_000) == 10_000


def test_garbage_collected_emitter_flushes_and_stops_its_thread(out: Path):
    before = set(threading.enumerate())
    em = Emitter(FIXTURE_CONFIG, out, flush_interval=3600)
    (flusher,) = [t for t in set(threading.enumerate()) - before if t.name.startswith("emitter-flush")]
    em.emit("robot_speed", {"speed": 1.0}, 1)
    del em
    gc.collect()
    assert len(read_lines(out)) == 1
    flusher.join(timeout=10)
    assert not flusher.is_alive()


def test_threads_share_one_emitter_without_loss_or_interleaving(out: Path):
    threads, per_thread = 8, 50_000
    with Emitter(FIXTURE_CONFIG, out, flush_interval=0.01) as em:

        def work(k: int) -> None:  # half the threads emit lines of a text topic, half rows of a numeric one
            for i in range(per_thread):
                if k % 2:
                    em.emit("covariance_accuracy", {"error_m": float(k), "sigma_m": 1.0, "within_1_sigma": i}, i)
                else:
                    em.emit("goal_distance", {"goal_name": f"thread-{k}", "distance_m": float(i)}, i)

        workers = [threading.Thread(target=work, args=(k,)) for k in range(threads)]
        for worker in workers:
            worker.start()
        for worker in workers:
            worker.join()
    seen: dict[str, list[int]] = {f"thread-{k}": [] for k in range(threads)}
    with out.open() as lines:
        for line in lines:
            record = strict_loads(line)
            thread = record["$data"].get("goal_name") or f"thread-{record['$data']['error_m']:.0f}"
            seen[thread].append(record["$metadata"]["timestamp"])
    assert all(stamps == list(range(per_thread)) for stamps in seen.values())


def run_child(script: str, *args: str, **popen) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(script), *args], text=True, **popen)


def test_sigkill_loses_at_most_the_last_flush_interval(out: Path):
    child = run_child(
        """
        import sys, time
        from lakegate.lake.emitter import Emitter
        em = Emitter(sys.argv[1], sys.argv[2], flush_interval=0.1)
        for i in range(1000):
            em.emit("robot_speed", {"speed": 1.0}, i)
        time.sleep(1.0)  # ten flush intervals
        print("slept", flush=True)
        em.emit("robot_speed", {"speed": 2.0}, 1000)  # may be lost: within the last interval
        time.sleep(3600)
        """,
        str(FIXTURE_CONFIG),
        str(out),
        stdout=subprocess.PIPE,
    )
    try:
        assert child.stdout.readline() == "slept\n"
        os.kill(child.pid, signal.SIGKILL)
        assert child.wait(timeout=30) == -signal.SIGKILL
    finally:
        child.kill()
        child.stdout.close()
    stamps = [line["$metadata"]["timestamp"] for line in read_lines(out)]
    assert stamps[:1000] == list(range(1000)) and len(stamps) <= 1001


def test_interpreter_exit_flushes_without_close(out: Path):
    child = run_child(
        """
        import sys, threading, time
        from lakegate.lake.emitter import Emitter
        held = Emitter(sys.argv[1], sys.argv[2], flush_interval=3600)
        for i in range(100):
            held.emit("robot_speed", {"speed": 1.0}, i)
        # only a daemon thread holds it, so it is never finalized: atexit must write its lines
        holder = threading.Thread(target=lambda em: time.sleep(3600), args=(held,), daemon=True)
        holder.start()
        del held
        dropped = Emitter(sys.argv[1], sys.argv[2] + ".2", flush_interval=3600)
        dropped.emit("robot_speed", {"speed": 1.0}, 0)
        del dropped  # garbage-collected before exit
        """,
        str(FIXTURE_CONFIG),
        str(out),
    )
    assert child.wait(timeout=60) == 0
    assert len(read_lines(out)) == 100
    assert len(read_lines(Path(str(out) + ".2"))) == 1


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_forked_child_does_not_write_the_parents_lines_twice(out: Path):
    with Emitter(FIXTURE_CONFIG, out, flush_interval=3600) as em:
        em.emit("robot_speed", {"speed": 1.0}, 1)  # still buffered at the fork
        pid = os.fork()
        if pid == 0:  # child: emit its own line, exit without running pytest's cleanup
            try:
                em.emit("robot_speed", {"speed": 2.0}, 2)
                em.close()
            finally:
                os._exit(0)
        assert os.waitpid(pid, 0)[1] == 0
    assert sorted(line["$metadata"]["timestamp"] for line in read_lines(out)) == [1, 2]


def test_written_floats_round_trip_exactly(emitter: Emitter, out: Path):
    values = [0.1, 1 / 3, 5e-324, 1.7976931348623157e308, -2.5e-10, 123456789.123456789]
    emitter.emit_series("robot_speed", {"speed": values}, list(range(len(values))))
    emitter.close()
    assert [line["$data"]["speed"] for line in read_lines(out)] == values


def test_float_text_is_json_dumps_text_at_every_magnitude(emitter: Emitter, out: Path):
    """Floats are written as json.dumps (Python's repr) writes them, byte for byte: random bit
    patterns, every power of ten, and the magnitudes below 1e-4 where other shortest-digit
    formatters choose another notation ("0.00001" or "1e-7" for repr's "1e-05", "1e-07")."""
    import random
    import struct

    rng = random.Random(3)
    values = [struct.unpack("<d", struct.pack("<Q", rng.getrandbits(64)))[0] for _ in range(20_000)]
    values += [sign * 10.0**e for e in range(-323, 308) for sign in (1, -1)]
    values += [rng.uniform(-10, 10) * 10.0**e for e in range(-12, 20) for _ in range(200)]
    values += [0.0, -0.0, 1e-4, -1e-4, 9.999999999999999e-05, 1e16, 9999999999999998.0, 5e-324]
    values = [v for v in values if v == v and abs(v) != float("inf")]
    stamps = list(range(len(values)))
    emitter.emit_series("robot_speed", {"speed": values}, stamps)
    for i in range(0, len(values), 97):
        emitter.emit("robot_speed", {"speed": values[i]}, timestamp=i)
    emitter.close()
    expected = [
        json.dumps({"$metadata": {"topic": "robot_speed", "timestamp": i}, "$data": {"speed": v}})
        for i, v in enumerate(values)
    ]
    expected += [
        json.dumps({"$metadata": {"topic": "robot_speed", "timestamp": i}, "$data": {"speed": values[i]}})
        for i in range(0, len(values), 97)
    ]
    assert out.read_text().splitlines() == expected


# --- text that is not valid Unicode -------------------------------------------------------

LONE = "\ud800"


def test_lone_surrogate_is_refused_at_emit_in_every_string_position(out: Path, tmp_path: Path):
    """UTF-8, and so Parquet, cannot store a lone surrogate: ingest would refuse the line (and the job)."""
    metric = {"name": "m", "type": "text", "value": "v"}
    with Emitter(FIXTURE_CONFIG, out) as em:
        for field, value in [
            ("name", LONE),
            ("description", "x" + LONE),
            ("tags", ["ok", LONE]),
            ("metrics", [{**metric, "value": LONE}]),
            ("metrics", [{**metric, "name": LONE}]),
        ]:
            error = rejected(em, "goal_reached", {**GOAL, field: value}, 1, method="emit_event")
            assert f"field {field!r}" in str(error) and "lone surrogate" in str(error)
        error = rejected(
            em, "goal_distance", {"goal_name": ["a", LONE], "distance_m": [1.0, 2.0]}, [1, 2], method="emit_series"
        )
        assert "index 1" in str(error) and "lone surrogate" in str(error)
    with Emitter(output_path=out) as em:  # without a config: topic names, field names, nested values
        for topic, data in [(LONE, {"a": 1}), ("t", {LONE: 1}), ("t", {"a": {"b": [LONE]}}), ("t", {"a": LONE})]:
            assert "Unicode" in str(rejected(em, topic, data, 1))
        em.emit("t", {"a": "\U0001f600 é"}, 1)  # written as the JSON escapes of a surrogate *pair*: valid
    assert [line["$data"]["a"] for line in read_lines(out)] == ["\U0001f600 é"]


def test_what_the_emitter_accepts_ingests(out: Path, tmp_path: Path):
    """Every line written for the value table ingests: emit-time and ingest-time rules agree."""
    from lakegate.lake.config import load_config
    from lakegate.lake.ingest import ingest_job

    config = write_config(tmp_path / "c.yaml", {f"t{i}": {"schema": {"v": t}} for i, t in enumerate(FIELD_TYPES)})
    written = 0
    with Emitter(config, out) as em:
        for i, _field_type in enumerate(FIELD_TYPES):
            for value in VALUE_TABLE:
                try:
                    em.emit(f"t{i}", {"v": value}, timestamp=1)
                    written += 1
                except ValidationError:
                    pass
    report = ingest_job(tmp_path / "lake", "main", "b", "j", [out], config=load_config([config]))
    assert report.bad_lines == 0 and sum(report.rows.values()) == written


# --- forked children -------------------------------------------------------------------------

FORK_SCRIPT = """
import multiprocessing, os, sys
from lakegate.lake.emitter import Emitter

mode, lines = sys.argv[3], 500
em = Emitter(sys.argv[1], sys.argv[2], flush_interval=3600)  # only exit paths write, never the interval


def work(k):
    for i in range(lines):  # a line of a text topic and a row of a numeric one
        em.emit("goal_distance", {"goal_name": f"child-{k}", "distance_m": float(i)}, i)
        em.emit("covariance_accuracy", {"error_m": float(k), "sigma_m": 1.0, "within_1_sigma": i}, i)
    return k


em.emit("goal_distance", {"goal_name": "parent", "distance_m": 0.0}, 0)  # queued at the fork: the parent's
ctx = multiprocessing.get_context("fork")
if mode == "process":
    children = [ctx.Process(target=work, args=(k,)) for k in range(8)]
    for child in children:
        child.start()
    for child in children:
        child.join()
    assert all(child.exitcode == 0 for child in children)
elif mode == "pool":
    with ctx.Pool(4) as pool:  # leaving the block terminates the workers (SIGTERM)
        assert sorted(pool.map(work, range(8), chunksize=1)) == list(range(8))
else:
    pids = []
    for k in range(8):
        pid = os.fork()
        if pid == 0:
            work(k)
            os._exit(0)  # no atexit, no finalizers, no flush
        pids.append(pid)
    assert all(os.waitpid(pid, 0)[1] == 0 for pid in pids)
"""


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
@pytest.mark.parametrize("mode", ["process", "pool", "os_fork_os_exit"])
def test_lines_of_forked_children_are_all_written(out: Path, mode: str):
    """Each of 8 children emits 1,000 lines: every line is in the file once, whole, in each child's order."""
    child = run_child(FORK_SCRIPT, str(FIXTURE_CONFIG), str(out), mode)
    assert child.wait(timeout=60) == 0
    seen: dict[str, list[int]] = {}
    for line in read_lines(out):
        data = line["$data"]
        who = data["goal_name"] if "goal_name" in data else f"child-{data['error_m']:.0f} rows"
        seen.setdefault(who, []).append(line["$metadata"]["timestamp"])
    children = {f"child-{k}{kind}": list(range(500)) for k in range(8) for kind in ("", " rows")}
    assert seen == {"parent": [0], **children}


# --- write errors: a full disk ---------------------------------------------------------------


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_write_errors_are_raised_to_the_caller():
    em = Emitter(FIXTURE_CONFIG, "/dev/full", flush_interval=0.01)
    em.emit("robot_speed", {"speed": 1.0}, 1)
    deadline = time.monotonic() + 10  # the flusher thread fails; the next emit raises its error
    with pytest.raises(OSError, match="No space left on device") as info:
        while time.monotonic() < deadline:
            em.emit("robot_speed", {"speed": 1.0}, 2)
            time.sleep(0.01)
    assert "could not write /dev/full" in str(info.value)
    with pytest.raises(OSError, match=r"No space left on device \(\d+ line\(s\) not written\)"):
        em.flush()
    with pytest.raises(OSError, match="not written"):
        em.close()
    em.close()  # closed now: nothing more to say


@pytest.fixture
def tiny_disk(tmp_path: Path):
    """A 64 KiB tmpfs (needs root and mount; skipped where not permitted)."""
    mount_point = tmp_path / "tiny"
    mount_point.mkdir()
    try:
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount_point)], capture_output=True, timeout=10
        )
    except (OSError, subprocess.SubprocessError):
        pytest.skip("mount is not available")
    if done.returncode != 0:
        pytest.skip(f"mounting a tmpfs is not permitted: {done.stderr.decode(errors='replace').strip()}")
    try:
        yield mount_point
    finally:
        subprocess.run(["umount", "-l", str(mount_point)], timeout=10, check=True)  # lazy: even if a file is open


def _half_full(tiny_disk: Path) -> tuple[Path, Path, Emitter]:
    """A filler of 32 KiB on the tiny disk, and an Emitter writing there that flushes only when asked."""
    filler = tiny_disk / "filler"
    filler.write_bytes(b"x" * 32 * 1024)
    out = tiny_disk / "emissions.resim.jsonl"
    return filler, out, Emitter(FIXTURE_CONFIG, out, flush_interval=3600)


def _flush_onto_the_full_disk(em: Emitter, out: Path, count: int) -> int:
    """Flush `count` queued lines onto the full disk: a prefix of whole lines is written (nothing glued)
    and the error counts the rest; how many were written."""
    with pytest.raises(OSError, match="No space left on device") as info:
        em.flush()
    text = out.read_bytes()
    written = len(text.splitlines())
    assert 0 < written < count and text.endswith(b"\n")
    assert f"({count - written} line(s) not written)" in str(info.value)
    return written


def test_full_disk_leaves_only_whole_lines_and_keeps_the_rest_queued(tiny_disk: Path):
    filler, out, em = _half_full(tiny_disk)
    count = 450  # about 43 KB: more than the free space, less than the disk
    em.emit_series(
        "goal_distance",
        {"goal_name": [f"goal-{i:04}" for i in range(count)], "distance_m": [float(i) for i in range(count)]},
        list(range(count)),
    )
    written = _flush_onto_the_full_disk(em, out, count)
    assert [line["$metadata"]["timestamp"] for line in read_lines(out)] == list(range(written))
    filler.unlink()  # space again: the lines kept in the queue are written, in order, once
    em.close()
    assert [line["$metadata"]["timestamp"] for line in read_lines(out)] == list(range(count))


# --- byte identity with the reference Emitters ------------------------------------------------


def load_shapes():
    """tests/lake/emitter_series_shapes.py as a module (a script the references' venvs run too)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("shapes", Path(__file__).with_name("emitter_series_shapes.py"))
    shapes = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(shapes)
    return shapes


def pinned_shape_lines() -> bytes:
    """What resim-open-core 1.6.0 and signalflag 1.8.0 wrote for the shapes."""
    return gzip.decompress((FIXTURE_CONFIG.parent / "emitter_series_shapes.jsonl.gz").read_bytes())


def test_series_are_byte_identical_to_the_references_and_take_the_column_path(tmp_path: Path, monkeypatch):
    """emit_series writes, byte for byte, what resim-open-core 1.6.0 and signalflag 1.8.0 wrote for the same
    calls (fixtures/emitter_series_shapes.jsonl.gz, made by tests/lake/emitter_series_shapes.py under their
    venvs), and every shape of scalar fields is built by the column-by-column path, not record by record."""
    from lakegate.lake import emitter as emitter_module

    shapes = load_shapes()
    by_record = []
    original = emitter_module.SeriesLines.encode

    def spy(self, stamps, columns):
        blocks = original(self, stamps, columns)
        if blocks is None:
            by_record.append(len(stamps))
        return blocks

    monkeypatch.setattr(emitter_module.SeriesLines, "encode", spy)
    out = tmp_path / "emissions.resim.jsonl"
    shapes.main("lakegate.lake.emitter", str(out))
    assert out.read_bytes() == pinned_shape_lines()
    assert by_record == [3]  # only the string[]/metric[] series


def test_emit_of_interleaved_topics_is_byte_identical_to_the_references(tmp_path: Path, monkeypatch):
    """emit() of every record of the shapes writes the references' lines (their emit_series writes each record
    as their emit does). The shapes' records are emitted round robin, so that the rows queued by the numeric
    topics and the lines of the text and list topics share every chunk; each numeric record takes the row path."""
    from lakegate.lake import emitter as emitter_module

    shapes = load_shapes()
    rows_written = []
    original = emitter_module.rows_text

    def spy(rows):
        rows_written.append(len(rows))
        return original(rows)

    monkeypatch.setattr(emitter_module, "rows_text", spy)
    calls = shapes.shapes()
    pinned = pinned_shape_lines().splitlines(keepends=True)
    records, expected, at = [], [], 0
    for topic, columns, stamps in calls:
        records.append([(topic, {k: v[i] for k, v in columns.items()}, stamp) for i, stamp in enumerate(stamps)])
        expected.append(pinned[at : at + len(stamps)])
        at += len(stamps)
    assert at == len(pinned)
    config = tmp_path / "config.resim.yaml"
    config.write_text(shapes.CONFIG)
    out = tmp_path / "emissions.resim.jsonl"
    order = [(k, i) for i in range(max(map(len, records))) for k in range(len(records)) if i < len(records[k])]
    with Emitter(config, out, flush_interval=3600) as em:
        for k, i in order:
            em.emit(*records[k][i])
    assert out.read_bytes() == b"".join(expected[k][i] for k, i in order)
    numeric = sum(len(stamps) for topic, _, stamps in calls if topic in ("floats", "ints", "flags"))
    assert sum(rows_written) == numeric and len(rows_written) > 3  # runs of rows between the other topics' lines


def test_series_the_column_path_declines_are_checked_record_by_record(emitter: Emitter, out: Path):
    """A NaN, a negative timestamp, a lone surrogate: the error names the first bad index; an int in a float
    field is written as the record-by-record path writes it."""
    n = 10_000
    speeds: list[object] = [0.5] * n
    speeds[7_000] = float("nan")
    error = rejected(emitter, "robot_speed", {"speed": speeds}, list(range(n)), method="emit_series")
    assert (error.field, error.index) == ("speed", 7_000)
    stamps = list(range(n))
    stamps[9_999] = -1
    assert rejected(emitter, "robot_speed", {"speed": [0.5] * n}, stamps, method="emit_series").index == 9_999
    states = ["WAITING"] * n
    states[4_321] = LONE
    error = rejected(emitter, "goal_status", {"state": states}, list(range(n)), method="emit_series")
    assert (error.field, error.index) == ("state", 4_321)
    speeds[7_000] = 3
    emitter.emit_series("robot_speed", {"speed": speeds}, list(range(n)))
    emitter.close()
    lines = out.read_bytes().splitlines()
    assert len(lines) == n and lines[7_000].endswith(b'"$data": {"speed": 3.0}}')


def test_full_disk_with_queued_rows_leaves_only_whole_lines(tiny_disk: Path):
    """Rows of a numeric topic become lines when written: on a full disk too, only whole lines, in order."""
    filler, out, em = _half_full(tiny_disk)
    count = 400  # about 46 KB: more than the free space, less than the disk
    for i in range(count):
        em.emit(ODOM, {"x": i / 3, "y": -i / 7, "z": 1e-5 * i}, timestamp=i)
    _flush_onto_the_full_disk(em, out, count)
    filler.unlink()
    em.close()
    expected = [
        json.dumps({"$metadata": {"topic": ODOM, "timestamp": i}, "$data": {"x": i / 3, "y": -i / 7, "z": 1e-5 * i}})
        for i in range(count)
    ]
    assert out.read_text().splitlines() == expected


def test_full_disk_during_a_long_series_leaves_only_whole_lines(tiny_disk: Path):
    filler, out, em = _half_full(tiny_disk)
    count = 10_000  # a series this long is written by the emitting thread, in blocks of lines
    em.emit_series("robot_speed", {"speed": [i / 7 for i in range(count)]}, list(range(count)))
    written = _flush_onto_the_full_disk(em, out, count)
    assert [line["$metadata"]["timestamp"] for line in read_lines(out)] == list(range(written))
    with pytest.raises(OSError, match="not written"):
        em.close()
