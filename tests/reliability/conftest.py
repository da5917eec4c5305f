"""What the hostile-load tests share: a real `lakegate serve` under a hard address-space cap, a client
that follows a statement to its end, and a watch of the memory the server's processes hold together
(the server and its query workers), sampled while the load runs."""

from __future__ import annotations

import os
import resource
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import requests

from tests.gateway.conftest import CLI, Output, build_server_lake

HEADERS = {"X-Trino-User": "tester", "X-Trino-Catalog": "lake", "X-Trino-Schema": "main"}
MEMORY_LIMIT_MB = 512
#: What the server's processes together may hold beyond --memory-limit with the default 8 query
#: workers and a warm one (docs/sql-endpoint.md, "Memory": about 180 MB and 45 MB per worker).
RSS_MARGIN_MB = 600
#: The hard cap on each server process's address space: far above what it should use, far below the machine.
ADDRESS_SPACE = 3 << 30
QUERY_TIMEOUT = 3


def capped() -> None:
    """Cap this process's address space at ADDRESS_SPACE (a subprocess's `preexec_fn`)."""
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


def process_tree(pid: int) -> list[int]:
    """`pid` and every process descended from it."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            children.setdefault(int(stat.rsplit(")", 1)[1].split()[1]), []).append(int(entry))
    found, todo = [], [pid]
    while todo:
        found.append(todo.pop())
        todo += children.get(found[-1], [])
    return found


def held_mb(pid: int) -> float:
    """Memory the processes of `pid`'s tree hold together, in MB: the sum of their proportional set
    sizes (a page shared by several processes counts once in all)."""
    total = 0
    for member in process_tree(pid):
        try:
            for line in Path(f"/proc/{member}/smaps_rollup").read_text().splitlines():
                if line.startswith("Pss:"):
                    total += int(line.split()[1])
        except OSError:
            pass  # ended meanwhile
    return total / 1024


def peak_of(pid: int) -> float:
    """The peak resident memory (VmHWM) of process `pid` alone, in MB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise AssertionError(f"no VmHWM for process {pid}")


class MemoryWatch:
    """The peak of `held_mb` of a process tree, sampled every 50 ms by a thread while in use."""

    def __init__(self, pid: int):
        self.pid, self.peak = pid, 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self) -> None:
        while not self._stop.wait(0.05):
            self.peak = max(self.peak, held_mb(self.pid))

    def __enter__(self) -> MemoryWatch:
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        self._thread.join()


def start_server(tmp_path: Path, *options: str) -> Iterator[tuple[subprocess.Popen, str, Path]]:
    """One `lakegate serve` over the server tests' lake with small limits (more `options` after
    them) under the address-space cap: yields (process, URL, lake), killed at the end."""
    lake = build_server_lake(tmp_path)
    command = [
        *CLI,
        "serve",
        "--lake",
        str(lake),
        "--port",
        "0",
        "--memory-limit",
        f"{MEMORY_LIMIT_MB}MB",
        "--query-timeout",
        str(QUERY_TIMEOUT),
        "--threads",
        "2",
        *options,
    ]
    with open(tmp_path / "stderr.log", "w") as stderr:
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=stderr, text=True, preexec_fn=capped)
    line = Output(process).wait_for(" at ", 60)
    try:
        assert line is not None, (tmp_path / "stderr.log").read_text()
        yield process, line.split(" at ", 1)[1].split()[0], lake
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


@pytest.fixture
def server(tmp_path):
    """One `lakegate serve` with small limits under the address-space cap: (process, URL, lake)."""
    yield from start_server(tmp_path)


def run_statement(url: str, body: bytes, lake: Path, *, seconds: float = 60, user: str = "tester") -> dict:
    """The last document of a statement of `user`, followed to its end (at most `seconds`), after
    checking its error message tells no traceback or server path."""
    deadline = time.monotonic() + seconds
    headers = {**HEADERS, "X-Trino-User": user}
    response = requests.post(f"{url}/v1/statement", data=body, headers=headers, timeout=seconds)
    if response.status_code == 413:
        return {"error": {"errorName": "QUERY_TEXT_TOO_LARGE"}, "stats": {"state": "FAILED"}}
    document = response.json()
    while "nextUri" in document and time.monotonic() < deadline:
        document = requests.get(document["nextUri"], timeout=seconds).json()
    message = document.get("error", {}).get("message", "")
    assert "Traceback" not in message and str(lake) not in message, message
    return document


def outcome(url: str, body: bytes, lake: Path, user: str = "tester") -> str:
    """The Trino error name a statement of `user` ends with (its state when it ends without one)."""
    document = run_statement(url, body, lake, user=user)
    return document.get("error", {}).get("errorName", document["stats"]["state"])


def select_one_seconds(url: str, lake: Path, user: str = "tester") -> float:
    """Seconds `SELECT 1` of `user` takes to answer, after checking it answers 1."""
    started = time.monotonic()
    assert run_statement(url, b"SELECT 1", lake, seconds=10, user=user).get("data") == [[1]]
    return time.monotonic() - started
