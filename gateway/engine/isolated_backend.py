"""`IsolatedBackend`: the DuckDB backend with each query run in a worker process (`worker_pool`), so
that no query can take the process that answers other clients down with it, however much memory
it takes or however long a Python function in it runs.

What a query answers is what `DuckDBBackend` answers (a worker runs one): the same translation,
limits and errors. This process keeps its own `DuckDBBackend` for the schemas (SHOW, DESCRIBE,
information_schema and system tables read them) and `translate`; queries go to a worker, and their
batches come back over a pipe in Arrow IPC, one batch ahead of the reader. The time limit is the
worker's, as in `DuckDBBackend`; a worker that does not answer `GRACE` seconds after it, or whose
query is canceled mid-work, is killed, so its slot is free at once, always.
"""

from __future__ import annotations

import threading
import time
import weakref
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import pyarrow as pa

from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope
from lakegate.dialect.session_functions import SessionNames
from lakegate.dialect.statements import Statement
from lakegate.gateway.engine.backend import IDLE_SECONDS, DuckDBBackend, QueryResult
from lakegate.gateway.engine.failures import time_limit_error
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.query_worker import send
from lakegate.gateway.engine.worker_pool import WorkerPool, WorkerProcess
from lakegate.lake.record import FileEntry

#: Seconds past the time limit a worker may take to stop its query before it is killed.
GRACE = 1.0
#: Longest a reader blocks in one wait for a worker's answer (a thread being stopped wakes then).
POLL_SECONDS = 0.1


class _Stream:
    """One query in one worker, read as an iterator of record batches; gives the worker back to the
    pool when the query ends, is closed or canceled."""

    def __init__(self, pool: WorkerPool, worker: WorkerProcess, deadline: float, timeout: float):
        self.pool, self.worker, self.deadline, self.timeout = pool, worker, deadline, timeout
        self.schema: pa.Schema | None = None
        self._first: pa.RecordBatch | None = None
        self._last = False
        self._lock = threading.Lock()
        self._returned = False

    def start(self, request: tuple) -> tuple[list[tuple[str, str]], str | None]:
        """Send the query; its columns and DuckDB SQL (DialectError when refused or failing)."""
        _, columns, duckdb_sql, schema, first, last = self._ask(request)
        if schema is not None:
            self.schema = pa.ipc.read_schema(pa.py_buffer(schema))
        self._first = self._decode(first)
        self._last = last
        if last:
            self._give_back(healthy=True)
        return columns, duckdb_sql

    def names(self, statement: Statement) -> object:
        """What the planner reads of `statement` (`planner.query_names`), read in the worker, which
        is then free again."""
        _, names = self._ask(("names", statement))
        self._last = True
        self._give_back(healthy=True)
        return names

    def _decode(self, data: bytes | None) -> pa.RecordBatch | None:
        if data is None or self.schema is None:
            return None
        return pa.ipc.read_record_batch(pa.py_buffer(data), self.schema)

    def __iter__(self) -> Iterator[pa.RecordBatch]:
        return self

    def __next__(self) -> pa.RecordBatch:
        if self._first is not None:
            batch, self._first = self._first, None
            return batch
        if self._last:
            raise StopIteration
        _, data, last = self._ask(("next",))
        self._last = last
        if last:
            self._give_back(healthy=True)
        batch = self._decode(data)
        if batch is None:
            raise StopIteration
        return batch

    def _ask(self, request: tuple) -> tuple:
        """The worker's answer to `request`; any failure (an error answer, the worker's end, the time
        limit, an exception raised in this thread) gives the worker back and raises."""
        connection = self.worker.connection
        try:
            send(connection, request)
            while not connection.poll(POLL_SECONDS):
                if time.monotonic() > self.deadline + GRACE:
                    self.worker.kill(time_limit_error(self.timeout))
            answer = connection.recv()
        except (EOFError, OSError):
            self._give_back(healthy=False)
            raise self.worker.killed or DialectError(
                f"The query's worker process ended unexpectedly (exit code {self.worker.process.exitcode})",
                error_name="GENERIC_INTERNAL_ERROR",
            ) from None
        except BaseException:
            self.worker.kill()
            self._give_back(healthy=False)
            raise
        if answer[0] == "error":
            _, message, line, column, error_name, retire = answer
            self._last = True
            self._give_back(healthy=not retire)
            raise DialectError(message, line=line, column=column, error_name=error_name)
        return answer

    def close(self) -> None:
        """Stop reading: the worker drops the result and is free for the next query."""
        self._first = None
        if not self._last and self.worker.killed is None:
            try:
                self.worker.connection.send(("close",))
            except OSError:
                self.worker.kill()
        self._last = True
        self._give_back(healthy=self.worker.killed is None)

    def stop(self, reason: DialectError) -> None:
        """Kill the worker mid-query: reading on raises `reason`."""
        with self._lock:
            if self._returned:
                return
            self.worker.kill(reason)

    def _give_back(self, *, healthy: bool) -> None:
        with self._lock:
            if self._returned:
                return
            self._returned = True
        self.pool.give_back(self.worker, healthy=healthy)


class IsolatedBackend(DuckDBBackend):
    """`DuckDBBackend` whose queries run in a pool of worker processes, at most
    `limits.max_concurrent_queries` at once, `warm` more kept ready and at least `keep` started.
    `memory_limit` bounds the memory the running queries take together, counted as the growth of
    their workers' resident sets (each worker's DuckDB has it as its own limit too)."""

    def __init__(
        self,
        lake: Path | None,
        *,
        memory_limit: str = "2GB",
        threads: int = 2,
        limits: Limits = Limits(),
        pending: Sequence[FileEntry] = (),
        idle_seconds: float = IDLE_SECONDS,
        warm: int = 1,
        keep: int = 1,
        pool: WorkerPool | None = None,
    ):
        super().__init__(
            lake, memory_limit=memory_limit, threads=threads, limits=limits, pending=pending, idle_seconds=idle_seconds
        )
        self.pending = tuple(pending)
        self._owns_pool = pool is None
        self.pool = pool or WorkerPool(
            self.lake,
            memory_limit=memory_limit,
            threads=threads,
            limits=limits,
            size=limits.max_concurrent_queries,
            warm=warm,
            keep=keep,
        )
        self._streams: weakref.WeakSet[_Stream] = weakref.WeakSet()

    def with_pending(self, pending: Sequence[FileEntry]) -> IsolatedBackend:
        """A backend over the same workers whose queries also see `pending` (close it after use)."""
        return IsolatedBackend(
            self.lake,
            memory_limit=self.memory_limit,
            threads=self.threads,
            limits=self.limits,
            pending=pending,
            idle_seconds=self.idle_seconds,
            pool=self.pool,
        )

    def _stream(self) -> _Stream:
        """A free worker (waiting for one within the time limit) for one request or query."""
        timeout = self.limits.query_timeout
        deadline = time.monotonic() + timeout
        worker = self.pool.take(deadline)
        if worker is None:
            raise time_limit_error(timeout)
        stream = _Stream(self.pool, worker, deadline, timeout)
        self._streams.add(stream)
        return stream

    def execute(
        self,
        sql: str | Statement,
        *,
        branch: str = "main",
        scope: Scope | None = None,
        params: Sequence[object] = (),
        time_zone: str = "UTC",
        session: SessionNames | None = None,
    ) -> QueryResult:
        """Run one Trino-dialect query in a worker (waiting for a free one within the time limit);
        as `DuckDBBackend.execute`."""
        return self._started(("execute", sql, branch, scope, tuple(params), time_zone, session, self.pending))

    def _started(self, request: tuple) -> QueryResult:
        """The result of a query `request` started in a free worker (waiting for one within the time limit)."""
        stream = self._stream()
        columns, duckdb_sql = stream.start(request)
        return QueryResult(
            columns=columns,
            batches=stream,
            duckdb_sql=duckdb_sql,
            _cancel=lambda: stream.stop(DialectError("Query was canceled", error_name="USER_CANCELED")),
        )

    def run_over_tables(
        self,
        duckdb_sql: str,
        tables: Mapping[str, pa.Table],
        columns: Sequence[tuple[str, str]],
        zones: Sequence[str | None],
    ) -> QueryResult:
        """Run a translated query over materialised system tables in a worker (waiting for a free one
        within the time limit), with the same memory and time limits as any query."""
        return self._started(("tables", duckdb_sql, dict(tables), list(columns), list(zones)))

    def query_names(self, statement: Statement) -> object:
        """`planner.query_names(statement)` run in a worker (waiting for a free one within the time
        limit), so that checking and parsing a large text costs the server's process nothing."""
        stream = self._stream()
        return stream.names(statement)

    def stop_all(self) -> None:
        """Kill every running query's worker: each fails with SERVER_SHUTTING_DOWN."""
        super().stop_all()
        for stream in list(self._streams):
            stream.stop(DialectError("The server is shutting down", error_name="SERVER_SHUTTING_DOWN"))

    def close(self) -> None:
        """Stop the running queries and end the workers (when this backend started them)."""
        self.stop_all()
        if self._owns_pool:
            self.pool.close()
        super().close()
