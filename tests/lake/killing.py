"""Killing a writer at one of lake.record's pause points (PAUSE_ENV), as a crash would."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path


def kill_when_paused(process: subprocess.Popen, marker: Path, seconds: float = 60) -> None:
    """Wait until `process` has written `marker` (it is paused there), then SIGKILL it."""
    try:
        deadline = time.monotonic() + seconds
        while not marker.exists() and process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert marker.exists(), process.stderr.read() if process.poll() is not None else "never paused"
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait(30)
    assert process.returncode == -signal.SIGKILL
