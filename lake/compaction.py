"""Compaction: a batch's per-job files become one file per table (`lakegate lake compact`).

Each job table's files of the batch are merged into one file sorted by `job_id` (`lake.batch_files`),
and the record is switched to them in ONE commit for every table of the
batch: a reader sees the batch all old or all new, and a compaction killed before its commit leaves
only files no record row names (removed by the next write of the batch). Each job keeps its own
record row (rows, time range), so scoped queries still find only their job's rows. It runs under
the batch's `paths.batch_files_lock`, which every commit that changes the batch's job tables takes
(ingest, metadata updates, `metrics run`): nothing changes the batch's files between the reading
and the commit, and no other lock is needed. A layout v1 branch is migrated first
(`record.Change.hold`). Re-ingesting a job of a compacted batch rewrites the compacted files
without it in the ingest's own commit (`record.Change`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from lakegate.lake import paths
from lakegate.lake.record import LAYOUT, Change, FileEntry, Record


@dataclass(frozen=True)
class Compacted:
    """What compacting one batch did: its jobs, and its job tables' files before and after."""

    batch_id: str
    jobs: int
    files_before: int
    files_after: int

    @property
    def changed(self) -> bool:
        return self.files_after != self.files_before


def migrate(lake: Path, branch: str, *, progress: bool = False) -> tuple[int, int] | None:
    """Migrate a layout v1 branch (every batch's files merged, `job_id` written into them); returns its
    data files before and after, or None when the branch is in layout v2 already."""
    record = Record(lake, branch)
    try:
        if record.layout() == LAYOUT:
            return None
        before = len({entry.path for entry in record.snapshot().files})
        change = Change(lake, branch, progress=progress)
        with change.hold(()):
            change.discard()
        return before, len({entry.path for entry in record.snapshot().files})
    finally:
        record.close()


def compact(lake: Path, branch: str, batch_ids: list[str] | None = None, *, progress: bool = False) -> list[Compacted]:
    """Compact the given batches of `branch` (default: every batch with jobs), one commit each.

    LookupError for a batch without jobs.
    """
    record = Record(lake, branch)
    try:
        known = record.batches()
    finally:
        record.close()
    for batch_id in batch_ids or ():
        paths.check_segment(batch_id, "batch id")
        if batch_id not in known:
            raise LookupError(f"batch {batch_id!r} has no jobs on branch {branch!r}")
    return [compact_batch(lake, branch, batch_id, progress=progress) for batch_id in batch_ids or known]


def compact_batch(lake: Path, branch: str, batch_id: str, *, progress: bool = False) -> Compacted:
    """Merge every job table's files of one batch into one file per table (per schema), in one commit."""
    change = Change(lake, branch, progress=progress)
    with change.hold([batch_id]):
        tables: dict[str, list[FileEntry]] = {}
        for entry in change.record.snapshot(batch_id).files:
            if entry.table not in paths.BATCH_TABLES:
                tables.setdefault(entry.table, []).append(entry)
        before = _files(tables)
        jobs = len({entry.job_id for entries in tables.values() for entry in entries})
        bar = tqdm(
            sorted(tables.items()), desc=f"compacting {batch_id}", unit="table", disable=not progress, leave=False
        )
        for _, entries in bar:
            if len({entry.path for entry in entries}) > 1 or any(paths.is_v1_path(e.path) for e in entries):
                change.add_merged(entries)
        if not change.entries:
            change.discard()
            return Compacted(batch_id, jobs, before, before)
        after = dict(tables)
        for entry in change.entries:
            after[entry.table] = [e for e in after[entry.table] if e.key != entry.key] + [entry]
        change.commit(f"compact {batch_id}")
    return Compacted(batch_id, jobs, before, _files(after))


def _files(tables: dict[str, list[FileEntry]]) -> int:
    return sum(len({entry.path for entry in entries}) for entries in tables.values())
