"""The config model: loading, every error with its line and column, merging, the JSON Schema."""

from __future__ import annotations

import textwrap
from pathlib import Path

import jsonschema
import pytest
import yaml

from lakegate.lake.config import (
    ConfigError,
    Location,
    count_placeholders,
    expand_config_paths,
    find_default_config,
    load_config,
)
from lakegate.lake.config_schema import json_schema

FIXTURE = Path(__file__).resolve().parents[2] / "fixtures" / "config.resim.yaml"

HEADER = "version: 1\n"


def write(folder: Path, text: str, name: str = "config.resim.yaml") -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
    return path


def errors(path: Path | list[Path]) -> list[tuple[int, int, str]]:
    """(line, column, message) of every problem with --strict; fails when the config loads."""
    with pytest.raises(ConfigError) as caught:
        load_config(path, strict=True)
    return [(p.location.line, p.location.column, p.message) for p in caught.value.problems]


def warnings_of(path: Path | list[Path]) -> list[tuple[int, int, str]]:
    """(line, column, message) of every warning of a config that loads without --strict."""
    return [(p.location.line, p.location.column, p.message) for p in load_config(path).warnings]


#: How a warning (lakegate stricter than ReSim on purpose) ends when --strict refuses it.
STRICT = " (ReSim accepts this; refused because of --strict)"
RESERVED = "metadata, events, metric_results, container_performance, test_length_seconds"


def one_error(folder: Path, text: str) -> tuple[int, int, str]:
    found = errors(write(folder, text))
    assert len(found) == 1, found
    return found[0]


def line_of(path: Path, text: str) -> int:
    """1-based number of the first line of `path` that is exactly `text`."""
    return path.read_text().splitlines().index(text) + 1


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


# -- errors: each names line, column and what was expected ----------------------------


def test_version_required_and_must_be_1(tmp_path):
    assert one_error(tmp_path, "topics: {}\n") == (1, 1, "missing required key 'version' in the config file")
    assert one_error(tmp_path, "version: 2\n") == (1, 10, "version must be 1, got integer 2")
    assert one_error(tmp_path, "version: '1'\n") == (1, 10, "version must be 1, got string '1'")


def test_unknown_keys_everywhere_with_did_you_mean_warn_or_fail_with_strict(tmp_path):
    path = write(
        tmp_path,
        """
        version: 1
        topcs: {}
        topics:
          t:
            shema: {x: float}
            schema: {x: float}
        metrics:
          X:
            type: test
            description: d
            querystring: SELECT 1
            query_string: SELECT 1
            template: line
            status: {query_string: 'SELECT ?', block: 1, blok: 2}
        metrics sets:
          S: {metric: [X], metrics: [X]}
    """,
    )
    expected = [
        (2, 1, "unknown key 'topcs' in the config file (did you mean 'topics'?): ignored"),
        (5, 5, "unknown key 'shema' in topic 't' (did you mean 'schema'?): ignored"),
        (11, 5, "unknown key 'querystring' in metric 'X' (did you mean 'query_string'?): ignored"),
        (14, 50, "unknown key 'blok' in status of metric 'X' (did you mean 'block'?): ignored"),
        (16, 7, "unknown key 'metric' in metrics set 'S' (did you mean 'metrics'?): ignored"),
    ]
    assert warnings_of(path) == expected
    config = load_config(path)  # read as ReSim reads it: the unknown keys are left out
    assert config.topics["t"].fields == {"x": "float"} and config.metrics_sets["S"].metrics == ["X"]
    assert errors(path) == [
        (line, column, message.removesuffix(": ignored") + STRICT) for line, column, message in expected
    ]


def test_unknown_key_without_a_close_match_has_no_suggestion(tmp_path):
    assert one_error(tmp_path, "version: 1\nzzz: 1\n") == (
        2,
        1,
        "unknown key 'zzz' in the config file" + STRICT,
    )


def test_unknown_field_type_with_did_you_mean(tmp_path):
    assert one_error(
        tmp_path,
        """
        version: 1
        topics:
          odom:
            schema:
              x: flaot
    """,
    ) == (
        5,
        10,
        "unknown field type 'flaot' for field 'x' of topic 'odom' (did you mean 'float'?); "
        "expected one of int, float, boolean, string, status, image, video, string[], metric[], bigint",
    )
    assert one_error(tmp_path, "version: 1\ntopics: {t: {schema: {x: }}}\n") == (
        2,
        25,
        "field 'x' of topic 't' needs a type, got nothing (null); expected one of int, float, boolean, "
        "string, status, image, video, string[], metric[], bigint",
    )


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("nav/odom", "topic 'nav/odom' contains '/', which topic names may not"),
        ('""', "topic '' has an empty name"),
        ("_private", "topic '_private' starts with '_' or '.', which topic names may not"),
        (".hidden", "topic '.hidden' starts with '_' or '.', which topic names may not"),
        ('"tab\\there"', "topic 'tab\there' contains a control character"),
        (
            "metadata",
            f"topic 'metadata' is a reserved table name ({RESERVED})",
        ),
        (
            "Events",
            f"topic 'Events' is a reserved table name ({RESERVED})",
        ),
        (
            "metric_results",
            f"topic 'metric_results' is a reserved table name ({RESERVED})",
        ),
    ],
)
def test_bad_topic_names(tmp_path, name, message):
    assert one_error(tmp_path, f"version: 1\ntopics:\n  {name}:\n    schema: {{x: float}}\n") == (3, 3, message)


def test_bad_field_names(tmp_path):
    assert errors(
        write(
            tmp_path,
            """
        version: 1
        topics:
          pose:
            schema:
              x: float
              X: float
              timestamp: int
              Job_ID: string
              true: boolean
    """,
        )
    ) == [
        (
            6,
            7,
            "field 'X' of topic 'pose' differs only in letter case from field 'x' (at line 5, column 7); "
            "SQL column names ignore case",
        ),
        (
            7,
            7,
            "field 'timestamp' of topic 'pose' is a column every topic row already has "
            "(timestamp, batch_id, job_id, experience_name, build_version, project_id, run_counter)",
        ),
        (
            8,
            7,
            "field 'Job_ID' of topic 'pose' is a column every topic row already has "
            "(timestamp, batch_id, job_id, experience_name, build_version, project_id, run_counter)",
        ),
        (
            9,
            7,
            "field 'true' in topic 'pose' is read by YAML as a boolean, not a string" + STRICT,
        ),
    ]


def test_topic_names_differing_only_in_case(tmp_path):
    assert one_error(tmp_path, "version: 1\ntopics:\n  speed: {schema: {}}\n  Speed: {schema: {}}\n") == (
        4,
        3,
        f"topic 'Speed' differs only in letter case from topic 'speed' ({tmp_path / 'config.resim.yaml'}:3:3); "
        "SQL table names ignore case",
    )


METRIC_WITH_STATUS = """
    version: 1
    metrics:
      M:
        type: test
        description: d
        query_string: SELECT 1
        template: scalar
        status:
          query_string: {query}
          block: 3
"""


@pytest.mark.parametrize(
    ("query", "found"),
    [
        ("SELECT 1 FROM t", 0),
        ("SELECT 1 FROM t WHERE a > ? AND b < ?", 2),
        ("SELECT '?' FROM t WHERE \"a?\" > 1 -- ?", 0),
        ("SELECT 1 /* ? */ FROM t", 0),
    ],
)
def test_status_query_needs_exactly_one_placeholder(tmp_path, query, found):
    text = METRIC_WITH_STATUS.replace("{query}", yaml.safe_dump(query).splitlines()[0])
    assert one_error(tmp_path, text) == (
        9,
        21,
        f"status query_string of metric 'M' must have exactly one ? placeholder "
        f"(replaced by the block and warn thresholds), found {found}",
    )


def test_status_query_with_one_placeholder_beside_quoted_ones_is_fine(tmp_path):
    query = """SELECT 'it''s ?' AS "who?" FROM t -- why?\n/* ? */ HAVING COUNT(*) < ?"""
    config = load_config(write(tmp_path, METRIC_WITH_STATUS.replace("{query}", yaml.safe_dump(query).strip())))
    assert config.metrics["M"].status.query_string == query


def test_status_query_unterminated_literal(tmp_path):
    text = METRIC_WITH_STATUS.replace("{query}", '"SELECT \'abc FROM t WHERE x < ?"')
    assert one_error(tmp_path, text) == (9, 21, "status query_string of metric 'M' has an unterminated string literal")


def test_count_placeholders():
    assert count_placeholders("SELECT ?") == 1
    assert count_placeholders("SELECT '?''?', \"?\"\"?\", ? -- ?\n, ? /* ?\n? */") == 2
    for sql, what in [("SELECT 'a", "string literal"), ('SELECT "a', "quoted identifier"), ("SELECT /* a", "comment")]:
        with pytest.raises(ValueError, match=f"unterminated {what}"):
            count_placeholders(sql)


def test_status_with_only_warn_loads(tmp_path):
    text = METRIC_WITH_STATUS.replace("{query}", "SELECT 1 FROM t HAVING COUNT(*) < ?").replace("block: 3", "warn: 3")
    status = load_config(write(tmp_path, text)).metrics["M"].status
    assert (status.block, status.warn) == (None, 3)


def test_status_without_block_or_warn(tmp_path):
    text = METRIC_WITH_STATUS.replace("{query}", "SELECT 1 FROM t HAVING COUNT(*) < ?").replace("      block: 3\n", "")
    assert one_error(tmp_path, text) == (8, 5, "status of metric 'M' needs 'block' or 'warn'")


def test_description_is_optional(tmp_path):
    text = METRIC_WITH_STATUS.replace("{query}", "SELECT 1 FROM t HAVING COUNT(*) < ?").replace(
        "        description: d\n", ""
    )
    assert load_config(write(tmp_path, text)).metrics["M"].description == ""


def test_metrics_set_may_list_dashboard_and_report_metrics(tmp_path):
    config = load_config(
        write(
            tmp_path,
            """
        version: 1
        metrics:
          A: {type: test, query_string: SELECT 1, template: scalar}
          Board: {type: dashboard, query_string: SELECT 1, template: line}
          Weekly: {type: report, query_string: SELECT 1, template: table}
        metrics sets:
          S: {metrics: [A, Board, Weekly]}
    """,
        )
    )
    assert [m.type for m in config.metrics_in_set("S")] == ["test", "dashboard", "report"]


def test_status_must_be_a_mapping_and_thresholds_scalars(tmp_path):
    assert errors(
        write(
            tmp_path,
            """
        version: 1
        metrics:
          A: {type: test, description: d, query_string: SELECT 1, template: scalar, status: block}
          B: {type: test, description: d, query_string: SELECT 1, template: scalar,
              status: {query_string: 'SELECT ?', block: [1], warn: true}}
    """,
        )
    ) == [
        (3, 85, "status of metric 'A' must be a mapping, got string 'block'"),
        (5, 49, "'block' in status of metric 'B' must be a number, got a list"),
        (5, 60, "'warn' in status of metric 'B' must be a number, got boolean true"),
    ]


def test_metrics_set_errors(tmp_path):
    assert errors(
        write(
            tmp_path,
            """
        version: 1
        metrics:
          Robot Speed: {type: test, description: d, query_string: SELECT 1, template: line}
          Board: {type: dashboard, description: d, query_string: SELECT 1, template: line}
          Weekly: {type: report, description: d, query_string: SELECT 1, template: table}
        metrics sets:
          S:
            metrics:
              - Robot Sped
              - Robot Speed
              - Robot Speed
              - Board
              - Weekly
              - Nothing Like It
    """,
        )
    ) == [
        (9, 9, "metrics set 'S' names unknown metric 'Robot Sped' (did you mean 'Robot Speed'?)"),
        (11, 9, "duplicate metric 'Robot Speed' in metrics set 'S' (first at line 10, column 9)"),
        (14, 9, "metrics set 'S' names unknown metric 'Nothing Like It'"),
    ]


def test_missing_and_empty_query_string(tmp_path):
    assert errors(
        write(
            tmp_path,
            """
        version: 1
        metrics:
          A:
            type: test
            description: d
            template: line
          B: {type: test, description: d, query_string: "  ", template: line}
    """,
        )
    ) == [
        (3, 3, "missing required key 'query_string' in metric 'A'"),
        (7, 49, "'query_string' in metric 'B' must not be empty"),
    ]


def test_wrong_value_types(tmp_path):
    assert errors(
        write(
            tmp_path,
            """
        version: 1
        topics:
          a:
            event: yes-please
            schema: [x, y]
          b: just a string
        metrics:
          M:
            type: tset
            description: 2024
            query_string: SELECT 1
            template: line
            units: [m]
            template_settings: [1]
            skip_if_no_data: "false"
        metrics sets:
          S: {metrics: Robot Speed}
    """,
        )
    ) == [
        (4, 12, "'event' in topic 'a' must be a boolean (true or false), got string 'yes-please'"),
        (5, 13, "'schema' in topic 'a' must be a mapping of field names to types, got a list"),
        (6, 6, "topic 'b' must be a mapping, got string 'just a string'"),
        (
            9,
            11,
            "unknown type 'tset' in metric 'M' (did you mean 'test'?); expected one of test, batch, dashboard, report",
        ),
        (10, 18, "'description' in metric 'M' must be a string, got integer 2024 (quote it)"),
        (13, 12, "'units' in metric 'M' must be a string, got a list"),
        (14, 24, "'template_settings' in metric 'M' must be a mapping, got a list"),
        (15, 22, "'skip_if_no_data' in metric 'M' must be a boolean (true or false), got string 'false'"),
        (17, 16, "'metrics' in metrics set 'S' must be a list of metric names, got string 'Robot Speed'"),
    ]


def test_template_rules(tmp_path):
    assert errors(
        write(
            tmp_path,
            """
        version: 1
        metrics:
          NoTemplate: {type: test, description: d, query_string: SELECT 1}
          NoFile: {type: test, description: d, query_string: SELECT 1, template_type: custom}
          FileWithSystem: {type: test, description: d, query_string: SELECT 1, template: line, template_file: t.json}
          BadKind: {type: test, description: d, query_string: SELECT 1, template_type: sytem}
    """,
        )
    ) == [
        (3, 3, "missing key 'template' in metric 'NoTemplate', needed with template_type: system"),
        (4, 3, "missing key 'template_file' in metric 'NoFile', needed with template_type: custom"),
        (5, 103, "'template_file' in metric 'FileWithSystem' is not used with template_type: system" + STRICT),
        (
            6,
            80,
            "unknown template_type 'sytem' in metric 'BadKind' (did you mean 'system'?); "
            "expected one of system, custom",
        ),
    ]


def test_duplicate_keys_are_detected(tmp_path):
    assert errors(
        write(
            tmp_path,
            """
        version: 1
        topics:
          t:
            schema:
              x: float
              x: int
        metrics:
          M:
            type: test
            description: d
            query_string: SELECT 1
            query_string: SELECT 2
            template: line
            template_settings: {a: 1, a: 2}
          M:
            type: batch
        topics: {}
    """,
        )
    ) == [
        (6, 7, "duplicate field 'x' in topic 't' (first at line 5, column 7)"),
        (12, 5, "duplicate key 'query_string' in metric 'M' (first at line 11, column 5)"),
        (14, 31, "duplicate key 'a' in template_settings of metric 'M' (first at line 14, column 25)"),
        (15, 3, "duplicate metric 'M' (first at line 8, column 3)"),
        (17, 1, "duplicate key 'topics' in the config file (first at line 2, column 1)"),
    ]


def test_invalid_yaml_reports_the_parser_position(tmp_path):
    line, column, message = one_error(tmp_path, "version: 1\ntopics:\n  t: {schema: {x: float}\nmetrics: {}\n")
    assert (line, column) == (4, 1)
    assert message.startswith("invalid YAML: expected ',' or '}', but got '<scalar>'")
    assert message.endswith("(while parsing a flow mapping, line 3, column 6)")
    line, column, message = one_error(tmp_path, "version: 1\ntopics:\n\tt: {}\n")
    assert (line, column) == (3, 1) and "found character '\\t' that cannot start any token" in message


def test_yaml_edge_cases(tmp_path):
    assert errors(
        write(
            tmp_path,
            """
        version: 1
        topics:
          1: {schema: {}}
          t:
            <<: 5
            schema: {}
        dashboards: &d {loop: *d}
    """,
        )
    ) == [
        (3, 3, "topic '1' is read by YAML as an integer, not a string" + STRICT),
        (5, 9, "'<<' can only merge mappings, got integer 5"),
        (7, 13, "recursive alias in dashboards of the config file"),
    ]


def test_yaml_1_2_scalars_stay_strings(tmp_path):
    """YAML 1.2 (ruamel.yaml, the library the dashboard edits configs with): `on`, `yes` and `1:30`
    are strings, as they come back from an edit; YAML 1.1 would read True, True and 90."""
    config = load_config(
        write(
            tmp_path,
            """
        version: 1
        topics:
          t: {schema: {on: string}}
        metrics:
          M:
            type: test
            description: d
            query_string: SELECT 1 WHERE ? = 'x'
            template: scalar
            units: on
            template_settings: {at: 1:30, show: yes}
    """,
        )
    )
    metric = config.metrics["M"]
    assert (metric.units, metric.template_settings) == ("on", {"at": "1:30", "show": "yes"})
    assert list(config.topics["t"].fields) == ["on"]


def test_file_level_problems(tmp_path):
    assert one_error(tmp_path, "# nothing here\n") == (
        1,
        1,
        "the file is empty; expected a mapping starting with 'version: 1'",
    )
    assert one_error(tmp_path, "- version: 1\n") == (1, 1, "the config file must be a mapping, got a list")
    missing = tmp_path / "missing.yaml"
    [(line, column, message)] = errors(missing)
    assert (line, column) == (0, 0) and message.startswith("cannot read the file: [Errno 2]")
    with pytest.raises(ConfigError) as caught:
        load_config(missing)
    assert str(caught.value).startswith(f"{missing}: cannot read the file")


def test_all_errors_are_reported_at_once(tmp_path):
    path = write(
        tmp_path,
        """
        version: 1
        topics:
          a/b: {schema: {x: flaot}}
        metrics:
          M: {type: test, description: d, querystring: SELECT 1, template: line}
        metrics sets:
          S: {metrics: [Missing]}
    """,
    )
    with pytest.raises(ConfigError) as caught:
        load_config(path, strict=True)
    text = str(caught.value).splitlines()
    assert len(text) == 5
    assert all(line.startswith(f"{path}:") for line in text)
    assert text[0] == f"{path}:3:3: topic 'a/b' contains '/', which topic names may not"


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


# -- the JSON Schema agrees with the loader ----------------------------------------------


@pytest.fixture(scope="module")
def validator() -> jsonschema.Draft202012Validator:
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def test_fixture_is_valid_under_the_json_schema(validator):
    assert list(validator.iter_errors(yaml.safe_load(FIXTURE.read_text()))) == []


M = "{type: test, description: d, query_string: SELECT 1, template: line"

# Each config is judged the same by the loader and the JSON Schema (True: valid).
AGREEMENT = [
    (True, "version: 1\n"),
    (True, "version: 1\ntopics:\nmetrics:\nmetrics sets:\n"),
    (True, "version: 1\ntopics: {t: {event: true, schema: {a: bigint, b: 'string[]'}}}\n"),
    (True, f"version: 1\nmetrics: {{M: {M}, status: {{query_string: 'SELECT ?', block: 1.5, warn: 2}}}}}}\n"),
    (True, f"version: 1\nmetrics: {{M: {M}, skip_if_no_data: true, template_settings: {{a: 1}}, units: s}}}}\n"),
    (
        True,
        "version: 1\nmetrics: {M: {type: report, description: d, query_string: x, template_type: custom, "
        "template_file: f.json}}\n",
    ),
    (True, "version: 1\ndashboards: {D: {any: [thing]}}\nglobal: {skip-if-no-data: true}\n"),
    (False, "version: 1\nglobal: {x: 1}\n"),
    (False, "version: 1\nglobal: {skip-if-no-data: 1}\n"),
    (False, "topics: {}\n"),
    (False, "version: 2\n"),
    (False, "version: 1\nextra: 1\n"),
    (False, "version: 1\ntopics: {a/b: {schema: {}}}\n"),
    (False, "version: 1\ntopics: {_a: {schema: {}}}\n"),
    (False, "version: 1\ntopics: {METADATA: {schema: {}}}\n"),
    (False, "version: 1\ntopics: {t: {}}\n"),
    (False, "version: 1\ntopics: {t: {schema: {x: flaot}}}\n"),
    (False, "version: 1\ntopics: {t: {schema: {timestamp: int}}}\n"),
    (False, "version: 1\ntopics: {t: {event: yes-please, schema: {}}}\n"),
    (False, "version: 1\ntopics: {t: {schema: [x]}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, querystring: x}}}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, template: line}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, query_string: ' ', template: line}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, status: {{query_string: 'SELECT ?'}}}}}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, status: {{query_string: 'SELECT ?', block: true}}}}}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, status: {{query_string: 'SELECT ?', block: '0.5'}}}}}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, query_string: x}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, query_string: x, template_type: custom}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, template_file: f.json}}}}\n"),
    (False, "version: 1\nmetrics: {M: {type: tset, description: d, query_string: x, template: line}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, query_string: x, template: lines}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, skip_if_no_data: 'no'}}}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}}}}}\nmetrics sets: {{S: {{metrics: [M, M]}}}}\n"),
    (False, "version: 1\nmetrics sets: {S: {metrics: Robot Speed}}\n"),
    (False, "version: 1\nmetrics sets: {S: {}}\n"),
    (False, "version: 1\ndashboards: [a]\n"),
]


@pytest.mark.parametrize(("valid", "text"), AGREEMENT)
def test_loader_and_json_schema_agree(tmp_path, validator, valid, text):
    path = write(tmp_path, text)
    try:
        load_config(path, strict=True)  # the JSON Schema is the strict form: warnings are findings too
        loader_valid = True
    except ConfigError:
        loader_valid = False
    schema_valid = validator.is_valid(yaml.safe_load(text))
    assert (loader_valid, schema_valid) == (valid, valid)


def test_rules_stricter_than_resim_warn_and_the_config_loads_as_resim_reads_it(tmp_path):
    path = write(
        tmp_path,
        """
        version: 1
        topics:
          2024:
            schema: {true: boolean, x: float}
        metrics:
          Speed:
            type: test
            query_string: SELECT x FROM "2024"
            template: scalar
            template_file: unused.liquid
            unit: m/s
          Both:
            type: test
            query_string: SELECT x FROM "2024"
            template: line
            units: m/s
            unit: km/h
        metrics sets:
          S: {metrics: [Speed, Both]}
    """,
    )
    found = [  # (line, column, what is stricter than ReSim, what lakegate does instead)
        (3, 3, "topic '2024' is read by YAML as an integer, not a string", "taken as the text '2024' (quote it)"),
        (
            4,
            14,
            "field 'true' in topic '2024' is read by YAML as a boolean, not a string",
            "taken as the text 'true' (quote it)",
        ),
        (10, 20, "'template_file' in metric 'Speed' is not used with template_type: system", "ignored"),
        (17, 11, "metric 'Both' has both units 'm/s' and unit 'km/h'", "units is used"),
    ]
    assert warnings_of(path) == [(line, column, f"{what}: {instead}") for line, column, what, instead in found]
    config = load_config(path)
    assert config.topics["2024"].fields == {"true": "boolean", "x": "float"}
    assert config.metrics["Speed"].template_file is None and config.metrics["Speed"].units == "m/s"
    assert config.metrics["Both"].units == "m/s"
    assert errors(path) == [(line, column, what + STRICT) for line, column, what, _ in found]


def test_unit_is_units_and_the_same_value_twice_is_no_warning(tmp_path):
    path = write(
        tmp_path,
        """
        version: 1
        metrics:
          A: {type: test, query_string: SELECT 1, template: table, unit: s, units: s}
    """,
    )
    assert warnings_of(path) == [] and load_config(path, strict=True).metrics["A"].units == "s"


def test_a_quoted_threshold_is_refused_as_signalflag_refuses_it(tmp_path):
    """SignalFlag's validator (open-core signalflag/demo/config_test.py) requires block and warn to be
    numbers: the platform refuses a quoted '0.5' at sync with "Expected Number but got String"."""
    assert errors(
        write(
            tmp_path,
            """
        version: 1
        metrics:
          M: {type: test, description: d, query_string: SELECT 1, template: scalar,
              status: {query_string: 'SELECT 1 WHERE 1 > ?', block: '0.5', warn: 0.25}}
    """,
        )
    ) == [(4, 61, "'block' in status of metric 'M' must be a number, not a quoted string, got string '0.5'")]


def test_topics_do_not_shadow_the_platform_tables(tmp_path):
    """SignalFlag's validator: `set(topics) & BUILTIN_TABLES` must be empty."""
    found = errors(write(tmp_path, "version: 1\ntopics:\n  test_length_seconds:\n    schema: {v: float}\n"))
    assert len(found) == 1 and "test_length_seconds" in found[0][2] and "reserved table name" in found[0][2]


# -- SignalFlag's merge: global per file, dashboards, config path patterns -------------------------


def test_global_skip_if_no_data_applies_to_its_own_file_and_a_metric_setting_wins(tmp_path):
    metric = "{type: test, query_string: SELECT 1, template: scalar"
    first = write(
        tmp_path,
        f"""
        version: 1
        global:
          skip-if-no-data: true
        metrics:
          A: {metric}}}
          B: {metric}, skip_if_no_data: false}}
        """,
        "a.resim.yml",
    )
    second = write(
        tmp_path,
        f"""
        version: 1
        metrics:
          C: {metric}}}
          D: {metric}, skip-if-no-data: true}}
        """,
        "b.resim.yml",
    )
    config = load_config([first, second])
    assert {m.name: m.skip_if_no_data for m in config.metrics.values()} == {
        "A": True,
        "B": False,
        "C": False,
        "D": True,
    }


def test_dashboards_name_a_known_set_and_a_positive_day_range(tmp_path):
    text = """
        version: 1
        metrics:
          T: {type: dashboard, query_string: SELECT 1, template: scalar}
        metrics sets:
          Trends: {metrics: [T]}
        dashboards:
          Weekly: {metrics_set: Trends, day_range: 7, refresh: auto, description: the week}
          Typo: {metrics_set: Trend}
          Forever: {metrics_set: Trends, day_range: 0}
    """
    assert errors(write(tmp_path, text)) == [
        (8, 3, "dashboard 'Typo' names unknown metrics set 'Trend' (did you mean 'Trends'?)"),
        (9, 3, "dashboard 'Forever': day_range must be a positive number of days, got 0"),
    ]
    config = load_config(write(tmp_path, text.split("          Typo")[0]))
    weekly = config.dashboard("Weekly")
    assert (weekly.metrics_set, weekly.day_range, weekly.refresh, weekly.description) == (
        "Trends",
        7,
        "auto",
        "the week",
    )
    with pytest.raises(KeyError, match="no dashboard 'weekly' \\(did you mean 'Weekly'\\?\\)"):
        config.dashboard("weekly")


def test_config_path_patterns_resolve_as_signalflags_cli(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("b.yml", "a.yml", "c.yaml", "notes.txt"):
        (tmp_path / "m").mkdir(exist_ok=True)
        (tmp_path / "m" / name).write_text("version: 1\n")
    assert expand_config_paths(["m/*.yml", "m/c.yaml"]) == [Path("m/a.yml"), Path("m/b.yml"), Path("m/c.yaml")]
    assert expand_config_paths(["m/c.yml,m/a.yaml"]) == [Path("m/c.yaml"), Path("m/a.yml")]  # commas; the twin
    with pytest.raises(FileNotFoundError, match="glob pattern 'x/\\*.yml' matched no config files"):
        expand_config_paths(["x/*.yml"])
    with pytest.raises(FileNotFoundError, match="config file 'm/d.yml' does not exist \\(nor its .yaml twin\\)"):
        expand_config_paths(["m/d.yml"])
