"""The loop of one query worker process (`worker_pool.WorkerPool` starts them): it owns a
`DuckDBBackend` over the lake and answers one query at a time over a pipe, so that a query that
allocates without bound, or never returns to Python, costs only this process.

The protocol is request/answer, one message each way (pickled tuples; batches as Arrow IPC):

- `("execute", sql, branch, scope, params, time_zone, session, pending)` starts a query and answers
  `("started", columns, duckdb_sql, schema, first, last)` or `("error", message, line, column, name,
  retire)` (`retire`: the worker ends after this answer, its state no longer to be trusted);
- `("tables", duckdb_sql, tables, columns, zones)` starts a translated query over system tables
  (`tables`: name -> Arrow table, materialised by the server) and answers as `execute` does;
- `("names", statement)` answers `("names", names)`: what the planner reads of a large statement
  (`planner.query_names`: checked and parsed here, not in the server) or an error; a statement
  whose `edits` the planner made without a tree gets it here (`planner.with_edits_applied`);
- `("next",)` answers `("batch", data, last)` or an error; `("close",)` drops the running result
  (no answer). A batch is sent with `last` true when none follows, so that a result of one batch
  needs one round trip.
"""

from __future__ import annotations

import logging
import pickle
import resource
import signal
from collections.abc import Iterator, Sequence
from multiprocessing.connection import Connection
from pathlib import Path

import pyarrow as pa

from lakegate.dialect.errors import DialectError
from lakegate.dialect.statements import Statement
from lakegate.gateway.engine.backend import DuckDBBackend, QueryResult
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.planner import query_names, with_edits_applied
from lakegate.gateway.engine.process_memory import statm
from lakegate.gateway.engine.system_queries import SystemDatabase
from lakegate.lake.record import FileEntry

#: How DuckDB's errors begin when they invalidate its database (a later query cannot run on it).
_FATAL = ("FATAL Error", "INTERNAL Error")
#: Backends over staged (pending) files kept per worker, beyond the lake's own.
PENDING_BACKENDS = 2
#: What a client reads when the engine failed inside: DuckDB's own text goes to the server's log only.
INTERNAL_FAILURE = "internal error: the engine failed on this query (its worker was replaced; the server's log has why)"
log = logging.getLogger("lakegate.worker")


def _invalidating(error: BaseException) -> bool:
    """Whether DuckDB invalidated its database with `error`: it, or a DuckDB error it was made from
    (an INTERNAL error reaches clients as a NOT_SUPPORTED refusal), begins as `_FATAL` says."""
    seen: BaseException | None = error
    while seen is not None:
        if str(seen).startswith(_FATAL) or isinstance(seen, DialectError) and seen.message.startswith(_FATAL):
            return True
        seen = seen.__cause__ or seen.__context__
    return False


def send(connection: Connection, message: tuple) -> None:
    """Send one message (the other end reads it with `recv`), pickled by the plain pickler:
    `Connection.send`'s builds a dispatch table for each message, a fast query's largest cost here."""
    connection.send_bytes(pickle.dumps(message, pickle.HIGHEST_PROTOCOL))


def _encoded(batch: pa.RecordBatch | None) -> bytes | None:
    return None if batch is None else batch.serialize().to_pybytes()


def _error(error: DialectError, *, retire: bool = False) -> tuple:
    return ("error", error.message, error.line, error.column, error.error_name, retire)


class _Ahead:
    """The batches of a result, read one ahead so that each answer says whether it is the last."""

    def __init__(self, batches: Iterator[pa.RecordBatch]):
        self.batches = batches
        self.following = next(batches, None)

    def next(self) -> tuple[pa.RecordBatch | None, bool]:
        current, self.following = self.following, (None if self.following is None else next(self.batches, None))
        return current, self.following is None


class Worker:
    """The state of a worker process: its backends (the lake's, and a few over staged files) and the
    result being read."""

    def __init__(self, lake: Path | None, memory_limit: str, threads: int, limits: Limits):
        self.lake, self.memory_limit, self.threads, self.limits = lake, memory_limit, threads, limits
        self.backend = self._backend(())
        self.pending: dict[tuple[FileEntry, ...], DuckDBBackend] = {}
        self.system: SystemDatabase | None = None  # for queries over system tables, made on first use
        self.result: _Ahead | None = None
        self.close_result: object = None
        self.broken = False  # its database can no longer be trusted: the process ends after answering

    def _backend(self, pending: Sequence[FileEntry]) -> DuckDBBackend:
        return DuckDBBackend(
            self.lake, memory_limit=self.memory_limit, threads=self.threads, limits=self.limits, pending=pending
        )

    def backend_for(self, pending: tuple[FileEntry, ...]) -> DuckDBBackend:
        """The lake's backend, or one that also shows `pending` (kept for the next queries)."""
        if not pending:
            return self.backend
        backend = self.pending.pop(pending, None) or self._backend(pending)
        self.pending[pending] = backend
        while len(self.pending) > PENDING_BACKENDS:
            self.pending.pop(next(iter(self.pending))).close()
        return backend

    def warm(self) -> None:
        """Open the database, make each branch's views and translate once, so that the first query
        pays for none of it."""
        branches = self.backend.branches()
        for branch in branches:
            try:
                self.backend.connection(branch).close()
            except DialectError:
                pass  # a branch without tables yet
        try:
            if branches:  # an empty lake has nothing to warm: its queries name no branch
                self.backend.execute("SELECT 1", branch=branches[0]).rows()
        except DialectError:
            pass  # nothing to warm there; a query on it says why

    def answer(self, request: tuple) -> tuple | None:
        """The answer to one request (None for `close`)."""
        kind = request[0]
        if kind == "close":
            self.drop()
            return None
        try:
            if kind == "execute":
                self.drop()
                _, sql, branch, scope, params, time_zone, session, pending = request
                if isinstance(sql, Statement):
                    sql = with_edits_applied(sql)
                result = self.backend_for(pending).execute(
                    sql, branch=branch, scope=scope, params=params, time_zone=time_zone, session=session
                )
                return self.started(result)
            if kind == "tables":
                self.drop()
                _, sql, tables, columns, zones = request
                if self.system is None:
                    self.system = SystemDatabase(self.memory_limit)
                return self.started(self.system.run(sql, tables, columns, zones, timeout=self.limits.query_timeout))
            if kind == "names":
                return ("names", query_names(request[1]))
            if kind == "next":
                if self.result is None:
                    return ("batch", None, True)
                batch, last = self.result.next()
                if last:
                    self.drop()
                return ("batch", _encoded(batch), last)
            raise DialectError(f"internal error: unknown worker request {kind!r}", error_name="GENERIC_INTERNAL_ERROR")
        except DialectError as error:
            self.drop()
            if error.message.startswith(_FATAL):  # DuckDB invalidated its database: this worker is done
                self.broken = True
                log.error("query worker: the engine failed: %s", error.message)
                return _error(DialectError(INTERNAL_FAILURE, error_name="GENERIC_INTERNAL_ERROR"), retire=True)
            if _invalidating(error):  # refused, but the database is no longer usable either
                self.broken = True
                return _error(error, retire=True)
            return _error(error)
        except MemoryError:
            self.drop()
            message = f"Query exceeded per-node memory limit of {self.memory_limit}"
            return _error(DialectError(message, error_name="EXCEEDED_LOCAL_MEMORY_LIMIT"), retire=True)
        except Exception:  # DuckDB failed inside (a FatalException invalidates its database): retire
            self.broken = True
            log.exception("query worker: the engine failed")
            return _error(DialectError(INTERNAL_FAILURE, error_name="GENERIC_INTERNAL_ERROR"), retire=True)

    def started(self, result: QueryResult) -> tuple:
        """The `started` answer of a query: its columns, DuckDB SQL and first batch (the result is kept
        for the `next` requests unless that batch is the last)."""
        self.close_result = getattr(result.batches, "close", None)
        self.result = _Ahead(iter(result.batches))
        first, last = self.result.next()
        schema = None if first is None else first.schema.serialize().to_pybytes()
        if last:
            self.drop()
        return ("started", result.columns, result.duckdb_sql, schema, _encoded(first), last)

    def drop(self) -> None:
        """Close the result being read, if any (its DuckDB work stops)."""
        close, self.result, self.close_result = self.close_result, None, None
        if callable(close):
            close()


def serve(
    connection: Connection,
    lake: Path | None,
    memory_limit: str,
    threads: int,
    limits: Limits,
    headroom: int | None,
) -> None:
    """Answer requests on `connection` until it closes (the pool's end of the pipe went away). Once
    warm, the process's address space is capped at its size plus `headroom` bytes (None: no cap), a
    hard stop behind the pool's watch of its resident memory."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C of a terminal is the parent's to handle
    worker = Worker(lake, memory_limit, threads, limits)
    worker.warm()
    if headroom is not None and (size := statm()[0]):
        hard = resource.getrlimit(resource.RLIMIT_AS)[1]
        cap = size + headroom if hard == resource.RLIM_INFINITY else min(size + headroom, hard)
        resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    try:
        connection.send(("ready",))
        while True:
            answer = worker.answer(connection.recv())
            if answer is not None:
                send(connection, answer)
            if worker.broken:
                return
    except (EOFError, OSError):
        return  # the pool's end went away (it closed, or its process ended)
