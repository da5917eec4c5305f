"""Scale benchmark (issue 12): what one 40-job batch costs on branches of 100, 1,000 and 10,000 jobs.

    python3 dev.py bench scale [--sizes 100,1000,10000] [--runs 3]

Builds (once, cached in bench/.work/scale/) a source lake: 40 simulated navigation jobs
(fixtures/generate.py) ingested into batch `nav-40` of branch `main`, with the example config.
Each branch of N jobs holds that batch plus N - 40 filler jobs (batches of 100): the 40 jobs'
files hard-linked under new partitions and recorded directly in the branch's file record (one
transaction; no footer read), so 10,000 jobs (120,000 files) build in a minute or two. Filler
rows keep the job ids of the files they link (their partition values are the new ones).

On each branch, measures (median of `--runs`):

* `lakegate metrics run` of batch `nav-40` with the "Nav Metrics" set (a fresh process each);
* through a warm `lakegate serve` (the official `trino` client, after one warm-up each): the query
  of test metric "Maximum Localization Error (job)" (session properties `batch_id` and `job_id`),
  of batch metric "Average Speed" (`batch_id`),
  `SELECT count(*) FROM metadata` and a GROUP BY over one topic; then the server's RSS;
* `lakegate ingest` of one more job (a fresh process each), against the same ingest into an
  empty branch.

Writes section "Scale" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import trino

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import timed, write_section  # noqa: E402
from server import Server  # noqa: E402

from lakegate.fixtures.generate import CONFIG_PATH, generate_batch  # noqa: E402
from lakegate.lake import paths  # noqa: E402
from lakegate.lake.config import load_config  # noqa: E402
from lakegate.lake.ingest import ingest_job  # noqa: E402
from lakegate.lake.metadata import load_metadata_file  # noqa: E402
from lakegate.lake.record import FileEntry, Record  # noqa: E402
from lakegate.lake.registry import BranchConfigs  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "scale"
CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
BRANCH, BATCH, JOBS, FILLER_BATCH = "main", "nav-40", 40, 100
METRICS_SET = "Nav Metrics"
TEST_METRIC, BATCH_METRIC = "Maximum Localization Error (job)", "Average Speed"  # of the example config
COUNT = "SELECT count(*) FROM metadata"
GROUP_BY = "SELECT job_id, count(*), max(speed) FROM robot_speed GROUP BY job_id"
GOALS = {"metrics run": 1.2, "ingest": 1.2}


def source() -> tuple[Path, list]:
    """The source lake (40 ingested jobs) and the generated jobs, built once."""
    lake, inputs = WORK / "source", WORK / "inputs"
    jobs = generate_batch(inputs, jobs=JOBS)  # deterministic: the same files every time
    if not (lake / ".complete").exists():
        shutil.rmtree(lake, ignore_errors=True)
        registry = BranchConfigs(lake, BRANCH)
        config = registry.load(registry.store([CONFIG_PATH]))
        for job in jobs:
            ingest_job(
                lake,
                BRANCH,
                BATCH,
                job.job_id,
                [job.emissions_path],
                config=config,
                metadata=load_metadata_file(job.metadata_path),
            )
        (lake / ".complete").touch()
    return lake, jobs


def build(size: int, source_lake: Path) -> Path:
    """A lake whose branch holds batch nav-40 and `size` - 40 filler jobs (hard links), built once."""
    lake = WORK / f"jobs-{size}"
    if (lake / ".complete").exists():
        return lake
    shutil.rmtree(lake, ignore_errors=True)
    source_root = paths.branch_dir(source_lake, BRANCH)
    root = paths.branch_dir(lake, BRANCH)
    shutil.copytree(source_root / "_configs", root / "_configs")
    record = Record(lake, BRANCH)
    record.generation()  # an empty record now: nothing to migrate later
    originals = Record(source_lake, BRANCH).snapshot().files
    by_job: dict[str, list[FileEntry]] = {}
    for entry in originals:
        by_job.setdefault(entry.job_id, []).append(entry)
    sources = sorted(by_job)
    entries = []
    for index in range(size):
        if index < JOBS:
            batch, job = BATCH, sources[index]
        else:
            batch, job = f"filler-{(index - JOBS) // FILLER_BATCH:04d}", f"job-{index:05d}"
        for entry in by_job[sources[index % JOBS]]:
            target = paths.partition_dir(lake, BRANCH, entry.table, batch, job) / Path(entry.path).name
            _link(source_root / entry.path, target)
            _link(source_root / entry.path, paths.reader_path(root, target.relative_to(root).as_posix()))
            entries.append(
                FileEntry(
                    entry.table,
                    batch,
                    job,
                    target.relative_to(root).as_posix(),
                    entry.rows,
                    entry.min_ts,
                    entry.max_ts,
                    entry.columns,
                )
            )
    record.commit(f"bench: {size} jobs", entries)
    record.close()
    (lake / ".complete").touch()
    return lake


def _link(source: Path, target: Path) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    os.link(source, target)


def command(*args: str) -> tuple[float, float]:
    """Run `lakegate ARGS` in a fresh process: its wall-clock and CPU (user + system) seconds."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([*CLI, *args], capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode not in (0, 2, 3):  # metrics run: 2 and 3 are statuses (BLOCKER, ERROR)
        raise SystemExit(f"lakegate {args[0]} failed: {done.stderr}")
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def metrics_run(lake: Path) -> tuple[float, float]:
    return command(
        "metrics",
        "run",
        "--lake",
        str(lake),
        "--branch",
        BRANCH,
        "--batch",
        BATCH,
        "--metrics-set",
        METRICS_SET,
        "--format",
        "json",
    )


def ingest(lake: Path, job, run: int) -> tuple[float, float]:
    return command(
        "ingest",
        "--lake",
        str(lake),
        "--branch",
        BRANCH,
        "--batch",
        "extra",
        "--job",
        f"extra-{run}",
        "--metadata",
        str(job.metadata_path),
        "--metrics-config-path",
        str(CONFIG_PATH),
        str(job.emissions_path),
    )


def medians(runs: list[tuple[float, float]], name: str) -> dict[str, float]:
    """The median wall-clock and CPU seconds of `runs`, as figures `name` and `name (CPU)`."""
    return {name: statistics.median(wall for wall, _ in runs), f"{name} (CPU)": statistics.median(c for _, c in runs)}


def served(lake: Path, runs: int, job_id: str) -> dict[str, float]:
    """Median seconds of each query through a warm `lakegate serve`, and the server's RSS (MB)."""
    server = Server(lake, ["--threads", "2"])
    try:
        figures = {}
        metrics = load_config(CONFIG_PATH).metrics
        for name, sql, session in (
            ("test metric", metrics[TEST_METRIC].query_string, {"batch_id": BATCH, "job_id": job_id}),
            ("batch metric", metrics[BATCH_METRIC].query_string, {"batch_id": BATCH}),
            ("count(*) FROM metadata", COUNT, {}),
            ("GROUP BY over one topic", GROUP_BY, {}),
        ):
            connection = trino.dbapi.connect(
                host="127.0.0.1",
                port=server.port,
                user="bench",
                catalog="lake",
                schema=BRANCH,
                session_properties=session,
            )

            def query() -> None:
                cursor = connection.cursor()
                cursor.execute(sql)
                cursor.fetchall()

            query()  # warm-up
            figures[name] = statistics.median(timed(query) for _ in range(max(runs, 5)))
        figures["server RSS (MB)"] = server.memory("VmRSS") / 2**20
        return figures
    finally:
        server.stop()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", default="100,1000,10000", help="branch sizes in jobs (comma-separated)")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args(argv)
    sizes = [int(size) for size in args.sizes.split(",")]
    source_lake, jobs = source()
    figures: dict[int, dict[str, float]] = {}
    for size in sizes:
        started = time.perf_counter()
        lake = build(size, source_lake)
        built = time.perf_counter() - started
        row = medians([metrics_run(lake) for _ in range(args.runs)], "metrics run")
        row |= served(lake, args.runs, jobs[0].job_id)
        row |= medians([ingest(lake, jobs[run % JOBS], run) for run in range(args.runs)], "ingest")
        figures[size] = row
        print(json.dumps({"size": size, "built_s": round(built, 1), **row}), flush=True)
    empty = WORK / "empty"
    shutil.rmtree(empty, ignore_errors=True)
    empty_ingest = medians([ingest(empty, jobs[run % JOBS], run) for run in range(args.runs)], "ingest")
    write_section(
        "Scale",
        f"python3 dev.py bench scale --sizes {args.sizes} --runs {args.runs}",
        _lines(sizes, figures, empty_ingest, args.runs),
    )
    return 0


def _lines(
    sizes: list[int], figures: dict[int, dict[str, float]], empty_ingest: dict[str, float], runs: int
) -> list[str]:
    measures = list(figures[sizes[0]])
    lines = [
        f"Branches of {', '.join(f'{s:,}' for s in sizes)} jobs (12 Parquet files per job); batch `{BATCH}` "
        f"(40 jobs) is the same in each. Medians of {runs} runs (queries: of {max(runs, 5)}, warm); the "
        "goals are judged on CPU seconds (user + system of the process), least disturbed by the other load "
        "on this shared machine. "
        f"Load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}.",
        "",
        "| measure | " + " | ".join(f"{s:,} jobs" for s in sizes) + f" | {sizes[-1]:,} / {sizes[0]:,} |",
        "|---|" + "---:|" * (len(sizes) + 1),
    ]
    for measure in measures:
        unit = "MB" if "MB" in measure else "s"
        cells = [f"{figures[s][measure]:.0f}" if unit == "MB" else _seconds(figures[s][measure]) for s in sizes]
        ratio = figures[sizes[-1]][measure] / figures[sizes[0]][measure]
        lines.append(f"| {measure} | " + " | ".join(cells) + f" | {ratio:.2f}x |")
    for measure, value in empty_ingest.items():
        lines.append(f"| {measure} into an empty branch | {_seconds(value)} |" + " |" * len(sizes))
    lines.append("")
    largest = figures[sizes[-1]]
    for measure, goal in GOALS.items():
        base = figures[sizes[0]][f"{measure} (CPU)"] if measure == "metrics run" else empty_ingest["ingest (CPU)"]
        ratio = largest[f"{measure} (CPU)"] / base
        lines.append(
            f"- goal: {measure} on {sizes[-1]:,} jobs within {goal}x of "
            f"{'the smallest branch' if measure == 'metrics run' else 'an empty branch'}: "
            f"{ratio:.2f}x in CPU seconds, **{'met' if ratio <= goal else 'not met'}**"
        )
    lines.append(
        f"- goal: `count(*) FROM metadata` under 100 ms: {_seconds(largest['count(*) FROM metadata'])}, "
        f"**{'met' if largest['count(*) FROM metadata'] < 0.1 else 'not met'}**"
    )
    lines.append(
        f"- goal: server RSS under 1 GB: {largest['server RSS (MB)']:.0f} MB, "
        f"**{'met' if largest['server RSS (MB)'] < 1024 else 'not met'}**"
    )
    return lines


def _seconds(value: float) -> str:
    return f"{value * 1000:.0f} ms" if value < 1 else f"{value:.2f} s"


if __name__ == "__main__":
    sys.exit(main())
