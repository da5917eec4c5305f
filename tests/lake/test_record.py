"""The branch's file record: a job's tables switch together, a killed `lakegate ingest` leaves the old
version whole, and a lake written before the record is migrated when first opened."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from lakegate.lake import paths
from lakegate.lake.catalog import Catalog
from lakegate.lake.record import PAUSE_ENV, RECORD, Record
from tests.lake.killing import kill_when_paused
from tests.lake.v1_lake import to_v1

CONFIG = """\
version: 1
topics:
  odom:
    schema: {x: float}
  goal:
    schema: {name: string}
"""
CLI = [sys.executable, "-m", "lakegate.gateway.cli"]


def line(topic: str, timestamp: int, data: dict) -> str:
    return json.dumps({"$metadata": {"topic": topic, "timestamp": timestamp}, "$data": data}) + "\n"


def emissions(root: Path, name: str, odom: int, goals: int) -> Path:
    path = root / f"{name}.jsonl"
    path.write_text(
        "".join(line("odom", i, {"x": float(i)}) for i in range(odom))
        + "".join(line("goal", 100 + i, {"name": f"g{i}"}) for i in range(goals))
    )
    return path


def ingest_cli(root: Path, lake: Path, source: Path, token: str, env: dict | None = None) -> subprocess.Popen:
    """A real `lakegate ingest` of job b1/j1, its experience name `token` (in every table's rows)."""
    config = root / "config.resim.yaml"
    config.write_text(CONFIG)
    return subprocess.Popen(
        [
            *CLI,
            "ingest",
            "--lake",
            str(lake),
            "--branch",
            "main",
            "--batch",
            "b1",
            "--job",
            "j1",
            "--metrics-config-path",
            str(config),
            "--experience-name",
            token,
            str(source),
        ],
        env={**os.environ, **(env or {})},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


def state(lake: Path) -> dict[str, tuple]:
    """Per table of job b1/j1 as lakegate reads it: (rows, the experience names in its rows)."""
    con = Catalog(lake).connect("main")
    return {
        table: con.execute(
            f"SELECT count(*), list(DISTINCT experience_name ORDER BY experience_name) FROM {table}"
        ).fetchone()
        for table in ("odom", "goal", "metadata")
    }


@pytest.mark.parametrize("point", ["added", "commit"])
def test_kill_9_between_publishing_and_commit_leaves_the_old_version_whole(tmp_path, point):
    lake = tmp_path / "lake"
    first = ingest_cli(tmp_path, lake, emissions(tmp_path, "old", odom=3, goals=2), "old")
    assert first.wait(60) == 0, first.stderr.read()
    before = state(lake)
    assert before == {"odom": (3, ["old"]), "goal": (2, ["old"]), "metadata": (1, ["old"])}
    marker = tmp_path / "paused"
    killed = ingest_cli(
        tmp_path, lake, emissions(tmp_path, "new", odom=5, goals=0), "new", env={PAUSE_ENV: f"{point}:{marker}"}
    )
    kill_when_paused(killed, marker)
    leftover = [p for p in lake.glob("main/*/batch_id=b1/*.parquet") if p.name.startswith(f"{killed.pid}-")]
    assert leftover, "the killed ingest had published a file under its new name"
    assert state(lake) == before  # every table of the job: the old version, whole
    again = ingest_cli(tmp_path, lake, emissions(tmp_path, "new", odom=5, goals=0), "new")
    assert again.wait(60) == 0, again.stderr.read()
    assert state(lake) == {"odom": (5, ["new"]), "goal": (0, None), "metadata": (1, ["new"])}
    assert not any(p.exists() for p in leftover)  # the dead writer's files were removed
    assert len(list(lake.glob("main/*/batch_id=b1/*.parquet"))) == 2  # odom and metadata only


def test_the_record_keeps_rows_timestamps_and_columns(tmp_path):
    lake = tmp_path / "lake"
    process = ingest_cli(tmp_path, lake, emissions(tmp_path, "e", odom=4, goals=1), "x")
    assert process.wait(60) == 0, process.stderr.read()
    record = Record(lake, "main")
    try:
        odom = record.find("odom", "b1", "j1")
        snapshot = record.snapshot()
    finally:
        record.close()
    assert (odom.rows, odom.min_ts, odom.max_ts) == (4, 0, 3)
    assert odom.columns == ("timestamp", "x", "experience_name", "build_version", "project_id", "run_counter", "job_id")
    assert sorted(e.table for e in snapshot.files) == ["goal", "metadata", "odom"]
    assert {t.name: t.row_count for t in Catalog(lake).tables("main")} == {
        "odom": 4,
        "goal": 1,
        "container_performance": 0,
        "test_length_seconds": 0,
        "events": 0,
        "metadata": 1,
    }


def test_a_lake_written_before_the_record_is_migrated_when_first_opened(tmp_path):
    """A lake of the earlier layout (`data.parquet` per partition, no record) reads as before; the
    next ingest of a job replaces its old file."""
    lake = tmp_path / "lake"
    process = ingest_cli(tmp_path, lake, emissions(tmp_path, "e", odom=3, goals=1), "legacy")
    assert process.wait(60) == 0, process.stderr.read()
    to_v1(lake)  # the layout written before the record: data.parquet in job_id=J/ directories
    assert state(lake) == {"odom": (3, ["legacy"]), "goal": (1, ["legacy"]), "metadata": (1, ["legacy"])}
    assert (lake / "main" / RECORD).is_file()
    again = ingest_cli(tmp_path, lake, emissions(tmp_path, "e2", odom=2, goals=0), "new")
    assert again.wait(60) == 0, again.stderr.read()
    assert state(lake) == {"odom": (2, ["new"]), "goal": (0, None), "metadata": (1, ["new"])}
    assert not list(lake.glob("main/*/batch_id=*/job_id=*/*"))  # migrated to layout v2 by the ingest
    assert Record(lake, "main").layout() == 2


def test_files_no_record_row_holds_are_invisible_to_lakegate(tmp_path):
    lake = tmp_path / "lake"
    process = ingest_cli(tmp_path, lake, emissions(tmp_path, "e", odom=3, goals=1), "x")
    assert process.wait(60) == 0, process.stderr.read()
    stray = paths.partition_dir(lake, "main", "odom", "b1") / "1-stray.parquet"
    pq.write_table(
        pa.table(
            {"timestamp": [9], "x": [9.0], "experience_name": ["stray"], "build_version": [None], "job_id": ["j1"]}
        ),
        stray,
    )
    assert state(lake)["odom"] == (3, ["x"])
    glob = str(lake / "main" / "odom" / "*" / "*.parquet")
    assert duckdb.connect().execute(f"SELECT count(*) FROM '{glob}'").fetchone() == (4,)  # what a glob would see
