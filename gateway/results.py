"""Evaluated metrics in the lake: the `metric_results` table.

One Parquet file per batch, `<lake>/<branch>/metric_results/batch_id=<B>/data.parquet`, one
row per evaluated metric (columns: `lakegate.lake.catalog.METRIC_RESULTS_COLUMNS`; `job_id`
is NULL for batch metrics). Evaluating a batch again replaces its file atomically, so the
table always holds the latest evaluation of each batch. The catalog shows it as a table of
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
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import orjson
import pyarrow as pa
import pyarrow.parquet as pq

from lakegate.lake import paths
from lakegate.lake.catalog import METRIC_RESULTS_COLUMNS

if TYPE_CHECKING:
    from lakegate.gateway.metrics import MetricResult

_ARROW = {"varchar": pa.string(), "double": pa.float64(), "bigint": pa.int64(), "timestamp(3)": pa.timestamp("ms")}
#: The Arrow schema of a batch's results file (batch_id lives in the directory name).
SCHEMA = pa.schema([(name, _ARROW[kind]) for name, kind in METRIC_RESULTS_COLUMNS if name != "batch_id"])


def _json(value: Any) -> str | None:
    """Compact JSON text (orjson: figures hold up to millions of numbers)."""
    return None if value is None else orjson.dumps(value, option=orjson.OPT_SERIALIZE_NUMPY).decode()


def result_row(result: "MetricResult", *, metrics_set: str | None, config_version: int | None,
               evaluated_at: dt.datetime) -> dict[str, Any]:
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
    """Writes the results of one evaluation of a batch as they come (one row group per `write`);
    `commit` then replaces the batch's file atomically. Closed without `commit`, nothing changes.
    """

    def __init__(self, lake: Path, branch: str, batch_id: str, *, metrics_set: str | None,
                 config_version: int | None, evaluated_at: dt.datetime):
        self.target = paths.batch_file(lake, branch, paths.METRIC_RESULTS_TABLE, batch_id)
        self._row = {"metrics_set": metrics_set, "config_version": config_version, "evaluated_at": evaluated_at}
        self._stack = contextlib.ExitStack()
        scratch = self._stack.enter_context(paths.staging(lake, branch))
        self._staged = scratch / paths.DATA_FILE
        self._writer = self._stack.enter_context(pq.ParquetWriter(self._staged, SCHEMA, compression="zstd"))

    def write(self, results: "Sequence[MetricResult]") -> None:
        rows = [result_row(r, **self._row) for r in results]
        self._writer.write_table(pa.Table.from_pylist(rows, schema=SCHEMA))

    def commit(self) -> Path:
        """Publish the written rows as the batch's results; returns the file."""
        self._writer.close()
        paths.publish(self._staged, self.target)
        self.close()
        return self.target

    def close(self) -> None:
        self._stack.close()

    def __enter__(self) -> "ResultsWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_results(lake: Path, branch: str, batch_id: str) -> list[dict[str, Any]]:
    """The stored rows of one batch (in evaluation order), or [] when it was never evaluated."""
    target = paths.batch_file(lake, branch, paths.METRIC_RESULTS_TABLE, batch_id)
    try:
        table = pq.read_table(target, schema=SCHEMA, partitioning=None)
    except FileNotFoundError:
        return []
    return [{"batch_id": batch_id, **row} for row in table.to_pylist()]
