"""Where the time goes in the workloads whose speed goals are not met: py-spy samples of every thread
of every process, grouped by what the code is doing.

    python3 dev.py bench profile [--seconds S] [--smoke]

Workloads: `lakegate serve` answering `SELECT 1` and a GROUP BY over the translate bench's 10M-row
topic (bench/.work/translate) through the official trino client, and `MetricsEngine.evaluate_batch`
(as `lakegate metrics run` calls it) over the metrics bench's batch (bench/.work/metrics). py-spy
(in the test extras) samples at 100 Hz with
`--subprocesses`, so query workers count too; samples of threads that wait are counted apart.

Writes section "Profiles" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from metrics import BATCH, METRICS, OURS, prepare  # noqa: E402
from results import parse_args, write_section  # noqa: E402
from server import Server, client_rows  # noqa: E402
from translate import build_lake  # noqa: E402

#: The raw py-spy files of the last run (flame graphs: `py-spy` raw format, one stack per line).
WORK = Path(__file__).resolve().parent / ".work" / "profile"
GROUP_BY = (
    "SELECT job_id, count(*) AS n, avg(x) AS ax, min(y) AS my, max(x) AS mx "
    "FROM odom_linear_velocity GROUP BY job_id ORDER BY job_id"
)
#: (category, substrings of a frame): a sample goes to the first category one of its frames matches,
#: looked for from the innermost frame out. Order matters: a wait inside the HTTP stack is a wait.
CATEGORIES = (
    (
        "waiting (a blocked thread)",
        ("Condition.wait", "SimpleQueue", "Event.wait", "select (selectors", "sleep (", "_worker (concurrent/futures"),
    ),
    ("DuckDB running the query", ("duckdb/",)),
    ("query worker start", ("forkserver.py", "WorkerPool._start", "Worker.warm")),
    ("memory watch", ("_watch_memory", "process_memory")),
    ("worker pipe (pickling, sending)", ("multiprocessing/connection", "query_worker.py", "isolated_backend")),
    ("scope views", ("_scope_views", "_swap_views", "view_sql", "catalog.py")),
    ("planning and translating", ("dialect/", "sqlglot/", "planner.py", "statements.py")),
    ("rendering figures", ("metrics/templates.py", "metrics/custom.py", "plotly")),
    ("judging statuses", ("metrics/statuses.py", "metrics/gating.py")),
    ("writing results, Arrow conversions", ("metrics/results_table.py", "lake/writer", "pyarrow/", "parquet")),
    ("HTTP and the client protocol", ("uvicorn/", "starlette/", "fastapi/", "gateway/server/", "httptools", "h11")),
    ("reading configs (YAML)", ("yaml/", "ruamel/", "lake/config")),
    (
        "system catalog, lake record and metadata",
        ("system_tables.py", "lake/record.py", "lake/metadata.py", "lake/paths"),
    ),
    ("Python start-up and imports", ("<frozen importlib", "_find_and_load")),
    ("the bench's own code around the call", ("metrics_run.py",)),
)


def py_spy() -> str:
    return str(Path(sys.executable).parent / "py-spy")


def categorize(raw: Path, first_pids: set[int] | None = None) -> tuple[collections.Counter, int, set[int]]:
    """Samples per category of a py-spy raw file, their total, and the pids seen."""
    counts: collections.Counter = collections.Counter()
    total, pids = 0, set()
    for line in raw.read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        if not count.isdigit():
            continue
        frames = stack.split(";")
        pid = int(frames[0].split()[1].split(":")[0]) if frames[0].startswith("process ") else 0
        pids.add(pid)
        total += int(count)
        if first_pids is not None and pid not in first_pids:
            counts["query worker start"] += int(count)  # a process born during the run: a new worker
            continue
        for frame in reversed(frames):
            found = next((name for name, keys in CATEGORIES if any(key in frame for key in keys)), None)
            if found:
                counts[found] += int(count)
                break
        else:
            counts["other"] += int(count)
    return counts, total, pids


def profile_server(lake: Path, sql: str, seconds: float, out: Path) -> dict:
    """Profile `lakegate serve` answering `sql` one after the other for `seconds`."""
    server = Server(lake, [])
    try:
        connection = server.connect()
        for _ in range(3 if "GROUP BY" in sql else 50):
            client_rows(connection, sql)
        first = set(server.pids())
        command = [py_spy(), "record", "-r", "100", "-d", str(max(1, round(seconds))), "--subprocesses"]
        spy = subprocess.Popen(
            [*command, "-f", "raw", "-o", str(out), "-p", str(server.process.pid)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        time.sleep(1.0)  # py-spy attaches
        queries, cpu, start = 0, server.cpu(), time.perf_counter()
        while time.perf_counter() - start < seconds - 1.5:
            client_rows(connection, sql)
            queries += 1
        cpu, wall = server.cpu() - cpu, time.perf_counter() - start
        born = len(set(server.pids()) - first)
        spy.wait(timeout=seconds + 60)
    finally:
        server.stop()
    counts, total, _ = categorize(out, first)
    return {"counts": counts, "total": total, "queries": queries, "cpu": cpu, "wall": wall, "born": born}


def profile_metrics(jobs: int, rows_per_job: int, out: Path) -> dict:
    lake, _ = prepare(jobs, rows_per_job)
    command = [py_spy(), "record", "-r", "100", "--subprocesses", "-f", "raw", "-o", str(out), "--"]
    script = WORK / "metrics_run.py"  # a file, not `-c`: py-spy names a process by its command line
    script.write_text(OURS)
    start = time.perf_counter()
    run = subprocess.run(
        [*command, sys.executable, str(script), str(lake), json.dumps(list(METRICS)), BATCH],
        capture_output=True,
        text=True,
        check=True,
    )
    wall = time.perf_counter() - start
    result = json.loads(next(line for line in reversed(run.stdout.splitlines()) if line.startswith("{")))
    counts, total, _ = categorize(out)
    return {"counts": counts, "total": total, "seconds": result["seconds"], "wall": wall, "jobs": result["jobs"]}


def table(counts: collections.Counter, total: int) -> list[str]:
    lines = ["| where | share of samples |", "|---|---:|"]
    for name, count in counts.most_common():
        lines.append(f"| {name} | {count / total * 100:.1f} % |")
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="seconds of each server profile (default 20)")
    parser.add_argument(
        "--jobs", type=int, default=100, help="jobs of the metrics batch profiled (default 100, the metrics bench's)"
    )
    args = parse_args(parser, seconds=4.0, jobs=3)
    lines: list[str] = [
        "py-spy at 100 Hz over every thread of every process of the workload (`--subprocesses`); a sample goes "
        "to the first category one of its frames matches, from the innermost frame out (bench/profile.py "
        "CATEGORIES). Samples of blocked threads are counted as waiting: they are not CPU, but show where a "
        "query waits.",
        "",
    ]
    WORK.mkdir(parents=True, exist_ok=True)
    small, large = build_lake(20_000 if args.smoke else 200_000), build_lake(20_000 if args.smoke else 10_000_000)
    for index, (title, lake, sql) in enumerate(
        (("`SELECT 1`", small, "SELECT 1"), ("GROUP BY over the topic", large, GROUP_BY))
    ):
        found = profile_server(lake, sql, args.seconds, WORK / f"server-{index}.txt")
        per = found["queries"] or 1
        lines += [
            f"### {title} through `lakegate serve`",
            "",
            f"`{sql}`: {found['queries']} queries in {found['wall']:.1f} s, server CPU "
            f"{found['cpu'] / per * 1e3:.2f} ms per query (the server and its query workers), "
            f"{found['born']} query workers started meanwhile (a worker that keeps more than 64 MB after "
            f"its query is replaced); {found['total']:,} samples.",
            "",
            *table(found["counts"], found["total"]),
            "",
        ]
    rows_per_job = 1_000 if args.smoke else 100_000
    found = profile_metrics(args.jobs, rows_per_job, WORK / "metrics.txt")
    lines += [
        "### `metrics run` (MetricsEngine.evaluate_batch)",
        "",
        f"The metrics bench's 10 metrics over a batch of {found['jobs']} jobs of {rows_per_job:,} rows: "
        f"{found['seconds']:.1f} s inside, {found['wall']:.1f} s with start-up; {found['total']:,} samples.",
        "",
        *table(found["counts"], found["total"]),
    ]
    write_section("Profiles", "python3 dev.py bench profile", lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
