"""Ingestion of one job: scan, write to staging, then publish the staged files as the job's tables
in one commit of the branch's record."""

from __future__ import annotations

import json
import sys
import time
from collections import deque
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow.compute as pc
from tqdm import tqdm

from lakegate.lake import paths, platform_tables
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import Config
from lakegate.lake.ingest import scan
from lakegate.lake.ingest.rules import MAX_PROBLEMS, BadLines, IngestError, LineProblem
from lakegate.lake.ingest.scan import (
    Block,
    Hinter,
    Result,
    merge_results,
    process_block,
    read_blocks,
    topic_plans,
)
from lakegate.lake.ingest.write import JobWriter
from lakegate.lake.metadata import build_metadata_row, metadata_table, write_metadata_file
from lakegate.lake.record import Change
from lakegate.lake.storage import LOCAL


@dataclass
class IngestReport:
    """What one ingest did."""

    branch: str
    batch_id: str
    job_id: str
    rows: dict[str, int]  # every declared topic -> rows written (0 if none), and each platform table written
    events: int
    lines: int
    bad_lines: int
    quarantine: Path | None
    seconds: float
    config_version: int
    files: list[Path] = field(default_factory=list)
    problems: list[LineProblem] = field(default_factory=list)  # the first MAX_PROBLEMS, when skipped
    skipped: str = ""  # what the skipped lines held, per topic (BadLines.what_skipping_drops)
    causes: list[tuple[LineProblem, int]] = field(default_factory=list)  # skipped lines by cause
    logs: Path | None = None  # the folder the job's logs were copied from


def ingest_job(
    lake: Path,
    branch: str,
    batch_id: str,
    job_id: str,
    emissions: Sequence[Path],
    *,
    config: Config,
    metadata: dict[str, Any] | None = None,
    skip_bad_lines: bool = False,
    progress: bool = False,
    logs: Path | None = None,
) -> IngestReport:
    """Ingest the emissions files of one job into the lake (replacing an earlier ingest of it).

    The platform's files beside them (`resource_metrics.resim.jsonl`, `test_length_metric.resim.jsonl`:
    `lake.platform_tables`) are read with them, unless already listed.
    `logs`: a folder of the job's log files (images, videos ... its metrics show), copied into the lake
    and made the job's logs in the same commit as its tables (None: the job keeps the logs it has).
    Raises IngestError (nothing written) when a line is bad and `skip_bad_lines` is off, or `logs` is
    not a folder; MetadataError for bad metadata, LakePathError for names the lake cannot hold.
    """
    started = time.perf_counter()
    lake = Path(lake)
    paths.encode_branch(branch)
    paths.check_segment(batch_id, "batch id")
    paths.check_segment(job_id, "job id")
    plans = topic_plans(config)
    files = [Path(p) for p in emissions]
    files += platform_tables.files_beside([p for p in files if p.is_file()])
    for path in files:
        if not path.is_file():
            raise IngestError(f"emissions file {str(path)!r} does not exist or is not a file")
    if logs is not None and not Path(logs).is_dir():
        raise IngestError(f"logs folder {str(logs)!r} does not exist or is not a folder")
    row = build_metadata_row(metadata or {}, lake=lake, branch=branch, batch_id=batch_id, job_id=job_id)
    problems: list[LineProblem] = []
    grouped = BadLines()
    bad = 0
    lines = 0
    with paths.job_lock(lake, branch, batch_id, job_id), paths.staging(lake, branch) as scratch:
        writer = JobWriter(scratch, plans, {c: row[c] for plan in plans for c in plan.job_file_columns})
        quarantine = scratch / "quarantine.jsonl"
        with (
            LOCAL.text_writer(quarantine) as bad_lines,
            ThreadPoolExecutor(scan.THREADS, thread_name_prefix="lakegate-ingest") as pool,
            tqdm(
                total=sum(p.stat().st_size for p in files),
                unit="B",
                unit_scale=True,
                desc="ingest",
                disable=not progress,
                file=sys.stderr,
                dynamic_ncols=True,
            ) as bar,
        ):
            pending: deque[tuple[Block, list[Future[Result]]]] = deque()

            def collect() -> None:
                nonlocal bad, lines
                block, futures = pending.popleft()
                results = [f.result() for f in futures]
                found = sorted((p for r in results for p in r.problems), key=lambda p: p.line)
                if found:
                    bad += len(found)
                    problems.extend(found[: max(0, MAX_PROBLEMS - len(problems))])
                    for problem in found:
                        grouped.add(problem)
                    if skip_bad_lines:
                        bad_lines.writelines(
                            json.dumps({"file": p.path, "line": p.line, "reason": p.reason, "text": p.text}) + "\n"
                            for p in found
                        )
                    else:
                        writer.enabled = False  # the job fails: keep counting problems, write nothing
                for index, table in merge_results(results).items():
                    writer.add(index, table)
                lines += len(block.offsets) - 1
                bar.update(len(block.data) - (1 if block.unterminated else 0))
                bar.set_postfix(lines=f"{lines:,}", refresh=False)

            topics = {plan.name: plan.topic for plan in plans}
            hinter = Hinter(plans)
            for path in files:
                for block in read_blocks(path):
                    pending.append((block, process_block(plans, topics, block, pool, hinter)))
                    while len(pending) > 2:
                        collect()
            while pending:
                collect()
        if bad and not skip_bad_lines:
            writer.close()
            raise IngestError(
                f"{bad} bad line{'s' if bad > 1 else ''} in the emissions of job {job_id!r}; nothing "
                "was written (--skip-bad-lines would keep the good rows and drop "
                f"{grouped.what_skipping_drops(topics)})",
                problems,
                bad,
                grouped,
            )
        staged = writer.close()
        metadata_file = scratch / "metadata.parquet"
        write_metadata_file(metadata_table(row), metadata_file)
        staged[paths.METADATA_TABLE] = metadata_file
        staged_logs = None
        if logs is not None:
            staged_logs = scratch / "logs"
            LOCAL.put(Path(logs), staged_logs)
        version = BranchConfigs(lake, branch).store_config(config)
        published = _publish(lake, branch, batch_id, job_id, staged, progress, staged_logs, scratch)
        quarantine_target = paths.quarantine_file(lake, branch, batch_id, job_id)
        if bad:
            paths.publish(quarantine, quarantine_target)
        else:
            LOCAL.delete(quarantine_target, missing_ok=True)
    return IngestReport(
        branch=branch,
        batch_id=batch_id,
        job_id=job_id,
        rows={name: n for name, n in writer.rows.items() if n or name not in platform_tables.TOPICS},
        events=writer.events,
        lines=lines,
        bad_lines=bad,
        quarantine=quarantine_target if bad else None,
        seconds=time.perf_counter() - started,
        config_version=version,
        files=published,
        problems=problems if bad else [],
        skipped=grouped.what_skipping_drops(topics) if bad else "",
        causes=list(grouped.causes.values()),
        logs=None if logs is None else Path(logs),
    )


def _publish(
    lake: Path,
    branch: str,
    batch_id: str,
    job_id: str,
    staged: dict[str, Path],
    progress: bool,
    staged_logs: Path | None,
    scratch: Path,
) -> list[Path]:
    """Make the staged files the job's tables, and `staged_logs` its logs, all at once (one record
    commit); the old files go (`progress`: a bar on standard error if a layout v1 branch is migrated
    first), and so do the batch's metric results this ingest makes stale (`_stale_results_dropped`)."""
    change = Change(lake, branch, progress=progress)
    for name, file in staged.items():
        change.add(name, batch_id, job_id, file)
    if staged_logs is not None:
        change.set_logs(batch_id, job_id, staged_logs)
    change.replace_job(batch_id, job_id)
    with change.hold([batch_id]):  # no other commit between reading the results and replacing them
        _stale_results_dropped(change, batch_id, job_id, scratch)
        return change.commit(f"ingest {batch_id}/{job_id}")


def _stale_results_dropped(change: Change, batch_id: str, job_id: str, scratch: Path) -> None:
    """Stage the batch's `metric_results` without the rows computed on the data this ingest replaces:
    the job's own and the batch metrics' (they read every job: the old version of this one, or the
    batch without it). Its metadata row's statuses start empty as well, so no verdict stays on data
    it was not computed from; the other jobs keep theirs (their data did not change)."""
    current = change.record.find(paths.METRIC_RESULTS_TABLE, batch_id, "")
    if current is None:
        return
    results = LOCAL.read_parquet(change.record.root / current.path, partitioning=None)
    job_ids = results.column("job_id")
    kept = results.filter(pc.fill_null(pc.not_equal(job_ids, job_id), False))
    if kept.num_rows == results.num_rows:
        return
    staged = scratch / "metric_results.parquet"
    LOCAL.write_parquet(kept, staged, compression="zstd")
    change.add(paths.METRIC_RESULTS_TABLE, batch_id, None, staged)
