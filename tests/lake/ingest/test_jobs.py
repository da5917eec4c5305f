"""Ingesting a job: replacing it, refusing names the lake cannot hold, storing the config, the progress
bar, and a kill -9 at any moment leaving nothing partial."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from lakegate.lake import paths
from lakegate.lake.config import Config, Topic, load_config
from lakegate.lake.ingest import IngestError, ingest_job
from tests.lake.ingest.lines import CONFIG, count, line, odom, query, write_lines

# -- replacing a job ------------------------------------------------------------------------


def test_reingesting_a_job_replaces_it_and_never_duplicates(tmp_path, config):
    lake = tmp_path / "lake"
    both = write_lines(
        tmp_path / "both.jsonl", [odom(i) for i in range(5)] + [line("stop", 1, {"name": "x", "speed": 1.0}, True)]
    )
    for _ in range(2):
        ingest_job(lake, "main", "b1", "j1", [both], config=config)
        assert count(lake, "odom") == 5 and count(lake, "stop") == 1 and count(lake, "events") == 1
        assert count(lake, "metadata") == 1
    ingest_job(lake, "main", "b1", "j2", [both], config=config)
    assert count(lake, "odom") == 10 and count(lake, "metadata") == 2
    only_odom = write_lines(tmp_path / "odom.jsonl", [odom(i) for i in range(3)])
    ingest_job(lake, "main", "b1", "j1", [only_odom], config=config)
    # j1's stop rows and events are gone, j2's stay
    assert query(lake, "SELECT job_id, COUNT(*) FROM odom GROUP BY 1 ORDER BY 1") == [("j1", 3), ("j2", 5)]
    assert query(lake, "SELECT job_id FROM stop") == [("j2",)] and query(lake, "SELECT job_id FROM events") == [("j2",)]
    assert not (paths.table_dir(lake, "main", "stop") / "batch_id=b1" / "job_id=j1").exists()


def test_names_the_lake_cannot_hold_are_refused_before_anything_is_written(tmp_path, config):
    emissions = write_lines(tmp_path / "e.jsonl", [odom(1)])
    for batch, job in (("a/b", "j"), ("b", "*"), ("..", "j"), ("b", "")):
        with pytest.raises(paths.LakePathError):
            ingest_job(tmp_path / "lake", "main", batch, job, [emissions], config=config)
    clash = Config(topics={"odom": Topic("odom", {"timestamp": "int"})})  # configs built in code are checked too
    with pytest.raises(IngestError, match="declares field 'timestamp', a column lakegate adds"):
        ingest_job(tmp_path / "lake", "main", "b", "j", [emissions], config=clash)
    for name in ("metadata", "events", "_configs", "a*b"):
        with pytest.raises(paths.LakePathError, match="topic name"):
            ingest_job(
                tmp_path / "lake",
                "main",
                "b",
                "j",
                [emissions],
                config=Config(topics={name: Topic(name, {"x": "int"})}),
            )
    with pytest.raises(IngestError, match="does not exist"):
        ingest_job(tmp_path / "lake", "main", "b", "j", [tmp_path / "missing.jsonl"], config=config)
    assert not (tmp_path / "lake").exists() or not list((tmp_path / "lake").glob("*/*/batch_id=*"))


def test_ingest_stores_its_config_and_reports_the_version(tmp_path, config, config_path):
    emissions = write_lines(tmp_path / "e.jsonl", [odom(1)])
    first = ingest_job(tmp_path / "lake", "main", "b1", "j1", [emissions], config=config)
    again = ingest_job(tmp_path / "lake", "main", "b1", "j2", [emissions], config=config)
    assert first.config_version == again.config_version == 1
    config_path.write_text(CONFIG + "  later:\n    schema: {n: int}\n")
    third = ingest_job(tmp_path / "lake", "main", "b1", "j3", [emissions], config=load_config(config_path))
    assert third.config_version == 2 and third.rows["later"] == 0


def test_progress_bar_goes_to_stderr_only_when_asked(tmp_path, config, capsys):
    emissions = write_lines(tmp_path / "e.jsonl", [odom(i) for i in range(100)])
    ingest_job(tmp_path / "lake", "main", "b1", "j1", [emissions], config=config)
    assert capsys.readouterr().err == ""
    ingest_job(tmp_path / "lake", "main", "b1", "j1", [emissions], config=config, progress=True)
    err = capsys.readouterr().err
    assert "ingest" in err and "lines=100" in err and "B/s" in err


# -- crash safety ---------------------------------------------------------------------------

CRASH_SCRIPT = """
import sys
from pathlib import Path
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job, scan, write
scan.BLOCK_SIZE, write.ROWS_PER_WRITE = 1 << 20, 20_000  # small blocks and writes: a file is open early
ingest_job(Path(sys.argv[1]), "main", "b1", "j1", [Path(sys.argv[3])], config=load_config(sys.argv[2]))
"""


def big_emissions(path, count):
    template = '{"$metadata": {"topic": "odom", "timestamp": %d}, "$data": {"x": %d.25, "y": -%d.5, "z": 0.125}}\n'
    with open(path, "w") as handle:
        for start in range(0, count, 10000):
            handle.write("".join(template % (i, i, i) for i in range(start, min(count, start + 10000))))
    return path


def visible_files(lake):
    return sorted(p.relative_to(lake) for p in Path(lake).glob("*/*/batch_id=*/job_id=*/*"))


@pytest.mark.parametrize("moment", ["reading", "writing"])
def test_kill_9_during_ingest_leaves_nothing_partial_and_a_rerun_succeeds(tmp_path, config_path, config, moment):
    lake = tmp_path / "lake"
    small = write_lines(tmp_path / "small.jsonl", [odom(i) for i in range(7)])
    ingest_job(lake, "main", "b1", "j1", [small], config=config)
    before = visible_files(lake)
    lines = 200_000
    big = big_emissions(tmp_path / "big.jsonl", lines)
    staging = paths.branch_dir(lake, "main") / paths.STAGING
    process = subprocess.Popen([sys.executable, "-c", CRASH_SCRIPT, str(lake), str(config_path), str(big)])
    try:
        deadline, reached = time.monotonic() + 60, False
        while not reached and time.monotonic() < deadline and process.poll() is None:
            scratch = list(staging.glob(f"{process.pid}-*"))
            reached = bool(scratch) and (moment == "reading" or bool(list(scratch[0].glob("*.parquet"))))
            time.sleep(0.002)
        assert reached and process.poll() is None, "the ingest finished before it could be killed"
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait()
    assert process.returncode == -signal.SIGKILL
    # readers see exactly the earlier version of the job, and every visible file is whole
    assert visible_files(lake) == before
    for relative in before:
        pq.read_metadata(lake / relative)
    assert count(lake, "odom") == 7
    # a re-run succeeds, cleans the dead writer's scratch, and counts match
    report = ingest_job(lake, "main", "b1", "j1", [big], config=config)
    assert report.rows["odom"] == lines and count(lake, "odom") == lines
    assert not list(staging.glob(f"{process.pid}-*"))
