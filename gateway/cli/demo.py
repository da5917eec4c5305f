"""`lakegate demo`: the whole workflow on a simulated navigation batch, in a few seconds.

Generates a deterministic batch (fixtures/generate.py) into `<lake>/_demo_inputs/`, stores the
example config (fixtures/config.resim.yaml, from the installed package) as branch `main`'s
config, ingests every job (copying its logs into the lake), evaluates the "Nav Metrics" set,
prints the results and writes an HTML report with every figure to `<lake>/report.html`.
Running it again replaces the batch and its results.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from importlib import resources
from pathlib import Path

from tqdm import tqdm

from lakegate.fixtures.generate import generate_batch
from lakegate.gateway.cli.errors import writable_lake
from lakegate.gateway.cli.metrics import format_table
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.report import write_report
from lakegate.lake import paths
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file
from lakegate.lake.registry import BranchConfigs

BRANCH = "main"
BATCH = "nav-regression-1"
METRICS_SET = "Nav Metrics"
INPUTS = "_demo_inputs"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="simulate a batch of navigation runs, ingest it, evaluate its metrics, write a report",
        description="Generate a deterministic simulated navigation batch, ingest it into a local lake, evaluate "
        f"the '{METRICS_SET}' metrics set of the example config (every example query of the product "
        "guide), print the results and write an HTML report with every figure.",
    )
    parser.add_argument(
        "--lake",
        type=Path,
        default=Path("lake-demo"),
        metavar="DIR",
        help="the lake's directory (default: ./lake-demo; created if missing, the demo batch replaced)",
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


def demo_command(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    lake = writable_lake(args.lake).resolve()
    inputs = lake / INPUTS
    _step(f"1/5 generating {args.jobs} simulated navigation jobs into {inputs}")
    jobs = generate_batch(inputs, jobs=args.jobs)

    config_file = resources.files("lakegate.fixtures") / "config.resim.yaml"
    with resources.as_file(config_file) as config_path:
        registry = BranchConfigs(lake, BRANCH)
        version = registry.store([config_path])
        config = registry.load(version)
    _step(f"2/5 stored the example config as branch {BRANCH!r}'s config, version {version} ({config.summary()})")

    _step(f"3/5 ingesting {len(jobs)} jobs into batch {BATCH!r}")
    rows = 0
    for job in tqdm(jobs, desc="ingesting", unit="job", disable=not progress, file=sys.stderr, leave=False):
        report = ingest_job(
            lake,
            BRANCH,
            BATCH,
            job.job_id,
            [job.emissions_path],
            config=config,
            metadata=load_metadata_file(job.metadata_path),
        )
        rows += sum(report.rows.values())
        logs = paths.logs_dir(lake, BRANCH, BATCH, job.job_id)
        shutil.rmtree(logs, ignore_errors=True)
        shutil.copytree(job.logs_dir, logs)
    _step(f"    {rows:,} rows written")

    _step(f"4/5 evaluating the metrics set {METRICS_SET!r}")
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

    report_path = write_report(evaluation, lake / "report.html")
    _step("5/5 wrote the report with every figure")
    print(f"\nreport: {report_path}")
    print(f"lake:   {lake}  (branch {BRANCH!r}, batch {BATCH!r}; done in {time.perf_counter() - started:.1f} s)")
    print("\nnext:")
    print(
        f'  lakegate query --lake {args.lake} "SELECT metric_name, status, COUNT(*) FROM metric_results '
        'GROUP BY 1, 2 ORDER BY 1, 2"'
    )
    print(f"  lakegate metrics run --lake {args.lake} --branch {BRANCH} --batch {BATCH} --metrics-set '{METRICS_SET}'")
    return 0
