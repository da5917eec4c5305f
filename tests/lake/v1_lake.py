"""Make a lake of layout v1 (`<table>/batch_id=<B>/job_id=<J>/` directories, files without `job_id`)
out of a lake written now: what lakes written before layout v2 look like on disk."""

from __future__ import annotations

import shutil
from pathlib import Path

import pyarrow.parquet as pq

from lakegate.lake import paths
from lakegate.lake.record import RECORD, Record


def to_v1(lake: Path, branch: str = "main", *, name: str = "data.parquet", record: bool = False) -> None:
    """Rewrite every job-table file of `branch` in layout v1, one file per job named `name`, and drop
    the record and reader links (`record=True`: record the v1 files as a record of layout v1 would)."""
    root = paths.branch_dir(lake, branch)
    for table in paths.table_names(lake, branch):
        if table in paths.BATCH_TABLES:
            continue
        for file in list(paths.data_files(lake, branch, table)):
            rows = pq.read_table(file, partitioning=None)
            for job_id in sorted(set(rows.column("job_id").to_pylist())):
                mine = rows.filter(rows.column("job_id").to_numpy(zero_copy_only=False) == job_id)
                target = file.parent / f"job_id={job_id}" / name
                target.parent.mkdir(parents=True, exist_ok=True)
                pq.write_table(mine.drop_columns(["job_id"]), target)
            file.unlink()
    for suffix in ("", "-journal"):
        (root / (RECORD + suffix)).unlink(missing_ok=True)
    shutil.rmtree(root / paths.READERS, ignore_errors=True)
    if record:
        opened = Record(lake, branch)
        try:
            opened.generation()  # records the v1 files (a record of layout v1)
        finally:
            opened.close()
