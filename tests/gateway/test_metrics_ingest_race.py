"""A `lakegate metrics run` racing a re-ingest of one of its jobs, as real processes: the statuses
and results stored are always those of the data the job holds (or the job has none yet, when the
re-ingest came last: a re-ingest drops the job's results and the batch metrics'); never a verdict
computed on the version the re-ingest replaced.

Some rounds are made to hit the window every time: the run stops just before its record commit
(lake.record's PAUSE_ENV hook), the job is re-ingested, and the run goes on. The others start the
two processes 0-1 s apart, as an unlucky CI job would.
"""

from __future__ import annotations

import csv
import io
import os
import random
import subprocess
import time
from pathlib import Path

import pytest

from lakegate.lake.record import PAUSE_ENV

from .conftest import CLI

NAV_SET = "Nav Metrics"


def _lakegate(*args: str | Path, env: dict[str, str] | None = None) -> subprocess.Popen:
    return subprocess.Popen(
        [*CLI, *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=None if env is None else {**os.environ, **env},
    )


def _finish(process: subprocess.Popen) -> tuple[int, str, str]:
    out, err = process.communicate(timeout=300)
    return process.returncode, out, err


def job_results(lake: Path) -> dict[str, list[tuple]]:
    """Each job's stored (metric, status, value) rows (batch metrics under ''), from `lakegate query`."""
    query = _lakegate(
        "query", "--lake", lake, "--format", "csv",
        "SELECT coalesce(job_id, '') AS job, metric_name, status, scalar_value, value_text FROM metric_results "
        "ORDER BY 1, 2",
    )  # fmt: skip
    code, out, err = _finish(query)
    assert code == 0, err
    found: dict[str, list[tuple]] = {}
    for row in csv.DictReader(io.StringIO(out)):
        found.setdefault(row.pop("job"), []).append(tuple(row.values()))
    return found


@pytest.mark.slow
def test_a_metrics_run_never_stores_a_verdict_on_data_it_did_not_read(nav_jobs, tmp_path: Path) -> None:
    lake = tmp_path / "lake"
    common = ("--lake", lake, "--branch", "main")
    # job 0 of the generated batch evaluates PASSED, job 2 BLOCKER: the job 'racer' alternates between them
    versions = {"passes": (nav_jobs.jobs[0], "PASSED"), "blocks": (nav_jobs.jobs[2], "BLOCKER")}

    def ingest(job_id: str, version: str) -> subprocess.Popen:
        job = versions[version][0]
        return _lakegate(
            "ingest", job.emissions_path, *common, "--batch", "nightly", "--job", job_id,
            "--metadata", job.metadata_path, "--metrics-config-path", nav_jobs.config, "--experience-name", version,
        )  # fmt: skip

    def metrics_run(marker: Path | None) -> subprocess.Popen:
        env = None if marker is None else {PAUSE_ENV: f"commit:{marker}"}
        return _lakegate("metrics", "run", *common, "--batch", "nightly", "--metrics-set", NAV_SET, env=env)

    # the steady jobs hold each version's data for good: racer's results must equal those of its version's
    for job_id, version in (("racer", "passes"), ("steady-blocks", "blocks"), ("steady-passes", "passes")):
        assert _finish(ingest(job_id, version))[0] == 0
    assert _finish(_lakegate("metrics", "sync", *common, "--metrics-config-path", nav_jobs.config))[0] == 0

    rng = random.Random(24)
    restarts = 0
    for round_number in range(4):
        version = ("blocks", "passes")[round_number % 2]
        paused = round_number < 2
        marker = tmp_path / f"paused-{round_number}"
        run = metrics_run(marker if paused else None)
        if paused:  # the run has evaluated everything and is about to commit: the job changes now
            deadline = time.monotonic() + 120
            while not marker.exists() and run.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            assert marker.exists(), _finish(run)
            reingest = ingest("racer", version)
            assert _finish(reingest)[0] == 0
            while run.poll() is None:  # let it go on, each time it stops before a commit
                marker.unlink(missing_ok=True)
                time.sleep(0.05)
        else:
            time.sleep(rng.uniform(0.0, 1.0))
            reingest = ingest("racer", version)
            assert _finish(reingest)[0] == 0
        code, _, err = _finish(run)
        assert "Traceback" not in err, err
        assert code in (0, 2) or (code == 1 and "nothing was written" in err), (code, err)
        restarts += err.count("evaluated again")
        said = err
        query = _lakegate(
            "query", "--lake", lake, "--format", "csv",
            "SELECT experience_name, job_conflated_status FROM metadata WHERE job_id = 'racer'",
        )  # fmt: skip
        code, out, err = _finish(query)
        assert code == 0, err
        [row] = list(csv.DictReader(io.StringIO(out)))
        expected = versions[row["experience_name"]][1]
        # the status is of the data the job holds now, or none yet (the re-ingest came after the run)
        assert row["job_conflated_status"] in ("", expected), (round_number, row)
        if row["job_conflated_status"]:  # and its metric results are those of that data, metric by metric
            stored = job_results(lake)
            assert stored["racer"] == stored[f"steady-{row['experience_name']}"], round_number
        else:  # the re-ingest came last: it dropped the results of the data it replaced
            assert "racer" not in job_results(lake), round_number
        if paused:  # the run evaluated the new version after the re-ingest, said so, and stored its verdict
            assert row == {"experience_name": version, "job_conflated_status": versions[version][1]}
            assert "job(s) 'racer'" in said and "of batch 'nightly' changed" in said and "evaluated again" in said
    assert restarts >= 2
    # a re-ingest with no run after it: no verdict stays on the new data, nor batch metrics computed
    # over the old; the steady jobs keep theirs
    before = job_results(lake)
    assert _finish(ingest("racer", "passes"))[0] == 0
    after = job_results(lake)
    assert "racer" not in after and "" not in after  # '': the batch metrics' rows
    assert after["steady-blocks"] == before["steady-blocks"] and after["steady-passes"] == before["steady-passes"]
