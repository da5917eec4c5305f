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
from lakegate.gateway.cli.backends import engine_from_args
from lakegate.gateway.cli.command_errors import UserError, os_error_text
from lakegate.gateway.cli.metrics import format_alerts
from lakegate.gateway.metrics.alerts import batch_checks
from lakegate.gateway.metrics.compare import (
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
from lakegate.gateway.metrics.flakes import Flake, find_flakes
from lakegate.gateway.metrics.templates import format_number
from lakegate.gateway.metrics.trends import branch_batches
from lakegate.lake.catalog import Catalog
from lakegate.lake.paths import LakePathError

EXIT_OK, EXIT_USAGE, EXIT_NEW_FAILURES, EXIT_REGRESSION = 0, 1, 4, 5


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
