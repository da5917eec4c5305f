"""lakegate against Trino 476: the same queries over the same Parquet files through the same client.

    python3 dev.py bench vs_trino [--smoke] [--runs R] [--trino-url URL]

Needs a running Trino 476 (`python3 dev.py trino start`; its URL from tools/trino_server.py unless
--trino-url). Builds (once, cached in bench/.work/vs_trino/) two lakes:

* the metrics lake: one batch of 40 generated jobs of the example config (bench/metrics.py's
  builder, about 5,000 topic rows per job);
* the ad hoc lake: bench/translate.py's builder, 10 jobs whose `odom_linear_velocity` holds
  1,000,000 generated rows in all.

Registers both in Trino's hive catalog with `lakegate trino-ddl --apply` (dropped again at the end
with `--drop`), starts `lakegate serve` of each on 127.0.0.1 (embedded DuckDB, 2 threads), and
sends the very same SQL text through the official `trino` client (one connection each, `fetchall`)
to lakegate and to Trino, alternating run by run:

* the metrics workload: every test metric of fixtures/config.resim.yaml (and its status query) for
  each job (answers compared on the first job's), scoped to the job as `lakegate metrics run --backend trino` sends it
  (`(SELECT * FROM t WHERE batch_id = 'B' AND job_id = 'J') t`), then the batch metrics scoped to
  the batch: the queries one after another, the whole workload timed;
* ad hoc: `SELECT 1` (median of 20 per run), a scan-aggregate of the 1,000,000-row topic, a join of
  it with `metadata`, and a fetch of all its 1,000,000 rows (3 columns).

Every other answer is checked equal on both (as multisets of rows, doubles to 9 significant digits)
before it is timed. Writes section "lakegate vs Trino" of bench/RESULTS.md (--smoke: 2 jobs,
20,000 rows, one run, printed only): the median of each figure on
both, the ratio lakegate / Trino, machine, versions, command and load average.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import time
import uuid
from pathlib import Path
from urllib.parse import urlsplit

import trino

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import metrics as metrics_bench  # noqa: E402
import translate as adhoc_bench  # noqa: E402
import trino_server  # noqa: E402
from results import write_section  # noqa: E402
from server import Server  # noqa: E402

from lakegate.dialect.scope import Scope  # noqa: E402
from lakegate.fixtures.generate import CONFIG_PATH  # noqa: E402
from lakegate.gateway.engine.trino_backend import forwarded_sql  # noqa: E402
from lakegate.gateway.engine.trino_registration import read_registration  # noqa: E402
from lakegate.lake.catalog import Catalog  # noqa: E402
from lakegate.lake.config import load_config  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "vs_trino"
CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
TOPIC = adhoc_bench.TOPIC
ADHOC = [
    ("scan-aggregate", f"SELECT job_id, count(*), avg(x), min(y), max(x) FROM {TOPIC} GROUP BY job_id"),
    (
        "join with metadata",
        f"SELECT m.experience_name, count(*), avg(o.x) FROM {TOPIC} o JOIN metadata m "
        "ON o.job_id = m.job_id AND o.batch_id = m.batch_id GROUP BY m.experience_name",
    ),
]


def lakegate(*args: object) -> str:
    done = subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=1800)
    if done.returncode != 0:
        raise SystemExit(f"lakegate {' '.join(map(str, args[:2]))} failed: {done.stderr.strip()}")
    return done.stdout


def metric_workload(lake: Path, batch: str) -> tuple[list[str], list[str]]:
    """The Trino SQL of every test metric (and status query) per job, then every batch metric; and
    the queries whose answers are compared (the first job's and the batch metrics')."""
    config = load_config(CONFIG_PATH)
    catalog = Catalog(lake)
    tables = set(catalog.schema("main"))
    jobs = [job.job_id for job in catalog.jobs("main", batch)]
    chosen = [m for m in config.metrics.values() if m.type in ("test", "batch")]

    def text(sql: str, scope: Scope, params: tuple = ()) -> str:
        return forwarded_sql(sql, scope=scope, params=params, tables=tables).sql

    queries = []
    for job in jobs:
        for metric in (m for m in chosen if m.type == "test"):
            queries.append(text(metric.query_string, Scope(batch, job)))
            if metric.status is not None:
                queries.append(text(metric.status.query_string, Scope(batch, job), (metric.status.block,)))
    per_job = len(queries) // len(jobs)
    batch_queries = [text(m.query_string, Scope(batch)) for m in chosen if m.type == "batch"]
    return queries + batch_queries, queries[:per_job] + batch_queries


class Client:
    """One `trino` client connection to a server, in a catalog and schema."""

    def __init__(self, url: str, catalog: str, schema: str):
        parts = urlsplit(url)
        self.connection = trino.dbapi.connect(
            host=parts.hostname, port=parts.port, user="bench", catalog=catalog, schema=schema, source="vs_trino"
        )

    def rows(self, sql: str) -> list:
        cursor = self.connection.cursor()
        cursor.execute(sql)
        return cursor.fetchall()

    def by_name(self, sql: str) -> list:
        """The rows with their columns in name order (`SELECT *` puts `batch_id` last in Trino)."""
        cursor = self.connection.cursor()
        cursor.execute(sql)
        rows = cursor.fetchall()
        order = sorted(range(len(cursor.description)), key=lambda i: cursor.description[i][0])
        return [[row[i] for i in order] for row in rows]

    def seconds(self, queries: list[str]) -> float:
        start = time.perf_counter()
        for sql in queries:
            self.rows(sql)
        return time.perf_counter() - start


def _canonical(value: object) -> object:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else float(f"{value:.9g}")
    if isinstance(value, (list, tuple)):
        return tuple(_canonical(v) for v in value)
    if isinstance(value, dict):
        return tuple(sorted((repr(k), _canonical(v)) for k, v in value.items()))
    return value


def check_same(sql: str, ours: list, theirs: list) -> None:
    """Both answers as the same multiset of rows (doubles to 9 significant digits), else stop."""
    a = sorted((_canonical(r) for r in ours), key=repr)
    b = sorted((_canonical(r) for r in theirs), key=repr)
    if a != b:
        raise SystemExit(f"lakegate and Trino answer differently:\n{sql}\nlakegate: {a[:5]}\nTrino:    {b[:5]}")


def register(lake: Path, url: str, prefix: str) -> str:
    """Register branch main of `lake` in Trino under `prefix`; its schema."""
    lakegate("trino-ddl", "--lake", lake, "--apply", "--trino-url", url, "--schema-prefix", prefix)
    return read_registration(lake, url).schemas["main"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--smoke", action="store_true", help="small sizes, one run, printed only: checks that the script works"
    )
    parser.add_argument("--runs", type=int, default=5, help="alternating runs per figure (default 5)")
    parser.add_argument("--trino-url", help="the Trino 476 to compare with (default: the one dev.py trino started)")
    args = parser.parse_args()
    state = trino_server.running()
    url = args.trino_url or (state or {}).get("url")
    if not url:
        raise SystemExit("needs a running Trino 476: python3 dev.py trino start")
    jobs, rows_per_job, rows, runs = (2, 500, 20_000, 1) if args.smoke else (40, 5_000, 1_000_000, args.runs)
    started = time.perf_counter()
    WORK.mkdir(parents=True, exist_ok=True)
    metrics_bench.WORK = WORK / "metrics"
    adhoc_bench.WORK = WORK / f"adhoc-{rows}"
    metrics_lake, topic_rows = metrics_bench.prepare(jobs, rows_per_job)
    adhoc_lake = adhoc_bench.build_lake(rows)
    prefix = f"bench_{uuid.uuid4().hex[:6]}_"
    schemas = {
        "metrics": register(metrics_lake, url, prefix + "m_"),
        "adhoc": register(adhoc_lake, url, prefix + "a_"),
    }
    servers = {
        name: Server(lake, ["--threads", "2"]) for name, lake in (("metrics", metrics_lake), ("adhoc", adhoc_lake))
    }
    try:
        clients = {
            (name, side): Client(f"http://127.0.0.1:{servers[name].port}", "lake", "main")
            if side == "lakegate"
            else Client(url, "hive", schemas[name])
            for name in servers
            for side in ("lakegate", "trino")
        }
        workload, compared = metric_workload(metrics_lake, metrics_bench.BATCH)
        fetch = f"SELECT timestamp, x, y FROM {TOPIC}"
        figures: dict[str, tuple[str, list[str]]] = {
            f"metrics workload ({len(workload)} queries, {jobs} jobs)": ("metrics", workload),
            "SELECT 1 (per query)": ("adhoc", ["SELECT 1"] * 20),
            **{name: ("adhoc", [sql]) for name, sql in ADHOC},
            f"fetch {rows:,} rows x 3 columns": ("adhoc", [fetch]),
        }
        for name, (lake_name, queries) in figures.items():  # equal answers first (and warm caches)
            for sql in dict.fromkeys(compared if name.startswith("metrics") else queries):
                check_same(sql, clients[lake_name, "lakegate"].by_name(sql), clients[lake_name, "trino"].by_name(sql))
        times: dict[str, dict[str, list[float]]] = {name: {"lakegate": [], "trino": []} for name in figures}
        for run in range(runs):
            for name, (lake_name, queries) in figures.items():
                sides = ("lakegate", "trino") if run % 2 == 0 else ("trino", "lakegate")
                for side in sides:
                    seconds = clients[lake_name, side].seconds(queries)
                    times[name][side].append(seconds / len(queries) if name.startswith("SELECT 1") else seconds)
            print(f"run {run + 1}/{runs} done, {time.perf_counter() - started:.0f} s", flush=True)
    finally:
        for server in servers.values():
            server.stop()
        for lake in (metrics_lake, adhoc_lake):
            lakegate("trino-ddl", "--lake", lake, "--drop", "--trino-url", url)
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    java = subprocess.run(
        [str(trino_server.java_home() / "bin" / "java"), "-version"], capture_output=True, text=True
    ).stderr.splitlines()[0]
    lines = [
        f"- Trino 476 at {url} (single node, heap 2 GB, hive catalog over the same Parquet files through "
        f"`lakegate trino-ddl --apply`; {java}) vs `lakegate serve` (embedded DuckDB, 2 threads); "
        "both through the `trino` Python client, one connection each; the first job's metric answers, "
        "the batch metrics' and every ad hoc answer checked equal first",
        f"- metrics lake: 1 batch of {jobs} jobs, {topic_rows:,} topic rows; ad hoc lake: 10 jobs, "
        f"`{TOPIC}` of {rows:,} rows",
        f"- median of {runs} alternating run(s); ratio = lakegate / Trino (below 1: lakegate is faster); "
        f"load average at the end: {load} on {os.cpu_count()} cores (shared with other work)",
        "",
        "| figure | lakegate | Trino 476 | ratio | runs (lakegate / Trino) |",
        "|---|---:|---:|---:|---|",
    ]
    for name, sides in times.items():
        ours, theirs = statistics.median(sides["lakegate"]), statistics.median(sides["trino"])
        unit = 1000.0
        lines.append(
            f"| {name} | {ours * unit:,.1f} ms | {theirs * unit:,.1f} ms | {ours / theirs:.2f}x | "
            + ", ".join(f"{t * unit:,.0f}" for t in sides["lakegate"])
            + " / "
            + ", ".join(f"{t * unit:,.0f}" for t in sides["trino"])
            + " |"
        )
    lines += ["", f"(benchmark took {time.perf_counter() - started:.0f} s)"]
    if args.smoke:  # checks the script; its figures are not results
        print("\n".join(lines))
        return 0
    write_section("lakegate vs Trino", f"python3 dev.py bench vs_trino --runs {runs}", lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
