"""`lakegate demo`: the whole workflow on a simulated navigation batch, in a few seconds.

Generates a deterministic batch (fixtures/generate.py) into `<lake>/_demo_inputs/`, plus two small
batches of earlier builds, stores the example config (fixtures/config.resim.yaml and the dashboard
metrics of fixtures/dashboard.resim.yaml, from the installed package) as branch `main`'s config,
ingests every job (copying its logs into the lake), evaluates the "Nav Metrics" set on the batch,
prints the results and writes an HTML report with every figure to `<lake>/report.html`; then
evaluates the dashboard metrics over the three batches (a trend from build to build) and writes
them to `<lake>/trends.html`. Running it again replaces the batches and their results.
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import timedelta
from importlib import resources
from pathlib import Path

from tqdm import tqdm

from lakegate.fixtures.generate import BUILD_TIME, BUILD_VERSION, GeneratedJob, generate_batch
from lakegate.gateway.cli.errors import writable_lake
from lakegate.gateway.cli.metrics import format_table, format_trends
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.report import write_report
from lakegate.gateway.metrics.trends import branch_batches, evaluate_trends, metrics_of, write_trends
from lakegate.lake import paths
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.compaction import compact_batch
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file
from lakegate.lake.storage import LakeStorage

BRANCH = "main"
BATCH = "nav-regression-1"
METRICS_SET = "Nav Metrics"
INPUTS = "_demo_inputs"
#: Where `lakegate serve --lake DIR` answers by default: the trends page's links point there.
LINK_BASE = "http://127.0.0.1:8080"
CONFIG_FILES = ("config.resim.yaml", "dashboard.resim.yaml")
#: Batches of earlier builds, for the dashboard's trend: (batch, build version, days before the demo batch).
EARLIER_BUILDS = (("nightly-1.4.0", "1.4.0", 14), ("nightly-1.4.1", "1.4.1", 7))
#: Jobs and samples per goal of each earlier batch (small: they only feed the trend).
EARLIER_JOBS, EARLIER_SAMPLES = 3, 20


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="simulate a batch of navigation runs, ingest it, evaluate its metrics, write a report and a trends page",
        description="Generate a deterministic simulated navigation batch, ingest it into a local lake, evaluate "
        f"the '{METRICS_SET}' metrics set of the example config (every example query of the product "
        "guide), print the results and write an HTML report with every figure; with two small batches of "
        "earlier builds, evaluate the example dashboard metrics (a trend from build to build) and write "
        "them to a trends page.",
    )
    parser.add_argument(
        "--lake",
        type=Path,
        default=Path("lake-demo"),
        metavar="DIR",
        help="the lake's directory (default: ./lake-demo; created if missing, the demo batches replaced)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=6,
        metavar="N",
        help="jobs in the batch (default 6: two each PASSED, WARNING and BLOCKER)",
    )
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show progress bars on standard error (default: when it is a terminal)",
    )
    parser.set_defaults(func=demo_command)


def _step(text: str) -> None:
    print(text, flush=True)


def _ingest(lake: Path, batch: str, jobs: list[GeneratedJob], config, progress: bool) -> int:
    """Ingest generated jobs into `batch` (copying their logs into the lake); the rows written."""
    rows, storage = 0, LakeStorage(lake)
    for job in tqdm(jobs, desc=f"ingesting {batch}", unit="job", disable=not progress, file=sys.stderr, leave=False):
        report = ingest_job(
            lake,
            BRANCH,
            batch,
            job.job_id,
            [job.emissions_path],
            config=config,
            metadata=load_metadata_file(job.metadata_path),
        )
        rows += sum(report.rows.values())
        logs = paths.logs_dir(lake, BRANCH, batch, job.job_id)
        storage.delete_tree(logs)
        storage.put(job.logs_dir, logs)
    return rows


def demo_command(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    lake = writable_lake(args.lake).resolve()
    inputs = lake / INPUTS
    _step(
        f"1/6 generating {args.jobs} simulated navigation jobs of build {BUILD_VERSION} into {inputs}, and "
        f"{EARLIER_JOBS} of each of builds {', '.join(build for _, build, _ in EARLIER_BUILDS)}"
    )
    jobs = generate_batch(inputs, jobs=args.jobs)
    earlier = {
        batch: generate_batch(
            inputs / batch,
            jobs=EARLIER_JOBS,
            seed=index,
            samples_per_goal=EARLIER_SAMPLES,
            build_version=build,
            build_time=BUILD_TIME - timedelta(days=days),
        )
        for index, (batch, build, days) in enumerate(EARLIER_BUILDS)
    }

    package = resources.files("lakegate.fixtures")
    with resources.as_file(package / CONFIG_FILES[0]) as main, resources.as_file(package / CONFIG_FILES[1]) as extra:
        registry = BranchConfigs(lake, BRANCH)
        version = registry.store([main, extra])
        config = registry.load(version)
    _step(
        f"2/6 stored the example config ({' + '.join(CONFIG_FILES)}) as branch {BRANCH!r}'s config, "
        f"version {version} ({config.summary()})"
    )

    _step(f"3/6 ingesting {len(jobs)} jobs into batch {BATCH!r}, and the earlier builds' batches")
    rows = _ingest(lake, BATCH, jobs, config, progress)
    for batch, batch_jobs in earlier.items():
        rows += _ingest(lake, batch, batch_jobs, config, progress)
    _step(f"    {rows:,} rows written")

    _step(f"4/6 evaluating the metrics set {METRICS_SET!r} on batch {BATCH!r}")
    with MetricsEngine(lake) as engine:
        evaluation = engine.evaluate_batch(
            BRANCH,
            BATCH,
            config.metrics_in_set(METRICS_SET),
            metrics_set=METRICS_SET,
            config_version=version,
            progress=progress,
        )
        print(format_table(evaluation))
        done = compact_batch(lake, BRANCH, BATCH, progress=progress)  # as `metrics run` does
        _step(f"    batch compacted, as after every metrics run: {done.files_before} files -> {done.files_after}")
        report_path = write_report(evaluation, lake / "report.html")
        _step("5/6 wrote the report with every figure")

        _step("6/6 evaluating the dashboard metrics over every batch of the branch (a trend from build to build)")
        trends = evaluate_trends(
            engine,
            BRANCH,
            metrics_of(config, "dashboard"),
            branch_batches(engine, BRANCH),
            kind="dashboard",
            config_version=version,
        )
    print(format_trends(trends))
    trends_path = write_trends(trends, lake / "trends.html", link_base=LINK_BASE)
    print(f"\nreport: {report_path}")
    print(f"trends: {trends_path}")
    print(f"lake:   {lake}  (branch {BRANCH!r}, batch {BATCH!r}; done in {time.perf_counter() - started:.1f} s)")
    print("\nnext:")
    print(
        f'  lakegate query --lake {args.lake} "SELECT metric_name, status, COUNT(*) FROM metric_results '
        'GROUP BY 1, 2 ORDER BY 1, 2"'
    )
    print(f"  lakegate metrics run --lake {args.lake} --branch {BRANCH} --batch {BATCH} --metrics-set '{METRICS_SET}'")
    print(f"  lakegate metrics dashboard --lake {args.lake} --branch {BRANCH} --window 2")
    print(f"  lakegate serve --lake {args.lake}   # then open {LINK_BASE}/dashboard/trends/?branch={BRANCH}")
    return 0
