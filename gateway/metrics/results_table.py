"""Evaluated metrics in the lake: the `metric_results` table.

One Parquet file per batch, `<lake>/<branch>/metric_results/batch_id=<B>/<name>.parquet`, one
row per evaluated metric (columns: `lakegate.lake.schema.METRIC_RESULTS_COLUMNS`; `job_id`
is NULL for batch metrics). Evaluating a batch again replaces its file and its jobs' statuses
in one commit of the branch's record, so the table always holds the latest evaluation of each
batch, and the statuses in `metadata` are the ones it computed. The catalog shows it as a table of
the branch, so trends across batches and builds are one SQL query away::

    SELECT m.build_name, AVG(r.scalar_value)
    FROM metric_results r JOIN metadata m ON r.batch_id = m.batch_id AND r.job_id = m.job_id
    WHERE r.metric_name = 'Time to reach final goal'
    GROUP BY m.build_name

`error_message` says why a metric errored or was not run; `error_line` / `error_column` are
the position in the failing query, `error_location` the same place in the config file.
"""

from __future__ import annotations

import contextlib
import datetime as dt
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import orjson
import pyarrow as pa

from lakegate.gateway.metrics.metric_result import MetricResult
from lakegate.lake import paths
from lakegate.lake.metadata import read_metadata_rows, stage_metadata_rows
from lakegate.lake.record import Change, FileEntry, JobVersions, Record, current_file
from lakegate.lake.schema import METRIC_RESULTS_COLUMNS, file_schema
from lakegate.lake.storage import LOCAL

#: The Arrow schema of a batch's results file (batch_id lives in the directory name).
SCHEMA = file_schema(paths.METRIC_RESULTS_TABLE, METRIC_RESULTS_COLUMNS)


def _json(value: Any) -> str | None:
    """Compact JSON text (orjson: figures hold up to millions of numbers)."""
    return None if value is None else orjson.dumps(value, option=orjson.OPT_SERIALIZE_NUMPY).decode()


def result_row(
    result: MetricResult, *, metrics_set: str | None, config_version: int | None, evaluated_at: dt.datetime
) -> dict[str, Any]:
    """The `metric_results` row of one evaluated metric."""
    rendered, error = result.rendered, result.error
    details = None
    if rendered is not None and (rendered.table is not None or rendered.images or rendered.problems):
        details = {"table": rendered.table, "images": rendered.images, "problems": rendered.problems}
    return {
        "batch_id": result.batch_id,
        "job_id": result.job_id,
        "metric_name": result.metric,
        "metric_type": result.metric_type,
        "template": result.template,
        "status": result.status,
        "scalar_value": result.scalar_value,
        "value_text": result.value_text,
        "units": result.units,
        "figure_json": _json(rendered.figure) if rendered is not None else None,
        "details_json": _json(details),
        "error_message": error.message if error is not None else None,
        "error_line": error.line if error is not None else None,
        "error_column": error.column if error is not None else None,
        "error_location": str(error.location) if error is not None and error.location is not None else None,
        "metrics_set": metrics_set,
        "config_version": config_version,
        "evaluated_at": evaluated_at,
    }


class ResultsWriter:
    """Writes the results of one evaluation of a batch as they come (one row group per `write`) and
    stages the jobs' new statuses (`stage_statuses`); `commit` then switches the batch's results and
    every staged status in ONE record commit (`lake.record`), so they always agree. Closed without
    `commit`, nothing changes. The caller holds the batch's lock (`paths.batch_lock`).

    The versions of the batch's jobs are read when the writer is made, before the evaluation reads
    anything: a commit finds them unchanged, or raises `StaleJobsError` and writes nothing (a job
    was re-ingested, added or removed meanwhile, so the results may not be of the data it now holds).
    """

    def __init__(
        self,
        lake: Path,
        branch: str,
        batch_id: str,
        *,
        metrics_set: str | None,
        config_version: int | None,
        evaluated_at: dt.datetime,
    ):
        self.lake, self.branch, self.batch_id = Path(lake), branch, batch_id
        self._row = {"metrics_set": metrics_set, "config_version": config_version, "evaluated_at": evaluated_at}
        self._change = Change(lake, branch)
        self._stack = contextlib.ExitStack()
        self._scratch = self._stack.enter_context(paths.staging(lake, branch))
        self._staged = self._scratch / "metric_results.parquet"
        self._writer = self._stack.enter_context(LOCAL.parquet_writer(self._staged, SCHEMA, compression="zstd"))
        self._statuses: dict[str, dict[str, Any]] = {}  # job -> its new metadata row, not yet published
        record = Record(self.lake, branch)
        try:
            self.versions = JobVersions(batch_id, record.job_versions(batch_id))
        finally:
            record.close()

    def write(self, results: Sequence[MetricResult]) -> None:
        rows = [result_row(r, **self._row) for r in results]
        self._writer.write_table(pa.Table.from_pylist(rows, schema=SCHEMA))

    def stage_statuses(self, statuses: Mapping[str, Mapping[str, str]]) -> None:
        """Stage new status columns of jobs' metadata rows (job id -> columns; shown with the results at
        `commit`)."""
        rows = read_metadata_rows(self.lake, self.branch, self.batch_id, list(statuses))
        for job_id, columns in statuses.items():
            row = rows.get(job_id)
            if row is None:
                raise LookupError(f"job {job_id!r} of batch {self.batch_id!r} has no metadata row any more")
            row.update(columns)
            self._statuses[job_id] = row

    def _publish_statuses(self) -> None:
        """Publish the staged rows as one `metadata` file of the batch (one file, however many jobs)."""
        if self._statuses:
            stage_metadata_rows(self._change, self._scratch, self.batch_id, self._statuses)
            self._statuses = {}

    @property
    def pending(self) -> list[FileEntry]:
        """The staged metadata rows (published now, not committed), for a catalog that shows them early."""
        self._publish_statuses()
        return list(self._change.entries)

    def commit_statuses(self) -> None:
        """Commit the staged statuses now, before the results (for a backend that cannot see staged files)."""
        self._publish_statuses()
        self._change.commit(f"statuses {self.batch_id}", expect=self.versions)
        self._change = Change(self.lake, self.branch)

    def commit(self) -> Path:
        """Publish the written rows as the batch's results, with the staged statuses; returns the file."""
        self._writer.close()
        self._publish_statuses()
        entry = self._change.add(paths.METRIC_RESULTS_TABLE, self.batch_id, None, self._staged)
        self._change.commit(f"metrics run {self.batch_id}", expect=self.versions)
        self.close()
        return self._change.record.root / entry.path

    def close(self) -> None:
        """Drop what was staged and not committed."""
        self._change.discard()
        self._stack.close()

    def __enter__(self) -> ResultsWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_results(lake: Path, branch: str, batch_id: str) -> list[dict[str, Any]]:
    """The stored rows of one batch (in evaluation order), or [] when it was never evaluated."""
    target = current_file(lake, branch, paths.METRIC_RESULTS_TABLE, batch_id)
    if target is None:
        return []
    table = LOCAL.read_parquet(target, schema=SCHEMA, partitioning=None)
    return [{"batch_id": batch_id, **row} for row in table.to_pylist()]
