"""`lakegate lake compact`: merge each batch's per-job files into one file per table (`lake.compaction`)."""

from __future__ import annotations

import argparse
import sys

from lakegate.gateway.cli.command_errors import UserError
from lakegate.lake.catalog import Catalog
from lakegate.lake.compaction import compact, migrate
from lakegate.lake.paths import LakePathError


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
