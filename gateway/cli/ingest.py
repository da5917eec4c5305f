"""`lakegate ingest` (emissions files of one job -> the lake) and `lakegate lake ls` (what is in it)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from lakegate.gateway.cli.command_errors import (
    UserError,
    existing_configs,
    print_config_warnings,
    writable_lake,
)
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.catalog import Catalog
from lakegate.lake.config import Config, ConfigError, find_default_config, load_config
from lakegate.lake.ingest import IngestError, IngestReport, LineProblem, ingest_job
from lakegate.lake.metadata import MetadataError, load_metadata_file
from lakegate.lake.paths import LakePathError

#: How many problems are printed before "... and N more".
SHOWN_PROBLEMS = 20


def _config(args: argparse.Namespace) -> Config:
    paths = args.config_paths
    if not paths:
        try:
            current = BranchConfigs(args.lake, args.branch).current()
        except ConfigError as exc:
            raise UserError(f"the branch's stored config does not load: {exc.problems[0]}") from None
        if current is not None:
            return current
        found = find_default_config()
        if found is None:
            raise UserError(
                f"no config: branch {args.branch!r} has none in the lake yet, and there is no "
                ".resim/metrics/config.resim.yaml here; pass --metrics-config-path"
            )
        paths = [found]
    config = load_config(existing_configs(paths), strict=args.strict)
    print_config_warnings(config)
    return config


def _logs(args: argparse.Namespace) -> Path | None:
    """The job's logs folder: --logs, else `logs/` beside the first emissions file (as SignalFlag's demo lays
    a job out), else None."""
    if args.logs is not None:
        if not args.logs.is_dir():
            raise UserError(f"logs folder {str(args.logs)!r} does not exist or is not a folder")
        return args.logs
    beside = args.emissions[0].parent / "logs"
    return beside if beside.is_dir() else None


def _metadata(args: argparse.Namespace) -> dict[str, Any]:
    values: dict[str, Any] = {}
    if args.metadata is not None:
        if not args.metadata.is_file():
            raise UserError(f"metadata file {str(args.metadata)!r} does not exist")
        values.update(load_metadata_file(args.metadata))
    flags = {
        "experience_name": args.experience_name,
        "build_name": args.build_name,
        "build_version": args.build_version,
        "experience_tag_names": args.tags,
        "job_status": args.job_status,
    }
    values.update({k: v for k, v in flags.items() if v is not None})
    return values


def _print_problems(title: str, problems: Sequence[str], total: int | None = None) -> None:
    total = len(problems) if total is None else total
    print(f"lakegate: {title}", file=sys.stderr)
    for problem in problems[:SHOWN_PROBLEMS]:
        print(f"  {problem}", file=sys.stderr)
    if total > SHOWN_PROBLEMS:
        print(f"  ... and {total - SHOWN_PROBLEMS} more", file=sys.stderr)


def _cause(first: LineProblem, count: int) -> str:
    """One cause of bad lines: its first line, and how many more lines share its reason."""
    return f"{first}" + (f" (and {count - 1} more line{'s' if count > 2 else ''} like it)" if count > 1 else "")


def ingest_command(args: argparse.Namespace) -> int:
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    writable_lake(args.lake)
    try:
        config = _config(args)
        report = ingest_job(
            args.lake,
            args.branch,
            args.batch,
            args.job,
            args.emissions,
            config=config,
            metadata=_metadata(args),
            skip_bad_lines=args.skip_bad_lines,
            progress=progress,
            logs=_logs(args),
        )
    except ConfigError as exc:
        _print_problems(f"the config has {len(exc.problems)} problem(s):", [str(p) for p in exc.problems])
        return 1
    except MetadataError as exc:
        _print_problems("bad metadata:", exc.problems)
        return 1
    except IngestError as exc:
        causes = exc.bad_lines.causes.values()
        _print_problems(
            exc.summary,
            [_cause(first, count) for first, count in causes] or [str(p) for p in exc.problems],
            len(causes) or exc.total,
        )
        return 1
    except (LakePathError, OSError) as exc:
        raise UserError(str(exc)) from None
    print(summary(report))
    return 0


def summary(report: IngestReport) -> str:
    """A few lines saying what an ingest wrote."""
    written = {name: rows for name, rows in report.rows.items() if rows}
    total = sum(written.values())
    lines = [
        f"ingested job {report.job_id!r} of batch {report.batch_id!r} on branch {report.branch!r}: "
        f"{total:,} rows in {len(written)} topic(s), {report.events:,} event(s), from {report.lines:,} lines "
        f"in {report.seconds:.2f} s (config version {report.config_version})"
    ]
    width = max((len(name) for name in written), default=0)
    lines += [f"  {name:<{width}}  {rows:>12,}" for name, rows in written.items()]
    empty = [name for name, rows in report.rows.items() if not rows]
    if empty:
        lines.append(f"  no rows for: {', '.join(empty)}")
    if report.logs is not None:
        lines.append(f"  logs: copied from {report.logs}")
    if report.bad_lines:
        lines.append(
            f"skipped {report.bad_lines:,} bad line(s), dropping {report.skipped}; they are in {report.quarantine}"
        )
        lines += [f"  {_cause(first, count)}" for first, count in report.causes[:SHOWN_PROBLEMS]]
        if len(report.causes) > SHOWN_PROBLEMS:
            lines.append(f"  ... and {len(report.causes) - SHOWN_PROBLEMS} more")
    return "\n".join(lines)


def ls_command(args: argparse.Namespace) -> int:
    catalog = Catalog(args.lake)
    if not args.lake.is_dir():
        raise UserError(f"no lake at {str(args.lake)!r}")
    if args.branch is None:
        branches = catalog.branches()
        if not branches:
            print(f"no branches in {args.lake}")
        for branch in branches:
            jobs = catalog.jobs(branch)
            batches = len({job.batch_id for job in jobs})
            batch_word, job_word = "batch" if batches == 1 else "batches", "job" if len(jobs) == 1 else "jobs"
            print(f"{branch}  ({batches} {batch_word}, {len(jobs)} {job_word})")
        return 0
    if args.branch not in catalog.branches():
        raise UserError(f"no branch {args.branch!r} in {args.lake}")
    try:
        jobs = catalog.jobs(args.branch)
        tables = catalog.tables(args.branch)
    except ConfigError as exc:
        raise UserError(f"the branch's stored config does not load: {exc.problems[0]}") from None
    print(f"branch {args.branch}")
    batches: dict[str, list[str]] = {}
    for job in jobs:
        batches.setdefault(job.batch_id, []).append(job.job_id)
    print(f"batches ({len(batches)}):")
    for batch, job_ids in batches.items():
        print(f"  {batch}: {len(job_ids)} job(s): {', '.join(job_ids)}")
    print(f"tables ({len(tables)}):")
    width = max(len(t.name) for t in tables)
    for table in tables:
        columns = ", ".join(f"{name} {kind}" for name, kind in table.columns)
        rows = "row " if table.row_count == 1 else "rows"
        print(f"  {table.name:<{width}}  {table.kind:<8}  {table.row_count:>12,} {rows}  ({columns})")
    unreadable = catalog.unreadable(args.branch)
    if unreadable:
        print(f"unreadable files ({len(unreadable)}): queries that read these jobs fail")
        for entry, reason in unreadable:
            print(f"  {entry.where}: {reason}")
    return 0
