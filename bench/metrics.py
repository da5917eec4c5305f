"""Metrics benchmark: evaluate a 10-metric set over a batch of 100 jobs of about 100k rows each.

    python3 dev.py bench metrics [--jobs N] [--rows-per-job R] [--runs K]

Builds (once, cached in bench/.work/metrics/) a lake with one batch of simulated navigation jobs
(fixtures/generate.py, `samples_per_goal` chosen for about R topic rows per job). Then measures,
alternating, each in a fresh process:

* lakegate: `MetricsEngine.evaluate_batch` (as `lakegate metrics run` calls it) of 10 metrics of the
  example config (7 test metrics:
  two line charts, two scalars with status checks, a table, a state timeline, a histogram; 3
  batch metrics: a scalar, a bar chart joining metadata, the tag-group table) -- translation,
  per-job scopes, DuckDB, rendering, statuses, metadata updates and the stored results table;
* baseline: the same queries (their DuckDB SQL, translated beforehand and not timed; a status check's
  warn query when its block query finds no row, as lakegate judges it) run with the
  same 2 threads, each job's on that job's own views (of the tables its queries read) over only its
  files (made by the same code lakegate uses, timed), the batch metrics on the batch's views, each
  result fetched as Arrow;
  nothing translated, rendered, judged or stored.

Reports the median seconds of each, jobs per second, the ratio, and the peak RSS of the
process. Writes section "Metrics" of bench/RESULTS.md. Goal: the whole batch in under 30 s on
2 cores, memory under 2 GB.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, run_python, run_times, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "metrics"
BATCH = "bench"
GOAL_SECONDS, GOAL_MB = 30.0, 2048
#: The 10 metrics of the example config evaluated (test metrics first, then batch metrics).
METRICS = (
    "Robot Speed",
    "Time to reach final goal",
    "Maximum Localization Error (job)",
    "Distance to Goal",
    "AMCL Covariance Calibration",
    "Goal Status",
    "Speed Distribution",
    "Average Speed",
    "Maximum Localization Error",
    "Passed Jobs by Tag Group",
)

OURS = """
import json, sys, time, resource
from pathlib import Path
from lakegate.fixtures.generate import CONFIG_PATH
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.lake.config import load_config
config = load_config(CONFIG_PATH)
metrics = [config.metrics[name] for name in json.loads(sys.argv[2])]
start = time.perf_counter()
with MetricsEngine(Path(sys.argv[1])) as engine:
    evaluation = engine.evaluate_batch("main", sys.argv[3], metrics, metrics_set="bench", keep_figures=False)
seconds = time.perf_counter() - start
statuses = {}
for job in evaluation.jobs:
    statuses[job.conflated_status] = statuses.get(job.conflated_status, 0) + 1
print(json.dumps({"seconds": seconds, "jobs": len(evaluation.jobs), "results": len(evaluation.results()),
                  "errors": evaluation.count("ERROR"), "statuses": statuses,
                  "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

BASELINE = """
import json, sys, time, resource
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from lakegate.dialect.scope import Scope
from lakegate.fixtures.generate import CONFIG_PATH
from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.lake.config import load_config
config = load_config(CONFIG_PATH)
metrics = [config.metrics[name] for name in json.loads(sys.argv[2])]
batch = sys.argv[3]
backend = DuckDBBackend(Path(sys.argv[1]))
jobs = [row[0] for row in backend.execute("SELECT job_id FROM metadata ORDER BY job_id", branch="main",
                                          scope=Scope(batch)).rows()]
queries = []  # (scope, DuckDB SQL of each query and status query) per job, then the batch metrics
for job in jobs:
    scope = Scope(batch, job)
    sql = [scope]
    for m in metrics:
        if m.type != "test":
            continue
        sql.append(backend.translate(m.query_string, branch="main", scope=scope).duckdb_sql)
        if m.status is not None:  # (block query, warn query run when the block query finds no row)
            block, warn = ((backend.translate(m.status.query_string, branch="main", scope=scope,
                                              params=(threshold,)).duckdb_sql if threshold is not None else None)
                           for threshold in (m.status.block, m.status.warn))
            sql.append((block, warn))
    queries.append(sql)
queries.append([Scope(batch)] + [backend.translate(m.query_string, branch="main", scope=Scope(batch)).duckdb_sql
                                   for m in metrics if m.type != "test"])
def run(sql_list):
    cursor = backend.connection("main")
    # the scope's own views of the tables its queries read, over only its files, as lakegate reads them
    # (made here by the same code, timed)
    state = backend._state("main")
    texts = [text for sql in sql_list[1:] for text in ([sql] if isinstance(sql, str) else sql) if text]
    tables = set().union(*(backend._tables(state, text) for text in texts))
    cursor.execute(f"SET search_path = '{backend._scope_views(state, 'main', sql_list[0], tables)}'")
    rows = 0
    for sql in sql_list[1:]:
        if isinstance(sql, str):
            rows += cursor.sql(sql).to_arrow_table().num_rows
            continue
        block, warn = sql  # a status check: the warn query runs when the block query found no row
        found = cursor.sql(block).to_arrow_table().num_rows
        if not found and warn is not None:
            found = cursor.sql(warn).to_arrow_table().num_rows
        rows += found
    cursor.close()
    return rows
start = time.perf_counter()
with ThreadPoolExecutor(2) as pool:
    rows = sum(pool.map(run, queries[:-1]))
rows += run(queries[-1])
seconds = time.perf_counter() - start
print(json.dumps({"seconds": seconds, "jobs": len(jobs), "rows": rows,
                  "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def prepare(jobs: int, rows_per_job: int) -> tuple[Path, int]:
    """The cached lake with one batch of `jobs` generated jobs, and its total topic rows."""
    lake = WORK / f"lake-{jobs}x{rows_per_job}"
    ready = lake / "ready.json"
    if ready.exists():
        return lake, json.loads(ready.read_text())["rows"]
    from lakegate.fixtures.generate import CONFIG_PATH, generate_batch
    from lakegate.lake.branch_configs import BranchConfigs
    from lakegate.lake.config import load_config
    from lakegate.lake.ingest import ingest_job
    from lakegate.lake.metadata import load_metadata_file

    shutil.rmtree(lake, ignore_errors=True)
    config = load_config(CONFIG_PATH)
    BranchConfigs(lake, "main").store([CONFIG_PATH])
    # 6 rows per sample and 3 goals, but a BLOCKER job (every third) stops after 2.1 goals on average
    samples_per_goal = max(2, round(rows_per_job / (18 * 0.9)))
    scratch = WORK / "inputs"
    total, seed = 0, 0
    started = time.perf_counter()
    print(f"building {lake} ({jobs} jobs of about {rows_per_job:,} rows; cached for later runs) ...", flush=True)
    while jobs > 0:
        shutil.rmtree(scratch, ignore_errors=True)
        generated = generate_batch(scratch, jobs=min(6, jobs), seed=1000 + seed, samples_per_goal=samples_per_goal)
        for job in generated:
            report = ingest_job(
                lake,
                "main",
                BATCH,
                job.job_id,
                [job.emissions_path],
                config=config,
                metadata=load_metadata_file(job.metadata_path),
            )
            total += sum(report.rows.values())
        jobs -= len(generated)
        seed += 1
        print(f"  {total:,} rows so far, {time.perf_counter() - started:.0f} s", flush=True)
    shutil.rmtree(scratch, ignore_errors=True)
    ready.write_text(json.dumps({"rows": total}))
    return lake, total


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=100, help="jobs in the batch (default 100)")
    parser.add_argument("--rows-per-job", type=int, default=100_000, help="topic rows per job (default 100,000)")
    parser.add_argument("--runs", type=int, default=3, help="measured runs of each side (default 3)")
    args = parse_args(parser, jobs=3, rows_per_job=1_000, runs=1)
    lake, total_rows = prepare(args.jobs, args.rows_per_job)
    names = json.dumps(list(METRICS))
    runs: dict[str, list[dict]] = {"lakegate": [], "baseline": []}
    for i in range(args.runs):
        for name, code in (("baseline", BASELINE), ("lakegate", OURS)):
            result = run_python(code, str(lake), names, BATCH)
            runs[name].append(result)
            print(
                f"run {i + 1}: {name:<8} {result['seconds']:.2f} s, {result['jobs'] / result['seconds']:.1f} jobs/s, "
                f"peak RSS {result['rss_mb']:.0f} MB",
                flush=True,
            )
    ours = runs["lakegate"]
    assert all(r["jobs"] == args.jobs and r["errors"] == 0 for r in ours), ours[0]
    median = {name: statistics.median(r["seconds"] for r in results) for name, results in runs.items()}
    rss = {name: max(r["rss_mb"] for r in results) for name, results in runs.items()}
    ratio = median["lakegate"] / median["baseline"]
    met = median["lakegate"] < GOAL_SECONDS and rss["lakegate"] < GOAL_MB
    lines = [
        f"Batch of {args.jobs} jobs, {total_rows:,} topic rows in all (about {args.rows_per_job:,} per job; "
        "generated by fixtures/generate.py, ingested once and cached). Metrics set of 10 metrics of "
        f"`fixtures/config.resim.yaml`: 7 test metrics per job ({', '.join(METRICS[:7])}), "
        f"3 batch metrics ({', '.join(METRICS[7:])}): {ours[0]['results']} evaluated metrics per run. "
        f"Median of {args.runs} alternating runs, each in a fresh process; 2 threads.",
        "",
        "| | median time | jobs/s | end-to-end (with start-up) | CPU (user+sys) | peak RSS |",
        "|---|---|---|---|---|---|",
    ]
    labels = {
        "lakegate": "lakegate `MetricsEngine.evaluate_batch` (translate, scope, run, render, judge, store)",
        "baseline": "bare DuckDB: the same queries' SQL, translated beforehand, results fetched as Arrow",
    }
    for name in ("lakegate", "baseline"):
        results = runs[name]
        lines.append(
            f"| {labels[name]} | {median[name]:.2f} s | {args.jobs / median[name]:.1f} | "
            f"{statistics.median(r['wall'] for r in results):.2f} s | "
            f"{statistics.median(r['cpu'] for r in results):.2f} s | {rss[name]:.0f} MB |"
        )
    lines += [
        "",
        f"- goal: the whole batch in < {GOAL_SECONDS:.0f} s and < {GOAL_MB / 1024:.0f} GB: "
        f"**{'met' if met else 'NOT met'}** ({median['lakegate']:.1f} s, {rss['lakegate']:.0f} MB)",
        f"- lakegate / bare DuckDB time: {ratio:.2f}x (the rest is each job's scope views, cursors, "
        "rendering, judging, metadata updates and writing the results; each metric is translated once per run)",
        f"- fastest run {min(r['seconds'] for r in ours):.1f} s; CPU time (all threads) "
        f"{statistics.median(r['cpu'] for r in ours):.1f} s, i.e. at least "
        f"{statistics.median(r['cpu'] for r in ours) / (os.cpu_count() or 1):.1f} s of wall-clock time on "
        f"{os.cpu_count()} idle cores",
        f"- job statuses: {ours[0]['statuses']}",
        f"- all runs (s): lakegate {run_times(ours)}; baseline {run_times(runs['baseline'])}; load average at the end "
        f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores",
    ]
    write_section("Metrics", "python3 dev.py bench metrics", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
