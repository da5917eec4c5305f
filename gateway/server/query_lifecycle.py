"""The life of the SQL endpoint's queries (gateway/server/app.py routes them).

`POST /v1/statement` answers session statements and CALL at once with their result. Every other
statement goes to a worker thread at once, and the POST waits a little (`Limits.answer_wait`) for it:
a query that ends in that time with at most one small page is answered whole in the POST's reply
(columns and rows, or its error, and no `nextUri`: one request per fast query); any other gets a
QUEUED / RUNNING document whose `nextUri` the client follows while the worker runs. The worker
turns the result's Arrow record batches into pages of JSON rows (about `Limits.page_bytes` each)
and hands them over through a small buffer, so a result is never held whole: a slow client makes
the worker wait. `GET nextUri` returns the next page (waiting up to
`Limits.wait` for it); the same URI again returns the same document. `DELETE nextUri` or
`DELETE /v1/query/{id}` cancel (the DuckDB work is interrupted). A reaper enforces the time limit,
fails queries whose client stopped polling for `Limits.client_timeout` seconds (ABANDONED_QUERY, as
Trino's `query.client.timeout`), and forgets finished queries.

Each running query has a daemon worker thread of its own while it runs, at most
`Limits.max_concurrent_queries` at once (a thread that ends a query waits for the next one), at
most `Limits.user_slots` of one user's, zombies (below) included (more stay QUEUED, as behind a Trino
resource group's per-user hardConcurrencyLimit), so that another user always finds a slot and a
query worker. A
query that ends (time limit, cancel, abandoned) while its worker still works is stopped: its DuckDB
work is interrupted, and Python work still planning it (parsing, translation) is abandoned by an
exception raised in the worker. Its slot is free at once: the worker counts as a "zombie" until
it returns, and at most `max_concurrent_queries` zombies are counted apart, so runaway work never
jams the server. Shutdown waits at most `SHUTDOWN_GRACE` seconds for workers.

A client that names encodings in `X-Trino-Query-Data-Encoding` gets its GET pages as segments of
Trino's spooling protocol (`spooling`): the worker also encodes each page, small ones are inlined,
larger ones are kept in the app's `SegmentStore` until acknowledged or expired (the reaper expires
them; a finished query's segments stay for a client still reading them).
"""

from __future__ import annotations

import asyncio
import ctypes
import logging
import os
import queue
import secrets
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

import orjson
import pyarrow as pa

from lakegate.dialect.errors import DialectError
from lakegate.dialect.statements import Statement
from lakegate.gateway.engine import session as sessions
from lakegate.gateway.engine.backend import QueryResult
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.failures import time_limit_error
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.session import Session
from lakegate.gateway.engine.trino_values import encode_columns
from lakegate.gateway.server import spooling
from lakegate.gateway.server.protocol import (
    Failure,
    Progress,
    QueryIds,
    columns_document,
    results_document,
)

log = logging.getLogger("lakegate.server")

#: Pages a worker may have ready before it waits for the client.
BUFFERED_PAGES = 2
#: Rows in a query's first page (later pages are sized to about Limits.page_bytes); as many as a
#: segment Trino inlines, so that the spooling protocol's first segment is inline.
FIRST_PAGE_ROWS = spooling.INLINE_MAX_ROWS
MAX_PAGE_ROWS = 65_536
#: The largest page that may also be a query's last document (larger ones get a last document of
#: their own, so that a finished query keeps little for a retried request).
FINAL_PAGE_BYTES = 65_536
#: How often the reaper looks at the queries.
REAP_INTERVAL = 0.25
#: Longest shutdown waits for workers to stop (they are daemon threads: the process may end without them).
SHUTDOWN_GRACE = 1.0
#: Payload bytes of spooled segments the server holds at once; past them pages are inlined.
SPOOLED_BYTES = 64 * 1024 * 1024


@dataclass
class _Page:
    data: bytes  # the JSON array of rows
    rows: int
    payload: bytes | None = None  # the rows as a spooling segment's payload, when the client chose an encoding
    sizes: dict[str, int] | None = None  # the payload's size attributes


class _Stopped(Exception):
    """The query ended (canceled, failed or timed out) while its worker was still producing."""


class _Abandoned(BaseException):
    """Raised in a worker whose query ended while it was planning (Python work nothing else stops)."""


def _raise_in(thread_id: int, exception: type[BaseException] | None) -> None:
    """Raise `exception` in the thread `thread_id` at its next Python instruction (None: forget one
    raised there and not yet delivered)."""
    ctypes.pythonapi.PyThreadState_SetAsyncExc(
        ctypes.c_ulong(thread_id), None if exception is None else ctypes.py_object(exception)
    )


def _now() -> datetime:
    return datetime.now(UTC)


def _resolve(future: asyncio.Future) -> None:
    if not future.done():
        future.set_result(None)


def _wake(waiters: list[asyncio.Future]) -> None:
    for future in waiters:
        try:
            future.get_loop().call_soon_threadsafe(_resolve, future)
        except RuntimeError:
            pass  # the event loop is closed: nobody waits any more


#: Fault injection for tests: a query whose text contains this variable's value first spends up to
#: 60 s in pure-Python work while planning, standing for a parse or translation that runs away.
SLOW_PLANNING_ENV = "LAKEGATE_TEST_SLOW_PLANNING"


def _injected_planning_work(sql: str) -> None:
    marker = os.environ.get(SLOW_PLANNING_ENV)
    if marker and marker in sql:
        end = time.monotonic() + 60
        while time.monotonic() < end:
            pass


class Query:
    """One statement: its state, the pages its worker produced, and the documents served so far."""

    def __init__(
        self,
        query_id: str,
        statement: Statement,
        session: Session,
        dequeued: Callable[[], None] = lambda: None,
        *,
        encoding: str | None = None,
        segments: spooling.SegmentStore | None = None,
    ):
        self.id, self.statement, self.sql, self.session = query_id, statement, statement.text, session
        self.encoding, self._segments = encoding if segments is not None else None, segments
        self._dequeued = dequeued  # called once, when the query leaves the queue (runs or fails)
        self.slug = secrets.token_hex(8)
        self.lock = threading.Lock()
        self._space = threading.Condition(self.lock)
        self._pages: deque[_Page] = deque()
        self._waiters: list[asyncio.Future] = []
        self._version = 0
        self._result: QueryResult | None = None
        self._fetching = asyncio.Lock()
        self.columns: list[dict] | None = None
        self.failure: Failure | None = None
        self.started = False
        self.working = False  # a worker runs the statement
        self.zombie = False  # the query ended but its worker still runs, counted apart
        self.blocked = False  # the worker waits for the client to read a page
        self._planner: int | None = None  # the worker thread while it plans the query
        self.done = False  # the worker produced everything, or the query failed
        self.final = False  # the last document was served
        self.rows = 0
        self.served_rows = 0  # rows of the documents served so far (a spooling segment's rowOffset)
        self.bytes = 0
        self.created = _now()
        self.started_at: datetime | None = None
        self.ended: datetime | None = None
        self._clock = {"created": time.monotonic(), "started": None, "ended": None}
        self.last_access = time.monotonic()
        self.token = 0
        self.body = b""

    # -- the worker's side ----------------------------------------------------------------

    def _changed(self) -> list[asyncio.Future]:
        """Record a change (lock held) and return the waiters to wake."""
        self._version += 1
        waiters, self._waiters = self._waiters, []
        self._space.notify_all()
        return waiters

    def begin(self) -> bool:
        """Mark the query running; False when it already ended while queued."""
        with self.lock:
            if self.done:
                return False
            self.started = True  # no waiter to wake: clients wait for pages or the end
            self.started_at = _now()
            self._clock["started"] = time.monotonic()
        self._dequeued()
        return True

    def attach(self, result: QueryResult) -> None:
        """Keep the running result (to cancel it) and its columns."""
        columns = columns_document(result.columns)
        with self.lock:
            self._result = result
            self.columns = columns
            stopped = self.done
        if stopped:
            result.cancel()
            raise _Stopped

    def put(self, page: _Page, *, last: bool = False) -> None:
        """Hand one page to the client, waiting while the buffer is full (`last`: the query's work
        is done with it); _Stopped when the query ended."""
        with self.lock:
            while len(self._pages) >= BUFFERED_PAGES and not self.done:
                self.blocked = True  # waiting for the client to read
                self._space.wait()
            self.blocked = False
            if self.done:
                raise _Stopped
            self._pages.append(page)
            self.rows += page.rows
            self.bytes += len(page.data)
            if last:
                self.done = True
                self._ended()
            waiters = self._changed()
        _wake(waiters)

    def finish(self) -> None:
        """The worker produced every page."""
        with self.lock:
            if self.done:
                return
            self.done = True
            self._ended()
            waiters = self._changed()
        _wake(waiters)

    def _ended(self) -> None:
        self.ended = _now()
        self._clock["ended"] = time.monotonic()

    def fail(self, failure: Failure) -> bool:
        """End the query with `failure` (pages not yet read are dropped) and interrupt its work.
        False when it had already failed or its last document was served."""
        with self.lock:
            if self.failure is not None or self.final:
                return False
            self.failure = failure
            self._pages.clear()
            if not self.done:
                self.done = True
                self._ended()
            waiters = self._changed()
            result, queued = self._result, not self.started
        _wake(waiters)
        if queued:
            self._dequeued()
        if result is not None:
            result.cancel()
        return True

    @property
    def running(self) -> bool:
        return self.started and not self.done

    def plan(self, start: Callable[[], QueryResult]) -> QueryResult:
        """`start()`: the query's planning (parsing, translation), which `interrupt` abandons by
        raising _Abandoned in this thread."""
        with self.lock:
            self._planner = threading.get_ident()
        try:
            _injected_planning_work(self.sql)
            return start()
        finally:
            with self.lock:
                self._planner = None
            _raise_in(threading.get_ident(), None)

    def interrupt(self) -> None:
        """Stop the ended query's work: interrupt its DuckDB work again (an interrupt that arrives
        just before DuckDB starts is lost; the reaper repeats it while a failed query's worker still
        runs), or abandon its planning."""
        with self.lock:
            result = self._result
            if self._planner is not None and self.done:
                _raise_in(self._planner, _Abandoned)
        if result is not None:
            result.cancel()

    def elapsed(self, what: str = "created") -> float:
        since = self._clock[what]
        return 0.0 if since is None else (self._clock["ended"] or time.monotonic()) - since

    # -- the client's side -----------------------------------------------------------------

    def state(self) -> str:
        if self.failure is not None:
            return "FAILED"
        if self.final:
            return "FINISHED"
        if not self.started:
            return "QUEUED"
        return "FINISHING" if self.done else "RUNNING"

    def queued_seconds(self) -> float:
        return (self._clock["started"] or time.monotonic()) - self._clock["created"]

    def document(self, base: str, token: int, *, data: bytes | None = None, last: bool = False) -> bytes:
        """The QueryResults document `token` of the query's current state (`last`: no nextUri)."""
        progress = Progress(
            self.state(),
            queued_ms=int(self.queued_seconds() * 1000),
            elapsed_ms=int(self.elapsed() * 1000),
            rows=self.rows,
            bytes=self.bytes,
        )
        next_uri = None if last else f"{base}/v1/statement/executing/{self.id}/{self.slug}/{token + 1}"
        return results_document(
            query_id=self.id,
            info_uri=f"{base}/v1/query/{self.id}",
            progress=progress,
            next_uri=next_uri,
            columns=self.columns,
            data=data,
            failure=self.failure,
        )

    def first_document(self, base: str) -> bytes:
        """The POST's reply (token 0) of the query as it is: the last document when the query ended
        with at most one small page (its rows, if any, are in it), else one with the nextUri."""
        with self.lock:
            whole = self.failure is not None or (self.done and self._fits())
            page = self._pages.popleft() if whole and self._pages else None
            self.served_rows += 0 if page is None else page.rows
            self.final = whole
            self.body = self.document(base, 0, data=None if page is None else page.data, last=whole)
        return self.body

    async def answer(self, base: str, wait: float) -> bytes:
        """The POST's reply, after waiting up to `wait` seconds for the query to end (`first_document`)."""
        deadline = time.monotonic() + wait
        async with self._fetching:
            while True:
                with self.lock:  # decided: the query ended, or has more rows than one reply holds
                    if self.done or not self._fits():
                        break
                    version = self._version
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                await self._changes(version, remaining)
            return self.first_document(base)

    def _fits(self) -> bool:
        """Whether the pages ready fit in one last document: at most one, and small (lock held)."""
        return len(self._pages) <= 1 and all(len(page.data) <= FINAL_PAGE_BYTES for page in self._pages)

    async def fetch(self, token: int, base: str, wait: float) -> bytes | None:
        """The document of `token`: the same bytes again for the current token, the next document
        for the next one (waiting up to `wait` seconds for a page); None for any other token."""
        async with self._fetching:
            self.last_access = time.monotonic()
            if token == self.token:
                return self.body
            if token != self.token + 1 or self.final:
                return None
            body = await self._next(base, token, wait)
            self.token, self.body = token, body
            self.last_access = time.monotonic()
            return body

    async def _next(self, base: str, token: int, wait: float) -> bytes:
        deadline = time.monotonic() + wait
        while True:
            with self.lock:
                page = self._pages.popleft() if self._pages else None
                if page is not None:
                    self._space.notify_all()
                    last = self.done and not self._pages and self.failure is None and len(page.data) <= FINAL_PAGE_BYTES
                    self.final = last
                    return self.document(base, token, data=self._data(page, base), last=last)
                version, done = self._version, self.done
            if done:
                return self._last(base, token)
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                with self.lock:
                    return self.document(base, token)
            await self._changes(version, remaining)

    def _data(self, page: _Page, base: str) -> bytes:
        """A GET reply's `data`: the page's rows, or its segment under the spooling protocol (lock held)."""
        offset, self.served_rows = self.served_rows, self.served_rows + page.rows
        if page.payload is None or self.encoding is None or self._segments is None:
            return page.data
        return spooling.segments_data(
            self.encoding,
            page.payload,
            page.sizes or {},
            rows=page.rows,
            row_offset=offset,
            base=base,
            store=self._segments,
        )

    def _last(self, base: str, token: int) -> bytes:
        with self.lock:
            self.final = True
            return self.document(base, token, last=True)

    async def _changes(self, version: int, timeout: float) -> None:
        """Wait until the query changes after `version`, or `timeout` seconds."""
        future = asyncio.get_running_loop().create_future()
        with self.lock:
            if self._version != version:
                return
            self._waiters.append(future)
        try:
            await asyncio.wait_for(future, timeout)
        except TimeoutError:
            pass
        finally:
            with self.lock:
                if future in self._waiters:
                    self._waiters.remove(future)

    def info(self) -> dict:
        """What GET /v1/query/{id} tells about the query."""
        info = {
            "queryId": self.id,
            "state": self.state(),
            "query": self.sql,
            "user": self.session.user,
            "source": self.session.source,
            "created": self.created.isoformat(),
            "elapsedTimeMillis": int(self.elapsed() * 1000),
            "processedRows": self.rows,
        }
        if self.failure is not None:
            info["error"] = self.failure.document()
        return info

    def row(self) -> tuple:
        """The query as a row of system.runtime.queries."""
        failure = self.failure
        return (
            self.id,
            self.state(),
            self.session.user,
            self.session.source,
            self.sql,
            None,
            int(self.queued_seconds() * 1000),
            0,
            0,
            self.created,
            self.started_at,
            _now(),
            self.ended,
            None if failure is None else failure.error_type,
            None if failure is None else failure.error_name,
        )


def _pages(
    columns: Sequence[tuple[str, str]], batches: Iterator[pa.RecordBatch], limits: Limits, encoding: str | None = None
) -> Iterator[_Page]:
    """The result's rows as pages of JSON (sized to about limits.page_bytes: a page holds fewer rows
    when their Arrow data is larger, a single row when one is), each also encoded as a spooling
    segment's payload when the client chose an `encoding`; a result with more than
    limits.max_rows rows fails."""
    seen, chunk = 0, FIRST_PAGE_ROWS
    for batch in batches:
        offset = 0
        while offset < batch.num_rows:
            part = batch.slice(offset, chunk)
            if part.num_rows > 1 and part.nbytes > limits.page_bytes:  # wide rows: fewer of them
                part = batch.slice(offset, max(1, part.num_rows * limits.page_bytes // part.nbytes))
            seen += part.num_rows
            if seen > limits.max_rows:
                raise DialectError(
                    f"Query exceeded the result limit of {limits.max_rows} rows (lakegate serve "
                    "--max-rows): narrow it with WHERE, LIMIT or an aggregate",
                    error_name="GENERIC_INSUFFICIENT_RESOURCES",
                )
            data = orjson.dumps(list(zip(*encode_columns(columns, part))))  # rows as tuples: cheaper than lists
            if encoding is None:
                yield _Page(data, part.num_rows)
            else:
                yield _Page(data, part.num_rows, *spooling.encode(encoding, data))
            offset += part.num_rows
            chunk = max(1, min(MAX_PAGE_ROWS, limits.page_bytes * part.num_rows // max(1, len(data))))


class QueryManager:
    """The server's queries: at most `max_concurrent_queries` running (and as many zombies, see the
    module docstring), a bounded queue, and the reaper that enforces the time limit, abandons
    queries clients left and forgets old ones."""

    def __init__(self, engine: Engine, limits: Limits, segments: spooling.SegmentStore | None = None):
        self.engine, self.limits, self.segments = engine, limits, segments
        self.ids = QueryIds()
        self._queries: dict[str, Query] = {}
        self._lock = threading.Lock()
        self._waiting = 0  # queries created and not yet running or failed
        self._waiting_chars = 0  # characters of their statement texts
        self.queued_text_chars = QUEUED_BODIES * limits.max_body  # the most they may hold
        self._queue: deque[Query] = deque()  # queries given to `start`, waiting for a worker
        self._running = 0  # workers of queries that have not ended
        self._zombies = 0  # workers of ended queries that still run
        self._closing = False  # shutting down: no new query runs
        self._working: set[Query] = set()  # queries whose thread still runs them (zombies too)
        self._handoff: queue.SimpleQueue[Query | None] = queue.SimpleQueue()  # to the idle query threads
        self._idle_threads = 0  # query threads waiting for the next query
        self.large_slots = max(1, limits.max_concurrent_queries // 4)  # of statements over LARGE_TEXT_BYTES
        self._stop = threading.Event()
        self._reaper = threading.Thread(target=self._reap, name="lakegate-reaper", daemon=True)
        self._reaper.start()

    def create(self, statement: Statement, session: Session, encoding: str | None = None) -> Query:
        """A new query for one statement, queued (`start` hands it to a worker), or failed with
        QUERY_QUEUE_FULL when too many wait. `encoding`: the spooling protocol's, if the client chose one."""
        size = len(statement.text)
        with self._lock:
            full = self._waiting >= self.limits.max_queued_queries
            too_much_text = not full and self._waiting_chars + size > self.queued_text_chars
            admitted = not (full or too_much_text)
            if admitted:
                self._waiting += 1
                self._waiting_chars += size
        query = Query(
            self.ids.next(),
            statement,
            session,
            dequeued=(lambda: self._dequeued(size)) if admitted else (lambda: None),
            encoding=encoding,
            segments=self.segments,
        )
        with self._lock:
            self._queries[query.id] = query
            closing = self._closing
        if closing:
            query.fail(SHUTTING_DOWN)
        elif full:
            query.fail(Failure('Too many queued queries for "global"', "QUERY_QUEUE_FULL"))
        elif too_much_text:
            query.fail(
                Failure(
                    'Too many queued queries for "global": the statements waiting hold '
                    f"{self._waiting_chars:,} characters of text",
                    "QUERY_QUEUE_FULL",
                )
            )
        return query

    def _dequeued(self, size: int) -> None:
        with self._lock:
            self._waiting -= 1
            self._waiting_chars -= size

    def start(self, query: Query) -> None:
        """Give a queued query to the next free worker."""
        with self._lock:
            self._queue.append(query)
            self._dispatch()

    def _dispatch(self) -> None:
        """Start a worker for each queued query a slot is free for (lock held): the oldest query of
        the user with the fewest running queries, none of a user already running `Limits.user_slots`,
        so that one user's many queries cannot keep another's waiting; a query whose client stopped
        polling is left to the reaper to drop."""
        while self._running < self.limits.max_concurrent_queries and self._queue and not self._closing:
            query = self._next_queued()
            if query is None:
                return
            self._running += 1
            query.working = True
            self._working.add(query)
            if self._idle_threads:
                self._idle_threads -= 1
                self._handoff.put(query)
            else:
                threading.Thread(target=self._serve, args=(query,), name="lakegate-query", daemon=True).start()

    def _next_queued(self) -> Query | None:
        """Take the queued query to run next off the queue (lock held); None when none should run.
        A statement text over LARGE_TEXT_BYTES waits while `large_slots` others are in the workers
        (zombies included: their parsing may still run), so that big texts cannot take every slot."""
        working = self._working
        running = Counter(q.session.user for q in working)  # a user's zombies too: they hold query workers
        large_busy = sum(len(q.sql) > LARGE_TEXT_BYTES for q in working) >= self.large_slots
        chosen, user_slots = None, self.limits.user_slots
        for query in list(self._queue):
            if query.done:
                self._queue.remove(query)  # failed while queued
            elif (
                running[query.session.user] < user_slots
                and not _silent_while_queued(query, self.limits)
                and not (large_busy and len(query.sql) > LARGE_TEXT_BYTES)
                and (chosen is None or running[query.session.user] < running[chosen.session.user])
            ):
                chosen = query
        if chosen is not None:
            self._queue.remove(chosen)
        return chosen

    def _serve(self, query: Query | None) -> None:
        """A query thread: runs `query`, then the queries `_dispatch` hands over, one at a time
        (threads are reused: starting one costs a fast query much of its CPU); ends when the manager
        closes."""
        while query is not None:
            self._work(query)
            with self._lock:
                if self._stop.is_set():
                    return
                self._idle_threads += 1
            query = self._handoff.get()

    def _work(self, query: Query) -> None:
        try:
            self._run(query)
        except _Abandoned:
            pass
        finally:
            with self._lock:
                query.working = False
                self._working.discard(query)
                if query.zombie:
                    self._zombies -= 1
                else:
                    self._running -= 1
                self._dispatch()

    def _bury(self, query: Query) -> None:
        """Count an ended query whose worker still runs as a zombie, freeing its slot (while fewer
        than `max_concurrent_queries` zombies are counted)."""
        with self._lock:
            if query.working and not query.zombie and self._zombies < self.limits.max_concurrent_queries:
                query.zombie = True
                self._running -= 1
                self._zombies += 1
                self._dispatch()

    def get(self, query_id: str) -> Query | None:
        with self._lock:
            return self._queries.get(query_id)

    def queries(self) -> list[Query]:
        with self._lock:
            return list(self._queries.values())

    def _run(self, query: Query) -> None:
        if not query.begin():
            return
        batches = None
        try:
            result = query.plan(lambda: self.engine.execute(query.statement, query.session))
            batches = result.batches
            query.attach(result)
            held = None  # each page waits for the next, so that the last one ends the query with it
            for page in _pages(result.columns, batches, self.limits, query.encoding):
                if held is not None:
                    query.put(held)
                held = page
            if held is not None:
                query.put(held, last=True)
            else:
                query.finish()
        except _Stopped:
            pass
        except DialectError as error:
            query.fail(Failure.of(error))
        except Exception as error:  # a bug: the client gets GENERIC_INTERNAL_ERROR, the log the traceback
            log.exception("query %s failed", query.id)
            query.fail(Failure.of(error))
        finally:
            close = getattr(batches, "close", None)
            if close is not None:
                close()

    def kill(self, query_id: str, message: str | None, session: Session, *, owner_only: bool) -> None:
        """CALL system.runtime.kill_query: fail a running or queued query with ADMINISTRATIVELY_KILLED
        (`owner_only`: only the caller's own queries; another user's is NOT_FOUND, as if it did not exist)."""
        query = self.get(query_id)
        if query is None or (owner_only and query.session.user != session.user):
            raise sessions.query_not_found(query_id)  # another user's query is not there for the caller
        text = f"Query killed. Message: {message}" if message else "Query killed. No message provided."
        if query.done or not query.fail(Failure(text, "ADMINISTRATIVELY_KILLED")):
            raise DialectError(f"Target query is not running: {query_id}", error_name="NOT_SUPPORTED")

    def _reap(self) -> None:
        limits = self.limits
        while not self._stop.wait(REAP_INTERVAL):
            now = time.monotonic()
            for query in self.queries():
                idle = now - query.last_access
                if query.running and query.elapsed("started") > limits.query_timeout:
                    query.fail(Failure.of(time_limit_error(limits.query_timeout)))
                elif not query.started and not query.done and _silent_while_queued(query, limits):
                    query.fail(
                        Failure(
                            f"Query {query.id} was abandoned by the client: it stopped polling while queued",
                            "ABANDONED_QUERY",
                        )
                    )
                elif query.running and query.blocked and idle > limits.heartbeat_timeout:
                    query.fail(
                        Failure(
                            f"Query {query.id} was abandoned by the client: it stopped reading results "
                            f"for {limits.heartbeat_timeout:g}s",
                            "ABANDONED_QUERY",
                        )
                    )
                elif not query.done and idle > limits.client_timeout:
                    query.fail(
                        Failure(
                            f"Query {query.id} was abandoned by the client: its results have not "
                            f"been accessed for {limits.client_timeout:g}s",
                            "ABANDONED_QUERY",
                        )
                    )
                if query.failure is not None and query.working:
                    query.interrupt()
                    self._bury(query)
                if query.done and not query.working and idle > limits.retention:
                    with self._lock:
                        self._queries.pop(query.id, None)
            if self.segments is not None:
                self.segments.expire(now)

    def shut_down(self) -> list[Query]:
        """Refuse new queries and fail every query now (SERVER_SHUTTING_DOWN), so that each client
        waiting for its query gets that answer; returns the queries that were still going."""
        with self._lock:
            self._closing = True
        going = [query for query in self.queries() if not query.final]
        for query in going:
            if query.fail(SHUTTING_DOWN):
                query.interrupt()
        return going

    def working(self) -> int:
        """Workers still running (of queries that ended, too)."""
        return sum(query.working for query in self.queries())

    def close(self) -> None:
        """Fail every query (SERVER_SHUTTING_DOWN), stop the reaper and wait (at most
        SHUTDOWN_GRACE seconds) for the workers to stop."""
        self._stop.set()
        self._reaper.join()
        with self._lock:
            for _ in range(self._idle_threads):
                self._handoff.put(None)  # an idle query thread ends
            self._idle_threads = 0
        queries = self.queries()
        for query in queries:
            query.fail(SHUTTING_DOWN)
        deadline = time.monotonic() + (0.2 if self._closing else SHUTDOWN_GRACE)  # `shut_down` waited already
        while any(query.working for query in queries) and time.monotonic() < deadline:
            for query in queries:  # repeat interrupts that came before DuckDB started
                query.interrupt()
            time.sleep(0.05)
        working = sum(query.working for query in queries)
        if working:
            log.warning("%d query workers still run at shutdown; they are left to end with the process", working)


SHUTTING_DOWN = Failure("The server is shutting down", "SERVER_SHUTTING_DOWN")
#: A statement text longer than this (characters) is large: parsing and translating it takes long
#: enough that only `QueryManager.large_slots` of them run at once.
LARGE_TEXT_BYTES = 64 * 1024
#: The statement text the queries waiting to run may hold together, in largest bodies
#: (`Limits.max_body`): the server's memory for its queue is bounded by bytes, not only by
#: `Limits.max_queued_queries`; a statement past it fails with QUERY_QUEUE_FULL.
QUEUED_BODIES = 32
#: Seconds a queued query's client may go without polling beyond `Limits.wait` (a polling client
#: asks again at least every `Limits.wait` seconds) before the query is dropped as abandoned.
QUEUED_SILENCE = 4.0


def _silent_while_queued(query: Query, limits: Limits) -> bool:
    """Whether a queued query's client stopped polling (it vanished: the query is not worth running)."""
    return time.monotonic() - query.last_access > limits.wait + QUEUED_SILENCE
