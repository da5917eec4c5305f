"""The parser of `lakegate lake compact`."""

from __future__ import annotations

import argparse
from pathlib import Path

from lakegate.gateway.cli.parsers import Command


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add `compact` to the `lakegate lake` commands."""
    parser = commands.add_parser(
        "compact",
        help="merge each batch's per-job files into one file per table (and migrate a layout v1 branch)",
        description="Merge the per-job Parquet files of each batch into one file per table, sorted by job_id "
        "(small jobs share row groups), in one commit per batch (a query sees each batch all old or all new; "
        "every answer stays the same). A job ingested again later replaces its rows inside the batch's "
        "file. A branch written by an earlier lakegate (job_id=<J>/ directories) is migrated first, which "
        "`lakegate trino-ddl` needs. `lakegate metrics run` compacts the batch it evaluates.",
    )
    parser.add_argument("--lake", required=True, type=Path, metavar="DIR", help="the lake's directory")
    parser.add_argument("--branch", default="main", metavar="B", help="the branch (default: main)")
    parser.add_argument(
        "--batch",
        action="append",
        dest="batches",
        metavar="ID",
        help="compact this batch only (repeat for several; default: every batch of the branch)",
    )
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show a progress bar on standard error (default: when it is a terminal)",
    )
    parser.set_defaults(func=Command("compact", "compact_command"))
