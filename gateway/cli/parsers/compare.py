"""The parser of `lakegate compare` and `lakegate flakes`."""

from __future__ import annotations

import argparse
from pathlib import Path

from lakegate.gateway.cli.parsers import Command
from lakegate.gateway.cli.parsers.shared_options import add_alert_arguments, add_backend_arguments, positive
from lakegate.gateway.metrics.defaults import ALPHA, CV_THRESHOLD, FLAKE_WINDOW

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
    add_alert_arguments(compare, "the new batch's build")
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
    compare.set_defaults(func=Command("compare", "compare_command"))

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
    flakes.set_defaults(func=Command("compare", "flakes_command"))


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
