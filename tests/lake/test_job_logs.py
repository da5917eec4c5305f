"""A job's logs are switched by the same record commit as its tables (`ingest_job(logs=...)`)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from lakegate.lake import paths
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import read_metadata_row
from lakegate.lake.record import PAUSE_ENV, job_logs_dir
from tests.lake.killing import kill_when_paused

CONFIG = "version: 1\ntopics:\n  speed:\n    schema: {v: float}\n"


def job(root: Path, name: str, speed: float, logs: dict[str, str]) -> tuple[Path, Path]:
    folder = root / name
    (folder / "logs").mkdir(parents=True)
    for file, text in logs.items():
        (folder / "logs" / file).write_text(text)
    emissions = folder / "emissions.resim.jsonl"
    emissions.write_text(f'{{"$metadata": {{"topic": "speed", "timestamp": 0}}, "$data": {{"v": {speed}}}}}\n')
    return emissions, folder / "logs"


def files(folder: Path) -> dict[str, str]:
    return {p.name: p.read_text() for p in folder.iterdir()}


def test_reingest_replaces_the_logs_and_a_killed_ingest_leaves_the_old_job_and_logs_whole(tmp_path):
    config_path = tmp_path / "config.resim.yaml"
    config_path.write_text(CONFIG)
    config = load_config(config_path)
    lake = tmp_path / "lake"
    hand_copied = paths.logs_dir(lake, "main", "b", "j")
    hand_copied.mkdir(parents=True)
    (hand_copied / "old.txt").write_text("copied by hand")

    emissions, logs = job(tmp_path, "first", 1.0, {"a.txt": "first"})
    ingest_job(lake, "main", "b", "j", [emissions], config=config, logs=logs)
    first = job_logs_dir(lake, "main", "b", "j")
    assert files(first) == {"a.txt": "first"} and not hand_copied.exists()  # the recorded folder replaces it

    emissions, logs = job(tmp_path, "second", 2.0, {"b.txt": "second"})
    marker = tmp_path / "paused"
    script = textwrap.dedent(
        f"""
        from pathlib import Path
        from lakegate.lake.config import load_config
        from lakegate.lake.ingest import ingest_job
        ingest_job(Path({str(lake)!r}), "main", "b", "j", [Path({str(emissions)!r})],
                   config=load_config({str(config_path)!r}), logs=Path({str(logs)!r}))
        """
    )
    killed = subprocess.Popen(
        [sys.executable, "-c", script], env={**os.environ, PAUSE_ENV: f"commit:{marker}"}, stderr=subprocess.PIPE
    )
    kill_when_paused(killed, marker)
    assert job_logs_dir(lake, "main", "b", "j") == first and files(first) == {"a.txt": "first"}
    assert read_metadata_row(lake, "main", "b", "j") is not None
    orphans = [d for d in first.parent.iterdir() if d != first]
    assert len(orphans) == 1 and files(orphans[0]) == {"b.txt": "second"}  # moved in, never committed

    emissions, logs = job(tmp_path, "third", 3.0, {"c.txt": "third"})
    ingest_job(lake, "main", "b", "j", [emissions], config=config, logs=logs)
    third = job_logs_dir(lake, "main", "b", "j")
    assert files(third) == {"c.txt": "third"}
    assert sorted(first.parent.iterdir()) == [third]  # the replaced folder and the killed writer's are gone

    ingest_job(lake, "main", "b", "j", [emissions], config=config)  # without logs: the job keeps its logs
    assert job_logs_dir(lake, "main", "b", "j") == third
