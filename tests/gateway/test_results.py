"""The `metric_results` table: stored as Parquet per batch, replaced on re-evaluation, queryable
through the dialect layer and DuckDB (trend queries joining metadata)."""

from __future__ import annotations

import json
import math
import textwrap
from pathlib import Path

import pytest

from lakegate.fixtures.generate import CONFIG_PATH, generate_batch
from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.results_table import read_results
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file
from lakegate.lake.record import current_file
from lakegate.lake.schema import METRIC_RESULTS_COLUMNS

BRANCH = "main"
#: batch -> build name of its jobs
BUILDS = {"b1": "Nav stack 1.0", "b2": "Nav stack 1.1"}
TREND = """
SELECT m.build_name, COUNT(*) AS jobs, AVG(r.scalar_value) AS mean_time
FROM metric_results r JOIN metadata m ON r.batch_id = m.batch_id AND r.job_id = m.job_id
WHERE r.metric_name = 'Time to reach final goal'
GROUP BY m.build_name
ORDER BY m.build_name
"""


def time_to_goal(emissions: Path) -> float:
    """The documented scalar, from the emitted lines: 75.0 unless exactly 3 goals, else their sum."""
    times = [
        json.loads(line)["$data"]["time_s"]
        for line in emissions.read_text().splitlines()
        if '"topic": "time_to_goal"' in line
    ]
    return math.fsum(times) if len(times) == 3 else 75.0


@pytest.fixture(scope="module")
def lake(tmp_path_factory):
    root = tmp_path_factory.mktemp("results")
    lake = root / "lake"
    version = BranchConfigs(lake, BRANCH).store([CONFIG_PATH])
    config = load_config(CONFIG_PATH)
    expected = {}
    for batch, build in BUILDS.items():
        jobs = generate_batch(root / batch, jobs=3, seed=len(expected) + 11, samples_per_goal=8)
        ingest_and_evaluate(lake, BRANCH, batch, jobs, config, version, build_name=build)
        expected[build] = [time_to_goal(job.emissions_path) for job in jobs]
    return lake, expected, jobs


def ingest_and_evaluate(lake: Path, branch: str, batch: str, jobs, config, version, **metadata) -> None:
    for job in jobs:
        ingest_job(
            lake,
            branch,
            batch,
            job.job_id,
            [job.emissions_path],
            config=config,
            metadata={**load_metadata_file(job.metadata_path), **metadata},
            logs=job.logs_dir,
        )
    with MetricsEngine(lake) as engine:
        engine.evaluate_batch(
            branch, batch, config.metrics_in_set("Nav Metrics"), metrics_set="Nav Metrics", config_version=version
        )


def test_every_evaluated_metric_is_stored(lake):
    lake_dir = lake[0]
    config = load_config(CONFIG_PATH)
    metrics = config.metrics_in_set("Nav Metrics")
    rows = read_results(lake_dir, BRANCH, "b1")
    tests = [m for m in metrics if m.type == "test"]
    assert len(rows) == 3 * len(tests) + len(metrics) - len(tests)
    assert current_file(lake_dir, BRANCH, "metric_results", "b1").is_file()
    for row in rows:
        assert set(row) == {name for name, _ in METRIC_RESULTS_COLUMNS}
        metric = config.metrics[row["metric_name"]]
        template = "custom" if metric.template_type == "custom" else metric.template
        assert (row["metric_type"], row["template"], row["batch_id"]) == (metric.type, template, "b1")
        assert (row["job_id"] is None) == (metric.type == "batch")
        assert (row["metrics_set"], row["config_version"]) == ("Nav Metrics", 1)
        assert (row["scalar_value"] is not None) == (metric.template == "scalar")
        assert (row["figure_json"] is None) == (metric.template in ("scalar", "image"))
        assert row["status"] in ("PASSED", "WARNING", "BLOCKER") and row["error_message"] is None
    line = next(r for r in rows if r["metric_name"] == "Robot Speed")
    assert json.loads(line["figure_json"])["data"][0]["type"] == "scatter"


def test_the_table_has_trino_types_and_answers_a_trend_query(lake):
    lake_dir, expected, _ = lake
    backend = DuckDBBackend(lake_dir)
    try:
        assert backend.schema(BRANCH)["metric_results"] == dict(METRIC_RESULTS_COLUMNS)
        result = backend.execute(TREND, branch=BRANCH)
        assert result.columns == [("build_name", "varchar"), ("jobs", "bigint"), ("mean_time", "double")]
        rows = result.rows()
        assert [(build, jobs) for build, jobs, _ in rows] == [(build, 3) for build in sorted(expected)]
        for build, _, mean in rows:
            assert mean == pytest.approx(math.fsum(expected[build]) / 3, rel=1e-12)
        statuses = backend.execute(
            "SELECT r.status, m.job_conflated_status FROM metric_results r JOIN metadata m "
            "ON r.job_id = m.job_id WHERE r.metric_name = 'Time to reach final goal'",
            branch=BRANCH,
        ).rows()
        assert len(statuses) == 6 and all(status in ("PASSED", "BLOCKER") for status, _ in statuses)
    finally:
        backend.close()


def test_re_evaluating_a_batch_replaces_only_its_results(lake, tmp_path):
    lake_dir, _, jobs = lake
    branch = "rerun"  # its own branch: the other tests see main as the fixture left it
    version = BranchConfigs(lake_dir, branch).store([CONFIG_PATH])
    for batch in ("r1", "r2"):
        ingest_and_evaluate(lake_dir, branch, batch, jobs, load_config(CONFIG_PATH), version)
    first = read_results(lake_dir, branch, "r1")
    assert len(first) == len(read_results(lake_dir, branch, "r2")) > 4
    config_path = tmp_path / "config.resim.yaml"
    topics = CONFIG_PATH.read_text().split("\nmetrics:\n")[0]
    config_path.write_text(
        topics
        + textwrap.dedent("""
        metrics:
          Broken:
            type: test
            description: refers to a column that does not exist
            query_string: SELECT nope FROM robot_speed
            template: scalar
          Rows:
            type: batch
            description: rows of the batch
            query_string: SELECT COUNT(*) FROM robot_speed
            template: scalar
        """)
    )
    config = load_config(config_path)
    before = read_results(lake_dir, branch, "r2")
    with MetricsEngine(lake_dir) as engine:
        engine.evaluate_batch(branch, "r1", list(config.metrics.values()))
    rows = read_results(lake_dir, branch, "r1")
    assert sorted(r["metric_name"] for r in rows) == ["Broken"] * 3 + ["Rows"]
    broken = [r for r in rows if r["metric_name"] == "Broken"]
    assert {(r["status"], r["error_line"], r["error_column"]) for r in broken} == {("ERROR", 1, 8)}
    lines = config_path.read_text().splitlines()
    line = next(i for i, text in enumerate(lines, 1) if "SELECT nope" in text)
    assert broken[0]["error_location"] == f"{config_path}:{line}:{lines[line - 1].index('nope') + 1}"
    assert all(r["config_version"] is None and r["metrics_set"] is None for r in rows)
    assert read_results(lake_dir, branch, "r2") == before
    backend = DuckDBBackend(lake_dir)
    try:
        counts = backend.execute(
            "SELECT batch_id, COUNT(*) FROM metric_results GROUP BY batch_id ORDER BY 1", branch=branch
        ).rows()
        assert counts == [("r1", 4), ("r2", len(before))]
    finally:
        backend.close()


def test_a_batch_never_evaluated_has_no_results(lake):
    assert read_results(lake[0], BRANCH, "b3") == []
