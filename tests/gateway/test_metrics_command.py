"""`lakegate metrics sync` and `lakegate metrics run`, as real subprocesses on real lakes."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from lakegate.fixtures.generate import CONFIG_PATH, generate_batch
from lakegate.gateway.metrics.evaluation import worst
from lakegate.gateway.metrics.results_table import read_results
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file, read_metadata_row

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
TOPICS = CONFIG_PATH.read_text().split("\nmetrics:\n")[0]


def lakegate(*args, cwd=None):
    return subprocess.run(
        [*CLI, *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        env={**os.environ, "COLUMNS": "200"},
        timeout=120,
    )


@pytest.fixture(scope="module")
def nav(tmp_path_factory):
    """A lake whose branch main has the fixture config; `batch(name)` ingests the 3 generated jobs
    (PASSED, WARNING, BLOCKER by construction) as a new batch."""
    root = tmp_path_factory.mktemp("metrics-command")
    jobs = generate_batch(root / "inputs", jobs=3, samples_per_goal=8)
    lake = root / "lake"
    config = load_config(CONFIG_PATH)
    BranchConfigs(lake, "main").store([CONFIG_PATH])

    def batch(name: str) -> str:
        for job in jobs:
            ingest_job(
                lake,
                "main",
                name,
                job.job_id,
                [job.emissions_path],
                config=config,
                metadata=load_metadata_file(job.metadata_path),
                logs=job.logs_dir,
            )
        return name

    return lake, jobs, batch


def relaxed_config(tmp_path: Path) -> Path:
    """The fixture config with thresholds nothing reaches."""
    text = CONFIG_PATH.read_text()
    for old, new in (("block: 3", "block: 0"), ("block: 1.0", "block: 50.0"), ("warn: 0.5", "warn: 40.0")):
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "relaxed.resim.yaml"
    path.write_text(text)
    shutil.copytree(CONFIG_PATH.parent / "templates", tmp_path / "templates", dirs_exist_ok=True)  # custom templates
    return path


def test_sync_stores_each_new_version_and_keeps_the_old(tmp_path):
    lake = tmp_path / "lake"
    first = lakegate("metrics", "sync", "--lake", lake, "--branch", "feature/x", "--metrics-config-path", CONFIG_PATH)
    assert first.returncode == 0, first.stderr
    assert "stored as version 1" in first.stdout and "15 metrics" in first.stdout
    again = lakegate("metrics", "sync", "--lake", lake, "--branch", "feature/x", "--metrics-config-path", CONFIG_PATH)
    assert "unchanged: the same as version 1" in again.stdout
    project = tmp_path / "project"
    (project / ".resim" / "metrics").mkdir(parents=True)
    relaxed_config(tmp_path).rename(project / ".resim" / "metrics" / "config.resim.yaml")
    changed = lakegate("metrics", "sync", "--lake", lake, "--branch", "feature/x", cwd=project)  # the default path
    assert changed.returncode == 0 and "stored as version 2" in changed.stdout, changed.stderr
    registry = BranchConfigs(lake, "feature/x")
    assert registry.versions() == [1, 2]
    assert registry.load(1).metrics["Time to reach final goal"].status.block == 3
    assert registry.current().metrics["Time to reach final goal"].status.block == 0
    bad = tmp_path / "bad.resim.yaml"
    bad.write_text(TOPICS + "\nmetrics sets:\n  S:\n    metrics: [Nope]\n")
    refused = lakegate("metrics", "sync", "--lake", lake, "--branch", "feature/x", "--metrics-config-path", bad)
    assert refused.returncode == 1
    assert f"{bad}:{len(TOPICS.splitlines()) + 4}:15: metrics set 'S' names unknown metric 'Nope'" in refused.stderr
    assert registry.versions() == [1, 2]


def test_run_prints_every_metric_as_json_and_exits_2_on_a_blocker(nav, tmp_path):
    lake, jobs, batch = nav
    report = tmp_path / "out" / "report.html"
    result = lakegate(
        "metrics",
        "run",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        batch("json"),
        "--metrics-set",
        "Nav Metrics",
        "--format",
        "json",
        "--report",
        report,
    )
    assert result.returncode == 2, result.stderr
    output = json.loads(result.stdout)
    assert (output["batch_id"], output["metrics_set"], output["config_version"], output["status"]) == (
        "json",
        "Nav Metrics",
        1,
        "BLOCKER",
    )
    assert [j["job_conflated_status"] for j in output["jobs"]] == ["PASSED", "WARNING", "BLOCKER"]
    assert [len(j["events"]) for j in output["jobs"]] == [
        job.emissions_path.read_text().count('"topic": "goal_reached"') for job in jobs
    ]
    metrics = output["metrics"]
    assert len(metrics) == 3 * 9 + 6
    assert set(metrics[0]) >= {"batch_id", "job_id", "metric", "type", "template", "status", "scalar_value", "error"}
    scalar = next(m for m in metrics if m["metric"] == "Time to reach final goal" and m["job_id"] == jobs[2].job_id)
    assert (scalar["status"], scalar["scalar_value"], scalar["error"]) == ("BLOCKER", 75.0, None)
    assert report.is_file() and "Plotly.newPlot" in report.read_text()
    assert f"report: {report.resolve()}" in result.stderr


def test_post_hoc_rerun_with_a_changed_config_without_reingesting(nav, tmp_path):
    lake, jobs, batch = nav
    name = batch("posthoc")
    stored = lakegate(
        "metrics", "run", "--lake", lake, "--branch", "main", "--batch", name, "--metrics-set", "Nav Metrics"
    )
    assert stored.returncode == 2, stored.stderr
    assert "BLOCKER" in stored.stdout and "Warehouse Loop" in stored.stdout
    relaxed = lakegate(
        "metrics",
        "run",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        name,
        "--metrics-set",
        "Nav Metrics",
        "--metrics-config-path",
        relaxed_config(tmp_path),
    )
    assert relaxed.returncode == 0, relaxed.stderr
    assert f"batch '{name}' on branch 'main': PASSED" in relaxed.stdout
    for job in jobs:
        row = read_metadata_row(lake, "main", name, job.job_id)
        assert (row["job_metrics_status"], row["job_conflated_status"]) == ("PASSED", "PASSED")
    rows = read_results(lake, "main", name)
    assert {r["status"] for r in rows} == {"PASSED"} and {r["config_version"] for r in rows} == {None}
    query = lakegate(
        "query",
        "--lake",
        lake,
        "--format",
        "json",
        f"SELECT status, COUNT(*) FROM metric_results WHERE batch_id = '{name}' GROUP BY status",
    )
    assert json.loads(query.stdout)["rows"] == [["PASSED", len(rows)]]
    again = lakegate(
        "metrics",
        "run",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        name,
        "--metrics-set",
        "Nav Metrics",
        "--format",
        "json",
    )
    assert again.returncode == 2 and json.loads(again.stdout)["config_version"] == 1  # the stored config again


def test_config_and_usage_errors_exit_1(nav, tmp_path):
    lake, _, batch = nav
    name = batch("usage")
    bad = tmp_path / "sets.resim.yaml"
    bad.write_text(
        TOPICS
        + textwrap.dedent("""
        metrics:
          Later:
            type: dashboard
            description: a dashboard metric
            query_string: SELECT 1
            template: table
          Count:
            type: test
            description: rows
            query_string: SELECT COUNT(*) FROM robot_speed
            template: scalar
        metrics sets:
          S:
            metrics: [Count, Count, Later, Missing]
        """)
    )
    lines = bad.read_text().splitlines()
    at, text = len(lines), lines[-1]
    result = lakegate(
        "metrics",
        "run",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        name,
        "--metrics-set",
        "S",
        "--metrics-config-path",
        bad,
    )
    assert result.returncode == 1
    assert f"{bad}:{at}:{text.index('Count, L') + 1}: duplicate metric 'Count'" in result.stderr
    assert "'Later'" not in result.stderr  # a set may list a dashboard metric, as in ReSim
    assert f"{bad}:{at}:{text.index('Missing') + 1}: metrics set 'S' names unknown metric 'Missing'" in result.stderr
    args = ["metrics", "run", "--lake", lake, "--branch", "main"]
    for extra, message in (
        (["--batch", name, "--metrics-set", "Nav Metrix"], "no metrics set 'Nav Metrix'"),
        (["--batch", "nope", "--metrics-set", "Nav Metrics"], "no batch 'nope' on branch 'main'"),
    ):
        result = lakegate(*args, *extra)
        assert result.returncode == 1 and message in result.stderr, result.stderr
    result = lakegate("metrics", "run", "--lake", lake, "--branch", "other", "--batch", name, "--all-metrics")
    assert result.returncode == 1 and "no branch 'other'" in result.stderr
    result = lakegate(*args, "--batch", name)
    assert result.returncode == 2 and "--metrics-set" in result.stderr  # argparse: one of the two is required


def test_all_metrics_of_a_config_without_sets_and_errors_exit_3(nav, tmp_path):
    lake, jobs, batch = nav
    name = batch("all")
    config = tmp_path / "nosets.resim.yaml"
    config.write_text(
        TOPICS
        + textwrap.dedent("""
        metrics:
          Count:
            type: test
            description: rows per job
            query_string: SELECT COUNT(*) FROM robot_speed
            template: scalar
          Broken:
            type: batch
            description: a typo
            query_string: |
              SELECT AVG(sped)
              FROM robot_speed
            template: scalar
        """)
    )
    result = lakegate(
        "metrics",
        "run",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        name,
        "--all-metrics",
        "--metrics-config-path",
        config,
        "--format",
        "json",
    )
    assert result.returncode == 3, result.stderr
    output = json.loads(result.stdout)
    counts = [m["scalar_value"] for m in output["metrics"] if m["metric"] == "Count"]
    assert counts == [
        sum('"topic": "robot_speed"' in line for line in job.emissions_path.read_text().splitlines()) for job in jobs
    ]
    (broken,) = [m for m in output["metrics"] if m["metric"] == "Broken"]
    line, text = next((i, text) for i, text in enumerate(config.read_text().splitlines(), 1) if "AVG(sped)" in text)
    assert broken["status"] == "ERROR" and broken["job_id"] is None
    assert (broken["error"]["line"], broken["error"]["column"]) == (1, 12)
    assert broken["error"]["location"] == f"{config}:{line}:{text.index('sped') + 1}"
    assert "sped" in broken["error"]["message"]
    assert output["status"] == "ERROR" and output["batch_metrics_status"] == "ERROR"


def test_two_branches_with_different_schemas_for_one_topic(tmp_path):
    lake = tmp_path / "lake"
    float_config, text_config = tmp_path / "float.resim.yaml", tmp_path / "text.resim.yaml"
    speed = """
          Speed:
            type: test
            description: the speed as the branch stores it
            query_string: SELECT speed, typeof(speed) FROM speed
            template: table
        """
    average = """
          Average:
            type: test
            description: needs a number
            query_string: SELECT AVG(speed) FROM speed
            template: scalar
        """
    float_config.write_text(
        "version: 1\ntopics:\n  speed:\n    schema: {speed: float}\nmetrics:\n"
        + textwrap.indent(textwrap.dedent(speed) + textwrap.dedent(average), "  ")
    )
    text_config.write_text(
        "version: 1\ntopics:\n  speed:\n    schema: {speed: string, unit: string}\nmetrics:\n"
        + textwrap.indent(textwrap.dedent(speed), "  ")
    )
    lines = {"main": {"speed": 1.5}, "feature/text": {"speed": "fast", "unit": "m/s"}}
    for branch, config in (("main", float_config), ("feature/text", text_config)):
        assert (
            lakegate("metrics", "sync", "--lake", lake, "--branch", branch, "--metrics-config-path", config).returncode
            == 0
        )
        emissions = tmp_path / f"{branch.replace('/', '_')}.jsonl"
        emissions.write_text(
            json.dumps({"$metadata": {"topic": "speed", "timestamp": 1}, "$data": lines[branch]}) + "\n"
        )
        ingested = lakegate("ingest", emissions, "--lake", lake, "--branch", branch, "--batch", "b", "--job", "j")
        assert ingested.returncode == 0, ingested.stderr  # with the branch's stored config
    for branch in lines:
        run = lakegate("metrics", "run", "--lake", lake, "--branch", branch, "--batch", "b", "--all-metrics")
        assert run.returncode == 0, run.stderr

    def speed_rows(branch):
        row = next(r for r in read_results(lake, branch, "b") if r["metric_name"] == "Speed")
        return json.loads(row["details_json"])["table"]["rows"]

    assert speed_rows("main") == [[1.5, "double"]]
    assert speed_rows("feature/text") == [["fast", "varchar"]]
    # main's config on the other branch: the queries meet that branch's schema, and main is untouched
    main_before = read_results(lake, "main", "b")
    cross = lakegate(
        "metrics",
        "run",
        "--lake",
        lake,
        "--branch",
        "feature/text",
        "--batch",
        "b",
        "--all-metrics",
        "--metrics-config-path",
        float_config,
        "--format",
        "json",
    )
    assert cross.returncode == 3, cross.stderr
    average = next(m for m in json.loads(cross.stdout)["metrics"] if m["metric"] == "Average")
    assert average["status"] == "ERROR" and "avg" in average["error"]["message"].lower()
    assert read_results(lake, "main", "b") == main_before


# -- one evaluation of a batch at a time, switched in one commit ----------------


def run_process(lake: Path, batch: str, *extra, env: dict | None = None) -> subprocess.Popen:
    return subprocess.Popen(
        [
            *CLI,
            "metrics",
            "run",
            "--lake",
            str(lake),
            "--branch",
            "main",
            "--batch",
            batch,
            "--metrics-set",
            "Nav Metrics",
            "--format",
            "json",
            *map(str, extra),
        ],
        env={**os.environ, **(env or {})},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def stored_run(lake: Path, batch: str, jobs) -> tuple[dict, dict]:
    """Each job's (metrics status, conflated status) in metadata, and the worst test-metric status
    of each job in metric_results, plus the config versions the results were made with."""
    statuses = {}
    for job in jobs:
        row = read_metadata_row(lake, "main", batch, job.job_id)
        statuses[job.job_id] = (row["job_metrics_status"], row["job_conflated_status"])
    results = read_results(lake, "main", batch)
    from_results = {job.job_id: worst(r["status"] for r in results if r["job_id"] == job.job_id) for job in jobs}
    return statuses, {"results": from_results, "versions": {r["config_version"] for r in results}}


def assert_agree(lake: Path, batch: str, jobs) -> dict:
    statuses, results = stored_run(lake, batch, jobs)
    assert {job: status[0] for job, status in statuses.items()} == results["results"], (statuses, results)
    return statuses


@pytest.mark.parametrize("point", ["added", "commit"])
def test_a_killed_run_leaves_the_previous_run_whole(nav, tmp_path, point):
    """kill -9 of a `metrics run` once it has staged new statuses (or just before its commit): the
    stored statuses and metric_results are still the previous run's, and agree."""
    lake, jobs, batch = nav
    name = batch(f"killed-{point}")
    first = run_process(lake, name)
    assert first.wait(120) == 2, first.stderr.read()
    before = stored_run(lake, name, jobs)
    assert [s[1] for s in before[0].values()] == ["PASSED", "WARNING", "BLOCKER"]
    marker = tmp_path / "paused"
    killed = run_process(
        lake, name, "--metrics-config-path", relaxed_config(tmp_path), env={"LAKEGATE_TEST_PAUSE": f"{point}:{marker}"}
    )
    try:
        deadline = time.monotonic() + 120
        while (
            killed.poll() is None
            and time.monotonic() < deadline
            and not marker.exists()
            and stored_run(lake, name, jobs)[0] == before[0]
        ):  # a run that writes statuses early is caught too
            time.sleep(0.01)
        os.kill(killed.pid, signal.SIGKILL)
    finally:
        killed.wait(30)
    assert killed.returncode == -signal.SIGKILL, killed.stderr.read()
    assert stored_run(lake, name, jobs) == before
    again = run_process(lake, name, "--metrics-config-path", relaxed_config(tmp_path))
    assert again.wait(120) == 0, again.stderr.read()
    assert set(assert_agree(lake, name, jobs).values()) == {("PASSED", "PASSED")}


def test_two_concurrent_runs_of_a_batch_end_with_statuses_and_results_agreeing(nav, tmp_path):
    lake, jobs, batch = nav
    name = batch("concurrent")
    strict, relaxed = (
        run_process(lake, name),
        run_process(lake, name, "--metrics-config-path", relaxed_config(tmp_path)),
    )
    assert strict.wait(120) == 2, strict.stderr.read()
    assert relaxed.wait(120) == 0, relaxed.stderr.read()
    statuses = assert_agree(lake, name, jobs)
    assert len({s for s in statuses.values()}) in (1, 3)  # all of one run: PASSED x3, or PASSED/WARNING/BLOCKER


def test_a_set_of_dashboard_metrics_only_leaves_the_batch_alone(nav, tmp_path):
    """A metrics set with no test or batch metric is refused naming `metrics dashboard`, and the batch's
    statuses and results stay those of the previous run (they were once replaced by NOT_RUN rows)."""
    lake, jobs, batch = nav
    name = batch("dashboard-only")
    trends = tmp_path / "trends.resim.yaml"
    trends.write_text("version: 1\nmetrics sets:\n  Demo Trends:\n    metrics: [Time to Final Goal by Build]\n")
    config = (
        CONFIG_PATH,
        "--metrics-config-path",
        CONFIG_PATH.parent / "dashboard.resim.yaml",
        "--metrics-config-path",
        trends,
    )
    first = lakegate(*RUN, lake, "--batch", name, "--metrics-set", "Nav Metrics", "--metrics-config-path", *config)
    assert first.returncode == 2, first.stderr
    before = stored_run(lake, name, jobs)
    assert before[0] != {job.job_id: ("PASSED", "PASSED") for job in jobs}
    again = lakegate(*RUN, lake, "--batch", name, "--metrics-set", "Demo Trends", "--metrics-config-path", *config)
    assert again.returncode != 0 and again.stdout == ""
    assert "metrics set 'Demo Trends' holds no test or batch metric" in again.stderr
    assert "lakegate metrics dashboard --metrics-set 'Demo Trends'" in again.stderr
    assert stored_run(lake, name, jobs) == before


RUN = ("metrics", "run", "--branch", "main", "--format", "json", "--lake")
