"""Configs written in the style of real ReSim Metrics 2.0 configs run as they are: ingested and
evaluated by the real CLI in subprocesses, with the expected values computed here from the data."""

from __future__ import annotations

import datetime as dt
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

CONFIGS = Path(__file__).resolve().parent / "configs"
SPLIT = [CONFIGS / "robot.topics.resim.yaml", CONFIGS / "robot.metrics.resim.yaml"]
CLI = [sys.executable, "-m", "lakegate.gateway.cli"]

# per job: robot_speed rows (phase, speed) and daily_distance rows (day, metres)
JOBS = {
    "j1": {
        "speeds": [("cruise", 0.5), ("cruise", 1.0), ("dock", 1.5)],
        "days": [("2026-01-01", 1.0), ("2026-01-05", 2.0)],
    },
    "j2": {
        "speeds": [("cruise", 1.0), ("dock", 2.0), ("cruise", 3.0)],
        "days": [("2026-01-10", 4.0), ("2026-01-20", 3.0)],
    },
}
WARN_ABOVE = 2.0  # the warn threshold of "Top Speed"


def lakegate(*args, check=True):
    result = subprocess.run(
        [*CLI, *map(str, args)], capture_output=True, text=True, timeout=180, env={**os.environ, "COLUMNS": "200"}
    )
    if check:
        assert result.returncode == 0, result.stderr
    return result


def emissions(path: Path, job: dict) -> Path:
    """The job's emissions as ReSim's emitter writes them: one JSON object per line."""
    lines = [
        {"$metadata": {"topic": "robot_speed", "timestamp": i}, "$data": {"speed": speed, "phase": phase}}
        for i, (phase, speed) in enumerate(job["speeds"])
    ]
    lines += [
        {"$metadata": {"topic": "daily_distance", "timestamp": i}, "$data": {"day": day, "distance_m": m}}
        for i, (day, m) in enumerate(job["days"])
    ]
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def best_week(days: list[tuple[str, float]]) -> float:
    """The largest sum of distances over a day and the 7 days before it."""
    dated = [(dt.date.fromisoformat(day), m) for day, m in days]
    return max(sum(m for d, m in dated if 0 <= (day - d).days <= 7) for day, _ in dated)


@pytest.fixture(scope="module")
def lake(tmp_path_factory):
    root = tmp_path_factory.mktemp("compat")
    lake = root / "lake"
    config_args = [arg for path in SPLIT for arg in ("--metrics-config-path", path)]
    for job_id, job in JOBS.items():
        lakegate(
            "ingest",
            "--lake",
            lake,
            "--branch",
            "main",
            "--batch",
            "b1",
            "--job",
            job_id,
            *config_args,
            "--build-version",
            "1.0",
            "--no-progress",
            emissions(root / f"{job_id}.jsonl", job),
        )
    return lake


def test_split_config_files_load_merged_as_they_are():
    checked = lakegate("config", "check", *SPLIT)
    assert "2 topics, 7 metrics, 1 metrics set" in checked.stdout


def test_the_split_config_runs_as_is_and_every_value_matches(lake):
    config_args = [arg for path in SPLIT for arg in ("--metrics-config-path", path)]
    result = lakegate(
        "metrics",
        "run",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        "b1",
        "--metrics-set",
        "Robot",
        *config_args,
        "--format",
        "json",
        "--no-progress",
        check=False,
    )
    assert result.returncode == 0, result.stderr  # warnings do not fail a batch
    output = json.loads(result.stdout)
    by = {(m["job_id"], m["metric"]): m for m in output["metrics"]}

    for job_id, job in JOBS.items():
        top = max(speed for _, speed in job["speeds"])
        metric = by[job_id, "Top Speed"]
        assert (metric["scalar_value"], metric["status"]) == (top, "WARNING" if top > WARN_ABOVE else "PASSED")
        assert by[job_id, "Speed Distribution"]["status"] == "PASSED"  # [group_name, value]
        assert by[job_id, "Speed by Phase"]["status"] == "PASSED"  # text x values as categories

    batch = {m["metric"]: m for m in output["metrics"] if m["job_id"] is None}
    tops = [max(speed for _, speed in job["speeds"]) for job in JOBS.values()]
    assert batch["Mean of Job Top Speeds"]["scalar_value"] == sum(tops) / len(tops)
    assert batch["Best Week"]["scalar_value"] == best_week([d for job in JOBS.values() for d in job["days"]])
    assert {batch[name]["status"] for name in ("Top Speed Trend", "Weekly Summary")} == {"NOT_RUN"}
    assert output["status"] == "WARNING"
