"""The config model's errors: each names its line, column and what was expected."""

from __future__ import annotations

import pytest
import yaml

from lakegate.lake.config import (
    ConfigError,
    count_placeholders,
    load_config,
)
from tests.lake.config_files import RESERVED, STRICT, errors, one_error, warnings_of, write

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
