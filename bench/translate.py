"""Translation benchmark: how long translating a metric query takes, and what the translated SQL
costs at run time against hand-written DuckDB SQL.

    python3 dev.py bench translate [--rows N] [--runs R]

1. Translation time of every query (and status query) of fixtures/config.resim.yaml, with the
   scope its metric type implies: cold (translation cache cleared before each call) and cached
   (the same call repeated), medians.
2. Execution on a topic of N rows (default 10M, in 10 jobs of 2 batches, written once as real Parquet
   in the lake layout under bench/.work/translate/N/): each typical metric query run through
   `DuckDBBackend.execute` (scope rewrite + translation + DuckDB, result streamed as Arrow batches)
   against hand-written DuckDB SQL over the same views, run the same way; median of R runs each,
   alternating; wall-clock and CPU time (all threads), the latter less disturbed by other processes.
   Writes section "Translation" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import shutil
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import median_of, parse_args, timed, write_section  # noqa: E402

from lakegate.dialect import translate as translate_module  # noqa: E402
from lakegate.dialect.scope import Scope  # noqa: E402
from lakegate.gateway.engine.backend import BATCH_ROWS, DuckDBBackend  # noqa: E402
from lakegate.lake import paths  # noqa: E402
from lakegate.lake.catalog import Catalog  # noqa: E402
from lakegate.lake.config import load_config  # noqa: E402
from lakegate.lake.ingest import ingest_job  # noqa: E402
from lakegate.lake.record import Change, current_file  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "translate"
CONFIG = ROOT / "fixtures" / "config.resim.yaml"
TOPIC = "odom_linear_velocity"
JOBS = [(f"b{1 + i // 5}", f"j{i}") for i in range(10)]
GOALS = {"cached_us": 50.0, "cold_ms": 5.0, "ratio": 1.1}

#: (name, Trino metric query, scope, hand-written DuckDB SQL over the same views)
EXECUTION = [
    (
        "aggregate (batch)",
        f"SELECT AVG(x), MAX(y), COUNT(*) FROM {TOPIC}",
        Scope(batch_id="b1"),
        f"SELECT avg(x), max(y), count(*) FROM {TOPIC} WHERE batch_id = 'b1'",
    ),
    (
        "line chart projection (job)",
        f'SELECT \'Speed\', timestamp / 1E9 AS "Time (s)", SQRT(POWER(x, 2) + POWER(y, 2)) AS "Speed (m/s)" '
        f"FROM {TOPIC}",
        Scope(batch_id="b1", job_id="j0"),
        f'SELECT \'Speed\', timestamp / 1e9 AS "Time (s)", sqrt(pow(x, 2) + pow(y, 2)) AS "Speed (m/s)" '
        f"FROM {TOPIC} WHERE batch_id = 'b1' AND job_id = 'j0'",
    ),
    (
        "join with metadata (batch)",
        f"SELECT m.experience_name, MIN(x), AVG(x), MAX(x) FROM {TOPIC} d JOIN metadata m ON d.job_id = m.job_id "
        "GROUP BY m.experience_name",
        Scope(batch_id="b1"),
        f"SELECT m.experience_name, min(x), avg(x), max(x) FROM {TOPIC} d JOIN metadata m ON d.job_id = m.job_id "
        "WHERE d.batch_id = 'b1' AND m.batch_id = 'b1' GROUP BY m.experience_name",
    ),
]


def build_lake(rows: int) -> Path:
    """The bench lake of `rows` rows (bench/.work/translate/<rows>/lake): the example config, 10 jobs
    ingested, then each job's topic file replaced by rows/10 generated rows of the same Arrow schema,
    published through the lake's record as ingest publishes. Built once per size, under a file lock, so
    benches started together (the smoke tests run in parallel) share it instead of clobbering it."""
    WORK.mkdir(parents=True, exist_ok=True)
    with open(WORK / f"{rows}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return _build_once(WORK / str(rows), rows)


def _build_once(work: Path, rows: int) -> Path:
    lake = work / "lake"
    ready = work / "READY"
    if ready.exists():
        return lake
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    config = load_config([CONFIG])
    seed = work / "seed.jsonl"
    seed.write_text(
        json.dumps({"$metadata": {"topic": TOPIC, "timestamp": 0}, "$data": {"x": 0.0, "y": 0.0, "z": 0.0}}) + "\n"
    )
    generator = np.random.default_rng(7)
    per_job = rows // len(JOBS)
    for i, (batch, job) in enumerate(JOBS):
        ingest_job(
            lake,
            "main",
            batch,
            job,
            [seed],
            config=config,
            metadata={"experience_name": f"experience {i % 3}", "build_version": "1.0"},
        )  # metadata, configs
        target = current_file(lake, "main", TOPIC, batch, job)
        seeded = pq.read_table(target)  # one row: the job's own columns hold what ingest gave them
        schema = seeded.schema
        columns = {
            "timestamp": pa.array(np.arange(per_job, dtype=np.int64) * 10_000_000),
            "x": pa.array(generator.normal(1.0, 0.5, per_job)),
            "y": pa.array(generator.normal(0.0, 0.2, per_job)),
            "z": pa.array(np.zeros(per_job)),
        }
        table = pa.table(
            {f.name: columns[f.name] if f.name in columns else pa.repeat(seeded[f.name][0], per_job) for f in schema},
            schema=schema,
        )
        scratch = work / f"{job}.parquet"
        pq.write_table(table, scratch, row_group_size=1_000_000)
        with paths.job_lock(lake, "main", batch, job):
            change = Change(lake, "main")
            change.add(TOPIC, batch, job, scratch)
            change.commit(f"bench data of {batch}/{job}")
    ready.write_text(str(rows))
    return lake


def metric_queries() -> list[tuple[str, str, Scope, list]]:
    """(name, SQL, scope, params) of every query and status query of the example config."""
    queries = []
    for metric in load_config([CONFIG]).metrics.values():
        scope = Scope(batch_id="b1", job_id="j0") if metric.type == "test" else Scope(batch_id="b1")
        queries.append((metric.name, metric.query_string, scope, []))
        if metric.status is not None:
            queries.append((f"{metric.name} (status)", metric.status.query_string, scope, [metric.status.block]))
    return queries


def translation_times(schema: dict, runs: int) -> tuple[list[str], dict[str, list[float]]]:
    """Per query: cold (every cache cleared, so the schema's types are parsed again), new text
    (a text not seen yet, schema types cached: what a new query costs in a running gateway), and
    cached (the same call again)."""
    lines = ["| query | cold (ms) | new text (ms) | cached (µs) |", "|---|---:|---:|---:|"]
    figures: dict[str, list[float]] = {"cold": [], "new": [], "cached": []}
    counter = iter(range(10**9))
    for name, sql, scope, params in metric_queries():

        def call(text: str = sql, scope=scope, params=params) -> None:
            translate_module.translate(text, schema, scope=scope, params=params, schema_version="v")

        def cold(call=call) -> float:
            translate_module.clear_cache()
            return timed(call)

        def new_text(call=call, sql=sql) -> float:
            call()
            text = f"-- {next(counter)}\n{sql}"
            return timed(lambda: call(text))

        def cached(repeat: int = 2000, call=call) -> float:
            call()
            return timed(lambda: [call() for _ in range(repeat)]) / repeat

        medians = {
            "cold": median_of(max(runs, 9), cold)[0],
            "new": median_of(max(runs, 9), new_text)[0],
            "cached": median_of(runs, cached)[0],
        }
        for key, value in medians.items():
            figures[key].append(value)
        lines.append(
            f"| {name} | {medians['cold'] * 1e3:.2f} | {medians['new'] * 1e3:.2f} | {medians['cached'] * 1e6:.1f} |"
        )
    return lines, figures


def consume(result_batches) -> int:
    return sum(batch.num_rows for batch in result_batches)


def wall_and_cpu(fn) -> tuple[float, float]:
    """Wall-clock seconds and CPU seconds (all threads of this process) of one call of `fn`."""
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def execution_ratios(backend: DuckDBBackend, runs: int) -> tuple[list[str], float, float]:
    """Per typical query: medians of wall and CPU time, translated vs hand-written, and their ratios
    (the CPU ratio is less disturbed by other processes on a busy machine)."""
    lines = [
        "| query | rows out | translated (ms) | hand-written DuckDB (ms) | wall ratio | CPU ratio |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    worst_wall = worst_cpu = 0.0
    for name, sql, scope, hand in EXECUTION:

        def ours(sql=sql, scope=scope) -> int:
            return consume(backend.execute(sql, scope=scope).batches)

        def theirs(hand=hand) -> int:
            cursor = backend.connection("main")
            try:
                return consume(cursor.sql(hand).to_arrow_reader(BATCH_ROWS))
            finally:
                cursor.close()

        rows_out = ours()
        if theirs() != rows_out:
            raise SystemExit(f"{name}: translated and hand-written SQL return different row counts")
        figures: dict[str, list[tuple[float, float]]] = {"ours": [], "theirs": []}
        for run in range(runs):  # alternate which goes first, so that both see the same cache state
            for key, fn in sorted((("ours", ours), ("theirs", theirs)), reverse=bool(run % 2)):
                figures[key].append(wall_and_cpu(fn))
        (ours_wall, ours_cpu), (theirs_wall, theirs_cpu) = (
            (statistics.median(w for w, _ in figures[k]), statistics.median(c for _, c in figures[k]))
            for k in ("ours", "theirs")
        )
        worst_wall = max(worst_wall, ours_wall / theirs_wall)
        worst_cpu = max(worst_cpu, ours_cpu / theirs_cpu)
        lines.append(
            f"| {name} | {rows_out:,} | {ours_wall * 1e3:.1f} | {theirs_wall * 1e3:.1f} | "
            f"{ours_wall / theirs_wall:.3f} | {ours_cpu / theirs_cpu:.3f} |"
        )
    return lines, worst_wall, worst_cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rows", type=int, default=10_000_000, help="rows of the benchmark topic (default 10M)")
    parser.add_argument(
        "--runs",
        type=int,
        default=15,
        help="runs per measurement; the median is reported (default 15: a query takes tens of ms)",
    )
    args = parse_args(parser, rows=20_000, runs=2)
    started = time.perf_counter()
    lake = build_lake(args.rows)
    schema = Catalog(lake).schema("main")
    translation_lines, figures = translation_times(schema, args.runs)
    backend = DuckDBBackend(lake, memory_limit="2GB", threads=2)
    try:
        execution_lines, worst_wall, worst_cpu = execution_ratios(backend, args.runs)
    finally:
        backend.close()
    cold, new, cached = (statistics.median(figures[k]) for k in ("cold", "new", "cached"))
    summary = [
        f"- translation of the {len(figures['cold'])} queries and status queries of fixtures/config.resim.yaml "
        f"(each with its test/batch scope and threshold), medians over the queries: cold {cold * 1e3:.2f} ms "
        f"(slowest query {max(figures['cold']) * 1e3:.2f} ms), new text with the schema's types cached "
        f"{new * 1e3:.2f} ms (slowest {max(figures['new']) * 1e3:.2f} ms); goal < {GOALS['cold_ms']:.0f} ms. "
        f"Cached {cached * 1e6:.1f} µs (slowest {max(figures['cached']) * 1e6:.1f} µs); "
        f"goal < {GOALS['cached_us']:.0f} µs",
        f"- execution on a {args.rows:,}-row topic ({len(JOBS)} jobs of Parquet, 2 threads), translated through "
        f"`DuckDBBackend.execute` vs hand-written DuckDB SQL on the same views, both streamed as Arrow batches, "
        f"median of {args.runs} alternating runs: worst ratio {worst_wall:.3f} in wall-clock time, {worst_cpu:.3f} "
        f"in CPU time (goal <= {GOALS['ratio']}; load average when done: {os.getloadavg()[0]:.1f} "
        f"on {os.cpu_count()} cores)",
        "",
        *translation_lines,
        "",
        *execution_lines,
        "",
        f"(benchmark took {time.perf_counter() - started:.0f} s)",
    ]
    write_section("Translation", "python3 dev.py bench translate", summary)


if __name__ == "__main__":
    main()
