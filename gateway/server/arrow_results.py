"""`POST /v1/arrow`: one query's result as an Arrow IPC stream, a lakegate extension beside Trino's
protocol for bulk fetches into dataframes (docs/bulk-results.md).

The request is the same as `POST /v1/statement`'s (the SQL text as body, session in `X-Trino-*`
headers, the same credentials); the reply is `application/vnd.apache.arrow.stream`, each column's
Trino type in its field's metadata (`arrow_output`). Only queries are taken (SELECT, WITH, VALUES,
TABLE, SHOW, DESCRIBE); anything else, an error found before the first rows, or a type Arrow cannot
carry exactly, is answered 400 with a Trino error document (`{"error": {...}}`). An error after the
first rows ends the stream without its end marker and breaks the HTTP response off (no final chunk),
so a reader fails loudly rather than seeing fewer rows. The backend bounds the query as any other
(its time limit and concurrent slots); `Limits.max_rows` bounds its rows. It is not listed in
`system.runtime.queries`; closing the connection cancels it.
"""

from __future__ import annotations

from collections.abc import Iterator

import orjson
import pyarrow as pa
from fastapi.responses import Response, StreamingResponse
from starlette.concurrency import run_in_threadpool

from lakegate.dialect.errors import DialectError
from lakegate.dialect.statements import read
from lakegate.gateway.engine.arrow_output import result_batches, result_schema
from lakegate.gateway.engine.backend import QueryResult
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.session import Session
from lakegate.gateway.server.protocol import Failure

PATH = "/v1/arrow"
MEDIA_TYPE = "application/vnd.apache.arrow.stream"
QUERY_KINDS = ("query", "show", "describe")


class _Chunks:
    """A write-only file the IPC writer fills; `take()` hands over what it wrote since."""

    closed = False

    def __init__(self):
        self._parts: list[bytes] = []

    def write(self, data) -> int:
        self._parts.append(bytes(data))
        return len(data)

    def flush(self) -> None:
        pass

    def take(self) -> bytes:
        data, self._parts = b"".join(self._parts), []
        return data


def _error(error: BaseException) -> Response:
    return Response(
        orjson.dumps({"error": Failure.of(error).document()}), status_code=400, media_type="application/json"
    )


def _too_many(limits: Limits) -> DialectError:
    return DialectError(
        f"Query exceeded the result limit of {limits.max_rows} rows (lakegate serve --max-rows): narrow it "
        "with WHERE, LIMIT or an aggregate",
        error_name="GENERIC_INSUFFICIENT_RESOURCES",
    )


def _closer(batches: object):
    """What stops the query's reading (frees its slot): its batches' close(), if they have one."""
    return getattr(batches, "close", None) or (lambda: None)


def _start(engine: Engine, sql: str, session: Session, limits: Limits) -> tuple[QueryResult, bytes]:
    """Plan and start the query and encode its schema and first batch (errors surface here, before
    the reply's status is sent)."""
    statement = read(sql)
    if statement.kind not in QUERY_KINDS:
        raise DialectError(
            f"{PATH} answers queries only (SELECT, WITH, VALUES, TABLE, SHOW, DESCRIBE): send other "
            "statements to /v1/statement",
            error_name="NOT_SUPPORTED",
        )
    result = engine.execute(statement, session)
    close = _closer(result.batches)
    try:
        schema = result_schema(result.columns)
        chunks = _Chunks()
        writer = pa.ipc.new_stream(chunks, schema)
        batches = result_batches(result, schema)
        first = next(batches, None)
        if first is not None:
            if first.num_rows > limits.max_rows:
                raise _too_many(limits)
            writer.write_batch(first)
        result.batches = _rest(batches, writer, chunks, limits, 0 if first is None else first.num_rows, close)
    except BaseException:
        close()
        raise
    return result, chunks.take()


def _rest(
    batches: Iterator[pa.RecordBatch],
    writer: pa.ipc.RecordBatchStreamWriter,
    chunks: _Chunks,
    limits: Limits,
    rows: int,
    close,
) -> Iterator[bytes]:
    try:
        for batch in batches:
            rows += batch.num_rows
            if rows > limits.max_rows:
                raise _too_many(limits)
            writer.write_batch(batch)
            yield chunks.take()
        writer.close()
        yield chunks.take()
    finally:
        close()


async def arrow_response(engine: Engine, sql: str, session: Session, limits: Limits) -> Response:
    """The reply of `POST /v1/arrow` for `sql` in `session`."""
    try:
        result, head = await run_in_threadpool(_start, engine, sql, session, limits)
    except (DialectError, pa.ArrowException) as error:
        return _error(error)

    def body() -> Iterator[bytes]:
        yield head
        yield from result.batches

    return StreamingResponse(body(), media_type=MEDIA_TYPE)
