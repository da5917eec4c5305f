"""Backends: run one Trino-dialect query on a branch of the lake and stream its result.

`DuckDBBackend` is the embedded default: one in-memory DuckDB database per backend (one memory
budget, one thread pool), in which each branch is an attached in-memory database with a view per
lake table (`Catalog.view_sql`), released when idle; a scoped query (a batch or a job) reads views
over only its scope's files, each made when a query first names its table. It is locked down before
any user query runs (defence in depth behind the dialect guard): no file access outside the lake,
no extension installing or loading, settings locked. Each query is translated by
`lakegate.dialect.translate`, checked once more by DuckDB's own parser (exactly one SELECT), and
run on its own cursor, so queries run concurrently and `QueryResult.cancel()` interrupts just one.
EXPLAIN is answered with DuckDB's plan of the translated query; SHOW and DESCRIBE are the Engine's
(its system tables), not a backend's.

Every caller (the server, the dashboard, metrics, `lakegate query`) gets the same `Limits`: at most
`max_concurrent_queries` queries run DuckDB work at once (a query waits for a slot within its time),
and a timer interrupts a query (EXPLAIN ANALYZE included) `query_timeout` seconds after `execute`
was called, which then fails with EXCEEDED_TIME_LIMIT. Errors name lake files relative to the lake,
never by their absolute path.

DuckDB's allowed directories cannot be made read-only: raw DuckDB SQL on these connections could
still COPY or ATTACH inside the lake directory. No such statement reaches them: the guard refuses
it, and only a single statement that DuckDB itself parses as a SELECT is ever run.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import shutil
import tempfile
import threading
import time
import weakref
from collections.abc import Callable, Collection, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import duckdb
import pyarrow as pa
from sqlglot import exp

from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope
from lakegate.dialect.scope_values import translate_in_scope
from lakegate.dialect.session_functions import SessionNames
from lakegate.dialect.statements import Statement, read, shifted
from lakegate.dialect.translate import Translation
from lakegate.gateway.engine import udfs
from lakegate.gateway.engine.branch_state import BranchState, ScopeViews
from lakegate.gateway.engine.failures import duckdb_failure, hide_paths, time_limit_error
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.query_run import Run, in_zones
from lakegate.lake import paths
from lakegate.lake.catalog import Catalog
from lakegate.lake.record import FileEntry, Record, Snapshot
from lakegate.lake.storage import LOCAL

#: Rows per streamed record batch.
BATCH_ROWS = 65_536
#: How often a query starts again when a file it listed was replaced before its first row.
RETRIES = 3
#: Parsed DuckDB statements kept per branch (parsing costs about 0.4 ms).
STATEMENT_CACHE = 256
#: Scopes whose views (over only their files) are kept per branch, beyond those used in the last
#: SCOPE_GRACE seconds (a query may be about to bind them).
SCOPE_VIEWS = 64
SCOPE_GRACE = 60.0
#: Seconds without a query after which a branch's views are released (made again on its next query).
IDLE_SECONDS = 600.0


@dataclass
class QueryResult:
    """A running query: its (name, Trino type) columns and its rows as a stream of Arrow batches."""

    columns: list[tuple[str, str]]
    batches: Iterator[pa.RecordBatch]
    duckdb_sql: str | None = None
    _cancel: Callable[[], None] | None = field(default=None, repr=False)

    def rows(self) -> list[tuple]:
        """Every remaining row, as tuples of Python values."""
        rows: list[tuple] = []
        for batch in self.batches:
            rows.extend(zip(*(column.to_pylist() for column in batch.columns)))
        return rows

    def cancel(self) -> None:
        """Interrupt the query's DuckDB work (reading on raises a USER_CANCELED DialectError)."""
        if self._cancel is not None:
            self._cancel()


class Backend(Protocol):
    """What the gateway needs from a place that runs queries."""

    def schema(self, branch: str) -> dict[str, dict[str, str]]:
        """Table -> column -> Trino type name of a branch."""

    def execute(
        self,
        sql: str | Statement,
        *,
        branch: str,
        scope: Scope | None = None,
        params: Sequence[object] = (),
        time_zone: str = "UTC",
        session: SessionNames | None = None,
    ) -> QueryResult:
        """Start one Trino-dialect query or EXPLAIN (its text, or as the planner read and rewrote it) in
        the session zone `time_zone` (canonical: dialect/zones.py), with `current_user`,
        `current_catalog` and `current_schema` answered from `session`; raises DialectError when it
        is refused or fails."""


def _quote_ident(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


class DuckDBBackend:
    """Embedded DuckDB over the lake at `lake` (None: no lake, constant queries only).

    `memory_limit` and `threads` are shared by every branch (one DuckDB database; each branch is
    attached to it on first use and detached after `idle_seconds` without a query, at least the
    query timeout, so that no query still runs on it); `limits` bound every query's time and how
    many run at once (`query_timeout`, `max_concurrent_queries`). Each query reads its
    branch's record generation (`lake.record`) once; when it changed (a commit) or the config registry
    did, the views are rebuilt from one snapshot of the record, in one DuckDB transaction, so a query
    sees every table at one generation. `pending` files (staged, not committed) replace the record's
    files of their keys (`with_pending`).
    """

    def __init__(
        self,
        lake: Path | None,
        *,
        memory_limit: str = "2GB",
        threads: int = 2,
        limits: Limits = Limits(),
        pending: Sequence[FileEntry] = (),
        idle_seconds: float = IDLE_SECONDS,
    ):
        self.lake = Path(lake).resolve() if lake is not None else None
        self.catalog = Catalog(self.lake, pending) if self.lake is not None else None
        self.memory_limit, self.threads, self.limits = memory_limit, threads, limits
        self.idle_seconds = max(idle_seconds, limits.query_timeout)
        self._database: duckdb.DuckDBPyConnection | None = None
        self._branch_ids = itertools.count(1)
        self._slots = threading.BoundedSemaphore(limits.max_concurrent_queries)
        self._runs: weakref.WeakSet[Run] = weakref.WeakSet()  # queries started and not collected
        self._branches: dict[str, BranchState] = {}
        self._paths: dict[str, tuple[str, str]] = {}  # branch -> its directory and configs directory
        self._records: dict[str, Record] = {}
        self._listed: tuple[object, list[str]] = (None, [])  # (the lake directory's mtime, its branches)
        self._lock = threading.Lock()
        self._scope_ids = itertools.count(1)
        self._temp = tempfile.mkdtemp(prefix="lakegate-duckdb-")
        self._cleanup = weakref.finalize(self, shutil.rmtree, self._temp, ignore_errors=True)

    def with_pending(self, pending: Sequence[FileEntry]) -> DuckDBBackend:
        """A new backend over the same lake that already shows `pending` (close it after use)."""
        return DuckDBBackend(
            self.lake,
            memory_limit=self.memory_limit,
            threads=self.threads,
            limits=self.limits,
            pending=pending,
            idle_seconds=self.idle_seconds,
        )

    # -- branches -------------------------------------------------------------------------

    def branches(self) -> list[str]:
        """The branches of the lake (listed again only when the lake directory changes)."""
        if self.catalog is None:
            return []
        try:
            stamp = LOCAL.stat(self.lake).mtime_ns
        except FileNotFoundError:
            return []
        listed_stamp, listed = self._listed
        if listed_stamp != stamp:
            listed = self.catalog.branches()
            self._listed = (stamp, listed)
        return list(listed)

    def _stamp(self, branch: str) -> object:
        """What changes when the branch's tables may have changed: its record's generation and the
        mtime of its config registry (called under `_lock`)."""
        if self.lake is None:
            return None
        found = self._paths.get(branch)
        if found is None:
            try:
                found = str(paths.branch_dir(self.lake, branch)), str(paths.configs_dir(self.lake, branch))
            except paths.LakePathError as error:
                raise DialectError(str(error), error_name="SCHEMA_NOT_FOUND") from None
        directory, configs = found
        if not LOCAL.is_dir(directory):
            known = ", ".join(self.branches()) or "none"
            raise DialectError(
                f"Schema '{branch}' does not exist: no branch '{branch}' in the lake (branches: {known})",
                error_name="SCHEMA_NOT_FOUND",
            )
        self._paths[branch] = found  # only branches that exist
        record = self._records.setdefault(branch, Record(self.lake, branch))
        try:
            return record.generation(), LOCAL.stat(configs).mtime_ns
        except FileNotFoundError:
            return record.generation(), None

    def _connect(self) -> duckdb.DuckDBPyConnection:
        """The backend's one database, locked down (made on first use; called under `_lock`)."""
        if self._database is None:
            database = duckdb.connect(
                ":memory:",
                config={
                    "threads": self.threads,
                    "memory_limit": self.memory_limit,
                    "temp_directory": self._temp,
                    "autoinstall_known_extensions": False,
                    "autoload_known_extensions": False,
                    "python_enable_replacements": False,
                },
            )
            udfs.install(database)
            self._lock_down(database)
            self._database = database
        return self._database

    def _lock_down(self, connection: duckdb.DuckDBPyConnection) -> None:
        connection.execute("SET TimeZone = 'UTC'")
        if self.lake is not None:
            connection.execute("SET allowed_directories = ?", [[str(self.lake) + "/"]])
        connection.execute("SET enable_external_access = false")
        connection.execute("SET lock_configuration = true")

    def _state(self, branch: str, *, views: bool = False) -> BranchState:
        """The branch at its record's current generation: its schema, and with `views` its branch-wide
        views (a query without a scope reads them; a scoped one reads `_scope_views`)."""
        with self._lock:
            self._release_idle()  # before the stamp: it may close this branch's record
            stamp = self._stamp(branch)
            state = self._branches.get(branch)
            if state is None:
                database, name = self._connect(), f"branch_{next(self._branch_ids)}"
                database.execute(f"ATTACH ':memory:' AS {name}")
                state = self._branches[branch] = BranchState(database, name, stamp=object())
            state.used = time.monotonic()
            if state.stamp != stamp or (views and not state.loaded):
                self._load(state, branch, stamp, views)
            return state

    def _release_idle(self) -> None:
        """Detach the branches not queried for `idle_seconds` (called under `_lock`)."""
        limit = time.monotonic() - self.idle_seconds
        for branch, state in list(self._branches.items()):
            if state.used < limit:
                del self._branches[branch]
                state.close_idle()
                state.database.execute(f"DETACH {state.name}")
                self._records.pop(branch).close()

    def _load(self, state: BranchState, branch: str, stamp: object, views: bool) -> None:
        """Take the schema of the record's current generation; with `views`, replace the branch-wide
        views by those of its snapshot (otherwise only the record's tables are read, no file list)."""
        if self.catalog is None:
            state.stamp = stamp
            return
        record = self._records[branch]
        snapshot = self._load_views(state, branch) if views else self.catalog.snapshot(branch, record, files=False)
        schema = self.catalog.schema(branch, snapshot)
        state.schema, state.stamp, state.loaded = schema, (snapshot.generation, stamp[1]), views
        state.version = hashlib.sha1(
            repr(sorted((t, sorted(c.items())) for t, c in schema.items())).encode()
        ).hexdigest()

    def _load_views(self, state: BranchState, branch: str) -> Snapshot:
        """Replace the branch-wide views by those of the record's current snapshot (a newer one when
        a writer replaced one of its files meanwhile, `_create_views`); returns the snapshot."""
        root = str(paths.branch_dir(self.lake, branch))
        while True:
            snapshot = self.catalog.snapshot(branch, self._records[branch])
            files = {paths.reader_file(root, e.path): e.where for e in snapshot.files}
            state.files = {**state.listed, **files}  # queries still running may name the last files
            if self._create_views(state, branch, snapshot, state.views):
                break
        state.files, state.listed = {**state.listed, **files}, files
        state.views = set(self.catalog.schema(branch, snapshot))
        return snapshot

    def _create_views(
        self,
        state: BranchState,
        branch: str,
        snapshot: Snapshot,
        old: Iterable[str] = (),
        schema: str | None = None,
        tables: Collection[str] | None = None,
    ) -> bool:
        """Create the views of `snapshot` (only those of `tables` when given) in one transaction (in
        DuckDB schema `schema`, default the branch's own views, dropping the `old` views it no longer
        has). A file that cannot be read is left out (queries of its job fail, `Catalog.view_sql`);
        False when one was replaced meanwhile (a writer committed after the snapshot was read): take
        a newer snapshot."""
        root = str(paths.branch_dir(self.lake, branch))
        unreadable: set[str] = set()
        while True:
            views = self.catalog.view_sql(branch, snapshot, unreadable=unreadable)
            if tables is not None:
                views = {name: select for name, select in views.items() if name in tables}
            if (failed := self._swap_views(state, views, old, schema)) is None:
                return True
            files = (paths.reader_file(root, e.path) for e in snapshot.files)
            named = {path for path in files if path in failed}
            if named <= unreadable:
                raise state.failure(duckdb.Error(failed))
            if not all(map(LOCAL.exists, named)) and self._records[branch].generation() != snapshot.generation:
                return False
            unreadable |= named  # corrupt, or missing although the record holds it

    @staticmethod
    def _swap_views(state: BranchState, views: dict[str, str], old: Iterable[str], schema: str | None) -> str | None:
        """Replace views in one transaction; the error text if one cannot be made."""
        prefix = f"{schema}." if schema else ""
        cursor = state.cursor()
        try:
            cursor.execute("BEGIN")
            if schema:
                cursor.execute(f"CREATE SCHEMA IF NOT EXISTS {schema}")
            for name in set(old) - set(views):
                cursor.execute(f"DROP VIEW IF EXISTS {_quote_ident(name)}")
            for name, select in views.items():
                cursor.execute(f"CREATE OR REPLACE VIEW {prefix}{_quote_ident(name)} AS {select}")
            cursor.execute("COMMIT")
            return None
        except duckdb.Error as error:
            cursor.execute("ROLLBACK")
            return str(error)
        finally:
            cursor.close()

    def _scope_views(self, state: BranchState, branch: str, scope: Scope, tables: Collection[str]) -> str:
        """The DuckDB schema whose views of `tables` read only the files of `scope` (the job's files
        and its batch's batch-level files, found by the record's index). One schema per scope and
        generation, kept in an LRU; each view is made when a query first names its table (binding a
        view reads its files' footers), with those of the tables queries of other scopes of its kind
        (job or batch) named, outside the backend's lock, so other queries go on meanwhile."""
        key = (state.stamp[0], scope.batch_id, scope.job_id)
        while True:  # a writer may commit meanwhile: the scope's files are then those of its generation
            with self._lock:
                now = time.monotonic()
                entry = state.scopes.get(key)
                if entry is None:
                    snapshot = self.catalog.snapshot(
                        branch, self._records[branch], batch_id=scope.batch_id, job_id=scope.job_id
                    )
                    key = (snapshot.generation, scope.batch_id, scope.job_id)
                    entry = state.scopes.get(key)
                if entry is None:
                    root = str(paths.branch_dir(self.lake, branch))
                    files = {paths.reader_file(root, e.path): e.where for e in snapshot.files}
                    entry = state.scopes[key] = ScopeViews(
                        f"{state.name}.scope_{next(self._scope_ids)}", snapshot, files, now
                    )
                    while (
                        len(state.scopes) > SCOPE_VIEWS and next(iter(state.scopes.values())).used < now - SCOPE_GRACE
                    ):
                        state.database.execute(f"DROP SCHEMA {state.scopes.popitem(last=False)[1].name} CASCADE")
                state.scopes.move_to_end(key)
                entry.used = now
            with entry.lock:
                made = entry.made
                missing = set(tables).difference(made or ())
                if made is not None and not missing:
                    return entry.name
                learned = state.scoped_tables[scope.job_id is not None]
                missing |= learned.difference(made or ())  # what the scope's next queries likely name
                learned.update(tables)
                if self._create_views(state, branch, entry.snapshot, schema=entry.name, tables=missing):
                    entry.made = missing.union(made or ())
                    return entry.name
            key = (None, scope.batch_id, scope.job_id)  # the snapshot is outdated: take the record's current one

    def _known_views(self, state: BranchState, scope: Scope | None) -> str | None:
        """The schema of the views a query of `scope` most likely reads (its scope's, when made at the
        branch's current generation; None for the branch's own), so that a cursor already reading
        them can be reused; `_rows` moves the cursor when the guess is wrong."""
        if not self._scoped(scope):
            return None
        with self._lock:
            entry = state.scopes.get((state.stamp[0], scope.batch_id, scope.job_id))
        return entry.name if entry is not None else None

    def _scoped(self, scope: Scope | None) -> bool:
        """Whether a query of `scope` reads the scope's own views (`_scope_views`)."""
        return self.catalog is not None and scope is not None and bool(scope.conditions())

    def schema(self, branch: str = "main") -> dict[str, dict[str, str]]:
        """Table -> column -> Trino type name of `branch` (empty without a lake)."""
        return self._state(branch).schema

    def connection(self, branch: str = "main") -> duckdb.DuckDBPyConnection:
        """A new cursor on the branch's locked-down DuckDB database (raw DuckDB SQL, for tests and tools)."""
        return self._state(branch, views=True).cursor()

    # -- queries --------------------------------------------------------------------------

    def translate(
        self,
        sql: str,
        *,
        branch: str = "main",
        scope: Scope | None = None,
        params: Sequence[object] = (),
        time_zone: str = "UTC",
        session: SessionNames | None = None,
    ) -> Translation:
        """The translation of one query over `branch`'s schema (cached by text, params, zone, session
        names and schema; one entry serves every job and batch scope, `dialect.scope_values`)."""
        state = self._state(branch)
        return translate_in_scope(
            sql,
            state.schema,
            scope=scope,
            params=params,
            schema_version=state.version,
            time_zone=time_zone,
            session=session,
        )

    @staticmethod
    def _translate(
        state: BranchState,
        statement: Statement,
        tree: exp.Expression,
        scope: Scope | None,
        params: Sequence[object],
        time_zone: str,
        session: SessionNames | None = None,
    ) -> Translation:
        """The translation of the statement's query (for EXPLAIN: the query it explains), from its
        `tree`; errors positioned in that query's text."""
        return translate_in_scope(
            statement.body,
            state.schema,
            scope=scope,
            params=params,
            schema_version=state.version,
            time_zone=time_zone,
            session=session,
            tree=tree,
            rewrite=statement.edits,
        )

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
        """Translate and start one Trino-dialect query (or EXPLAIN) on `branch`, restricted to `scope`,
        with `params` bound to its `?`, in the session zone `time_zone`, its session functions
        answered from `session`. Raises DialectError (with position) when refused or failing."""
        deadline = time.monotonic() + self.limits.query_timeout
        try:
            return self._execute(sql, branch, scope, params, deadline, time_zone, session)
        except DialectError as error:
            raise self._for_client(error) from None

    def _execute(
        self,
        sql: str | bytes | Statement,
        branch: str,
        scope: Scope | None,
        params: Sequence[object],
        deadline: float,
        time_zone: str = "UTC",
        session: SessionNames | None = None,
    ) -> QueryResult:
        # a text is read (and its refusal raised) before it is parsed; a Statement comes from the planner,
        # which raised its refusal
        statement = sql if isinstance(sql, Statement) else read(sql)
        if statement is not sql:
            statement.check()
        state = self._state(branch, views=not self._scoped(scope))
        if statement.kind == "explain":
            translation = self._explain(statement, state, scope, params, time_zone, session)
            return self._start(
                branch,
                state,
                translation,
                deadline,
                scope,
                explain="EXPLAIN ANALYZE " if statement.analyze else "EXPLAIN ",
            )
        translation = self._translate(state, statement, statement.tree, scope, params, time_zone, session)
        return self._start(branch, state, translation, deadline, scope)

    def _start(
        self,
        branch: str,
        state: BranchState,
        translation: Translation,
        deadline: float,
        scope: Scope | None,
        *,
        explain: str | None = None,
    ) -> QueryResult:
        """Take a slot (waiting at most until `deadline`) and start the translated query on its own
        cursor, reading the views of its `scope` (`_scope_views`); with `explain` ("EXPLAIN " or
        "EXPLAIN ANALYZE "), its plan is the result."""
        timeout = self.limits.query_timeout
        remaining = deadline - time.monotonic()
        if remaining <= 0 or not self._slots.acquire(timeout=remaining):
            raise time_limit_error(timeout)
        where = [self._known_views(state, scope) if explain is None else None]  # the views the cursor reads
        cursor = state.cursor(where[0])
        try:
            if explain is None:
                produce: Callable[[], Iterable[pa.RecordBatch]] = in_zones(
                    self._rows(branch, state, cursor, where, translation.duckdb_sql, scope), translation.zones
                )
                columns = list(translation.columns)
            else:
                if self._scoped(scope):
                    self._use_views(
                        cursor, self._scope_views(state, branch, scope, self._tables(state, translation.duckdb_sql))
                    )
                self._single_select(cursor, translation.duckdb_sql)
                produce = functools.partial(self._plan_batches, cursor, explain + translation.duckdb_sql)
                columns = [("Query Plan", "varchar")]
        except BaseException as error:
            cursor.close()
            self._slots.release()
            raise self._for_client(state.failure(error)) if isinstance(error, duckdb.Error) else error from None
        run = Run(
            cursor,
            produce,
            release=self._slots.release,
            timeout=timeout,
            remaining=max(0.0, deadline - time.monotonic()),
            failure=lambda error: self._for_client(state.failure(error)),
            recycle=(lambda cursor: state.recycle(cursor, where[0])) if explain is None else None,
        )
        self._runs.add(run)
        return QueryResult(columns=columns, batches=run, duckdb_sql=translation.duckdb_sql, _cancel=run.cancel)

    def _rows(
        self,
        branch: str,
        state: BranchState,
        cursor: duckdb.DuckDBPyConnection,
        where: list[str | None],
        duckdb_sql: str,
        scope: Scope | None,
    ) -> Callable[[], Iterator[pa.RecordBatch]]:
        """Bind the query on `cursor` now, over the views of its `scope` (`where` holds the schema of
        views the cursor reads, kept up to date); the returned function reads its record batches. A
        query that finds a listed file gone before its first row (a writer replaced it after the
        query's views were read) starts again on the branch's views as they are now, up to RETRIES
        times."""

        def bind(attempt: BranchState, retries: int) -> duckdb.DuckDBPyRelation:
            try:
                if self._scoped(scope):
                    schema = self._scope_views(attempt, branch, scope, self._tables(attempt, duckdb_sql))
                    if schema != where[0]:
                        self._use_views(cursor, schema)
                        where[0] = schema
                return cursor.sql(self._statement(attempt, cursor, duckdb_sql))
            except duckdb.Error as error:
                return again(attempt, error, retries)

        def again(attempt: BranchState, error: BaseException, retries: int) -> duckdb.DuckDBPyRelation:
            if not attempt.vanished(error):
                raise error
            if retries == 0:
                raise attempt.failure(error, vanished=True) from None
            return bind(self._state(branch, views=not self._scoped(scope)), retries - 1)

        first = bind(state, RETRIES)

        def read() -> Iterator[pa.RecordBatch]:
            relation, retries = first, RETRIES
            while True:
                started = False
                try:
                    for batch in relation.to_arrow_reader(BATCH_ROWS):
                        started = True
                        yield batch
                    return
                except duckdb.Error as error:
                    if started:
                        raise
                    relation, retries = again(state, error, retries), retries - 1

        return read

    @staticmethod
    def _tables(state: BranchState, duckdb_sql: str) -> set[str]:
        """The branch's tables a translated query names (the DuckDB writer quotes every identifier;
        a column of the same name adds its table too): the views its scope needs."""
        text = duckdb_sql.lower()
        return {table for table in state.schema if _quote_ident(table.lower()) in text}

    @staticmethod
    def _use_views(cursor: duckdb.DuckDBPyConnection, schema: str) -> None:
        """Make the cursor's table names resolve to the views of `schema`."""
        cursor.execute(f"SET search_path = '{schema}'")

    def _plan_batches(self, cursor: duckdb.DuckDBPyConnection, explain_sql: str) -> list[pa.RecordBatch]:
        return [self._plan(cursor, explain_sql)]

    def _plan(self, cursor: duckdb.DuckDBPyConnection, explain_sql: str) -> pa.RecordBatch:
        """DuckDB's plan (EXPLAIN [ANALYZE] runs here) as one row, lake paths made relative."""
        rows = cursor.execute(explain_sql).fetchall()
        plan = hide_paths("\n".join(str(row[-1]).rstrip() for row in rows), self.lake, self._temp, keep_width=True)
        return pa.record_batch([pa.array([plan], pa.string())], names=["Query Plan"])

    def _failure(self, error: BaseException) -> DialectError:
        return self._for_client(duckdb_failure(error))

    def _for_client(self, error: DialectError) -> DialectError:
        """`error` without absolute paths of the lake or the spill directory in its message."""
        message = hide_paths(error.message, self.lake, self._temp)
        if message == error.message:
            return error
        return DialectError(message, line=error.line, column=error.column, error_name=error.error_name)

    def _statement(self, state: BranchState, cursor: duckdb.DuckDBPyConnection, duckdb_sql: str) -> object:
        """The checked DuckDB Statement of the translated SQL, parsed once per text."""
        with self._lock:
            statement = state.statements.get(duckdb_sql)
            if statement is not None:
                state.statements.move_to_end(duckdb_sql)
                return statement
        statement = self._single_select(cursor, duckdb_sql)
        with self._lock:
            state.statements[duckdb_sql] = statement
            if len(state.statements) > STATEMENT_CACHE:
                state.statements.popitem(last=False)
        return statement

    @staticmethod
    def _single_select(cursor: duckdb.DuckDBPyConnection, duckdb_sql: str) -> object:
        """DuckDB's parse of the translated SQL, which must be exactly one SELECT."""
        statements = cursor.extract_statements(duckdb_sql)
        if len(statements) != 1 or statements[0].type != duckdb.StatementType.SELECT:
            kinds = ", ".join(s.type.name for s in statements)
            raise DialectError(
                f"internal error: the translation is not one SELECT ({kinds}); refused",
                error_name="GENERIC_INTERNAL_ERROR",
            )
        return statements[0]

    def _explain(
        self,
        statement: Statement,
        state: BranchState,
        scope: Scope | None,
        params: Sequence[object],
        time_zone: str,
        session: SessionNames | None = None,
    ) -> Translation:
        """The translation of the query an EXPLAIN [ANALYZE] explains (errors positioned in the
        whole EXPLAIN text)."""
        tree = statement.tree  # its parse errors come positioned in the whole text
        try:
            return self._translate(state, statement, tree, scope, params, time_zone, session)
        except DialectError as error:
            raise shifted(error, statement.text, statement.offset) from None

    def stop_all(self) -> None:
        """Interrupt every running query: each fails with SERVER_SHUTTING_DOWN."""
        for run in list(self._runs):
            run.stop(DialectError("The server is shutting down", error_name="SERVER_SHUTTING_DOWN"))

    def close(self) -> None:
        """Interrupt running queries, close every branch database and remove the spill directory."""
        self.stop_all()
        with self._lock:
            if self._database is not None:
                self._database.close()
            self._branches.clear()
            for record in self._records.values():
                record.close()
            self._records.clear()
        self._cleanup()
