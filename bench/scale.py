"""Scale benchmark: what one 40-job batch costs on branches of 100, 1,000 and 10,000 jobs.

    python3 dev.py bench scale [--sizes 100,1000,10000] [--runs 3]

Builds (the source once, cached in bench/.work/scale/) a source lake: 40 simulated navigation jobs
(fixtures/generate.py) ingested into batch `nav-40` of branch `main`, with the example config.
Each branch of N jobs holds that batch (the 40 jobs' own files, hard-linked) plus N - 40 filler
jobs in batches of 100, written directly as compacted batches: per table and batch one file of
the 40 jobs' rows repeated under the filler jobs' ids (sorted by job, as
`lakegate lake compact` writes them), recorded directly in the branch's file record (one
transaction), so 10,000 jobs build in a few minutes.

On each branch, measures (median of `--runs`):

* `lakegate metrics run --no-compact` of batch `nav-40` with the "Nav Metrics" set (a fresh
  process each), then `lakegate lake compact --batch nav-40` once (the queries below run on
  the compacted branch);
* through a warm `lakegate serve` (the official `trino` client, after one warm-up each): the query
  of test metric "Maximum Localization Error (job)" (session properties `batch_id` and `job_id`),
  of batch metric "Average Speed" (`batch_id`),
  `SELECT count(*) FROM metadata` and a GROUP BY over one topic; each query's *planning overhead*:
  its time through the server less DuckDB's own time for the same translated SQL over the same
  files (a plain DuckDB connection in this process with the record's views of the query's scope,
  the server's thread count, the same alternation); `count(*) FROM metadata` again just after one
  more job was published (the views are rebuilt from the record); then the server's memory (PSS over its processes);
* `lakegate ingest` of one more job (a fresh process each), against the same ingest into an
  empty branch;
* memory with 20 branches open: one server (`--memory-limit 1GB`) over a lake of 20 branches of
  1,000 jobs each (hard links), each branch queried (count(*) and the GROUP BY, which reads every
  file of the topic); the server's memory (PSS) and peak RSS against that budget.

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
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import duckdb
import pyarrow as pa
import trino

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, timed, write_section  # noqa: E402
from server import Server  # noqa: E402

from lakegate.dialect.scope import Scope  # noqa: E402
from lakegate.fixtures.generate import CONFIG_PATH, generate_batch  # noqa: E402
from lakegate.gateway.engine.backend import DuckDBBackend  # noqa: E402
from lakegate.lake import paths  # noqa: E402
from lakegate.lake.batch_files import job_rows, write_jobs  # noqa: E402
from lakegate.lake.branch_configs import BranchConfigs  # noqa: E402
from lakegate.lake.catalog import Catalog  # noqa: E402
from lakegate.lake.config import load_config  # noqa: E402
from lakegate.lake.ingest import ingest_job  # noqa: E402
from lakegate.lake.metadata import load_metadata_file  # noqa: E402
from lakegate.lake.record import LAYOUT, RECORD, FileEntry, Record  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "scale"
CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
BRANCH, BATCH, FILLER_BATCH = "main", "nav-40", 100
METRICS_SET = "Nav Metrics"
TEST_METRIC, BATCH_METRIC = "Maximum Localization Error (job)", "Average Speed"  # of the example config
COUNT = "SELECT count(*) FROM metadata"
GROUP_BY = "SELECT job_id, count(*), max(speed) FROM robot_speed GROUP BY job_id"
GOALS = {"metrics run": 1.2, "ingest": 1.2}
#: The 20-branch memory measurement: branches, jobs per branch, the server's DuckDB memory budget.
BUDGET = "1GB"


def source(count: int = 40) -> tuple[Path, list]:
    """The source lake (`count` ingested jobs, 40 but under --smoke) and the generated jobs, built once."""
    lake, inputs = WORK / f"source-{count}", WORK / f"inputs-{count}"
    jobs = generate_batch(inputs, jobs=count)  # deterministic: the same files every time
    if not (lake / ".complete").exists() or Record(lake, BRANCH).layout() != LAYOUT:  # built before layout v2
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
    """A lake whose branch holds batch nav-40 (hard links) and `size` - 40 filler jobs (compacted
    batches of 100), built once."""
    lake = WORK / f"jobs-{size}"  # built again each time: the measures write to it
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
    for job in sources[:size]:  # nav-40: the ingested jobs' own files
        for entry in by_job[job]:
            target = root / entry.path
            _link(source_root / entry.path, target)
            _link(source_root / entry.path, paths.reader_path(root, entry.path))
            entries.append(entry)
    tables = sorted({entry.table for entry in originals})
    rows = {  # (table, source job) -> its rows, read once
        (entry.table, entry.job_id): job_rows(source_root / entry.path, entry.job_id, v1=False, position=0)
        for entry in originals
    }
    fillers = [f"job-{index:05d}" for index in range(len(sources), size)]
    with paths.staging(lake, BRANCH) as scratch:
        for start in range(0, len(fillers), FILLER_BATCH):
            batch = f"filler-{start // FILLER_BATCH:04d}"
            jobs = fillers[start : start + FILLER_BATCH]
            for table in tables:
                parts, described = [], []
                for offset, job in enumerate(jobs):
                    source_job = sources[(start + offset) % len(sources)]
                    found = rows.get((table, source_job))
                    if found is None:
                        continue
                    ids = pa.repeat(pa.scalar(job, pa.string()), found.num_rows)
                    parts.append((job, found.set_column(found.schema.get_field_index("job_id"), "job_id", ids)))
                    described.append((job, next(e for e in by_job[source_job] if e.table == table)))
                if not parts:
                    continue
                staged = scratch / "batch.parquet"
                write_jobs(staged, parts)
                target = paths.new_data_file(lake, BRANCH, table, batch, None)
                paths.publish_linked(staged, target)
                relative = target.relative_to(root).as_posix()
                entries += [replace(entry, batch_id=batch, job_id=job, path=relative) for job, entry in described]
    record.commit(f"bench: {size} jobs", entries)
    record.close()
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
        "--no-compact",
    )


def compact(lake: Path) -> tuple[float, float]:
    return command("lake", "compact", "--lake", str(lake), "--branch", BRANCH, "--batch", BATCH)


def ingest(lake: Path, job, run: int | str) -> tuple[float, float]:
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


def served(lake: Path, runs: int, job) -> dict[str, float]:
    """Median seconds of each query through a warm `lakegate serve` and its planning overhead
    (less DuckDB's own time, `direct`), `count(*)` just after a publish, and the server's memory (PSS, MB)."""
    server = Server(lake, ["--threads", "2"])
    try:
        figures = {}
        metrics = load_config(CONFIG_PATH).metrics
        for name, sql, session in (
            ("test metric", metrics[TEST_METRIC].query_string, {"batch_id": BATCH, "job_id": job.job_id}),
            ("batch metric", metrics[BATCH_METRIC].query_string, {"batch_id": BATCH}),
            ("count(*) FROM metadata", COUNT, {}),
            ("GROUP BY over one topic", GROUP_BY, {}),
        ):
            query = _client_query(server, sql, session)
            direct = _direct_query(lake, sql, session)
            query(), direct()  # warm-up
            through, alone = [], []
            for _ in range(max(runs, 5)):  # alternating, so that both see the same load
                through.append(timed(query))
                alone.append(timed(direct))
            figures[name] = statistics.median(through)
            figures[f"{name}: planning overhead"] = statistics.median(t - a for t, a in zip(through, alone))
        ingest(lake, job, "fresh")
        figures["count(*) FROM metadata, first after a publish"] = timed(_client_query(server, COUNT, {}))
        figures["server memory, PSS (MB)"] = server.memory("Pss") / 2**20
        return figures
    finally:
        server.stop()


def _client_query(server: Server, sql: str, session: dict[str, str]) -> Callable[[], None]:
    """Run `sql` through the server with the official client (one connection, a cursor per call)."""
    connection = trino.dbapi.connect(
        host="127.0.0.1", port=server.port, user="bench", catalog="lake", schema=BRANCH, session_properties=session
    )

    def query() -> None:
        cursor = connection.cursor()
        cursor.execute(sql)
        cursor.fetchall()

    return query


def _direct_query(lake: Path, sql: str, session: dict[str, str]) -> Callable[[], None]:
    """Run the DuckDB translation of `sql` on a plain DuckDB connection (the server's thread count)
    over views of the files of the session's scope, as the record lists them now."""
    backend = DuckDBBackend(lake)
    scope = Scope(**session) if session else None
    try:
        duckdb_sql = backend.translate(sql, branch=BRANCH, scope=scope).duckdb_sql
    finally:
        backend.close()
    catalog = Catalog(lake)
    snapshot = catalog.snapshot(BRANCH, batch_id=session.get("batch_id"), job_id=session.get("job_id"))
    connection = duckdb.connect(config={"threads": 2})
    connection.execute("SET TimeZone = 'UTC'")
    for name, select in catalog.view_sql(BRANCH, snapshot).items():
        connection.execute(f'CREATE VIEW "{name}" AS {select}')
    return lambda: connection.execute(duckdb_sql).fetchall()


def many_branches(source_lake: Path, branches: int, branch_jobs: int) -> dict[str, float]:
    """Memory (PSS) and peak RSS (MB) of one server (memory budget BUDGET) after a query of each of
    `branches` branches of `branch_jobs` jobs (hard links of one built branch; each its own record)."""
    lake = WORK / f"branches-{branches}x{branch_jobs}"
    if not (lake / ".complete").exists():
        shutil.rmtree(lake, ignore_errors=True)
        one = paths.branch_dir(build(branch_jobs, source_lake), BRANCH)
        for index in range(branches):
            root = paths.branch_dir(lake, f"b{index:02d}")
            shutil.copytree(one, root, copy_function=os.link, ignore=shutil.ignore_patterns(RECORD))
            shutil.copy(one / RECORD, root / RECORD)
        (lake / ".complete").touch()
    server = Server(lake, ["--threads", "2", "--memory-limit", BUDGET])
    try:
        for index in range(branches):
            for sql in (COUNT, GROUP_BY):
                connection = trino.dbapi.connect(
                    host="127.0.0.1", port=server.port, user="bench", catalog="lake", schema=f"b{index:02d}"
                )
                cursor = connection.cursor()
                cursor.execute(sql)
                cursor.fetchall()
        return {
            f"server memory (PSS), {branches} branches open (MB)": server.memory("Pss") / 2**20,
            f"server peak RSS, {branches} branches (MB)": server.memory("VmHWM") / 2**20,
        }
    finally:
        server.stop()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", default="100,1000,10000", help="branch sizes in jobs (comma-separated)")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--batch-jobs", type=int, default=40, help="jobs of the evaluated batch nav-40")
    parser.add_argument("--branches", type=int, default=20, help="branches open at once in the memory measure")
    parser.add_argument("--branch-jobs", type=int, default=1000, help="jobs of each of those branches")
    args = parse_args(parser, argv, sizes="4", runs=1, batch_jobs=2, branches=2, branch_jobs=4)
    sizes = [int(size) for size in args.sizes.split(",")]
    load_before = os.getloadavg()
    source_lake, jobs = source(args.batch_jobs)
    figures: dict[int, dict[str, float]] = {}
    for size in sizes:
        started = time.perf_counter()
        lake = build(size, source_lake)
        built = time.perf_counter() - started
        row = medians([metrics_run(lake) for _ in range(args.runs)], "metrics run")
        row |= medians([compact(lake)], "lake compact of nav-40")
        row |= served(lake, args.runs, jobs[0])
        row |= medians([ingest(lake, jobs[run % len(jobs)], run) for run in range(args.runs)], "ingest")
        figures[size] = row
        print(json.dumps({"size": size, "built_s": round(built, 1), **row}), flush=True)
    empty = WORK / "empty"
    shutil.rmtree(empty, ignore_errors=True)
    empty_ingest = medians([ingest(empty, jobs[run % len(jobs)], run) for run in range(args.runs)], "ingest")
    branches = many_branches(source_lake, args.branches, args.branch_jobs)
    print(json.dumps(branches), flush=True)
    write_section(
        "Scale",
        f"python3 dev.py bench scale --sizes {args.sizes} --runs {args.runs}",
        _lines(sizes, figures, empty_ingest, branches, args, load_before),
    )
    return 0


def _lines(
    sizes: list[int],
    figures: dict[int, dict[str, float]],
    empty_ingest: dict[str, float],
    branches: dict[str, float],
    args: argparse.Namespace,
    load_before: tuple[float, float, float],
) -> list[str]:
    measures = list(figures[sizes[0]])
    lines = [
        f"Branches of {', '.join(f'{s:,}' for s in sizes)} jobs: batch `{BATCH}` (40 jobs, 12 Parquet "
        f"files per job) is the same in each, the other jobs are in compacted batches of {FILLER_BATCH} (one file "
        "per table and batch); the queries run after `lake compact` of nav-40. "
        f"Medians of {args.runs} runs (queries: of {max(args.runs, 5)}, warm; `lake compact`: one run); the "
        "goals are judged on CPU seconds (user + system of the process), least disturbed by the other load "
        "on this shared machine (2 cores). "
        f"Load average (1, 5, 15 min) at the start: {', '.join(f'{x:.2f}' for x in load_before)}; "
        f"at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}.",
        "",
        "| measure | " + " | ".join(f"{s:,} jobs" for s in sizes) + f" | {sizes[-1]:,} / {sizes[0]:,} |",
        "|---|" + "---:|" * (len(sizes) + 1),
    ]
    for measure in measures:
        unit = "MB" if "MB" in measure else "s"
        cells = [f"{figures[s][measure]:.0f}" if unit == "MB" else _seconds(figures[s][measure]) for s in sizes]
        base = figures[sizes[0]][measure]
        ratio = f"{figures[sizes[-1]][measure] / base:.2f}x" if base > 0 else "-"
        lines.append(f"| {measure} | " + " | ".join(cells) + f" | {ratio} |")
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
    for measure in measures:
        if measure.endswith("planning overhead"):
            lines.append(
                f"- goal: warm planning overhead under 50 ms ({measure}): {_seconds(largest[measure])}, "
                f"**{'met' if largest[measure] < 0.05 else 'not met'}**"
            )
    memory = largest["server memory, PSS (MB)"]
    lines.append(
        f"- goal: server memory (PSS: shared pages counted once) under 1 GB: {memory:.0f} MB, "
        f"**{'met' if memory < 1024 else 'not met'}**"
    )
    budget = int(BUDGET.removesuffix("GB")) * 1024
    for measure, value in branches.items():
        lines.append(
            f"- {measure.replace(' (MB)', '')} ({args.branches} branches of {args.branch_jobs:,} jobs, each queried, "
            f"`--memory-limit {BUDGET}`): {value:.0f} MB, "
            f"**{'within' if value <= budget else 'over'}** the budget"
        )
    return lines


def _seconds(value: float) -> str:
    return f"{value * 1000:.0f} ms" if value < 1 else f"{value:.2f} s"


if __name__ == "__main__":
    sys.exit(main())
