"""ReSim's and SignalFlag's rules: where lakegate is stricter than ReSim (a warning, an error with
--strict), what SignalFlag's validator refuses, and SignalFlag's merge of several files."""

from __future__ import annotations

from pathlib import Path

import pytest

from lakegate.lake.config import (
    expand_config_paths,
    load_config,
)
from tests.lake.config_files import STRICT, errors, warnings_of, write


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
