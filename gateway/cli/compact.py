"""`lakegate lake compact`: merge each batch's per-job files into one file per table (`lake.compaction`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lakegate.gateway.cli.errors import UserError
from lakegate.lake.catalog import Catalog
from lakegate.lake.compaction import compact, migrate
from lakegate.lake.paths import LakePathError


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
    parser.set_defaults(func=compact_command)


def compact_command(args: argparse.Namespace) -> int:
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    if not args.lake.is_dir():
        raise UserError(f"no lake at {str(args.lake)!r}")
    if args.branch not in Catalog(args.lake).branches():
        raise UserError(f"no branch {args.branch!r} in {args.lake}")
    try:
        migrated = migrate(args.lake, args.branch, progress=progress)
        if migrated is not None:
            print(
                f"migrated branch {args.branch!r} to layout v2 (job_id in the files, each batch's files of a "
                f"table merged): {migrated[0]:,} files -> {migrated[1]:,}"
            )
        done = compact(args.lake, args.branch, args.batches, progress=progress)
    except (LookupError, LakePathError) as exc:
        raise UserError(str(exc)) from None
    for batch in done:
        if batch.changed:
            print(
                f"compacted batch {batch.batch_id!r} ({batch.jobs} job(s)): "
                f"{batch.files_before:,} files -> {batch.files_after:,}"
            )
        else:
            print(f"batch {batch.batch_id!r} ({batch.jobs} job(s)) is compacted already: {batch.files_after:,} files")
    if not done:
        print(f"branch {args.branch!r} has no batches")
    return 0
