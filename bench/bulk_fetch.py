"""Benchmark: a bulk fetch into pandas, by each path a user can take.

1,000,000 rows x 3 columns (timestamp, x, y of one job of the bench lake, bench/translate.py) into a
pandas DataFrame:
* the official `trino` client against `lakegate serve`: the direct protocol (`encoding=None`) and the
  spooling protocol with each encoding (json, json+zstd, json+lz4), `fetchall()` then DataFrame;
* `POST /v1/arrow` of the same server (an Arrow IPC stream) read with
  `pyarrow.ipc.open_stream(response.raw).read_pandas()`;
* `lakegate query --format arrow` (a fresh process, its start-up included) read with
  `pyarrow.ipc.open_stream(...).read_pandas()`, and `--format parquet --output FILE` then
  `pandas.read_parquet`;
* baseline: DuckDB in this process on the same Parquet files through the lake's views, `.df()`.
Runs alternate between the paths; the median of RUNS runs is reported, with the load average.

    python3 dev.py bench bulk_fetch [--rows 1000000] [--runs 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pyarrow as pa

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, write_section  # noqa: E402
from server import Server, direct_duckdb  # noqa: E402
from translate import JOBS, TOPIC, build_lake  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work"
GOAL = 1_000_000  # rows/s into pandas by a documented path
ENCODINGS = ("json", "json+zstd", "json+lz4")


def fetch_sql(rows: int) -> str:
    return f"SELECT timestamp, x, y FROM {TOPIC} WHERE job_id = '{JOBS[0][1]}' LIMIT {rows}"


def via_client(server: Server, sql: str, encoding: str | None) -> pd.DataFrame:
    import trino

    connection = trino.dbapi.connect(
        host="127.0.0.1", port=server.port, user="bench", catalog="lake", schema="main", encoding=encoding
    )
    cursor = connection.cursor()
    cursor.execute(sql)
    rows = cursor.fetchall()
    connection.close()
    return pd.DataFrame(rows, columns=[d[0] for d in cursor.description])


def via_arrow_endpoint(server: Server, sql: str) -> pd.DataFrame:
    import requests

    headers = {"X-Trino-User": "bench", "X-Trino-Catalog": "lake", "X-Trino-Schema": "main"}
    response = requests.post(f"http://127.0.0.1:{server.port}/v1/arrow", data=sql, headers=headers, stream=True)
    if response.status_code != 200:
        raise SystemExit(f"POST /v1/arrow failed: {response.text}")
    return pa.ipc.open_stream(response.raw).read_pandas()


def via_cli(lake: Path, sql: str, fmt: str) -> pd.DataFrame:
    command = [sys.executable, "-m", "lakegate.gateway.cli", "query", "--lake", str(lake), "--format", fmt]
    if fmt == "arrow":
        process = subprocess.Popen([*command, sql], stdout=subprocess.PIPE)
        frame = pa.ipc.open_stream(process.stdout).read_pandas()
        if process.wait() != 0:
            raise SystemExit("lakegate query --format arrow failed")
        return frame
    out = WORK / "bulk_fetch.parquet"
    subprocess.run([*command, "--output", str(out), sql], check=True)
    frame = pd.read_parquet(out)
    out.unlink()
    return frame


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", type=int, default=1_000_000, help="rows fetched (default 1000000)")
    parser.add_argument("--runs", type=int, default=3, help="runs per path; the median is reported (default 3)")
    args = parse_args(parser, rows=20_000, runs=1)
    lake = build_lake(max(args.rows * len(JOBS), 200_000))
    sql = fetch_sql(args.rows)
    load_start = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    server = Server(lake, [])
    direct = direct_duckdb(lake)
    paths = {
        "trino client, direct protocol (JSON pages)": lambda: via_client(server, sql, None),
        **{f"trino client, spooling `{e}`": (lambda e=e: via_client(server, sql, e)) for e in ENCODINGS},
        "`POST /v1/arrow` (requests) -> pyarrow -> pandas": lambda: via_arrow_endpoint(server, sql),
        "`lakegate query --format arrow` (new process) -> pyarrow -> pandas": lambda: via_cli(lake, sql, "arrow"),
        "`lakegate query --format parquet --output F` -> pandas.read_parquet": lambda: via_cli(lake, sql, "parquet"),
        "baseline: DuckDB in this process, `.df()`": lambda: direct.execute(sql).df(),
    }
    seconds: dict[str, list[float]] = {name: [] for name in paths}
    try:
        for run in range(args.runs):
            for name, fetch in paths.items():  # alternate, so that load changes hit all paths alike
                start = time.perf_counter()
                frame = fetch()
                seconds[name].append(time.perf_counter() - start)
                if len(frame) != args.rows or list(frame.columns) != ["timestamp", "x", "y"]:
                    raise SystemExit(f"{name}: got {len(frame)} rows, columns {list(frame.columns)}")
            print(f"run {run + 1}/{args.runs} done", file=sys.stderr, flush=True)
    finally:
        server.stop()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    baseline = statistics.median(seconds["baseline: DuckDB in this process, `.df()`"])
    lines = [
        f"{args.rows:,} rows x 3 columns (bigint, double, double) of `{TOPIC}` into a pandas DataFrame, every path "
        f"in the same run, alternating; median of {args.runs} runs (wall-clock, the client's whole wait). Load "
        f"average (1, 5, 15 min) at the start {load_start}; at the end {load} (2 cores shared with other work).",
        "",
        "| path | median time | rows/s | vs baseline | runs (s) |",
        "|---|---:|---:|---:|---|",
    ]
    for name, runs in seconds.items():
        median = statistics.median(runs)
        lines.append(
            f"| {name} | {median:.2f} s | {args.rows / median:,.0f} | {median / baseline:.2f}x | "
            + ", ".join(f"{s:.2f}" for s in runs)
            + " |"
        )
    best = max(args.rows / statistics.median(seconds[name]) for name in paths if name.startswith("`"))
    lines += [
        "",
        f"- goal: >= {GOAL:,} rows/s into pandas by a documented path (docs/bulk-results.md): "
        f"**{'met' if best >= GOAL else 'NOT met'}** ({best:,.0f} rows/s)",
    ]
    write_section("Bulk fetch", "python3 dev.py bench bulk_fetch", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
