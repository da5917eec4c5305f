"""The config model: loading a valid config, merging several files, finding the default config."""

from __future__ import annotations

import pytest

from lakegate.lake.config import (
    ConfigError,
    Location,
    find_default_config,
    load_config,
)
from tests.lake.config_files import FIXTURE, HEADER, line_of, write

# -- the valid example -----------------------------------------------------------------


def test_fixture_loads_topics_metrics_and_set():
    config = load_config(FIXTURE)
    assert list(config.topics) == [
        "odom_linear_velocity",
        "goal_distance",
        "pose_difference",
        "covariance_accuracy",
        "time_to_goal",
        "goal_status",
        "camera_gif",
        "robot_speed",
        "drone_speed",
        "goal_reached",
    ]
    assert config.topics["odom_linear_velocity"].fields == {"x": "float", "y": "float", "z": "float"}
    assert config.topics["covariance_accuracy"].fields["within_1_sigma"] == "int"
    assert config.topics["camera_gif"].fields == {"filename": "image"}
    goal = config.topics["goal_reached"]
    assert goal.event and not config.topics["goal_status"].event
    assert goal.fields == {
        "name": "string",
        "description": "string",
        "status": "status",
        "tags": "string[]",
        "metrics": "metric[]",
    }
    assert goal.location == Location(str(FIXTURE), line_of(FIXTURE, "  goal_reached:"), 3)

    assert len(config.metrics) == 15
    speed = config.metrics["Robot Speed"]
    assert (speed.type, speed.template_type, speed.template, speed.status) == ("test", "system", "line", None)
    assert speed.query_string.startswith("SELECT\n  'Speed',") and "FROM odom_linear_velocity;" in speed.query_string
    assert speed.location == Location(str(FIXTURE), line_of(FIXTURE, "  Robot Speed:"), 3)
    assert speed.query_location is not None and speed.query_location.line == speed.location.line + 3

    to_goal = config.metrics["Time to reach final goal"]
    assert to_goal.units == "s" and to_goal.template == "scalar"
    assert to_goal.status is not None
    assert to_goal.status.query_string == "SELECT '1' FROM time_to_goal HAVING COUNT(*) < ?"
    assert (to_goal.status.block, to_goal.status.warn) == (3, None)
    job_error = config.metrics["Maximum Localization Error (job)"].status
    assert job_error is not None and (job_error.block, job_error.warn) == (1.0, 0.5)
    assert config.metrics["Average Speed"].type == "batch"
    assert config.metrics["Job Outcomes"].template == "pie"

    assert list(config.metrics_sets) == ["Nav Metrics"]
    names = config.metrics_sets["Nav Metrics"].metrics
    assert len(names) == 15 and names[:2] == ["Robot Speed", "Time to reach final goal"]
    assert [m.name for m in config.metrics_in_set("Nav Metrics")] == names
    assert config.paths == [str(FIXTURE)]
    assert config.summary() == "10 topics, 15 metrics, 1 metrics set"


def test_metrics_in_set_unknown_name_lists_known_sets():
    config = load_config(FIXTURE)
    with pytest.raises(KeyError) as caught:
        config.metrics_in_set("Nav metrics")
    assert (
        caught.value.args[0] == "no metrics set 'Nav metrics' (did you mean 'Nav Metrics'?); known sets: 'Nav Metrics'"
    )


def test_only_version_is_required_and_empty_sections_are_fine(tmp_path):
    config = load_config(write(tmp_path, HEADER))
    assert (config.topics, config.metrics, config.metrics_sets, config.dashboards) == ({}, {}, {}, {})
    config = load_config(write(tmp_path, "version: 1\ntopics:\nmetrics:\nmetrics sets:\ndashboards:\nglobal:\n"))
    assert config.summary() == "0 topics, 0 metrics, 0 metrics sets"


def test_bigint_is_int_and_every_field_type_loads(tmp_path):
    config = load_config(
        write(
            tmp_path,
            """
        version: 1
        topics:
          t:
            schema: {a: int, b: bigint, c: float, d: boolean, e: string, f: status, g: image, h: video,
                     i: "string[]", j: "metric[]"}
    """,
        )
    )
    assert config.topics["t"].fields == {
        "a": "int",
        "b": "int",
        "c": "float",
        "d": "boolean",
        "e": "string",
        "f": "status",
        "g": "image",
        "h": "video",
        "i": "string[]",
        "j": "metric[]",
    }


def test_real_world_extras_load(tmp_path):
    config = load_config(
        write(
            tmp_path,
            """
        version: 1
        global:
          refresh_s: 30
          owner: nav-team
        topics:
          speed: {schema: {v: float}}
        metrics:
          Hist:   {type: test,  description: d, query_string: SELECT v FROM speed, template: histogram}
          Share:  {type: batch, description: d, query_string: SELECT 1, template: pie, skip_if_no_data: true}
          Clip:   {type: test,  description: d, query_string: SELECT 'a.mp4', template: video}
          Log:    {type: test,  description: d, query_string: SELECT 'log.txt', template: artifact}
          Board:  {type: dashboard, description: d, query_string: SELECT 1, template: line}
          Weekly:
            type: report
            description: d
            query_string: SELECT 1
            template_type: custom
            template_file: templates/weekly.json
            template_settings:
              colors: [red, blue]
              legend: {show: false}
        dashboards:
          Overview:
            metrics: [Board]
            layout: {columns: 2}
    """,
        )
    )
    assert {m.name: m.template for m in config.metrics.values() if m.template} == {
        "Hist": "histogram",
        "Share": "pie",
        "Clip": "video",
        "Log": "artifact",
        "Board": "line",
    }
    assert config.metrics["Share"].skip_if_no_data and not config.metrics["Hist"].skip_if_no_data
    weekly = config.metrics["Weekly"]
    assert (weekly.type, weekly.template_type, weekly.template_file) == ("report", "custom", "templates/weekly.json")
    assert weekly.template_settings == {"colors": ["red", "blue"], "legend": {"show": False}}
    assert config.metrics["Board"].type == "dashboard"
    overview = config.dashboards["Overview"]
    assert overview.settings == {"metrics": ["Board"], "layout": {"columns": 2}}
    assert (overview.metrics_set, overview.day_range) == (None, None)
    assert config.global_settings == {}
    # SignalFlag's global section has one setting: other keys warn (ignored), as unknown keys do
    assert [(w.location.line, w.message) for w in config.warnings] == [
        (3, "unknown key 'refresh_s' in global of the config file: ignored"),
        (4, "unknown key 'owner' in global of the config file: ignored"),
        (  # kept (above), but a custom template's figure is what the template writes, as in SignalFlag
            20,
            "template_settings of metric 'Weekly' (colors, legend.show) are not applied to its custom template "
            "'templates/weekly.json': ignored, as SignalFlag ignores them (a custom template's figure is what the "
            "template writes: set titles, ranges and colours there)",
        ),
    ]
    assert config.summary() == "1 topic, 6 metrics, 0 metrics sets, 1 dashboard"


def test_yaml_anchors_and_merge_keys(tmp_path):
    config = load_config(
        write(
            tmp_path,
            """
        version: 1
        metrics:
          Base: &base
            type: test
            description: shared
            query_string: SELECT 1
            template: scalar
            template_settings: &settings {digits: 2}
          Derived:
            <<: *base
            description: own
            template_settings: *settings
    """,
        )
    )
    derived = config.metrics["Derived"]
    assert (derived.type, derived.description, derived.template) == ("test", "own", "scalar")
    assert derived.template_settings == {"digits": 2}


# -- several files ---------------------------------------------------------------------


def test_merge_two_files(tmp_path):
    topics = write(
        tmp_path,
        """
        version: 1
        topics:
          speed: {schema: {v: float}}
    """,
        "topics.resim.yaml",
    )
    metrics = write(
        tmp_path,
        """
        version: 1
        metrics:
          Top Speed: {type: test, description: d, query_string: SELECT MAX(v) FROM speed, template: scalar}
        metrics sets:
          Fast: {metrics: [Top Speed]}
    """,
        "metrics.resim.yaml",
    )
    config = load_config([topics, str(metrics)])
    assert list(config.topics) == ["speed"] and list(config.metrics) == ["Top Speed"]
    assert config.paths == [str(topics), str(metrics)]
    assert config.topics["speed"].location == Location(str(topics), 3, 3)
    assert config.metrics["Top Speed"].location == Location(str(metrics), 3, 3)
    assert [m.name for m in config.metrics_in_set("Fast")] == ["Top Speed"]


def test_merge_duplicates_name_both_files(tmp_path):
    first = write(
        tmp_path,
        """
        version: 1
        topics:
          speed: {schema: {v: float}}
        metrics:
          M: {type: test, description: d, query_string: SELECT 1, template: line}
        metrics sets:
          S: {metrics: [M]}
        dashboards:
          D: {}
    """,
        "a.resim.yaml",
    )
    second = write(
        tmp_path,
        """
        version: 1
        metrics sets:
          S: {metrics: []}
        metrics:
          M: {type: batch, description: d, query_string: SELECT 2, template: line}
        topics:
          speed: {schema: {v: int}}
          SPEED: {schema: {v: int}}
        dashboards:
          D: {}
    """,
        "b.resim.yaml",
    )
    with pytest.raises(ConfigError) as caught:
        load_config([first, second])
    assert [str(p) for p in caught.value.problems] == [
        f"{second}:3:3: duplicate metrics set name 'S' found across config files (first defined at {first}:7:3)",
        f"{second}:5:3: duplicate metric name 'M' found across config files (first defined at {first}:5:3)",
        f"{second}:7:3: duplicate topic name 'speed' found across config files (first defined at {first}:3:3)",
        f"{second}:8:3: topic 'SPEED' differs only in letter case from topic 'speed' ({first}:3:3); "
        "SQL table names ignore case",
        f"{second}:10:3: duplicate dashboard name 'D' found across config files (first defined at {first}:9:3)",
    ]


def test_load_config_needs_a_path():
    with pytest.raises(ValueError, match="at least one config file"):
        load_config([])


# -- finding the default config ----------------------------------------------------------


def test_find_default_config(tmp_path):
    assert find_default_config(tmp_path) is None
    (tmp_path / ".resim/metrics").mkdir(parents=True)
    yml = tmp_path / ".resim/metrics/config.resim.yml"
    yml.write_text(HEADER)
    nested = tmp_path / "src/robot"
    nested.mkdir(parents=True)
    assert find_default_config(nested) == yml.resolve()
    yaml_path = tmp_path / ".resim/metrics/config.resim.yaml"
    yaml_path.write_text(HEADER)
    assert find_default_config(tmp_path) == yaml_path.resolve()


def test_find_default_config_defaults_to_cwd(tmp_path, monkeypatch):
    (tmp_path / ".resim/metrics").mkdir(parents=True)
    path = tmp_path / ".resim/metrics/config.resim.yaml"
    path.write_text(HEADER)
    monkeypatch.chdir(tmp_path)
    assert find_default_config() == path.resolve()
