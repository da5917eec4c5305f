"""The MCAP example of README ("Importing robot logs (MCAP)"): fixtures/odometry.mcap, written by
fixtures/make_mcap.py, imported with fixtures/odometry.mapping.yaml by the real CLI as README shows."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from lakegate.fixtures import make_mcap

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
CLI = [sys.executable, "-m", "lakegate.gateway.cli"]


def imported(log: Path, tmp_path: Path) -> list[dict]:
    """The emissions `lakegate import mcap LOG --mapping ... --output ...` writes."""
    output = tmp_path / f"{log.stem}.resim.jsonl"
    done = subprocess.run(
        [*CLI, "import", "mcap", str(log), "--mapping", str(FIXTURES / "odometry.mapping.yaml")]
        + ["--metrics-config-path", str(FIXTURES / "config.resim.yaml"), "--output", str(output)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"wrote 5 rows from 50 messages to {output} (odom_linear_velocity: 5)"
    return [json.loads(line) for line in output.read_text().splitlines()]


def test_the_readme_example_imports_every_tenth_message(tmp_path):
    rows = imported(FIXTURES / "odometry.mcap", tmp_path)
    expected = []
    for i in range(0, make_mcap.MESSAGES, 10):  # decimate: 10
        message = make_mcap.message(i)
        stamp = message["header"]["stamp"]
        expected.append(
            {
                "$metadata": {"topic": "odom_linear_velocity", "timestamp": stamp["sec"] * 10**9 + stamp["nanosec"]},
                "$data": message["twist"]["twist"]["linear"],
            }
        )
    assert rows == expected


def test_the_script_writes_the_example_again(tmp_path):
    again = tmp_path / "odometry.mcap"
    done = subprocess.run(
        [sys.executable, str(FIXTURES / "make_mcap.py"), str(again)], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert imported(again, tmp_path) == imported(FIXTURES / "odometry.mcap", tmp_path)
