"""`lakegate demo`: the whole workflow on a simulated navigation batch, in a few seconds.

Generates a deterministic batch (fixtures/generate.py) into `<lake>/_demo_inputs/`, plus two small
batches of earlier builds, stores the example config (fixtures/config.resim.yaml and the dashboard
metrics of fixtures/dashboard.resim.yaml, from the installed package) as branch `main`'s config,
ingests every job (copying its logs into the lake), evaluates the "Nav Metrics" set on the batch,
prints the results and writes an HTML report with every figure to `<lake>/report.html`; then
evaluates the dashboard metrics over the three batches (a trend from build to build) and writes
them to `<lake>/trends.html`; then compares the three builds (`lakegate compare`), writing the
comparison of the last two to `<lake>/compare.html`. Running it again replaces the batches and their
results.

What the comparison shows is built into the plans below (fixtures/generate.py `plan`):

* build 1.4.1 -> 1.4.2, a real regression: Parking Lot passed on 1.4.1 and blocks on 1.4.2 (fewer than 3
  goals reached): **new failure**;
* a fix: Loading Dock blocked on 1.4.1 and passes on 1.4.2: **fixed**;
* a flaky experience: Narrow Aisle runs three times on 1.4.2 and warns on one run only (its status
  flips between runs of one build), after passing on 1.4.1: **flaky**, not a new failure;
* build 1.4.0 -> 1.4.1: Parking Lot, blocking on 1.4.0, is fixed on 1.4.1.
"""

from __future__ import annotations

import argparse
import shlex
import shutil
import sys
import time
from datetime import timedelta
from importlib import resources
from pathlib import Path

from tqdm import tqdm

from lakegate.fixtures.generate import BUILD_TIME, BUILD_VERSION, EXPERIENCES, OUTCOMES, GeneratedJob, generate_batch
from lakegate.gateway.cli.command_errors import writable_lake
from lakegate.gateway.cli.compare import format_comparison
from lakegate.gateway.cli.metrics import format_table, format_trends
from lakegate.gateway.cli.parsers.demo import METRICS_SET
from lakegate.gateway.metrics.compare import compare_batches
from lakegate.gateway.metrics.compare_page import write_compare
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.report import write_report
from lakegate.gateway.metrics.trends import branch_batches, evaluate_trends, metrics_of, write_trends
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.compaction import compact_batch
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file

BRANCH = "main"
BATCH = "nav-regression-1"
INPUTS = "_demo_inputs"
#: Where `lakegate serve --lake DIR` answers by default: the trends page's links point there.
LINK_BASE = "http://127.0.0.1:8080"
CONFIG_FILES = ("config.resim.yaml", "dashboard.resim.yaml")
#: Batches of earlier builds, for the dashboard's trend and the comparison: (batch, build version, days
#: before the demo batch, (experience, outcome) of each job).
EARLIER_BUILDS = (
    (
        "nightly-1.4.0",
        "1.4.0",
        14,
        (("Warehouse Loop", "PASSED"), ("Office Corridor", "WARNING"), ("Parking Lot", "BLOCKER")),
    ),
    (
        "nightly-1.4.1",
        "1.4.1",
        7,
        (
            ("Warehouse Loop", "PASSED"),
            ("Office Corridor", "WARNING"),
            ("Parking Lot", "PASSED"),  # blocks on 1.4.2: the regression
            ("Loading Dock", "BLOCKER"),  # passes on 1.4.2: the fix
            ("Narrow Aisle", "PASSED"),  # warns on one run of three on 1.4.2: flaky
            ("Open Field", "BLOCKER"),
        ),
    ),
)
#: Repeated runs of Narrow Aisle added to the demo batch: with its WARNING run of the cycle, it fails one run in three.
RERUNS = (("Narrow Aisle", "PASSED"), ("Narrow Aisle", "PASSED"))
#: Samples per goal of each earlier batch's jobs (small: they only feed the trend and the comparison).
EARLIER_SAMPLES = 20


def lakegate_command() -> str:
    """How to run `lakegate` again from the current folder, as this process was started: `lakegate`
    when that is the one on PATH, else the script's path (`.venv/bin/lakegate`), or `python -m`."""
    script = Path(sys.argv[0]).absolute()
    if script.name != "lakegate":  # python -m lakegate.gateway.cli
        return f"{shlex.quote(_shown_path(Path(sys.executable)))} -m lakegate.gateway.cli"
    on_path = shutil.which("lakegate")
    if on_path is not None and Path(on_path).absolute() == script:
        return "lakegate"
    return shlex.quote(_shown_path(script))


def _shown_path(path: Path) -> str:
    """`path` relative to the current folder when it is inside it, else absolute."""
    path = path.absolute()
    if not path.is_relative_to(Path.cwd()):
        return str(path)
    relative = str(path.relative_to(Path.cwd()))
    return relative if "/" in relative else f"./{relative}"


def _step(text: str) -> None:
    print(text, flush=True)


def _ingest(lake: Path, batch: str, jobs: list[GeneratedJob], config, progress: bool) -> int:
    """Ingest generated jobs into `batch` (copying their logs into the lake); the rows written."""
    rows = 0
    for job in tqdm(jobs, desc=f"ingesting {batch}", unit="job", disable=not progress, file=sys.stderr, leave=False):
        report = ingest_job(
            lake,
            BRANCH,
            batch,
            job.job_id,
            [job.emissions_path],
            config=config,
            metadata=load_metadata_file(job.metadata_path),
            logs=job.logs_dir,
        )
        rows += sum(report.rows.values())
    return rows


def demo_command(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    lake = writable_lake(args.lake).resolve()
    inputs = lake / INPUTS
    plan = [(EXPERIENCES[i % len(EXPERIENCES)][0], OUTCOMES[i % len(OUTCOMES)]) for i in range(args.jobs)]
    plan += RERUNS
    _step(
        f"1/7 generating {len(plan)} simulated navigation jobs of build {BUILD_VERSION} into {inputs}, and "
        f"jobs of builds {', '.join(build for _, build, _, _ in EARLIER_BUILDS)}"
    )
    jobs = generate_batch(inputs, plan=plan)
    earlier = {
        batch: generate_batch(
            inputs / batch,
            plan=list(runs),
            seed=index,
            samples_per_goal=EARLIER_SAMPLES,
            build_version=build,
            build_time=BUILD_TIME - timedelta(days=days),
        )
        for index, (batch, build, days, runs) in enumerate(EARLIER_BUILDS)
    }

    package = resources.files("lakegate.fixtures")
    with resources.as_file(package / CONFIG_FILES[0]) as main, resources.as_file(package / CONFIG_FILES[1]) as extra:
        registry = BranchConfigs(lake, BRANCH)
        version = registry.store([main, extra])
        config = registry.load(version)
    _step(
        f"2/7 stored the example config ({' + '.join(CONFIG_FILES)}) as branch {BRANCH!r}'s config, "
        f"version {version} ({config.summary()})"
    )

    _step(f"3/7 ingesting {len(jobs)} jobs into batch {BATCH!r}, and the earlier builds' batches")
    rows = _ingest(lake, BATCH, jobs, config, progress)
    for batch, batch_jobs in earlier.items():
        rows += _ingest(lake, batch, batch_jobs, config, progress)
    _step(f"    {rows:,} rows written")

    _step(f"4/7 evaluating the metrics set {METRICS_SET!r} on batch {BATCH!r}")
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
        for batch in earlier:  # the earlier builds' results, for the comparison of step 7
            engine.evaluate_batch(
                BRANCH, batch, config.metrics_in_set(METRICS_SET), metrics_set=METRICS_SET, config_version=version
            )
            compact_batch(lake, BRANCH, batch)
        done = compact_batch(lake, BRANCH, BATCH, progress=progress)  # as `metrics run` does
        _step(
            f"    batch compacted, as after every metrics run: {done.files_before} files -> {done.files_after}; "
            f"the earlier builds' batches evaluated too"
        )
        report_path = write_report(evaluation, lake / "report.html")
        _step("5/7 wrote the report with every figure")

        _step("6/7 evaluating the dashboard metrics over every batch of the branch (a trend from build to build)")
        trends = evaluate_trends(
            engine,
            BRANCH,
            metrics_of(config, "dashboard"),
            branch_batches(engine, BRANCH),
            kind="dashboard",
            config_version=version,
        )
        builds = [batch for batch, *_ in EARLIER_BUILDS] + [BATCH]
        comparisons = [compare_batches(engine, BRANCH, base, new) for base, new in zip(builds, builds[1:])]
    print(format_trends(trends))
    trends_path = write_trends(trends, lake / "trends.html", link_base=LINK_BASE)
    _step("7/7 comparing the builds: 1.4.0 -> 1.4.1 -> 1.4.2 (new failures, fixes, flaky experiences)")
    for comparison in comparisons:
        print(format_comparison(comparison))
        print()
    compare_path = write_compare(comparisons[-1], lake / "compare.html")
    print(f"\nreport:  {report_path}")
    print(f"trends:  {trends_path}")
    print(f"compare: {compare_path}")
    print(f"lake:    {lake}  (branch {BRANCH!r}, batch {BATCH!r}; done in {time.perf_counter() - started:.1f} s)")
    lakegate, where = lakegate_command(), shlex.quote(str(args.lake))
    print("\nnext:")
    print(
        f'  {lakegate} query --lake {where} "SELECT metric_name, status, COUNT(*) FROM metric_results '
        'GROUP BY 1, 2 ORDER BY 1, 2"'
    )
    print(f"  {lakegate} metrics run --lake {where} --branch {BRANCH} --batch {BATCH} --metrics-set '{METRICS_SET}'")
    print(f"  {lakegate} metrics dashboard --lake {where} --branch {BRANCH} --window 2")
    batches = ",".join([*(batch for batch, *_ in EARLIER_BUILDS), BATCH])
    print(f"  {lakegate} metrics report --lake {where} --branch {BRANCH} --batches {batches}")
    print(
        f"  {lakegate} compare --lake {where} --branch {BRANCH} --base-build 1.4.1 --build {BUILD_VERSION} "
        "--fail-on new-failures"
    )
    print(f"  {lakegate} flakes --lake {where} --branch {BRANCH}")
    print(f"  {lakegate} serve --lake {where}   # then open {LINK_BASE}/")
    return 0
