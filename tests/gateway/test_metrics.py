"""The metrics engine on a real lake: a generated navigation batch ingested as Parquet, evaluated with
the example config through the dialect layer and DuckDB. Expected values are computed here, in
plain Python, from the emitted JSON lines (never from the engine's own output)."""

from __future__ import annotations

import json
import math
import textwrap
from collections import defaultdict
from dataclasses import dataclass
from decimal import ROUND_HALF_UP, Decimal
from pathlib import Path

import orjson
import pytest

from lakegate.dialect.scope import Scope
from lakegate.fixtures.generate import CONFIG_PATH, GeneratedJob, generate_batch
from lakegate.gateway.metrics.evaluation import (
    BatchEvaluation,
    MetricsEngine,
    config_position,
    conflated_status,
    select_metrics,
    worst,
)
from lakegate.gateway.metrics.plotly_arrays import plain_figure
from lakegate.gateway.metrics.result_columns import result_table, table_rows
from lakegate.gateway.metrics.results_table import read_results
from lakegate.gateway.metrics.templates import render
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import Location, Metric, StatusCheck, load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file, read_metadata_row
from lakegate.lake.record import job_logs_dir
from lakegate.lake.schema import METADATA_COLUMNS
from lakegate.lake.template_kinds import TEMPLATES

BRANCH, BATCH = "main", "nav"


def read_emissions(path: Path) -> dict[str, list[tuple[int, dict]]]:
    """topic -> [(timestamp, data)] in file order."""
    topics: dict[str, list[tuple[int, dict]]] = defaultdict(list)
    for line in path.read_text().splitlines():
        record = json.loads(line)
        topics[record["$metadata"]["topic"]].append((record["$metadata"]["timestamp"], record["$data"]))
    return topics


def ingest(lake: Path, batch: str, job: GeneratedJob, config, **metadata) -> None:
    values = {**load_metadata_file(job.metadata_path), **metadata}
    ingest_job(lake, BRANCH, batch, job.job_id, [job.emissions_path], config=config, metadata=values, logs=job.logs_dir)


def flat(points) -> list:
    """Sorted (x, y) points as one flat list (pytest.approx compares flat sequences)."""
    return [value for point in sorted(points) for value in point]


def expected_status(topics: dict[str, list[tuple[int, dict]]]) -> str:
    """The job's status under the fixture metrics, from its emissions: fewer than 3 goals or an
    error above 1 m blocks, an error above 0.5 m warns."""
    goals = len(topics["time_to_goal"])
    error = max(data["position_diff_m"] for _, data in topics["pose_difference"])
    return "BLOCKER" if goals < 3 or error > 1.0 else "WARNING" if error > 0.5 else "PASSED"


@dataclass
class Nav:
    lake: Path
    config: object
    jobs: list[GeneratedJob]
    emissions: dict[str, dict[str, list[tuple[int, dict]]]]  # job id -> topic -> rows
    metadata: dict[str, dict]  # job id -> metadata file values
    engine: MetricsEngine
    evaluation: BatchEvaluation

    def result(self, metric: str, job_id: str | None = None):
        found = [r for r in self.evaluation.results() if r.metric == metric and r.job_id == job_id]
        assert len(found) == 1, (metric, job_id)
        return found[0]


@pytest.fixture(scope="module")
def nav(tmp_path_factory) -> Nav:
    root = tmp_path_factory.mktemp("metrics")
    jobs = generate_batch(root / "inputs", jobs=6, samples_per_goal=12)
    lake = root / "lake"
    version = BranchConfigs(lake, BRANCH).store([CONFIG_PATH])
    config = load_config(CONFIG_PATH)
    for job in jobs:
        ingest(lake, BATCH, job, config)
    engine = MetricsEngine(lake)
    evaluation = engine.evaluate_batch(
        BRANCH, BATCH, config.metrics_in_set("Nav Metrics"), metrics_set="Nav Metrics", config_version=version
    )
    yield Nav(
        lake,
        config,
        jobs,
        {j.job_id: read_emissions(j.emissions_path) for j in jobs},
        {j.job_id: load_metadata_file(j.metadata_path) for j in jobs},
        engine,
        evaluation,
    )
    engine.close()


def write_config(tmp_path: Path, metrics_yaml: str, sets_yaml: str = "") -> Path:
    """A config with the fixture's topics and the given metrics (and sets) sections."""
    topics = CONFIG_PATH.read_text().split("\nmetrics:\n")[0]
    path = tmp_path / "config.resim.yaml"
    metrics = textwrap.indent(textwrap.dedent(metrics_yaml), "  ")
    path.write_text(topics + "\nmetrics:\n" + metrics + "\n" + textwrap.dedent(sets_yaml))
    return path


# -- statuses ---------------------------------------------------------------------------------


def test_job_statuses_follow_the_emitted_data_and_reach_the_metadata(nav):
    jobs = {job.job_id: job for job in nav.evaluation.jobs}
    assert list(jobs) == [j.job_id for j in nav.jobs]  # by start time, as generated
    for job_id, topics in nav.emissions.items():
        want = expected_status(topics)
        assert (jobs[job_id].metrics_status, jobs[job_id].conflated_status) == (want, want)
        row = read_metadata_row(nav.lake, BRANCH, BATCH, job_id)
        assert (row["job_metrics_status"], row["job_conflated_status"]) == (want, want)
    assert {j.conflated_status for j in jobs.values()} == {"PASSED", "WARNING", "BLOCKER"}
    assert nav.evaluation.batch_metrics_status == "PASSED"
    assert nav.evaluation.status == "BLOCKER"  # the jobs fold into the batch's status


def test_the_block_status_of_the_documented_scalar(nav):
    for job_id, topics in nav.emissions.items():
        goals = len(topics["time_to_goal"])
        result = nav.result("Time to reach final goal", job_id)
        assert result.status == ("BLOCKER" if goals < 3 else "PASSED")


def test_status_checks_block_warn_neither_and_error(nav):
    job = nav.jobs[1]  # WARNING by construction: its largest error is in (0.5, 1.0]
    top = max(d["position_diff_m"] for _, d in nav.emissions[job.job_id]["pose_difference"])
    scope = Scope(BATCH, job.job_id)

    def status(block, warn=None, query="SELECT 1 FROM pose_difference HAVING MAX(position_diff_m) > ?"):
        metric = Metric(
            name="m",
            type="test",
            query_string="SELECT MAX(position_diff_m) FROM pose_difference",
            template="scalar",
            status=StatusCheck(query, block, warn),
        )
        return nav.engine.evaluate(metric, BRANCH, scope)

    assert status(top - 0.01).status == "BLOCKER"
    assert status(top - 0.01, warn=top - 0.02).status == "BLOCKER"  # block wins
    assert status(top + 0.01, warn=top - 0.01).status == "WARNING"
    assert status(top + 0.01, warn=top + 0.005).status == "PASSED"
    assert status(top + 0.01).status == "PASSED"  # no warn threshold
    failing = status(1, query="SELECT 1 FROM pose_difference\nHAVING MAX(no_such_column) > ?")
    assert failing.status == "ERROR"
    assert (failing.error.query, failing.error.line, failing.error.column) == ("status query", 2, 12)
    assert "no_such_column" in failing.error.message
    # thresholds are typed parameters: a string is a string, never SQL text
    states = "SELECT 1 FROM goal_status WHERE state = ?"
    assert status("REACHED", query=states).status == "BLOCKER"
    assert status("ABORTED", query=states).status == "PASSED"
    assert status("x' OR '1' = '1", query=states).status == "PASSED"


def test_worst_and_conflated_status():
    assert worst([]) == "PASSED" and worst(["NOT_RUN"]) == "PASSED"
    assert worst(["PASSED", "WARNING", "NOT_RUN"]) == "WARNING"
    assert worst(["WARNING", "BLOCKER", "PASSED"]) == "BLOCKER"
    assert worst(["BLOCKER", "ERROR"]) == "ERROR"
    assert conflated_status("FAILED", "PASSED") == "ERROR"
    assert conflated_status("SUCCEEDED", "WARNING") == "WARNING"


# -- the documented example queries, checked against the emitted data ----------------------------


def test_robot_speed_line(nav):
    for job_id, topics in nav.emissions.items():
        result = nav.result("Robot Speed", job_id)
        (trace,) = plain_figure(result.rendered.figure)["data"]
        assert trace["name"] == "Speed"
        expected = [(t / 1e9, math.sqrt(d["x"] ** 2 + d["y"] ** 2)) for t, d in topics["odom_linear_velocity"]]
        assert flat(zip(trace["x"], trace["y"])) == pytest.approx(flat(expected), rel=1e-12)
        layout = result.rendered.figure["layout"]
        assert (layout["xaxis"]["title"]["text"], layout["yaxis"]["title"]["text"]) == ("Time (s)", "Speed (m/s)")


def test_time_to_reach_final_goal_scalar(nav):
    for job_id, topics in nav.emissions.items():
        times = [d["time_s"] for _, d in topics["time_to_goal"]]
        want = 75.0 if len(times) != 3 else math.fsum(times)
        result = nav.result("Time to reach final goal", job_id)
        assert result.scalar_value == pytest.approx(want, rel=1e-12)
        assert result.value_text.endswith(" s")


def test_distance_to_goal_line_has_one_series_per_goal(nav):
    for job_id, topics in nav.emissions.items():
        series = defaultdict(list)
        for t, d in topics["goal_distance"]:
            series[d["goal_name"]].append((t / 1e9, d["distance_m"]))
        traces = plain_figure(nav.result("Distance to Goal", job_id).rendered.figure)["data"]
        assert {t["name"]: flat(zip(t["x"], t["y"])) for t in traces} == {
            name: pytest.approx(flat(points), rel=1e-12) for name, points in series.items()
        }


def covariance_text(flags: list[int]) -> str:
    """Trino: CASE ... 1.0 ELSE 0.0 is decimal(2,1); AVG keeps decimal(2,1), rounding half up;
    100.0 * it is decimal(6,2); ROUND(.., 1) keeps decimal(6,2); CAST to varchar shows 2 decimals."""
    average = (Decimal(sum(flags)) / Decimal(len(flags))).quantize(Decimal("0.1"), rounding=ROUND_HALF_UP)
    product = Decimal("100.0") * average
    rounded = product.quantize(Decimal("0.1"), rounding=ROUND_HALF_UP).quantize(Decimal("0.01"))
    return f"{rounded}%"


def test_covariance_table_has_trino_decimal_text(nav):
    assert covariance_text([1, 1, 0]) == "70.00%"  # 0.666.. -> 0.7
    assert covariance_text([1, 0, 0, 0]) == "30.00%"  # 0.25 -> 0.3 (half up)
    for job_id, topics in nav.emissions.items():
        flags = [d["within_1_sigma"] for _, d in topics["covariance_accuracy"]]
        table = nav.result("AMCL Covariance Calibration", job_id).rendered.table
        assert table == {
            "columns": ["Metric", "Value"],
            "rows": [["Total Samples", str(len(flags))], ["Within 1σ (target: ~68%)", covariance_text(flags)]],
        }


def test_camera_image_resolved_in_the_job_logs(nav):
    for job in nav.jobs:
        rendered = nav.result("Stereo Camera Feed", job.job_id).rendered
        expected = job_logs_dir(nav.lake, BRANCH, BATCH, job.job_id) / "camera.gif"
        assert "/_job_logs/" in str(expected)  # the folder the ingest recorded, not the hand-copied _logs
        assert rendered.images == [str(expected.resolve())] and rendered.problems == []


def test_goal_status_state_timeline(nav):
    for job_id, topics in nav.emissions.items():
        points = sorted(((t, d["state"]) for t, d in topics["goal_status"]), key=lambda p: p[0])
        first, last = points[0][0], points[-1][0]
        segments = []
        for t, state in points:
            if not segments or segments[-1][1] != state:
                if segments:
                    segments[-1][3] = (t - first) / 1e9
                segments.append(["Navigation", state, (t - first) / 1e9, None])
        segments[-1][3] = (last - first) / 1e9
        rendered = nav.result("Goal Status", job_id).rendered
        assert rendered.table["rows"] == segments
        assert rendered.figure["layout"]["xaxis"]["title"]["text"] == "Elapsed time (s)"
        assert rendered.figure["layout"]["yaxis"]["title"]["text"] == "System"


def test_average_speed_batch_scalar(nav):
    speeds = [d["speed"] for topics in nav.emissions.values() for _, d in topics["robot_speed"]]
    assert nav.result("Average Speed").scalar_value == pytest.approx(math.fsum(speeds) / len(speeds), rel=1e-12)


def test_maximum_localization_error_per_experience_bar(nav):
    per_experience = defaultdict(float)
    for job in nav.jobs:
        for _, d in nav.emissions[job.job_id]["pose_difference"]:
            per_experience[job.experience_name] = max(per_experience[job.experience_name], d["position_diff_m"])
    (trace,) = nav.result("Maximum Localization Error").rendered.figure["data"]
    assert trace["name"] == "Maximum"
    assert trace["x"] == sorted(per_experience)  # ORDER BY m.experience_name
    assert trace["y"] == [per_experience[name] for name in sorted(per_experience)]


def test_drone_speed_by_experience_table(nav):
    speeds = defaultdict(list)
    for job in nav.jobs:
        speeds[job.experience_name] += [d["speed"] for _, d in nav.emissions[job.job_id]["drone_speed"]]
    table = nav.result("Drone Speed by Experience").rendered.table
    assert table["columns"] == ["experience_name", "_col1", "_col2", "_col3"]
    got = {row[0]: row[1:] for row in table["rows"]}
    assert got == {
        name: pytest.approx([min(v), math.fsum(v) / len(v), max(v)], rel=1e-12) for name, v in speeds.items()
    }


def test_select_star_from_metadata(nav):
    table = nav.result("Job Metadata").rendered.table
    assert table["columns"] == [name for name, _ in METADATA_COLUMNS]
    job_ids = [row[table["columns"].index("job_id")] for row in table["rows"]]
    assert sorted(job_ids) == sorted(j.job_id for j in nav.jobs)


def test_classified_tag_query_counts_passed_jobs(nav):
    statuses = {job.job_id: job.conflated_status for job in nav.evaluation.jobs}
    passed = {}
    for job_id, values in nav.metadata.items():
        tags = values["experience_tag_names"]
        group = next((t for t in tags if t.startswith("my_prefix_")), None)
        if "my_tag" in tags and group is not None:
            passed[group] = passed.get(group, 0) + (statuses[job_id] == "PASSED")
    table = nav.result("Passed Jobs by Tag Group").rendered.table
    assert table["columns"] == ["group_name", "passed"]
    assert dict(map(tuple, table["rows"])) == passed
    assert set(passed.values()) != {0}  # the written statuses were seen by the batch metric


def test_job_outcomes_pie_counts_conflated_statuses(nav):
    counts = defaultdict(int)
    for job in nav.evaluation.jobs:
        counts[job.conflated_status] += 1
    (pie,) = nav.result("Job Outcomes").rendered.figure["data"]
    assert dict(zip(pie["labels"], pie["values"])) == counts


# -- scopes -------------------------------------------------------------------------------------


def test_a_test_metric_sees_only_its_job_and_a_batch_metric_sees_the_batch(nav):
    metric = Metric(
        name="rows",
        type="test",
        template="table",
        query_string=(
            "SELECT (SELECT COUNT(DISTINCT job_id) FROM odom_linear_velocity), (SELECT MIN(job_id) FROM metadata), "
            "(SELECT COUNT(*) FROM odom_linear_velocity o JOIN metadata m ON o.job_id = m.job_id)"
        ),
    )
    for job in nav.jobs:
        rows = nav.engine.evaluate(metric, BRANCH, Scope(BATCH, job.job_id)).rendered.table["rows"]
        assert rows == [[1, job.job_id, len(nav.emissions[job.job_id]["odom_linear_velocity"])]]
    every = sum(len(t["odom_linear_velocity"]) for t in nav.emissions.values())
    rows = nav.engine.evaluate(metric, BRANCH, Scope(BATCH)).rendered.table["rows"]
    assert rows == [[len(nav.jobs), min(j.job_id for j in nav.jobs), every]]


def test_metric_queries_are_answered_as_the_server_answers_them(nav):
    """Metrics query through the Engine: qualified names, information_schema and SHOW work as they
    do for `lakegate serve`, still inside the metric's scope."""
    job = nav.jobs[0]
    samples = len(nav.emissions[job.job_id]["odom_linear_velocity"])
    metric = Metric(
        name="qualified",
        type="test",
        template="table",
        query_string=(
            "SELECT (SELECT count(*) FROM lake.main.odom_linear_velocity), "
            "(SELECT count(*) FROM main.odom_linear_velocity WHERE main.odom_linear_velocity.job_id IS NOT NULL)"
        ),
    )
    rows = nav.engine.evaluate(metric, BRANCH, Scope(BATCH, job.job_id)).rendered.table["rows"]
    assert rows == [[samples, samples]]
    tables = Metric(
        name="tables",
        type="batch",
        template="scalar",
        query_string="SELECT count(*) FROM information_schema.tables WHERE table_name = 'metadata'",
    )
    assert nav.engine.evaluate(tables, BRANCH, Scope(BATCH)).rendered.scalar == 1
    show = Metric(name="show", type="test", template="table", query_string="SHOW COLUMNS FROM metadata")
    shown = nav.engine.evaluate(show, BRANCH, Scope(BATCH, job.job_id))
    assert shown.status == "PASSED", shown.error
    assert ["job_id", "varchar", "", ""] in shown.rendered.table["rows"]


def test_metric_queries_use_the_engine_python_functions(nav):
    """The hash functions the engine registers (gateway/engine/udfs.py) and from_unixtime_nanos
    answer in metric queries too."""
    job = nav.jobs[0]
    metric = Metric(
        name="hashes",
        type="test",
        template="table",
        query_string="SELECT to_hex(murmur3(to_utf8('hashme'))), CAST(min(from_unixtime_nanos(timestamp)) "
        "= from_unixtime_nanos(min(timestamp)) AS varchar) FROM odom_linear_velocity",
    )
    evaluated = nav.engine.evaluate(metric, BRANCH, Scope(BATCH, job.job_id))
    assert evaluated.status == "PASSED", evaluated.error
    assert evaluated.rendered.table["rows"] == [["93192FE805BE23041C8318F67EC4F2BC", "true"]]  # TestVarbinaryFunctions


# -- errors, skipping, unsupported ---------------------------------------------------------------


def test_errors_are_recorded_with_positions_and_the_rest_of_the_set_runs(nav, tmp_path):
    config_path = write_config(
        tmp_path,
        """\
      Broken Column:
        description: a metric of this test
        type: test
        query_string: |
          SELECT
            timestamp,
            speed_typo
          FROM robot_speed
        template: table
      Broken Table:
        description: a metric of this test
        type: test
        query_string: SELECT COUNT(*) FROM nowhere_topic
        template: scalar
      Wrong Shape:
        description: a metric of this test
        type: test
        query_string: SELECT timestamp, speed FROM robot_speed
        template: line
      Fine:
        description: a metric of this test
        type: test
        query_string: SELECT COUNT(*) FROM robot_speed
        template: scalar
      Batch Count:
        description: a metric of this test
        type: batch
        query_string: SELECT count_if(job_conflated_status = 'ERROR') FROM metadata
        template: scalar
    """,
        """\
    metrics sets:
      Mixed:
        metrics: [Broken Column, Broken Table, Wrong Shape, Fine, Batch Count]
    """,
    )
    lines = config_path.read_text().splitlines()
    column_line = next(i for i, text in enumerate(lines, 1) if "speed_typo" in text)
    table_line = next(i for i, text in enumerate(lines, 1) if "nowhere_topic" in text)
    config = load_config(config_path)
    for job in nav.jobs[:2]:
        ingest(nav.lake, "errors", job, config)
    with MetricsEngine(nav.lake) as engine:
        evaluation = engine.evaluate_batch(BRANCH, "errors", select_metrics(config, "Mixed"))
    for job in evaluation.jobs:
        by_name = {r.metric: r for r in job.results}
        column = by_name["Broken Column"]
        assert column.status == "ERROR" and (column.error.line, column.error.column) == (3, 3)
        assert column.error.location == Location(
            str(config_path), column_line, lines[column_line - 1].index("speed_typo") + 1
        )
        assert str(column.error).startswith(f"{config_path}:{column_line}:")
        table = by_name["Broken Table"]
        assert table.status == "ERROR" and table.error.line == 1
        assert table.error.location.line == table_line
        assert table.error.location.column == lines[table_line - 1].index("nowhere_topic") + 1
        shape = by_name["Wrong Shape"]
        assert shape.status == "ERROR" and shape.error.query == "template" and shape.error.line is None
        assert "'Wrong Shape'" in shape.error.message and "exactly 3 columns" in shape.error.message
        assert by_name["Fine"].status == "PASSED"
        assert by_name["Fine"].scalar_value == len(nav.emissions[job.job_id]["robot_speed"])
        assert (job.metrics_status, job.conflated_status) == ("ERROR", "ERROR")
    (count,) = evaluation.batch_results
    assert count.status == "PASSED" and count.scalar_value == 2  # the batch metric saw the ERROR jobs


def test_skip_if_no_data_and_unsupported_metrics_are_not_run(nav, tmp_path):
    config_path = write_config(
        tmp_path,
        """\
      Nothing:
        description: a metric of this test
        type: test
        query_string: SELECT speed FROM robot_speed WHERE speed < 0
        template: scalar
        skip_if_no_data: true
      Nothing Unskipped:
        description: a metric of this test
        type: test
        query_string: SELECT speed FROM robot_speed WHERE speed < 0
        template: scalar
      Later:
        description: a metric of this test
        type: dashboard
        query_string: SELECT 1
        template: table
      Custom:
        description: a metric of this test
        type: test
        query_string: SELECT 1
        template_type: custom
        template_file: mine.json
    """,
    )
    config = load_config(config_path)
    scope = Scope(BATCH, nav.jobs[0].job_id)
    results = {m.name: nav.engine.evaluate(m, BRANCH, scope) for m in select_metrics(config, all_metrics=True)}
    assert results["Nothing"].status == "NOT_RUN" and "skip_if_no_data" in results["Nothing"].error.message
    assert results["Nothing Unskipped"].status == "NO_DATA"  # SignalFlag's rule: test_no_data_outcome
    assert "no rows" in results["Nothing Unskipped"].error.message
    assert results["Later"].status == "NOT_RUN"
    assert results["Later"].error.message == "a dashboard metric runs over many batches: lakegate metrics dashboard"
    assert results["Custom"].status == "ERROR"  # rendered by its template now: tests/gateway/test_custom_templates.py
    assert (
        results["Custom"].error.message == "metric 'Custom': custom template 'mine.json' not found in "
        "the config file's folder or its templates/ folder"
    )
    assert worst(r.status for name, r in results.items() if name != "Custom") == "PASSED"


def test_no_data_outcome(nav, tmp_path):
    """SignalFlag's config reference (signalskills, skills/signalflag-compose-metrics/config-reference.md,
    "Required vs optional data", verified on the server): with `skip_if_no_data: false` a query returning
    no rows, or one row of NULLs (MIN(x) over no rows), is NO_DATA and its status check never runs, even
    one that blocks on absence; the job stays PASSED. COUNT(*) over no rows is a row (0): its status
    check runs and blocks."""
    config_path = write_config(
        tmp_path,
        """\
      Absent:
        type: test
        query_string: SELECT speed AS value FROM robot_speed WHERE speed < 0
        template: scalar
        skip_if_no_data: false
        status:
          query_string: SELECT 1 FROM (SELECT COUNT(*) AS n FROM robot_speed WHERE speed < 0) s WHERE s.n <= ?
          block: 0
      Minimum:
        type: test
        query_string: SELECT MIN(speed) AS value FROM robot_speed WHERE speed < 0
        template: scalar
      Counted:
        type: test
        query_string: SELECT COUNT(*) AS value FROM robot_speed WHERE speed < 0
        template: scalar
        skip_if_no_data: false
        status:
          query_string: SELECT 1 FROM (SELECT COUNT(*) AS n FROM robot_speed WHERE speed < 0) s WHERE s.n <= ?
          block: 0
      Hidden:
        type: test
        query_string: SELECT speed AS value FROM robot_speed WHERE speed < 0
        template: scalar
        skip_if_no_data: true
    """,
        """\
    metrics sets:
      Presence:
        metrics: [Absent, Minimum, Hidden]
      Gate:
        metrics: [Absent, Minimum, Counted, Hidden]
    """,
    )
    config = load_config(config_path)
    job = nav.jobs[0]
    ingest(nav.lake, "no-data", job, config)
    with MetricsEngine(nav.lake) as engine:
        presence = engine.evaluate_batch(BRANCH, "no-data", select_metrics(config, "Presence"))
        by_name = {r.metric: r for r in presence.results()}
        assert {name: r.status for name, r in by_name.items()} == {
            "Absent": "NO_DATA",
            "Minimum": "NO_DATA",
            "Hidden": "NOT_RUN",
        }
        assert "one row of NULLs" in by_name["Minimum"].error.message
        assert "status check does not run" in by_name["Absent"].error.message
        (outcome,) = presence.jobs
        assert (outcome.metrics_status, outcome.conflated_status, presence.status) == ("PASSED", "PASSED", "PASSED")
        stored = {(r["metric_name"], r["status"]) for r in read_results(nav.lake, BRANCH, "no-data")}
        assert stored == {("Absent", "NO_DATA"), ("Minimum", "NO_DATA"), ("Hidden", "NOT_RUN")}
        row = read_metadata_row(nav.lake, BRANCH, "no-data", job.job_id)
        assert (row["job_metrics_status"], row["job_conflated_status"]) == ("PASSED", "PASSED")
        gate = engine.evaluate_batch(BRANCH, "no-data", select_metrics(config, "Gate"))
        counted = next(r for r in gate.results() if r.metric == "Counted")
        assert (counted.status, counted.scalar_value, gate.jobs[0].conflated_status) == ("BLOCKER", 0.0, "BLOCKER")


def test_a_template_error_tells_the_status_outcome(nav, tmp_path):
    config_path = write_config(
        tmp_path,
        """\
      Wrong Shape Blocking:
        type: test
        query_string: SELECT timestamp, speed FROM robot_speed
        template: line
        status:
          query_string: SELECT 1 FROM robot_speed WHERE speed > ?
          block: -1
      Wrong Shape Passing:
        type: test
        query_string: SELECT timestamp, speed FROM robot_speed
        template: line
        status:
          query_string: SELECT 1 FROM robot_speed WHERE speed > ?
          warn: 1000000
    """,
    )
    config = load_config(config_path)
    scope = Scope(BATCH, nav.jobs[0].job_id)
    results = {m.name: nav.engine.evaluate(m, BRANCH, scope) for m in select_metrics(config, all_metrics=True)}
    blocking, passing = results["Wrong Shape Blocking"], results["Wrong Shape Passing"]
    assert blocking.status == passing.status == "ERROR"
    assert "exactly 3 columns" in blocking.error.message
    assert blocking.error.message.endswith("; the status check gave BLOCKER")
    assert passing.error.message.endswith("; the status check gave PASSED")


def test_a_failed_job_is_error_whatever_its_metrics(nav):
    config = nav.config
    job = nav.jobs[0]  # PASSED by its data
    ingest(nav.lake, "failed", job, config, job_status="FAILED")
    evaluation = nav.engine.evaluate_batch(BRANCH, "failed", config.metrics_in_set("Nav Metrics"))
    (outcome,) = evaluation.jobs
    assert (outcome.job_status, outcome.metrics_status, outcome.conflated_status) == ("FAILED", "PASSED", "ERROR")
    assert evaluation.status == "ERROR"
    pie = next(r for r in evaluation.batch_results if r.metric == "Job Outcomes").rendered.figure["data"][0]
    assert dict(zip(pie["labels"], pie["values"])) == {"ERROR": 1}


def test_an_unknown_batch_has_no_jobs(nav):
    with pytest.raises(LookupError, match="no jobs"):
        nav.engine.evaluate_batch(BRANCH, "never-ingested", nav.config.metrics_in_set("Nav Metrics"))


# -- events -------------------------------------------------------------------------------------


def test_events_are_listed_per_job(nav):
    for outcome in nav.evaluation.jobs:
        emitted = nav.emissions[outcome.job_id]["goal_reached"]
        assert [(e.timestamp, e.name, e.status, e.tags) for e in outcome.events] == [
            (t, d["name"], d["status"], d["tags"]) for t, d in emitted
        ]
        for event, (_, data) in zip(outcome.events, emitted):
            assert [(m.name, m.type, m.value) for m in event.metrics] == [
                (m["name"], m["type"], m["value"]) for m in data["metrics"]
            ]
        assert nav.engine.job_events(BRANCH, BATCH, outcome.job_id) == outcome.events
    assert sum(len(j.events) for j in nav.evaluation.jobs) == sum(
        len(t["goal_reached"]) for t in nav.emissions.values()
    )


# -- config positions ---------------------------------------------------------------------------


def test_config_position_maps_query_positions_into_the_file(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text('a:\n  q: |\n    SELECT\n      x\n  p: SELECT y\n  s: "SELECT z"\n  f: >\n    SELECT\n    w\n')
    file = str(path)
    assert config_position(Location(file, 2, 6), "SELECT\n  x\n", 2, 3) == Location(file, 4, 7)
    assert config_position(Location(file, 5, 6), "SELECT y", 1, 8) == Location(file, 5, 13)
    assert config_position(Location(file, 6, 6), "SELECT z", 1, 8) == Location(file, 6, 14)
    assert config_position(Location(file, 7, 6), "SELECT w\n", 1, 8) is None  # folded: no exact place
    assert config_position(Location(file, 5, 6), "SELECT other", 1, 8) is None  # not the file's text
    assert config_position(None, "SELECT 1", 1, 1) is None


def test_a_batch_image_metric_of_labels_and_job_ids_shows_each_jobs_files(nav, tmp_path):
    """ReSim's isaacsim-demo config (.resim/metrics/config.resim.yml, "Camera feed (bright scenes)")
    has batch image metrics returning [experience_name, job_id]: each listed job's image files, labelled."""
    config_path = write_config(
        tmp_path,
        """\
      Camera feeds:
        type: batch
        query_string: |
          SELECT m.experience_name, c.job_id FROM camera_gif c JOIN metadata m ON c.job_id = m.job_id
          WHERE m.job_id IN (?, ?) ORDER BY m.experience_name
        template: image
      Camera feeds of nobody:
        type: batch
        query_string: SELECT 'nobody' AS label, 'no-such-job' AS job_id
        template: image
    """,
    )
    picked = nav.jobs[:2]
    text = config_path.read_text().replace("IN (?, ?)", f"IN ('{picked[0].job_id}', '{picked[1].job_id}')")
    config_path.write_text(text)
    config = load_config(config_path)
    scope = Scope(BATCH)
    feeds = nav.engine.evaluate(config.metrics["Camera feeds"], BRANCH, scope)
    assert feeds.status == "PASSED", feeds.error
    expected = []
    for job in sorted(picked, key=lambda j: nav.metadata[j.job_id]["experience_name"]):
        for _, data in nav.emissions[job.job_id]["camera_gif"]:
            expected.append((f"{nav.metadata[job.job_id]['experience_name']}: {data['filename']}", job.job_id))
    rows = feeds.rendered.table["rows"]
    assert len({job for _, job in expected}) == 2  # both jobs logged camera images
    assert [row[0] for row in rows] == [caption for caption, _ in expected]
    for row, (_, job_id) in zip(rows, expected):
        assert Path(row[1]).parent == job_logs_dir(nav.lake, BRANCH, BATCH, job_id).resolve()
        assert Path(row[1]).is_file() and row[3] == "image/gif"
    assert feeds.rendered.text == f"{len(expected)} images of 2 jobs" and feeds.rendered.problems == []
    nobody = nav.engine.evaluate(config.metrics["Camera feeds of nobody"], BRANCH, scope)
    assert nobody.rendered.problems == ["nobody: job no-such-job has no image files"]


def test_platform_tables_exist_empty_on_a_lake_without_their_files(nav, tmp_path):
    """container_performance and test_length_seconds are tables ReSim's platform generates (SignalFlag's
    validator, open-core signalflag/demo/config_test.py, BUILTIN_TABLES); a job without their files has no
    rows in them, so a metric over them is NO_DATA, never an unknown table."""
    config_path = write_config(
        tmp_path,
        """\
      Peak memory:
        type: test
        query_string: SELECT MAX(memory_usage_gib) FROM container_performance
        template: scalar
    """,
    )
    config = load_config(config_path)
    result = nav.engine.evaluate(config.metrics["Peak memory"], BRANCH, Scope(BATCH, nav.jobs[0].job_id))
    assert result.status == "NO_DATA"
    assert result.error.message == "the query returned one row of NULLs; the status check does not run (NO_DATA)"


def test_figures_from_arrow_columns_are_those_from_rows_on_a_real_run(nav):
    """A run renders each query's Arrow table column by column (gateway/metrics/result_columns.py): for
    every metric of the run, in every job, the figure, table and text are byte for byte those rendered
    from the rows of the same answer, as the templates read results before. (Each query runs once:
    without ORDER BY, two runs may give their rows in another order.)"""
    compared = set()
    for result in nav.evaluation.results():
        metric = nav.config.metrics[result.metric]
        if result.status == "ERROR" or metric.template_type == "custom" or TEMPLATES[metric.template].files:
            continue
        scope = Scope(BATCH, result.job_id) if result.job_id else Scope(BATCH)
        answer = nav.engine.query(metric.query_string, BRANCH, scope)
        table = result_table(answer.batches)
        shown = [
            render(metric.name, metric.template, answer.columns, rows, units=metric.units)
            for rows in (table, table_rows(table))
        ]
        assert len({orjson.dumps([s.figure, s.table, s.text, s.problems], default=str) for s in shown}) == 1
        compared.add(metric.template)
    assert {"line", "histogram", "state_timeline", "bar", "table", "pie", "scalar"} <= compared
