"""Compaction and layout v2: every table answers the same before and after `lakegate lake compact`
(through the Engine, scoped or not), a re-ingest or a metadata update of one job of a compacted batch
replaces only that job (also in what Trino's Hive connector reads: every file of the folder), a killed
compaction leaves the lake as it was, and a layout v1 lake reads the same and is migrated."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import duckdb
import pytest

from lakegate.dialect.scope import Scope
from lakegate.fixtures.generate import CONFIG_PATH, generate_batch
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.lake import paths
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.catalog import Catalog
from lakegate.lake.compaction import compact
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file, read_metadata_row, update_metadata_row
from lakegate.lake.record import PAUSE_ENV, Record
from tests.lake.killing import kill_when_paused
from tests.lake.v1_lake import to_v1

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
BATCHES = {"b1": 4, "b2": 2, "b3": 1}
SET = "Nav Metrics"


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    """A lake of three batches (4, 2 and 1 jobs of the fixture config: every field type, events with
    metric[] rows), `b1` evaluated (metric_results, statuses in metadata), never compacted."""
    root = tmp_path_factory.mktemp("compaction")
    lake = root / "lake"
    config = load_config(CONFIG_PATH)
    BranchConfigs(lake, "main").store([CONFIG_PATH])
    for seed, (batch, count) in enumerate(BATCHES.items()):
        for job in generate_batch(root / "inputs" / batch, jobs=count, seed=seed, samples_per_goal=3):
            metadata = load_metadata_file(job.metadata_path)
            ingest_job(lake, "main", batch, job.job_id, [job.emissions_path], config=config, metadata=metadata)
    with MetricsEngine(lake) as engine:
        engine.evaluate_batch("main", "b1", config.metrics_in_set(SET), metrics_set=SET)
    return lake


@pytest.fixture
def lake(built, tmp_path) -> Path:
    copy = tmp_path / "lake"
    shutil.copytree(built, copy, symlinks=True)
    return copy


def answers(lake: Path, **scope: str) -> dict[str, tuple]:
    """Every table's columns (names and Trino types) and rows, `SELECT *` ordered by every column
    (arrays, which lakegate does not order by, in Python), through the Engine (a metric's scope:
    `batch_id`, `job_id`)."""
    found = {}
    with MetricsEngine(lake) as engine:
        for table, columns in Catalog(lake).schema("main").items():
            order = ", ".join(str(i + 1) for i, kind in enumerate(columns.values()) if "(" not in kind)
            sql = f'SELECT * FROM "{table}" ORDER BY {order}'
            result = engine.query(sql, "main", Scope(**scope) if scope else None)
            found[table] = (result.columns, sorted(result.rows(), key=repr))
    return found


def hive_rows(lake: Path, table: str) -> list[tuple]:
    """What Trino's Hive connector reads of a table: every Parquet file of its batch folders."""
    glob = paths.table_glob(lake, "main", table)
    if not list(Path("/").glob(glob.lstrip("/"))):
        return []  # a table no job wrote (a platform table): Trino reads its empty folder as no rows
    sql = f"SELECT batch_id, job_id, count(*) FROM read_parquet('{glob}', hive_partitioning = true) GROUP BY ALL"
    return sorted(duckdb.connect().execute(sql).fetchall())


def record_rows(lake: Path, table: str) -> list[tuple]:
    """The same, as the record counts it."""
    record = Record(lake, "main")
    try:
        return sorted((e.batch_id, e.job_id, e.rows) for e in record.snapshot().of(table) if e.rows)
    finally:
        record.close()


def files_of(lake: Path, table: str, batch: str) -> list[Path]:
    return sorted(paths.partition_dir(lake, "main", table, batch).glob("*.parquet"))


def jobs_of(lake: Path, batch: str) -> list[str]:
    return [job.job_id for job in Catalog(lake).jobs("main", batch)]


def test_every_table_answers_the_same_after_compaction_scoped_or_not(lake):
    job = jobs_of(lake, "b1")[1]
    before = [answers(lake), answers(lake, batch_id="b1"), answers(lake, batch_id="b1", job_id=job)]
    assert len(before[0]["metadata"][1]) == 7 and len(before[2]["metadata"][1]) == 1
    generation = Record(lake, "main").generation()
    done = compact(lake, "main")
    assert [(c.batch_id, c.jobs, c.changed) for c in done] == [("b1", 4, True), ("b2", 2, True), ("b3", 1, False)]
    assert Record(lake, "main").generation() == generation + 2  # one commit per batch: all tables at once
    after = [answers(lake), answers(lake, batch_id="b1"), answers(lake, batch_id="b1", job_id=job)]
    assert after == before
    tables = [t for t in Catalog(lake).schema("main") if t != paths.METRIC_RESULTS_TABLE]
    for table in tables:
        for batch in BATCHES:
            assert len(files_of(lake, table, batch)) <= 1, (table, batch)
        assert hive_rows(lake, table) == record_rows(lake, table), table
    assert compact(lake, "main", ["b1"])[0].changed is False  # nothing more to do


def test_a_reader_keeps_its_snapshot_while_a_batch_is_compacted(lake):
    catalog = Catalog(lake)
    old = catalog.view_sql("main")
    con = duckdb.connect()
    expected = {t: sorted(map(str, con.execute(f"SELECT * FROM ({sql})").fetchall())) for t, sql in old.items()}
    compact(lake, "main", ["b1"])
    new = catalog.snapshot("main")
    b1 = {e.path for e in new.files if e.batch_id == "b1" and e.table == "odom_linear_velocity"}
    assert len(b1) == 1  # the batch is all new for a reader that looks now
    for table, sql in old.items():  # the old files stay readable (reader links) for a query that listed them
        assert sorted(map(str, con.execute(f"SELECT * FROM ({sql})").fetchall())) == expected[table]


def test_queries_during_a_compaction_count_every_row_once(lake):
    """A real `lakegate lake compact` runs while queries read every table of the batch: each query
    sees the batch's files all old or all new (never both, never neither), so its counts never change."""
    tables = [t for t in Catalog(lake).schema("main") if t != paths.METRIC_RESULTS_TABLE]
    sql = " UNION ALL ".join(f"SELECT '{t}', count(*) FROM \"{t}\" WHERE batch_id = 'b1'" for t in tables)
    with MetricsEngine(lake) as engine:
        expected = sorted(engine.query(sql, "main", None).rows())
        process = subprocess.Popen(
            [*CLI, "lake", "compact", "--lake", lake, "--branch", "main", "--batch", "b1"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        seen = 0
        while process.poll() is None or seen == 0:
            assert sorted(engine.query(sql, "main", None).rows()) == expected
            seen += 1
        assert process.returncode == 0, process.stderr.read()
        assert "compacted batch 'b1'" in process.stdout.read()
        assert sorted(engine.query(sql, "main", None).rows()) == expected
    assert all(len(files_of(lake, table, "b1")) <= 1 for table in tables)


def test_reingest_of_a_job_after_compaction_replaces_only_that_job(lake, tmp_path):
    compact(lake, "main")
    jobs = jobs_of(lake, "b1")
    before = answers(lake)
    config = load_config(CONFIG_PATH)
    other = generate_batch(tmp_path / "other", jobs=1, seed=42, samples_per_goal=4)[0]
    ingest_job(lake, "main", "b1", jobs[2], [other.emissions_path], config=config, metadata={"experience_name": "new"})
    after = answers(lake)
    for table, (columns, rows) in after.items():
        assert columns == before[table][0]
        kept = [r for r in before[table][1] if jobs[2] not in r]
        if table == paths.METRIC_RESULTS_TABLE:  # the batch metrics read the replaced data: dropped with the job's
            job_at = [name for name, _ in columns].index("job_id")
            kept = [r for r in kept if r[job_at] is not None]
            assert kept and all(r[job_at] is not None for r in rows)
        assert [r for r in rows if jobs[2] not in r] == kept, table  # every other job as it was
    assert read_metadata_row(lake, "main", "b1", jobs[2])["experience_name"] == "new"
    for table in Catalog(lake).schema("main"):
        if table != paths.METRIC_RESULTS_TABLE:
            assert hive_rows(lake, table) == record_rows(lake, table), table  # the old rows are gone for Trino
    compact(lake, "main", ["b1"])
    assert answers(lake) == after


def test_a_metadata_update_after_compaction_rewrites_the_batch_file_without_the_old_row(lake):
    compact(lake, "main")
    first = jobs_of(lake, "b2")[0]
    update_metadata_row(lake, "main", "b2", first, job_metrics_status="BLOCKER")
    assert hive_rows(lake, "metadata") == record_rows(lake, "metadata")
    statuses = dict(
        duckdb.connect()
        .execute(
            f"SELECT job_id, job_metrics_status FROM read_parquet('{paths.table_glob(lake, 'main', 'metadata')}') "
            "WHERE job_id IN (SELECT job_id FROM read_parquet("
            f"'{paths.table_glob(lake, 'main', 'metadata')}', hive_partitioning = true) WHERE batch_id = 'b2')"
        )
        .fetchall()
    )
    assert statuses[first] == "BLOCKER" and len(statuses) == 2


def test_metrics_run_writes_one_metadata_file_and_compacts_the_batch(lake):
    result = subprocess.run(
        [*CLI, "metrics", "run", "--lake", lake, "--branch", "main", "--batch", "b2", "--metrics-set", SET],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode in (0, 2, 3), result.stderr
    for table in ("metadata", "odom_linear_velocity", "events"):
        assert len(files_of(lake, table, "b2")) == 1, table
    assert len(files_of(lake, "metadata", "b3")) == 1  # other batches untouched
    kept = subprocess.run(
        [*CLI, "metrics", "run", "--lake", lake, "--branch", "main", "--batch", "b1", "--metrics-set", SET]
        + ["--no-compact"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert kept.returncode in (0, 2, 3), kept.stderr
    assert len(files_of(lake, "metadata", "b1")) == 1  # the new statuses: one file for the batch
    assert len(files_of(lake, "odom_linear_velocity", "b1")) == 4  # not compacted


def test_scoped_metrics_answer_the_same_over_a_compacted_batch(lake):
    config = load_config(CONFIG_PATH)

    def evaluate() -> list[tuple]:
        with MetricsEngine(lake) as engine:
            run = engine.evaluate_batch("main", "b1", config.metrics_in_set(SET), store=False)
        results = [r for job in run.jobs for r in job.results] + run.batch_results
        return [(r.job_id, r.metric, r.status, r.scalar_value, r.value_text) for r in results]

    before = evaluate()
    compact(lake, "main", ["b1"])
    # the same rows; a sum of doubles may differ in its last bit when they are read in another order
    assert evaluate() == [(*r[:3], r[3] if r[3] is None else pytest.approx(r[3], rel=1e-12), r[4]) for r in before]


def test_a_compaction_killed_before_its_commit_leaves_the_lake_as_it_was(lake, tmp_path):
    before = answers(lake)
    record = Record(lake, "main")
    files = record.snapshot().files
    record.close()
    marker = tmp_path / "paused"
    killed = subprocess.Popen(
        [*CLI, "lake", "compact", "--lake", lake, "--branch", "main", "--batch", "b1"],
        env={**os.environ, PAUSE_ENV: f"commit:{marker}"},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    kill_when_paused(killed, marker, 120)
    leftover = [p for p in files_of(lake, "events", "b1") if p.name.startswith(f"{killed.pid}-")]
    assert leftover, "the killed compaction had published its files"
    record = Record(lake, "main")
    assert record.snapshot().files == files  # the record as it was
    record.close()
    assert answers(lake) == before
    compact(lake, "main", ["b1"])  # the next write of the batch removes the dead compaction's files
    assert not any(p.exists() for p in leftover)
    assert answers(lake) == before


@pytest.mark.parametrize("recorded", [True, False], ids=["v1-record", "before-the-record"])
def test_a_layout_v1_lake_reads_the_same_and_its_first_writer_migrates_it(lake, recorded, tmp_path):
    before = [answers(lake), answers(lake, batch_id="b1", job_id=jobs_of(lake, "b1")[0])]
    to_v1(lake, record=recorded)
    assert list(lake.glob("main/metadata/batch_id=b1/job_id=*/data.parquet"))
    assert [answers(lake), answers(lake, batch_id="b1", job_id=jobs_of(lake, "b1")[0])] == before
    assert Record(lake, "main").layout() == 1
    # the first writer (here a metadata update) migrates the branch, in one commit
    job = jobs_of(lake, "b3")[0]
    row = update_metadata_row(lake, "main", "b3", job, job_metrics_status="PASSED")
    assert Record(lake, "main").layout() == 2
    assert not list(lake.glob("main/*/batch_id=*/job_id=*"))
    after = answers(lake)
    changed = [r for r in after["metadata"][1] if job in r]
    assert [r for r in after["metadata"][1] if job not in r] == [r for r in before[0]["metadata"][1] if job not in r]
    assert row["job_metrics_status"] == "PASSED" and len(changed) == 1
    assert {t: v for t, v in after.items() if t != "metadata"} == {
        t: v for t, v in before[0].items() if t != "metadata"
    }
    for table in Catalog(lake).schema("main"):
        if table != paths.METRIC_RESULTS_TABLE:
            assert hive_rows(lake, table) == record_rows(lake, table), table
