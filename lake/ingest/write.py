"""Ingestion write: a job's checked rows -> Parquet files in the staging directory (each topic's, and
the `events` rows of its event topics)."""

from __future__ import annotations

from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from lakegate.lake import paths
from lakegate.lake.ingest.scan import JOB_FILE_COLUMNS, LINE, Plan
from lakegate.lake.schema import EVENTS_COLUMNS, TIMESTAMP, file_schema
from lakegate.lake.storage import LOCAL

#: Rows buffered per topic before they are written as (part of) a row group.
ROWS_PER_WRITE = 128 * 1024
EVENTS_SCHEMA = file_schema(paths.EVENTS_TABLE, EVENTS_COLUMNS)
#: events column -> field types of an event topic that fill it (other types leave it NULL).
EVENT_FIELDS = {
    "name": ("string", "status", "image", "video"),
    "description": ("string", "status", "image", "video"),
    "status": ("string", "status", "image", "video"),
    "tags": ("string[]",),
    "metrics": ("metric[]",),
}


class JobWriter:
    """Buffers each topic's rows and writes them to Parquet files in the staging directory."""

    def __init__(self, scratch: Path, plans: list[Plan], job_values: dict[str, str | None]):
        self.scratch = scratch
        self.plans = plans
        self.job_values = job_values
        self.buffers: dict[int, list[pa.Table]] = {}
        self.buffered: dict[int, int] = {}
        self.writers: dict[str, pq.ParquetWriter] = {}
        self.rows = {plan.name: 0 for plan in plans}
        self.events = 0
        self.enabled = True

    def add(self, index: int, table: pa.Table) -> None:
        plan = self.plans[index]
        self.rows[plan.name] += table.num_rows
        if not self.enabled:
            return
        self.buffers.setdefault(index, []).append(table)
        self.buffered[index] = self.buffered.get(index, 0) + table.num_rows
        if self.buffered[index] >= ROWS_PER_WRITE:
            self._flush(index)

    def _constants(self, schema: pa.Schema, names: tuple[str, ...], count: int) -> list[pa.Array]:
        """The columns `names` of a file of `schema`: each the job's one value, `count` times."""
        return [pa.repeat(pa.scalar(self.job_values.get(name), schema.field(name).type), count) for name in names]

    def _flush(self, index: int) -> None:
        tables = self.buffers.pop(index, [])
        self.buffered[index] = 0
        if not tables:
            return
        plan = self.plans[index]
        table = pa.concat_tables(tables).drop_columns([LINE])
        constants = self._constants(plan.file_schema, plan.job_file_columns, table.num_rows)
        table = pa.Table.from_arrays([*table.columns, *constants], schema=plan.file_schema)
        self._write(plan.name, table)
        if plan.topic.event:
            self._write_events(plan, table)

    def _write_events(self, plan: Plan, table: pa.Table) -> None:
        count = table.num_rows
        columns = [table.column(TIMESTAMP), pa.repeat(pa.scalar(plan.name, pa.string()), count)]
        for name, kinds in EVENT_FIELDS.items():
            if plan.topic.fields.get(name) in kinds:
                columns.append(table.column(name))
            else:
                columns.append(pa.nulls(count, EVENTS_SCHEMA.field(name).type))
        columns += self._constants(EVENTS_SCHEMA, JOB_FILE_COLUMNS, count)
        self.events += count
        self._write(paths.EVENTS_TABLE, pa.Table.from_arrays(columns, schema=EVENTS_SCHEMA))

    def _write(self, name: str, table: pa.Table) -> None:
        writer = self.writers.get(name)
        if writer is None:
            strings = [f.name for f in table.schema if pa.types.is_string(f.type)]  # numbers rarely repeat
            writer = LOCAL.parquet_writer(
                self.scratch / f"{name}.parquet", table.schema, compression="zstd", use_dictionary=strings
            )
            self.writers[name] = writer
        writer.write_table(table, row_group_size=1 << 20)

    def close(self) -> dict[str, Path]:
        """Write what is buffered and close the files; table name -> staged file."""
        if self.enabled:
            for index in list(self.buffers):
                self._flush(index)
        for writer in self.writers.values():
            writer.close()
        return {name: self.scratch / f"{name}.parquet" for name in self.writers}
