"""Shared by the benchmark scripts: machine facts, medians, and writing one section of RESULTS.md."""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import time
import urllib.request
from collections.abc import Callable, Iterable, Iterator
from importlib import metadata
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "RESULTS.md"
#: The venvs of the implementations the benches compare with, installed once per machine (as the real
#: Trino is), not per checkout: a fresh clone's smoke runs reuse them. `$LAKEGATE_BENCH_VENVS` moves them.
VENVS = Path(
    os.environ.get("LAKEGATE_BENCH_VENVS")
    or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "lakegate" / "bench-venvs"
)
#: Set by `parse_args(--smoke)`: tiny sizes, figures printed, RESULTS.md left alone.
_smoke = False
#: The load average when the bench started (its module was imported), stated beside the one at the end.
_LOAD_AT_START = os.getloadavg()
HEADER = (
    "# Benchmark results\n\nEach section is written by the script it names; re-run it to refresh that section."
    " The first section is\nwritten by hand from them.\n"
)


def machine() -> str:
    """One line describing the machine and the versions that matter."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = []
    for dist in ("duckdb", "sqlglot", "pyarrow", "trino", "fastapi", "uvicorn"):
        try:
            versions.append(f"{dist} {metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            pass
    return f"{cpu}, {os.cpu_count()} cores; Python {platform.python_version()}; " + ", ".join(versions)


@contextlib.contextmanager
def venv_lock(venv: Path) -> Iterator[Path]:
    """Held while the venv `venv` (a folder of VENVS) is checked and, if need be, built: two runs at once
    (two checkouts) build it once, and neither uses it half built."""
    venv.parent.mkdir(parents=True, exist_ok=True)
    with open(venv.parent / f"{venv.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield venv


def median_of(runs: int, fn: Callable[[], float]) -> tuple[float, list[float]]:
    """Call `fn` (which returns one measured figure) `runs` times; the median and all figures."""
    figures = [fn() for _ in range(runs)]
    return statistics.median(figures), figures


def timed(fn: Callable[[], object]) -> float:
    """Seconds one call of `fn` takes."""
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def run_python(code: str, *args: str) -> dict:
    """Run `code` in a fresh interpreter; the JSON it prints, plus `wall` and `cpu` seconds and
    `rss_mb` (peak RSS, unless the code reported its own)."""
    start = time.perf_counter()
    process = subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.PIPE, text=True)
    output = process.stdout.read()
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - start
    process.stdout.close()
    if status != 0:
        raise SystemExit(f"benchmark subprocess failed (status {status})")
    result = json.loads(output)
    result.update(wall=wall, cpu=usage.ru_utime + usage.ru_stime)
    result.setdefault("rss_mb", usage.ru_maxrss / 1024)
    return result


def run_times(results: Iterable[dict]) -> str:
    """The `seconds` of each run, for a results line."""
    return ", ".join(f"{r['seconds']:.2f}" for r in results)


def wait_serving(process: subprocess.Popen, port: int, stop: Callable[[], None], what: str, log: str) -> None:
    """Wait (at most 60 s) until the server `process` answers `/v1/info` on 127.0.0.1:`port`; if it
    exits or the time is up, `stop` it and exit naming `what` and its `log`."""
    deadline = time.monotonic() + 60
    while True:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/v1/info", timeout=2):
                return
        except OSError:
            if process.poll() is not None or time.monotonic() > deadline:
                stop()
                raise SystemExit(f"{what} did not start; see {log}") from None
            time.sleep(0.2)


def _loads(loads: tuple[float, float, float]) -> str:
    return ", ".join(f"{load:.2f}" for load in loads)


def git_revision() -> str:
    try:
        return subprocess.check_output(["git", "rev-parse", "--short", "HEAD"], cwd=RESULTS.parent, text=True).strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def parse_args(
    parser: argparse.ArgumentParser, argv: list[str] | None = None, **smoke_sizes: object
) -> argparse.Namespace:
    """The bench's arguments plus `--smoke`, which replaces its sizes by `smoke_sizes` (a run of
    seconds that exercises every code path; CI runs every bench so, so none can rot) and leaves
    RESULTS.md alone."""
    global _smoke
    parser.add_argument(
        "--smoke", action="store_true", help="tiny sizes that run in seconds; print the figures, leave RESULTS.md alone"
    )
    args = parser.parse_args(argv)
    if args.smoke:
        _smoke = True
        vars(args).update(smoke_sizes)
    return args


def write_section(title: str, command: str, lines: Iterable[str]) -> None:
    """Replace (or append) the section `## title` of RESULTS.md with the given Markdown lines (only
    print them under --smoke)."""
    body = "\n".join(
        [
            f"## {title}",
            "",
            f"- command: `{command}`",
            f"- machine: {machine()}",
            f"- revision: {git_revision()}, {time.strftime('%Y-%m-%d %H:%M', time.localtime())}",
            f"- load average (1, 5, 15 min) at the start: {_loads(_LOAD_AT_START)};"
            f" at the end: {_loads(os.getloadavg())} ({os.cpu_count()} cores)",
            "",
            *lines,
            "",
        ]
    )
    if _smoke:
        print(body)
        return
    text = RESULTS.read_text() if RESULTS.exists() else HEADER
    pattern = re.compile(rf"^## {re.escape(title)}\n.*?(?=^## |\Z)", re.S | re.M)
    text = pattern.sub(lambda _: body + "\n", text) if pattern.search(text) else text.rstrip("\n") + "\n\n" + body
    RESULTS.write_text(text)
    print(body, file=sys.stdout)
