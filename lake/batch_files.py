"""Files that hold many jobs of one batch: written sorted by `job_id`, a row group per job or per
run of small jobs.

`write_jobs` reads each job's rows from its current file (a job's own file, a file shared with
other jobs of its batch, or a layout v1 file without the `job_id` column, which it adds) and writes
them into one new Parquet file, so Parquet's statistics on `job_id` let a reader of one job skip the
others. Small jobs share a row group (up to `GROUP_ROWS` rows, a job never split below it): a row
group per job of `metadata` (one row each) would make a count over 10,000 jobs read 10,000 row
groups (80 ms per 1,000 measured), while the statistics of a shared group, sorted by job, still
skip every group that does not hold the job. Compaction, the split of a shared file when one of
its jobs is replaced, and the migration of a layout v1 branch all write files this way
(`lake.record.Change`, `lake.compaction`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc

from lakegate.lake import paths
from lakegate.lake.storage import LOCAL

JOB_ID = "job_id"
#: Rows a row group holds before the next job starts a new one (jobs smaller than this share one).
GROUP_ROWS = 16 * 1024
#: Rows per row group within one job's rows (a job larger than this gets several).
ROW_GROUP_ROWS = 1 << 20


def job_rows(source: Path, job_id: str, *, v1: bool, position: int) -> pa.Table:
    """The rows of one job in `source`: all of a v1 file (`job_id` added at `position`), else those
    whose `job_id` is `job_id` (row groups of other jobs are skipped by their statistics)."""
    if not v1:
        return LOCAL.read_parquet(source, filters=pc.field(JOB_ID) == job_id, partitioning=None)
    table = LOCAL.read_parquet(source, partitioning=None)
    return table.add_column(position, JOB_ID, pa.repeat(pa.scalar(job_id, pa.string()), table.num_rows))


def jobs_rows(source: Path, job_ids: Sequence[str], *, v1: bool, position: int) -> dict[str, pa.Table]:
    """The rows of each of `job_ids` in `source`, read once (a v1 file holds one job: `job_rows`)."""
    if v1:
        return {job_id: job_rows(source, job_id, v1=True, position=position) for job_id in job_ids}
    table = jobs_table(source, job_ids, v1=False, position=position)
    return {job_id: table.filter(pc.field(JOB_ID) == job_id) for job_id in job_ids}


def jobs_table(source: Path, job_ids: Sequence[str], *, v1: bool, position: int) -> pa.Table:
    """The rows of `job_ids` in `source`, as one table in file order (a v1 file holds one job: `job_rows`)."""
    if v1:
        return pa.concat_tables(job_rows(source, job_id, v1=True, position=position) for job_id in job_ids)
    return LOCAL.read_parquet(source, filters=pc.field(JOB_ID).isin(list(job_ids)), partitioning=None)


def job_id_position(table: str, names: Sequence[str]) -> int:
    """Where `job_id` goes among a v1 file's columns `names`: after `org_id` in `metadata` (its place in
    the table), last in topics and `events` (after `build_version`)."""
    return 1 if table == paths.METADATA_TABLE else len(names)


def write_jobs(target: Path, parts: Sequence[tuple[str, pa.Table]]) -> None:
    """Write the jobs' rows (`parts`: job id -> rows, one schema) into `target`, sorted by job id: a
    job starts a new row group once the current one holds `GROUP_ROWS` rows."""
    ordered = sorted(parts, key=lambda part: part[0])
    schema = ordered[0][1].schema
    strings = [f.name for f in schema if pa.types.is_string(f.type)]
    with LOCAL.parquet_writer(target, schema, compression="zstd", use_dictionary=strings) as writer:
        group: list[pa.Table] = []
        for _, rows in ordered:
            group.append(rows.cast(schema))
            if sum(t.num_rows for t in group) >= GROUP_ROWS:
                writer.write_table(pa.concat_tables(group), row_group_size=ROW_GROUP_ROWS)
                group = []
        if sum(t.num_rows for t in group):
            writer.write_table(pa.concat_tables(group), row_group_size=ROW_GROUP_ROWS)
