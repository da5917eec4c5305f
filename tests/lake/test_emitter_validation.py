"""The Emitter's line format and validation rules: every field type, series, events, numpy values, no config."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lakegate.lake.config import ConfigError
from lakegate.lake.emitter import Emitter, ValidationError
from lakegate.lake.types import FIELD_TYPES, check_value
from tests.lake.emitter_support import FIXTURE_CONFIG, GOAL, LONE, ODOM, read_lines, rejected, write_config

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
