"""The parser of `lakegate demo`."""

from __future__ import annotations

import argparse
from pathlib import Path

from lakegate.gateway.cli.parsers import Command

#: The metrics set of the example config the demo evaluates.
METRICS_SET = "Nav Metrics"


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
        help="jobs in the batch, cycling through the experiences and outcomes, plus two repeated runs of "
        "Narrow Aisle (default 6: two each PASSED, WARNING and BLOCKER, then the two runs, PASSED)",
    )
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show progress bars on standard error (default: when it is a terminal)",
    )
    parser.set_defaults(func=Command("demo", "demo_command"))
