"""The tables ReSim's platform generates for each job: a job folder's `resource_metrics.resim.jsonl` and
`test_length_metric.resim.jsonl` (emissions files beside its emissions) become `container_performance`
and `test_length_seconds`; a job without them has no rows there, and a metric over them is NO_DATA,
never an unknown table. `project_id` and `run_counter` are columns of metadata and of every topic.
Real files through the real CLI; the forwarding test runs the same config against the real Trino."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.results_table import read_results
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from tests.compat.test_resim_configs import CONFIGS, lakegate

CONFIG = CONFIGS / "platform_tables.resim.yaml"
#: per job: (experience, run_counter, container samples (container, cpu cores, memory GiB) per second,
#: test length in seconds); None: the job's folder has no platform files.
JOBS = {
    "j1": ("Lobby", None, [("nav2", 0.5, 1.25), ("isaacsim", 2.0, 2.5), ("nav2", 0.75, 1.5)], 42.5),
    "j2": ("Ward", 2, [("nav2", 1.0, 3.5), ("isaacsim", 1.5, 2.0)], 60.0),
    "j3": ("Dock", None, None, None),
}


def write_job(folder: Path, job: tuple) -> Path:
    """The job's folder as ReSim's platform leaves it: its emissions and, if any, the platform's files."""
    folder.mkdir(parents=True)
    _, _, samples, length = job
    emissions = folder / "emissions.resim.jsonl"
    lines = [{"$metadata": {"topic": "drive", "timestamp": i * 10**9}, "$data": {"speed": 1.0 + i}} for i in range(2)]
    emissions.write_text("".join(json.dumps(line) + "\n" for line in lines))
    if samples is not None:
        rows = [
            {
                "$metadata": {"topic": "container_performance", "timestamp": i * 10**9},
                "$data": {
                    "timestamp_seconds": 1767225600.0 + i,
                    "container_name": name,
                    "cpu_usage_core_seconds_per_sec": cpu,
                    "cpu_throttling_seconds": 0.0,
                    "memory_usage_gib": memory,
                    "memory_limit_failures": 0.0,
                },
            }
            for i, (name, cpu, memory) in enumerate(samples)
        ]
        (folder / "resource_metrics.resim.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
        length_row = {"$metadata": {"topic": "test_length_seconds", "timestamp": 0}, "$data": {"test_length": length}}
        (folder / "test_length_metric.resim.jsonl").write_text(json.dumps(length_row) + "\n")
    return emissions


def ingest(lake: Path, root: Path, branch: str = "main") -> None:
    """Every job of JOBS into batch b1 of `branch` (the CLI, as a user would)."""
    for job_id, job in JOBS.items():
        emissions = write_job(root / job_id, job)
        extra = []
        if job[1] is not None:
            metadata = root / f"{job_id}.metadata.yaml"
            metadata.write_text(f"run_counter: {job[1]}\n")
            extra = ["--metadata", metadata]
        lakegate(
            "ingest", "--lake", lake, "--branch", branch, "--batch", "b1", "--job", job_id,
            "--metrics-config-path", CONFIG, "--experience-name", job[0], "--no-progress", *extra, emissions,
        )  # fmt: skip


@pytest.fixture(scope="module")
def lake(tmp_path_factory):
    root = tmp_path_factory.mktemp("platform")
    ingest(root / "lake", root)
    return root / "lake"


def query(lake: Path, sql: str) -> list[list]:
    """The rows of `sql` on branch main, through the Engine `lakegate query` uses (in process: cheap)."""
    with MetricsEngine(lake) as engine:
        return [list(row) for row in engine.query(sql, "main", None).rows()]


def test_the_platform_files_beside_the_emissions_become_the_two_tables(lake):
    rows = query(
        lake,
        "SELECT job_id, timestamp, container_name, cpu_usage_core_seconds_per_sec, memory_usage_gib, "
        "timestamp_seconds, org_id IS NOT NULL FROM container_performance ORDER BY job_id, timestamp",
    )
    expected = [
        [job_id, i * 10**9, name, cpu, memory, 1767225600.0 + i, True]
        for job_id, (_, _, samples, _) in JOBS.items()
        for i, (name, cpu, memory) in enumerate(samples or [])
    ]
    assert rows == expected
    assert query(lake, "SELECT job_id, test_length FROM test_length_seconds ORDER BY 1") == [
        [job_id, job[3]] for job_id, job in JOBS.items() if job[3] is not None
    ]
    described = query(
        lake,
        "SELECT column_name, data_type FROM information_schema.columns "
        "WHERE table_name = 'container_performance' ORDER BY ordinal_position",
    )
    assert described == [
        ["timestamp", "bigint"],
        ["timestamp_seconds", "double"],
        ["container_name", "varchar"],
        ["cpu_usage_core_seconds_per_sec", "double"],
        ["cpu_throttling_seconds", "double"],
        ["memory_usage_gib", "double"],
        ["memory_limit_failures", "double"],
        ["org_id", "varchar"],
        ["experience_name", "varchar"],
        ["build_version", "varchar"],
        ["project_id", "varchar"],
        ["run_counter", "bigint"],
        ["batch_id", "varchar"],
        ["job_id", "varchar"],
    ]
    # org_id and project_id are the job's metadata values
    joined = "SELECT count(*) FROM {t} c JOIN metadata m ON c.job_id = m.job_id AND c.org_id = m.org_id"
    assert query(lake, joined.format(t="container_performance")) == [[5]]


def test_project_id_and_run_counter_are_on_metadata_and_every_topic(lake):
    expected = [[job_id, 0 if job[1] is None else job[1]] for job_id, job in JOBS.items()]
    assert query(lake, "SELECT job_id, run_counter FROM metadata ORDER BY 1") == expected
    for table in ("drive", "container_performance", "test_length_seconds"):
        rows = query(
            lake,
            f"SELECT t.job_id, t.run_counter, t.project_id = m.project_id FROM {table} t "
            "JOIN metadata m ON t.job_id = m.job_id GROUP BY 1, 2, 3 ORDER BY 1",
        )
        assert rows == [[job_id, counter, True] for job_id, counter in expected if table == "drive" or job_id != "j3"]
    assert query(lake, "SELECT count(DISTINCT project_id) FROM drive") == [[1]]  # a lake is one project


def test_a_branch_without_platform_files_has_both_tables_empty(tmp_path):
    emissions = write_job(tmp_path / "j1", JOBS["j3"])
    lake = tmp_path / "lake"
    report = ingest_job(lake, "main", "b1", "j1", [emissions], config=load_config(CONFIG))
    assert report.rows == {"drive": 2}  # no 'no rows for' noise about the platform tables
    assert query(lake, "SELECT count(*) FROM container_performance") == [[0]]
    assert query(lake, "SELECT count(*), max(test_length) FROM test_length_seconds") == [[0, None]]


def test_the_config_over_the_platform_tables_runs_with_values_from_the_files(lake):
    done = lakegate(
        "metrics", "run", "--lake", lake, "--branch", "main", "--batch", "b1", "--metrics-set", "Platform",
        "--metrics-config-path", CONFIG, "--format", "json", "--no-progress", check=False,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr  # j2's peak memory blocks
    by = {(m["job_id"], m["metric"]): m for m in json.loads(done.stdout)["metrics"]}
    for job_id, (_, _, samples, length) in JOBS.items():
        peak, lengths = by[(job_id, "Peak Memory")], by[(job_id, "Test Length")]
        if samples is None:
            assert {by[(job_id, m)]["status"] for m in ("CPU Usage", "Memory Usage")} == {"NO_DATA"}
            assert (peak["status"], lengths["status"]) == ("NO_DATA", "NO_DATA")
            continue
        top = max(memory for _, _, memory in samples)
        assert (peak["status"], peak["scalar_value"]) == ("BLOCKER" if top > 3.0 else "PASSED", top)
        assert (lengths["status"], lengths["scalar_value"]) == ("PASSED", length)
        containers = {name for name, _, _ in samples}
        assert by[(job_id, "Memory Usage")]["value"] == f"{len(containers)} series, {len(samples)} points"
    assert (by[(None, "Samples per Run")]["status"], by[(None, "Samples per Run")]["value"]) == (
        "PASSED",
        "2 rows, 4 columns",
    )
    stored = {row["metric_name"]: json.loads(row["details_json"] or "{}") for row in read_results(lake, "main", "b1")}
    assert stored["Samples per Run"]["table"]["rows"] == [["Lobby", 0, True, 3], ["Ward", 2, True, 2]]
