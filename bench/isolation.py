"""Isolation benchmark: what running each query in a worker process costs, per query.

    python3 dev.py bench isolation [--runs R] [--rows N]

Uses the translate benchmark's lake (bench/.work/translate/, built at N rows when missing) and
runs the same statements through an Engine over `DuckDBBackend` (queries in this process, the
baseline) and over `IsolatedBackend` (each query in a warm worker process, batches back over a pipe
as Arrow IPC), alternating, R times each after a warm-up:

* `SELECT 1`, an aggregate over one job, and fetching one job's rows (3 columns): median wall time
  per query, and mean CPU per query of this process and its workers together (/proc/PID/stat);
* recovery: a query killed past the memory limit (a 10^8-element list), then the wall time until
  the next `SELECT 1` has answered (the pool keeps a warm worker ready).

Writes section "Query isolation" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, write_section  # noqa: E402
from translate import TOPIC, build_lake  # noqa: E402

from lakegate.dialect.errors import DialectError  # noqa: E402
from lakegate.gateway.engine.backend import DuckDBBackend  # noqa: E402
from lakegate.gateway.engine.engine import Engine  # noqa: E402
from lakegate.gateway.engine.isolated_backend import IsolatedBackend  # noqa: E402
from lakegate.gateway.engine.limits import Limits  # noqa: E402

THREADS = 2
MEMORY_LIMIT = "1GB"
STATEMENTS = {
    "`SELECT 1`": "SELECT 1",
    "aggregate over one job": f"SELECT count(*), avg(x), max(y) FROM {TOPIC} WHERE job_id = 'j0'",
    "one job's rows (3 columns)": f"SELECT timestamp, x, y FROM {TOPIC} WHERE job_id = 'j0'",
}
BOMB = "SELECT cardinality(flatten(transform(sequence(1, 10000), x -> sequence(1, 10000))))"
_TICK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pids: list[int]) -> float:
    """CPU seconds (user + system) used so far by this process and the processes `pids`."""
    own = os.times()
    total = own.user + own.system
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / _TICK
        except (OSError, IndexError):
            pass
    return total


def measure(engine: Engine, sql: str, pids: list[int]) -> tuple[float, float, int]:
    """(wall seconds, CPU seconds, rows) of one statement, read to its end."""
    session = engine.session(branch="main")
    cpu, start = cpu_seconds(pids), time.perf_counter()
    rows = sum(batch.num_rows for batch in engine.execute(sql, session).batches)
    return time.perf_counter() - start, cpu_seconds(pids) - cpu, rows


def recovery_seconds(engine: Engine) -> tuple[str, float]:
    """The error of a query killed past the memory limit, and seconds until `SELECT 1` answers after it."""
    session = engine.session(branch="main")
    try:
        engine.execute(BOMB, session).rows()
        name = "FINISHED"
    except DialectError as error:
        name = error.error_name
    start = time.perf_counter()
    engine.execute("SELECT 1", session).rows()
    return name, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=101, help="runs per statement and backend (default 101)")
    parser.add_argument(
        "--rows", type=int, default=1_000_000, help="rows of the bench lake's topic (default 1,000,000)"
    )
    args = parse_args(parser, runs=5, rows=20_000)
    lake = build_lake(args.rows)
    limits = Limits(query_timeout=30)
    direct = Engine(DuckDBBackend(lake, memory_limit=MEMORY_LIMIT, threads=THREADS, limits=limits), owns_backend=True)
    isolated_backend = IsolatedBackend(lake, memory_limit=MEMORY_LIMIT, threads=THREADS, limits=limits)
    isolated = Engine(isolated_backend, owns_backend=True)
    isolated_backend.pool.wait_ready(60)
    table = [
        "| statement | rows | in process: wall | isolated: wall | ratio | in process: CPU | isolated: CPU | ratio |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    try:
        for name, sql in STATEMENTS.items():
            figures: dict[str, list[tuple[float, float, int]]] = {"direct": [], "isolated": []}
            for _ in range(3):  # warm-up: views, caches, the workers' first queries
                measure(direct, sql, [])
                measure(isolated, sql, isolated_backend.pool.pids())
            for _ in range(args.runs):
                figures["direct"].append(measure(direct, sql, []))
                figures["isolated"].append(measure(isolated, sql, isolated_backend.pool.pids()))
            wall = {k: statistics.median(f[0] for f in v) for k, v in figures.items()}
            cpu = {k: sum(f[1] for f in v) / len(v) for k, v in figures.items()}  # ticks: a mean, not a median
            rows = figures["direct"][0][2]
            table.append(
                f"| {name} | {rows:,} | {wall['direct'] * 1e3:.2f} ms | {wall['isolated'] * 1e3:.2f} ms | "
                f"{wall['isolated'] / wall['direct']:.2f} | {cpu['direct'] * 1e3:.1f} ms | "
                f"{cpu['isolated'] * 1e3:.1f} ms | {cpu['isolated'] / max(cpu['direct'], 1e-4):.2f} |"
            )
        error, recovery = recovery_seconds(isolated)
    finally:
        direct.close()
        isolated.close()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    lines = [
        f"- lake: bench/.work/translate ({args.rows:,} rows of `{TOPIC}` in 10 jobs); DuckDB {THREADS} threads, "
        f"memory limit {MEMORY_LIMIT}; median of {args.runs} alternating runs per statement after 3 warm-up runs; "
        "CPU per query is the mean over the runs of this process's and its worker processes' CPU together "
        "(/proc/PID/stat, counted in 10 ms ticks)",
        f"- load average at the end: {load} (2 cores, shared)",
        "",
        *table,
        "",
        f"- recovery: a 10^8-element list query failed with {error}; the next `SELECT 1` answered "
        f"{recovery * 1e3:.0f} ms after (a warm worker was ready)",
    ]
    write_section("Query isolation", "python3 dev.py bench isolation", lines)


if __name__ == "__main__":
    main()
