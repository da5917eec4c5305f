"""Ingest benchmark: `lakegate` ingestion (validation on) against DuckDB's own `read_json` + `COPY ... TO parquet`.

    python3 dev.py bench ingest [--lines N] [--runs R]

Generates (once, cached in bench/.work/ingest/) an emissions file of realistic topics of the
example config (odometry, goals, covariance, states, images, events with metrics), then
measures, alternating, in fresh subprocesses: `ingest_job` of the whole file into a new
lake, and DuckDB reading the same file with `read_json` and writing it to one Parquet file
without any validation. Rows per second use the time of the operation itself (interpreter
start-up excluded for both; the end-to-end time is shown too). Peak memory is the RSS of
the subprocess (wait4), also measured on a file a third as long to show that it does not
grow with the input. Writes section "Ingest" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, run_python, run_times, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "ingest"
CONFIG = ROOT / "fixtures" / "config.resim.yaml"
GOAL = 0.7

OURS = """
import json, sys, time
from pathlib import Path
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
config = load_config(sys.argv[3])
start = time.perf_counter()
report = ingest_job(Path(sys.argv[1]), "main", "bench", "job", [Path(sys.argv[2])], config=config,
                    metadata={"experience_name": "bench", "build_version": "1.0"})
seconds = time.perf_counter() - start
print(json.dumps({"seconds": seconds, "rows": sum(report.rows.values())}))
"""

BASELINE = """
import json, sys, time
import duckdb
con = duckdb.connect()
con.execute("SET enable_progress_bar = false")
start = time.perf_counter()
target = sys.argv[2].replace("'", "''")
copy = f"COPY (SELECT * FROM read_json(?, format = 'newline_delimited')) TO '{target}' (FORMAT parquet)"
rows = con.execute(copy, [sys.argv[1]]).fetchone()[0]
seconds = time.perf_counter() - start
print(json.dumps({"seconds": seconds, "rows": rows}))
"""


def generate(path: Path, lines: int, seed: int = 7) -> None:
    """Write `lines` emission lines of the example config's topics (as the Emitter formats them)."""
    rnd = random.Random(seed)
    goals = ["goal_1", "goal_2", "goal_3"]
    states = ["IDLE", "NAVIGATING", "REACHED", "FAILED"]
    out = []
    tmp = path.with_suffix(".partial")
    with open(tmp, "w", encoding="utf-8") as handle:
        for i in range(lines):
            t = (i + 1) * 10_000_000
            r = rnd.random()
            head = '{"$metadata": {"topic": "%s", "timestamp": %d}, "$data": '
            if r < 0.40:
                out.append(
                    head % ("odom_linear_velocity", t)
                    + f'{{"x": {rnd.uniform(-2, 2)!r}, "y": {rnd.uniform(-2, 2)!r}, "z": {rnd.uniform(-0.1, 0.1)!r}}}}}'
                )
            elif r < 0.50:
                out.append(head % ("pose_difference", t) + f'{{"position_diff_m": {rnd.uniform(0, 1.5)!r}}}}}')
            elif r < 0.65:
                out.append(
                    head % ("goal_distance", t)
                    + f'{{"goal_name": "{rnd.choice(goals)}", "distance_m": {rnd.uniform(0, 30)!r}}}}}'
                )
            elif r < 0.75:
                error, sigma = rnd.uniform(0, 1), rnd.uniform(0.1, 1)
                out.append(
                    head % ("covariance_accuracy", t)
                    + f'{{"error_m": {error!r}, "sigma_m": {sigma!r}, "within_1_sigma": {int(error < sigma)}}}}}'
                )
            elif r < 0.85:
                out.append(head % ("robot_speed", t) + f'{{"speed": {rnd.uniform(0, 2)!r}}}}}')
            elif r < 0.90:
                out.append(head % ("drone_speed", t) + f'{{"speed": {rnd.uniform(0, 20)!r}}}}}')
            elif r < 0.95:
                out.append(head % ("goal_status", t) + f'{{"state": "{rnd.choice(states)}"}}}}')
            elif r < 0.97:
                out.append(
                    head % ("time_to_goal", t)
                    + f'{{"goal_name": "{rnd.choice(goals)}", "time_s": {rnd.uniform(1, 100)!r}}}}}'
                )
            elif r < 0.995:
                out.append(head % ("camera_gif", t) + f'{{"filename": "frames/frame_{i:08d}.png"}}}}')
            else:
                out.append(
                    json.dumps(
                        {
                            "$metadata": {"topic": "goal_reached", "timestamp": t, "event": True},
                            "$data": {
                                "name": "Goal reached",
                                "description": "Robot reached a goal",
                                "status": "PASSED",
                                "tags": ["navigation", "goal"],
                                "metrics": [
                                    {
                                        "name": "Distance",
                                        "type": "scalar",
                                        "value": rnd.uniform(0, 1),
                                        "status": "PASSED",
                                    }
                                ],
                            },
                        }
                    )
                )
            if len(out) >= 20000:
                handle.write("\n".join(out) + "\n")
                out = []
        if out:
            handle.write("\n".join(out) + "\n")
    tmp.replace(path)


def emissions(lines: int) -> Path:
    path = WORK / f"emissions-{lines}.jsonl"
    if not path.exists():
        WORK.mkdir(parents=True, exist_ok=True)
        print(f"generating {path} ({lines:,} lines) ...", flush=True)
        generate(path, lines)
    return path


def ours(path: Path) -> dict:
    lake = WORK / "lake"
    shutil.rmtree(lake, ignore_errors=True)
    try:
        return run_python(OURS, str(lake), str(path), str(CONFIG))
    finally:
        shutil.rmtree(lake, ignore_errors=True)


def baseline(path: Path) -> dict:
    target = WORK / "duckdb.parquet"
    try:
        return run_python(BASELINE, str(path), str(target))
    finally:
        target.unlink(missing_ok=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lines", type=int, default=1_500_000, help="lines of the emissions file (default 1.5M)")
    parser.add_argument("--runs", type=int, default=3, help="measured runs of each side (default 3)")
    args = parse_args(parser, lines=5_000, runs=1)
    path = emissions(args.lines)
    small = emissions(args.lines // 3)
    size_mb = path.stat().st_size / 1e6
    runs: dict[str, list[dict]] = {"lakegate": [], "duckdb": []}
    for i in range(args.runs):
        for name, fn in (("duckdb", baseline), ("lakegate", ours)):
            result = fn(path)
            runs[name].append(result)
            print(
                f"run {i + 1}: {name:<8} {result['seconds']:.2f} s, {args.lines / result['seconds']:,.0f} rows/s, "
                f"peak RSS {result['rss_mb']:.0f} MB",
                flush=True,
            )
    small_rss = ours(small)["rss_mb"]
    for name, results in runs.items():
        assert all(r["rows"] == args.lines for r in results), f"{name} wrote {results[0]['rows']} rows"
    median = {name: statistics.median(r["seconds"] for r in results) for name, results in runs.items()}
    rate = {name: args.lines / seconds for name, seconds in median.items()}
    ratio = rate["lakegate"] / rate["duckdb"]
    rss = {name: max(r["rss_mb"] for r in results) for name, results in runs.items()}
    bounded = rss["lakegate"] < 1.5 * small_rss and rss["lakegate"] < size_mb * 2
    lines = [
        f"Emissions file: {args.lines:,} lines, {size_mb:.0f} MB, 10 topics of `fixtures/config.resim.yaml` "
        "(0.5% events with metric[] fields). Median of "
        f"{args.runs} alternating runs, each in a fresh process; rows/s over the operation itself.",
        "",
        "| | median time | rows/s | end-to-end (with start-up) | CPU (user+sys) | peak RSS |",
        "|---|---|---|---|---|---|",
    ]
    labels = {
        "lakegate": "lakegate `ingest_job` (validated, per-topic Parquet, zstd)",
        "duckdb": "DuckDB `read_json` + `COPY TO parquet` (no validation)",
    }
    for name in ("lakegate", "duckdb"):
        results = runs[name]
        lines.append(
            f"| {labels[name]} | {median[name]:.2f} s | {rate[name]:,.0f} | "
            f"{statistics.median(r['wall'] for r in results):.2f} s | "
            f"{statistics.median(r['cpu'] for r in results):.2f} s | {rss[name]:.0f} MB |"
        )
    lines += [
        "",
        f"- ratio lakegate / DuckDB: **{ratio:.2f}x** (goal >= {GOAL}x): {'met' if ratio >= GOAL else 'NOT met'}",
        f"- memory: peak RSS {rss['lakegate']:.0f} MB for {size_mb:.0f} MB of input, {small_rss:.0f} MB for a third "
        f"of it: {'bounded (streaming)' if bounded else 'NOT bounded'}",
        f"- all runs (s): lakegate {run_times(runs['lakegate'])}; DuckDB {run_times(runs['duckdb'])}; "
        f"load average at the end {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores",
    ]
    write_section("Ingest", "python3 dev.py bench ingest", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
