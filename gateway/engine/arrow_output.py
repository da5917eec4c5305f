"""A query result as an Arrow IPC stream or Parquet (`lakegate query --format arrow|parquet`, `POST
/v1/arrow` of `lakegate serve`), the fast way into
pandas, Polars or DuckDB (millions of rows a second, against about 250,000 through the Trino
protocol's JSON).

Each column keeps its Trino type's exact values in the Arrow type that carries them
(`trino_values.arrow_type`: bigint int64, double float64, real float32, decimal(p,s) decimal128,
varchar string, date date32, timestamp(p) timestamp[ms|us], arrays, maps and rows nested), and
names its Trino type in the field's metadata (`trino_type`). A type Arrow cannot carry exactly is
refused with NOT_SUPPORTED before anything is written: `timestamp(p) with time zone` and
`time(p) with time zone` (Arrow has no zone per value), `timestamp(p)` and `time(p)` with p > 6
(nanoseconds and beyond).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import BinaryIO

import pyarrow as pa
import pyarrow.parquet as pq

from lakegate.dialect.errors import DialectError
from lakegate.dialect.trino_types import TType, parse_type
from lakegate.gateway.engine.backend import QueryResult
from lakegate.gateway.engine.trino_values import arrow_type

TYPE_KEY = b"trino_type"


def _refusal(t: TType) -> str | None:
    """Why Arrow cannot carry values of `t` exactly (None: it can)."""
    if t.base in ("timestamp_tz", "time_tz"):
        return "Arrow keeps no time zone per value"
    if t.base in ("timestamp", "time") and t.args and t.args[0] > 6:
        return "Arrow keeps at most microseconds here"
    for arg in t.args:
        inner = arg[1] if isinstance(arg, tuple) else arg
        if isinstance(inner, TType):
            reason = _refusal(inner)
            if reason is not None:
                return reason
    return None


def result_schema(columns: list[tuple[str, str]]) -> pa.Schema:
    """The Arrow schema of a result's (name, Trino type) columns; DialectError NOT_SUPPORTED naming
    the first column whose type Arrow cannot carry exactly."""
    fields = []
    for name, trino_type in columns:
        t = parse_type(trino_type)
        reason = _refusal(t)
        if reason is not None:
            raise DialectError(
                f"column {name!r} of type {trino_type} cannot be written as Arrow or Parquet ({reason}): "
                "use --format json or csv, or CAST it (for example to varchar)",
                error_name="NOT_SUPPORTED",
            )
        fields.append(pa.field(name, arrow_type(t), metadata={TYPE_KEY: trino_type.encode()}))
    return pa.schema(fields)


def result_batches(result: QueryResult, schema: pa.Schema) -> Iterator[pa.RecordBatch]:
    """The result's batches under `schema` (a column of another Arrow type is cast, refusing any
    cast that would change a value)."""
    for batch in result.batches:
        columns = []
        for column, field in zip(batch.columns, schema):
            if column.type != field.type:
                try:
                    column = column.cast(field.type)
                except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as error:
                    raise DialectError(
                        f"column {field.name!r} cannot be written as {field.type} exactly: {error}",
                        error_name="NOT_SUPPORTED",
                    ) from None
            columns.append(column)
        yield pa.RecordBatch.from_arrays(columns, schema=schema)


def write_arrow(result: QueryResult, out: BinaryIO) -> int:
    """Stream the result as Arrow IPC (the streaming format) to `out`; the rows written."""
    schema = result_schema(result.columns)
    rows = 0
    with pa.ipc.new_stream(out, schema) as writer:
        for batch in result_batches(result, schema):
            writer.write_batch(batch)
            rows += batch.num_rows
    return rows


def write_parquet(result: QueryResult, out: BinaryIO | str) -> int:
    """Write the result as one Parquet file (zstd) to `out`; the rows written."""
    schema = result_schema(result.columns)
    rows = 0
    with pq.ParquetWriter(out, schema, compression="zstd") as writer:
        for batch in result_batches(result, schema):
            writer.write_batch(batch)
            rows += batch.num_rows
    return rows
