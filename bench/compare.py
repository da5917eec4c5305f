"""Build comparison benchmark: `lakegate compare` of two batches of 1,000 jobs each.

    python3 dev.py bench compare [--jobs N] [--runs K] [--smoke]

Builds (once per size, cached in bench/.work/compare/) a lake with two batches of N jobs (250
experiences run N/250 times each, builds 1.0 and 1.1). Each job has what `lakegate metrics run`
stores: a metadata row and the rows of `metric_results` of 3 test metrics (a scalar with a status,
a histogram of 200 values, a line of 200 points) plus a state timeline of 20 states, and 2 batch
metrics, written with the lake's own writers (lake/metadata.py, gateway/metrics/results_table.py) from
figures rendered by the templates. The new batch shifts some experiences' values and flips some
statuses, so every tag and many significant tests occur. Then measures, alternating, each in a
fresh process:

* lakegate: `compare_batches` (as `lakegate compare` calls it): the SQL of the pairing, tags and
  deltas through the Engine, flakes over the window, the figures read and every two-sample test;
* baseline: the same batches' `metric_results` files read with pyarrow, their figures parsed and
  the same SciPy tests run on every (experience, series metric) pair; no SQL, pairing or tags.

Also times `lakegate compare --format json` end to end (a subprocess, start-up included) once.
Reports the median seconds of each and the ratio. Writes section "Compare" of bench/RESULTS.md
(not with --smoke: 20 jobs, one run, nothing written). Goal: under 10 s for two 1,000-job batches.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import run_python, run_times, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "compare"
EXPERIENCES = 250
GOAL_SECONDS = 10.0
SAMPLES = 200

BUILD = """
import datetime as dt, sys
from pathlib import Path
import numpy as np
from lakegate.gateway.metrics.metric_result import MetricResult
from lakegate.gateway.metrics.results_table import ResultsWriter
from lakegate.gateway.metrics.templates import render
from lakegate.lake import paths
from lakegate.lake.metadata import build_metadata_row, stage_metadata_rows
from lakegate.lake.record import Change

lake, jobs, experiences, samples = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
start = dt.datetime(2026, 1, 1)
for side, (batch, build) in enumerate((("base", "1.0"), ("new", "1.1"))):
    rng = np.random.default_rng(side)
    rows, results = {}, []
    for index in range(jobs):
        experience = f"exp-{index % experiences:04d}"
        job = f"{batch}-{index:05d}"
        shifted = side == 1 and index % experiences < experiences // 10  # 10% of experiences drift
        mean = 4.0 + (1.5 if shifted else 0.0) + (2.0 if side == 1 and index % 97 == 0 else 0.0)
        values = rng.normal(mean, 1.0, samples)
        average = float(values.mean())
        status = "BLOCKER" if average > 6 else "WARNING" if average > 5 else "PASSED"
        states = [("IDLE", "RUN", "STOP")[int(v) % 3] for v in rng.integers(0, 3 if shifted else 2, 20)]
        moment = start + dt.timedelta(days=side, seconds=index)
        rows[job] = build_metadata_row(
            {"experience_name": experience, "build_version": build, "time": moment.isoformat(),
             "job_metrics_status": status, "job_conflated_status": status},
            lake=lake, branch="main", batch_id=batch, job_id=job)
        figures = [
            ("Mean", "scalar", [("v", "double")], [(average,)], status),
            ("Histogram", "histogram", [("v", "double")], [(float(v),) for v in values], "PASSED"),
            ("Line", "line", [("s", "varchar"), ("t", "bigint"), ("v", "double")],
             [("v", i, float(v)) for i, v in enumerate(values)], "PASSED"),
            ("Modes", "state_timeline", [("s", "varchar"), ("t", "bigint"), ("state", "varchar")],
             [("robot", i * 10**9, s) for i, s in enumerate(states)], "PASSED"),
        ]
        for name, template, columns, data, verdict in figures:
            results.append(MetricResult(name, "test", template, batch, job, verdict,
                                        rendered=render(name, template, columns, data)))
    for name, value in (("Batch mean", 4.0 + side), ("Jobs", float(jobs))):
        results.append(MetricResult(name, "batch", "scalar", batch, None, "PASSED",
                                    rendered=render(name, "scalar", [("v", "double")], [(value,)])))
    change = Change(lake, "main")
    with paths.staging(lake, "main") as scratch:
        stage_metadata_rows(change, scratch, batch, rows)
        change.commit(f"bench metadata {batch}")
    with ResultsWriter(lake, "main", batch, metrics_set=None, config_version=None,
                       evaluated_at=dt.datetime(2026, 1, 2)) as writer:
        writer.write(results)
        writer.commit()
print("{}")
"""

OURS = """
import json, sys, time
from lakegate.gateway.metrics.compare import compare_batches
from lakegate.gateway.metrics.evaluation import MetricsEngine
import scipy.stats  # imported before the clock starts, as for the baseline (the end-to-end run counts it)
engine = MetricsEngine(sys.argv[1])
started = time.perf_counter()
comparison = compare_batches(engine, "main", "base", "new")
seconds = time.perf_counter() - started
print(json.dumps({"seconds": seconds, "experiences": comparison.counts(), "metrics": comparison.metric_counts(),
                  "rows": len(comparison.metrics)}))
"""

BASELINE = """
import json, sys, time
from pathlib import Path
import orjson, pyarrow.parquet as pq
from scipy import stats
from lakegate.gateway.metrics.compare import SERIES_TEMPLATES, series_values, two_sample_test
lake = Path(sys.argv[1])
started = time.perf_counter()
sides = []
for batch in ("base", "new"):
    metadata = {}
    for path in (lake / "main" / "metadata" / f"batch_id={batch}").glob("*.parquet"):
        for row in pq.read_table(path, columns=["job_id", "experience_name"]).to_pylist():
            metadata[row["job_id"]] = row["experience_name"]
    values = {}
    for path in (lake / "main" / "metric_results" / f"batch_id={batch}").glob("*.parquet"):
        table = pq.read_table(path, columns=["job_id", "metric_name", "template", "figure_json"])
        for row in table.to_pylist():
            if row["template"] in SERIES_TEMPLATES and row["figure_json"]:
                key = (metadata[row["job_id"]], row["metric_name"], row["template"])
                values.setdefault(key, []).extend(series_values(row["template"], orjson.loads(row["figure_json"])))
    sides.append(values)
tests = [two_sample_test(key[2], sides[0][key], sides[1][key]) for key in sides[0].keys() & sides[1].keys()]
print(json.dumps({"seconds": time.perf_counter() - started, "tests": len(tests)}))
"""


def build(jobs: int) -> Path:
    lake = WORK / f"lake-{jobs}"
    if (lake / "main").exists():
        return lake
    shutil.rmtree(lake, ignore_errors=True)
    lake.mkdir(parents=True)
    run_python(BUILD, str(lake), str(jobs), str(min(EXPERIENCES, jobs)), str(SAMPLES))
    return lake


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=1000, help="jobs per batch (default 1000)")
    parser.add_argument("--runs", type=int, default=3, help="measured runs of each (default 3)")
    parser.add_argument("--smoke", action="store_true", help="20 jobs per batch, one run, RESULTS.md untouched")
    args = parser.parse_args()
    jobs, runs = (20, 1) if args.smoke else (args.jobs, args.runs)
    started = time.perf_counter()
    lake = build(jobs)
    print(f"lake of 2 x {jobs} jobs ready in {time.perf_counter() - started:.1f} s: {lake}", file=sys.stderr)
    ours, baseline = [], []
    for _ in range(runs):
        ours.append(run_python(OURS, str(lake)))
        baseline.append(run_python(BASELINE, str(lake)))
    cli_started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "lakegate.gateway.cli", "compare", "--lake", str(lake), "--branch", "main"]
        + ["--base", "base", "--batch", "new", "--format", "json"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    cli_seconds = time.perf_counter() - cli_started
    if done.returncode != 0:
        raise SystemExit(f"lakegate compare failed: {done.stderr}")
    cli_rows = len(json.loads(done.stdout)["metrics"])
    median = statistics.median(r["seconds"] for r in ours)
    base_median = statistics.median(r["seconds"] for r in baseline)
    first = ours[0]
    experiences = min(EXPERIENCES, jobs)
    lines = [
        f"Two batches of {jobs:,} jobs ({experiences} experiences, each run {jobs // experiences} "
        f"times per batch), each job with 4 test metrics (scalar with status, histogram and line of {SAMPLES} values, "
        "state timeline of 20 states) and 2 batch metrics, written with the lake's writers. "
        f"Median of {runs} alternating runs, each in a fresh process.",
        "",
        "| | median time | per batch pair |",
        "|---|---|---|",
        f"| lakegate `compare_batches` (SQL pairing, tags, deltas, flakes; figures read; "
        f"{first['metrics']['significant']} significant of the two-sample tests) | {median:.2f} s | "
        f"{first['rows']:,} metric rows |",
        f"| baseline: pyarrow reads the results files, parses the figures, runs the same SciPy tests | "
        f"{base_median:.2f} s | {baseline[0]['tests']:,} tests |",
        "",
        f"- goal: two 1,000-job batches compared in < {GOAL_SECONDS:.0f} s: "
        f"**{'met' if median < GOAL_SECONDS else 'not met'}** ({median:.2f} s)",
        f"- lakegate / baseline: {median / base_median:.2f}x (the rest: SQL through the Engine, flake scores, tags)",
        f"- `lakegate compare --format json` end to end (start-up included): {cli_seconds:.2f} s, {cli_rows:,} rows",
        f"- experiences by tag: {first['experiences']}",
        f"- all runs (s): lakegate {run_times(ours)}; baseline {run_times(baseline)}; "
        f"load average at the end {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores",
    ]
    if args.smoke:
        print("\n".join(lines))
        return 0
    write_section("Compare", f"python3 dev.py bench compare --jobs {jobs} --runs {runs}", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
