"""Custom templates (`template_type: custom`): Liquid files that render a query
result as Plotly figure JSON, found next to the config, stored with the branch's config, with
errors that name the template's line. Real template files on disk, a real lake, the real CLI."""

from __future__ import annotations

import datetime as dt
import json
import os
import subprocess
import sys
import textwrap
from decimal import Decimal
from pathlib import Path

import pytest

from lakegate.fixtures.generate import CONFIG_PATH, generate_batch
from lakegate.gateway.metrics.custom import render_custom
from lakegate.gateway.metrics.results_table import read_results
from lakegate.gateway.metrics.templates import TemplateError
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
TOPICS = CONFIG_PATH.read_text().split("\nmetrics:\n")[0]
BARS = """\
{
  "data": [{"type": "bar", "x": {{ label | json }}, "y": {{ value | json }}, "name": {{ name | json }}}],
  "layout": {"title": {"text": {{ description | json }}}, "yaxis": {"title": {"text": "{{ units }}"}}}
}
"""


#: Settings SignalFlag applies to system templates only (a custom template's figure is its own).
SETTINGS = "template_settings: {yaxis: {label: Seconds, min: 0}, display: {bins: 9}}"


def config_with(
    folder: Path,
    template_file: str,
    *,
    query: str = "SELECT goal_name, time_s FROM time_to_goal",
    units: str = "s",
    settings: str = "",
) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "config.resim.yaml"
    path.write_text(
        TOPICS
        + textwrap.dedent(f"""
        metrics:
          Goal Times:
            type: test
            description: time per goal
            query_string: {query}
            template_type: custom
            template_file: {template_file}
            units: {units}{settings}
          Nothing Yet:
            type: test
            description: no rows, skipped
            query_string: SELECT goal_name AS label, time_s AS value FROM time_to_goal WHERE time_s < 0
            template_type: custom
            template_file: {template_file}
            skip_if_no_data: true
        metrics sets:
          Custom:
            metrics: [Goal Times, Nothing Yet]
        """)
    )
    return path


def metric_in(tmp_path: Path, template: str, *, name: str = "bars.liquid", where: str = "templates"):
    (tmp_path / where).mkdir(parents=True, exist_ok=True)
    (tmp_path / where / name).write_text(template)
    return load_config(config_with(tmp_path, name)).metrics["Goal Times"]


def test_columns_arrive_as_arrays_with_the_metrics_name_description_and_units(tmp_path):
    metric = metric_in(tmp_path, BARS)
    columns = [("label", "varchar"), ("value", "decimal(4,1)"), ("when", "timestamp(3)")]
    rows = [("a", Decimal("1.5"), dt.datetime(2024, 1, 2, 3, 4, 5)), (None, None, None)]
    rendered = render_custom(metric, columns, rows)
    assert rendered.template == "custom" and rendered.text == "1 trace from bars.liquid"
    assert rendered.figure == {
        # Trino's client protocol sends a decimal as its exact text: so does the template's json
        "data": [{"type": "bar", "x": ["a", None], "y": ["1.5", None], "name": "Goal Times"}],
        "layout": {"title": {"text": "time per goal"}, "yaxis": {"title": {"text": "s"}}},
    }


def test_a_template_beside_the_config_comes_before_its_templates_folder(tmp_path):
    metric = metric_in(tmp_path, BARS.replace('"bar"', '"scatter"'), where=".")
    (tmp_path / "templates").mkdir()
    (tmp_path / "templates" / "bars.liquid").write_text(BARS)
    assert metric.template_path() == (tmp_path / "bars.liquid").resolve()
    assert (
        render_custom(metric, [("label", "varchar"), ("value", "bigint")], [("a", 1)]).figure["data"][0]["type"]
        == "scatter"
    )


def test_a_template_outside_the_configs_folder_or_missing_is_an_error(tmp_path):
    (tmp_path / "bars.liquid").write_text(BARS)
    metric = load_config(config_with(tmp_path / "project", "../bars.liquid")).metrics["Goal Times"]
    with pytest.raises(
        TemplateError,
        match=r"^metric 'Goal Times': custom template '../bars.liquid' not found in "
        r"the config file's folder or its templates/ folder$",
    ):
        render_custom(metric, [("label", "varchar")], [])


@pytest.mark.parametrize(
    ("template", "message"),
    [
        (
            '{\n  "data": [\n    {"x": {{ labels | json }}}]}',
            r"bars.liquid:3:14: 'labels' is undefined",
        ),  # a misspelt column: line and column in the template
        ('{% if label %}\n{"data": []}\n', r"bars.liquid:\d+:\d+: expected tag endif.*"),
        ('{"data": [{"x": {{ label | nosuch }}}]}', r"bars.liquid:1:28: unknown filter 'nosuch'"),
        ('{"data": [{"x": {{ label }}}]}', r"the output of bars.liquid is not JSON \(output line 1, column 17: .*\)"),
        ('[{"type": "bar"}]', r'the output of bars.liquid is not a Plotly figure \(expected an object \{"data"'),
        ('{"data": [[1, 2]]}', r'the output of bars.liquid is not a Plotly figure \(expected an object \{"data"'),
    ],
)
def test_template_errors_say_where(tmp_path, template, message):
    metric = metric_in(tmp_path, template)
    with pytest.raises(TemplateError, match=rf"^metric 'Goal Times': {message}"):
        render_custom(metric, [("label", "varchar")], [("a",)])


def lakegate(*args):
    return subprocess.run(
        [*CLI, *map(str, args)], capture_output=True, text=True, env={**os.environ, "COLUMNS": "200"}, timeout=120
    )


def test_sync_stores_the_template_and_run_renders_it_into_results_and_report(tmp_path):
    job = generate_batch(tmp_path / "inputs", jobs=1, samples_per_goal=4)[0]
    project = tmp_path / "project"
    config_path = config_with(
        project,
        "bars.liquid",
        query="SELECT goal_name AS label, time_s AS value FROM time_to_goal ORDER BY timestamp",
        settings="\n" + " " * 12 + SETTINGS,
    )
    settings_line = config_path.read_text().splitlines().index("    " + SETTINGS) + 1
    (project / "templates").mkdir()
    (project / "templates" / "bars.liquid").write_text(BARS)
    lake = tmp_path / "lake"
    ingest_job(
        lake,
        "main",
        "b1",
        job.job_id,
        [job.emissions_path],
        config=load_config(config_path),
        metadata=load_metadata_file(job.metadata_path),
        logs=job.logs_dir,
    )
    sync = lakegate("metrics", "sync", "--lake", lake, "--branch", "main", "--metrics-config-path", config_path)
    assert sync.returncode == 0, sync.stderr
    # SignalFlag draws a custom template's figure as the template writes it: the settings are
    # ignored, and the warning names the file, line, metric and each setting
    assert (
        f"{config_path}:{settings_line}:24: warning: template_settings of metric 'Goal Times' "
        "(yaxis.label, yaxis.min, display.bins) are not applied to its custom template 'bars.liquid': "
        "ignored, as SignalFlag ignores them" in sync.stderr
    )
    strict = lakegate("metrics", "validate", "--metrics-config-path", config_path, "--strict")
    assert strict.returncode == 1 and "(ReSim accepts this; refused because of --strict)" in strict.stdout
    (project / "templates" / "bars.liquid").unlink()  # the stored config has its own copy

    report = tmp_path / "report.html"
    run = lakegate(
        "metrics",
        "run",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        "b1",
        "--metrics-set",
        "Custom",
        "--format",
        "json",
        "--report",
        report,
    )
    assert run.returncode == 0, run.stderr
    metric, skipped = json.loads(run.stdout)["metrics"]
    assert (metric["template"], metric["status"], metric["value"]) == ("custom", "PASSED", "1 trace from bars.liquid")
    assert metric["problems"] == [
        "template_settings not applied to a custom template: yaxis.label, yaxis.min, display.bins"
    ]
    assert (skipped["template"], skipped["status"], skipped["error"]["message"]) == (
        "custom",
        "NOT_RUN",
        "skipped: the query returned no rows (skip_if_no_data)",
    )

    emitted = [json.loads(line) for line in job.emissions_path.read_text().splitlines()]
    goals = [
        (e["$data"]["goal_name"], e["$data"]["time_s"]) for e in emitted if e["$metadata"]["topic"] == "time_to_goal"
    ]
    assert len(goals) >= 2
    stored, _ = read_results(lake, "main", "b1")
    figure = json.loads(stored["figure_json"])
    assert figure == {
        "data": [{"type": "bar", "x": [g for g, _ in goals], "y": [t for _, t in goals], "name": "Goal Times"}],
        "layout": {"title": {"text": "time per goal"}, "yaxis": {"title": {"text": "s"}}},  # as the template wrote it
    }
    assert (stored["metric_name"], stored["template"], stored["units"]) == ("Goal Times", "custom", "s")
    html = report.read_text()
    assert "Goal Times" in html and '"name":"Goal Times"' in html.replace(", ", ",").replace(": ", ":")
