"""`lakegate compare` (what changed between two batches of a branch) and `lakegate flakes` (which
experiences vary across runs of one build).

Exit codes of `compare`: 0 the comparison was made (whatever it found), 4 with `--fail-on
new-failures` when an experience that passed on the base fails now (a flaky one only with
`--strict`), 5 with `--fail-on regression` when a trend alert (gateway/metrics/alerts.py) marks a
metric of the new batch's build (and no new failure gave 4), 1 usage errors (an unknown lake,
branch, batch or build) or an unwritable report; a malformed command line is argparse's exit code 2.
`flakes` exits 0, or 1 for usage errors.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from lakegate.dialect.errors import DialectError
from lakegate.gateway.cli.backends import add_backend_arguments, engine_from_args
from lakegate.gateway.cli.errors import UserError, os_error_text, positive
from lakegate.gateway.cli.metrics import format_alerts
from lakegate.gateway.metrics.alerts import HISTORY, K, batch_checks
from lakegate.gateway.metrics.compare import (
    ALPHA,
    FLAKE_WINDOW,
    GONE,
    NEW,
    SAME,
    Comparison,
    MetricChange,
    compare_batches,
    latest_batch_of_build,
)
from lakegate.gateway.metrics.compare_page import write_compare
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.flakes import CV_THRESHOLD, Flake, find_flakes
from lakegate.gateway.metrics.templates import format_number
from lakegate.gateway.metrics.trends import branch_batches
from lakegate.lake.catalog import Catalog
from lakegate.lake.paths import LakePathError

EXIT_OK, EXIT_USAGE, EXIT_NEW_FAILURES, EXIT_REGRESSION = 0, 1, 4, 5
FAIL_ON = ("new-failures", "regression")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    compare = subparsers.add_parser(
        "compare",
        help="compare two batches (or builds) of a branch: new failures, fixes, flaky experiences, metric changes",
        description="Compare a new batch with a base batch of a branch, from the statuses and metric results "
        "already in the lake (run 'lakegate metrics run' on both first). Jobs are paired by experience "
        "(repeated runs are one group: worst status, mean scalar). Each experience and metric is tagged new "
        "failure, flaky (a new failure on an experience that is flaky), still failing, gone, new, fixed or "
        "same; scalars show base, new and change; series metrics (line, bar, histogram, state timeline) are "
        "compared with a SciPy two-sample test (Kolmogorov-Smirnov; chi-square for states) and flagged when "
        "p < --alpha. Exit code: 0 compared, 4 --fail-on new-failures and an experience that passed on the "
        "base fails now, 5 --fail-on regression and a trend alert marks a scalar metric of the new batch's "
        "build (its value beyond --alert-k standard deviations of the --alert-builds builds before it; 4 "
        "wins when both are asked for and found), 1 usage error.",
    )
    _lake_and_branch(compare)
    base = compare.add_mutually_exclusive_group(required=True)
    base.add_argument("--base", metavar="BATCH", help="the base batch (what the new batch is compared with)")
    base.add_argument("--base-build", metavar="V", help="the base build version: its latest batch")
    new = compare.add_mutually_exclusive_group(required=True)
    new.add_argument("--batch", metavar="BATCH", help="the new batch")
    new.add_argument("--build", metavar="V", help="the new build version: its latest batch")
    compare.add_argument(
        "--format",
        choices=("table", "json"),
        default="table",
        help="output: tables of the experiences and changed metrics by severity (default), or JSON with "
        "every experience and metric",
    )
    compare.add_argument("--all", action="store_true", help="the table lists unchanged metrics too")
    compare.add_argument(
        "--report", type=Path, metavar="FILE.html", help="also write an offline HTML page of the comparison"
    )
    compare.add_argument(
        "--fail-on",
        choices=FAIL_ON,
        action="append",
        default=[],
        help="new-failures: exit 4 when an experience that passed on the base fails now (known failures and "
        "flaky experiences do not count; see --strict); regression: exit 5 when a trend alert marks a metric "
        "of the new batch, as 'lakegate metrics dashboard --fail-on regression' does (may be given twice)",
    )
    compare.add_argument(
        "--alert-k",
        type=positive(float),
        default=K,
        metavar="K",
        help=f"trend alert: a scalar metric whose value on the new batch's build lies outside K standard "
        f"deviations of its previous builds (default {K:g})",
    )
    compare.add_argument(
        "--alert-builds",
        type=positive(int),
        default=HISTORY,
        metavar="N",
        help=f"trend alert: compare the new batch's build with the N builds before it (default {HISTORY}; 2 at least)",
    )
    compare.add_argument(
        "--strict", action="store_true", help="with --fail-on new-failures, a new failure of a flaky experience counts"
    )
    compare.add_argument(
        "--alpha",
        type=_probability,
        default=ALPHA,
        metavar="P",
        help=f"significance level of the two-sample tests (default {ALPHA})",
    )
    _flake_options(compare, "flaky experiences are looked for in the last N batches up to the new one")
    add_backend_arguments(compare)
    compare.set_defaults(func=compare_command)

    flakes = subparsers.add_parser(
        "flakes",
        help="list the experiences whose status or metric values vary across runs of one build",
        description="For every experience and build in the last --window batches of a branch: its runs, how "
        "often its job status changed from one run to the next (flip rate) and the largest coefficient of "
        "variation of its scalar metrics. Flaky: a status flip, or a CV above --cv. Flakiest first.",
    )
    _lake_and_branch(flakes)
    _flake_options(flakes, "look at the last N batches of the branch")
    flakes.add_argument("--format", choices=("table", "json"), default="table", help="output (default: table)")
    flakes.add_argument("--all", action="store_true", help="list every experience, not only the flaky ones")
    add_backend_arguments(flakes)
    flakes.set_defaults(func=flakes_command)


def _lake_and_branch(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--lake", required=True, type=Path, metavar="DIR", help="the lake's directory")
    parser.add_argument("--branch", required=True, metavar="B", help="the branch")


def _flake_options(parser: argparse.ArgumentParser, window_help: str) -> None:
    parser.add_argument(
        "--window",
        type=positive(int),
        default=FLAKE_WINDOW,
        metavar="N",
        help=f"{window_help} (default {FLAKE_WINDOW})",
    )
    parser.add_argument(
        "--cv",
        type=positive(float),
        default=CV_THRESHOLD,
        metavar="X",
        help="an experience with a scalar whose coefficient of variation over runs of one build exceeds X "
        f"is flaky (default {CV_THRESHOLD})",
    )


def _probability(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a probability between 0 and 1, got {text!r}") from None
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"expected a probability between 0 and 1, got {text!r}")
    return value


def _check_branch(lake: Path, branch: str) -> None:
    if not lake.is_dir():
        raise UserError(f"no lake at {str(lake)!r}")
    try:
        branches = Catalog(lake).branches()
    except LakePathError as error:
        raise UserError(str(error)) from None
    if branch not in branches:
        raise UserError(f"no branch {branch!r} in {lake} (branches: {', '.join(map(repr, branches)) or 'none'})")


def compare_command(args: argparse.Namespace) -> int:
    _check_branch(args.lake, args.branch)
    if args.report is not None and args.report.is_dir():
        raise UserError(f"--report {str(args.report)!r} is a directory; name the HTML file to write")
    queries = engine_from_args(args, args.lake)
    engine = MetricsEngine(args.lake, queries)
    try:
        base = args.base or latest_batch_of_build(engine, args.branch, args.base_build)
        new = args.batch or latest_batch_of_build(engine, args.branch, args.build)
        comparison = compare_batches(
            engine, args.branch, base, new, alpha=args.alpha, flake_window=args.window, cv_threshold=args.cv
        )
        checks = (
            batch_checks(engine, args.branch, new, k=args.alert_k, history=args.alert_builds)
            if "regression" in args.fail_on
            else None
        )
    except LookupError as error:
        raise UserError(str(error.args[0])) from None
    except (DialectError, LakePathError) as error:
        raise UserError(str(error)) from None
    finally:
        queries.close()
    if args.format == "json":
        answer = comparison.as_dict()
        if checks is not None:
            answer["trend_checks"] = [c.as_dict() for c in checks]
        json.dump(answer, sys.stdout, ensure_ascii=False, indent=2)
        sys.stdout.write("\n")
    else:
        print(format_comparison(comparison, every_metric=args.all, strict=args.strict))
        if checks is not None:
            print(
                format_alerts(checks) if checks else f"\ntrend alerts: no scalar metric of {new} has 2 earlier builds"
            )
    if args.report is not None:
        try:
            path = write_compare(comparison, args.report)
        except OSError as error:
            raise UserError(f"cannot write the report {str(args.report)!r}: {os_error_text(error)}") from None
        print(f"report: {path.resolve()}", file=sys.stderr if args.format == "json" else sys.stdout)
    if "new-failures" in args.fail_on and comparison.new_failures(strict=args.strict):
        return EXIT_NEW_FAILURES
    if checks is not None and any(c.alert for c in checks):
        return EXIT_REGRESSION
    return EXIT_OK


def _number(value: float | None) -> str:
    if value is None:
        return ""
    return format_number(value)


def _relative(value: float | None) -> str:
    if value is None or not math.isfinite(value):
        return ""
    return f"{value * 100:+.1f}%"


def _p_value(change: MetricChange) -> str:
    if change.series is None:
        return ""
    return f"{change.series.p_value:.3g}{' *' if change.significant else ''}"


def _aligned(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> list[str]:
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(len(header))]
    return ["  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip() for row in [header, *rows]]


def format_comparison(comparison: Comparison, *, every_metric: bool = False, strict: bool = False) -> str:
    """The comparison as text: experiences by severity, changed metrics by severity, then the counts."""
    jobs = [
        (
            j.tag.upper(),
            j.experience or "",
            j.base_status or "-",
            j.new_status or "-",
            f"{j.base_runs or 0}/{j.new_runs or 0}",
        )
        for j in comparison.jobs
    ]
    lines = _aligned(("TAG", "EXPERIENCE", "BASE", "NEW", "RUNS"), jobs)
    whole = {(j.experience, j.tag) for j in comparison.jobs if j.tag in (NEW, GONE)}  # listed above already
    shown = [m for m in comparison.metrics if every_metric or (m.changed and (m.experience, m.tag) not in whole)]
    if shown:
        rows = [
            (
                m.tag.upper(),
                m.experience or "(batch)",
                m.metric,
                f"{m.base_status or '-'} -> {m.new_status or '-'}",
                _number(m.base_value),
                _number(m.new_value),
                _number(m.change),
                _relative(m.relative_change),
                _p_value(m),
            )
            for m in shown
        ]
        lines += ["", *_aligned(("TAG", "EXPERIENCE", "METRIC", "STATUS", "BASE", "NEW", "CHANGE", "REL", "P"), rows)]
    unchanged = len(comparison.metrics) - len(shown)
    counts = comparison.counts()
    metric_counts = comparison.metric_counts()
    summary = ", ".join(f"{count} {tag}" for tag, count in counts.items() if count)
    metric_summary = ", ".join(f"{count} {tag}" for tag, count in metric_counts.items() if count and tag != SAME)
    failures = comparison.new_failures(strict=strict)
    lines += [
        "",
        f"{comparison.base} ({', '.join(comparison.base_builds) or '?'}) -> {comparison.new} "
        f"({', '.join(comparison.new_builds) or '?'}) on branch {comparison.branch!r}: "
        f"experiences: {summary or 'none'}; metrics: {metric_summary or 'no change'}"
        f"{f' ({unchanged} unchanged or of new and gone experiences not listed)' if unchanged else ''}; "
        f"flaky: {', '.join(sorted(comparison.flaky)) or 'none'}; {comparison.seconds:.1f} s",
        f"new failures: {', '.join(str(j.experience) for j in failures) or 'none'}",
    ]
    return "\n".join(lines)


def flakes_command(args: argparse.Namespace) -> int:
    _check_branch(args.lake, args.branch)
    queries = engine_from_args(args, args.lake)
    engine = MetricsEngine(args.lake, queries)
    try:
        batches = [b.batch_id for b in branch_batches(engine, args.branch)][-args.window :]
        flakes = find_flakes(engine, args.branch, batches, cv_threshold=args.cv)
    except (DialectError, LakePathError) as error:
        raise UserError(str(error)) from None
    finally:
        queries.close()
    listed = [f for f in flakes if args.all or f.flaky]
    if args.format == "json":
        answer = {"branch": args.branch, "batches": batches, "flakes": [f.as_dict() for f in listed]}
        json.dump(answer, sys.stdout, ensure_ascii=False, indent=2)
        sys.stdout.write("\n")
    else:
        print(format_flakes(listed, batches))
    return EXIT_OK


def format_flakes(flakes: list[Flake], batches: list[str]) -> str:
    """The flakes as text, flakiest first, then which batches were looked at."""
    rows = [
        (
            "FLAKY" if f.flaky else "",
            f.experience or "",
            f.build or "",
            str(f.runs),
            f"{f.flip_rate:.2f}",
            ",".join(f.statuses),
            "" if f.cv is None else f"{f.cv:.3f} ({f.cv_metric})",
        )
        for f in flakes
    ]
    lines = _aligned(("", "EXPERIENCE", "BUILD", "RUNS", "FLIP RATE", "STATUSES", "MAX CV"), rows) if rows else []
    flaky = sum(1 for f in flakes if f.flaky)
    lines.append(f"{flaky} flaky experience(s) over the last {len(batches)} batches: {', '.join(batches) or 'none'}")
    return "\n".join(lines)
