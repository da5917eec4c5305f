"""Backends: run one Trino-dialect query on a branch of the lake and stream its result.

`DuckDBBackend` is the embedded default: per branch, one in-memory DuckDB database with a view per
lake table (`Catalog.view_sql`), locked down before any user query runs (defence in depth behind
the dialect guard): no file access outside the lake, no extension installing or loading, settings
locked. Each query is translated by `lakegate.dialect.translate`, checked once more by DuckDB's own
parser (exactly one SELECT), and run on its own cursor, so queries run concurrently and
`QueryResult.cancel()` interrupts just one. SHOW / DESCRIBE are answered from the branch schema
(`introspection`), EXPLAIN with DuckDB's plan of the translated query.

DuckDB's allowed directories cannot be made read-only: raw DuckDB SQL on these connections could
still COPY or ATTACH inside the lake directory. No such statement reaches them: the guard refuses
it, and only a single statement that DuckDB itself parses as a SELECT is ever run.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import threading
import weakref
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Protocol, Sequence

import duckdb
import pyarrow as pa

from lakegate.dialect import guard
from lakegate.dialect.errors import DialectError, runtime_error
from lakegate.dialect.scope import Scope
from lakegate.dialect.translate import Translation, translate
from lakegate.gateway import introspection
from lakegate.lake import paths
from lakegate.lake.catalog import Catalog
from lakegate.lake.record import FileEntry, Record

#: Rows per streamed record batch.
BATCH_ROWS = 65_536
#: How often a query starts again when a file it listed was replaced before its first row.
RETRIES = 3
#: Parsed DuckDB statements kept per branch (parsing costs about 0.4 ms).
STATEMENT_CACHE = 256


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

    def execute(self, sql: str, *, branch: str, scope: Scope | None = None,
                params: Sequence[object] = ()) -> QueryResult:
        """Start one Trino-dialect query; raises DialectError when it is refused or fails."""


def _static(columns: list[tuple[str, str]], rows: list[tuple]) -> QueryResult:
    """A result computed in Python (all columns varchar)."""
    arrays = [pa.array([row[i] for row in rows], pa.string()) for i in range(len(columns))]
    batch = pa.record_batch(arrays, names=[name for name, _ in columns])
    return QueryResult(columns=columns, batches=iter([batch]))


def _failure(error: BaseException) -> DialectError:
    """The DialectError (Trino error name) for an error DuckDB raised while running a query."""
    if isinstance(error, duckdb.InterruptException) or "INTERRUPT Error" in str(error):
        return DialectError("Query was canceled", error_name="USER_CANCELED")
    if isinstance(error, duckdb.OutOfMemoryException) or "Out of Memory Error" in str(error):
        return DialectError(f"Query exceeded the memory limit: {error}", error_name="EXCEEDED_GLOBAL_MEMORY_LIMIT")
    return runtime_error(str(error))


def _quote_ident(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


class _Run:
    """One query on its own cursor: started lazily by the first read, so it can be canceled.

    `describe` turns a DuckDB error into the DialectError to raise; `again` (if given) starts the
    query once more when it fails before its first row because a file it listed was replaced.
    """

    def __init__(self, cursor: duckdb.DuckDBPyConnection, relation: duckdb.DuckDBPyRelation, *,
                 describe: Callable[[BaseException], DialectError] | None = None,
                 again: Callable[[BaseException], "_Run | None"] | None = None):
        self.cursor, self.relation = cursor, relation
        self.describe, self.again = describe or _failure, again
        self.canceled = False

    def cancel(self) -> None:
        self.canceled = True
        try:
            self.cursor.interrupt()
        except duckdb.Error:
            pass  # already closed: nothing runs

    def batches(self) -> Iterator[pa.RecordBatch]:
        retry = None
        try:
            if self.canceled:
                raise DialectError("Query was canceled", error_name="USER_CANCELED")
            started = False
            try:
                reader = self.relation.to_arrow_reader(BATCH_ROWS)
                for batch in reader:
                    started = True
                    yield batch
            except (duckdb.Error, OSError, pa.ArrowException) as error:
                retry = None if started or self.again is None else self.again(error)
                if retry is None:
                    raise self.describe(error) from None
        finally:
            self.cursor.close()
        if retry is not None:
            self.cursor = retry.cursor  # `cancel` interrupts the query's new run
            yield from retry.batches()


@dataclass
class _Branch:
    connection: duckdb.DuckDBPyConnection
    stamp: object = None
    schema: dict[str, dict[str, str]] = field(default_factory=dict)
    version: str = ""
    statements: OrderedDict = field(default_factory=OrderedDict)  # DuckDB SQL -> its checked Statement
    files: dict[str, str] = field(default_factory=dict)  # reader path -> "table T, batch B, job J" (last 2 loads)
    listed: dict[str, str] = field(default_factory=dict)  # the same, of the views' files only

    def failure(self, error: BaseException, *, vanished: bool = False) -> DialectError:
        """The DialectError for a DuckDB error: a listed file is named by its table, batch and job
        (HIVE_BAD_DATA when it cannot be read, HIVE_FILE_NOT_FOUND when writers kept replacing
        it), never by its path."""
        message = str(error)
        named = [path for path in self.files if path in message]
        if not named:
            return _failure(error)
        for path in named:
            message = message.replace(f"'{path}'", path).replace(f'"{path}"', path).replace(path, self.files[path])
        if vanished:
            return DialectError(f"The data of {self.files[named[0]]} was replaced while the query read it, "
                                "again and again; run the query again", error_name="HIVE_FILE_NOT_FOUND")
        first = message.strip().splitlines()[0].split(": ", 1)[-1]
        return DialectError(f"Cannot read the Parquet file of {self.files[named[0]]}: {first}",
                            error_name="HIVE_BAD_DATA")

    def vanished(self, error: BaseException) -> bool:
        """Whether the error is about a listed file that is gone (a writer replaced it)."""
        message = str(error)
        return any(path in message and not os.path.exists(path) for path in self.files)


class DuckDBBackend:
    """Embedded DuckDB over the lake at `lake` (None: no lake, constant queries only).

    `memory_limit` and `threads` apply to each branch's database. Each query reads its branch's
    record generation (`lake.record`) once; when it changed (a commit) or the config registry did,
    the views are rebuilt from one snapshot of the record, in one DuckDB transaction, so a query
    sees every table at one generation. `pending` files (staged, not committed) replace the
    record's files of their keys (`with_pending`).
    """

    def __init__(self, lake: Path | None, *, memory_limit: str = "2GB", threads: int = 2,
                 pending: Sequence[FileEntry] = ()):
        self.lake = Path(lake).resolve() if lake is not None else None
        self.catalog = Catalog(self.lake, pending) if self.lake is not None else None
        self.memory_limit, self.threads = memory_limit, threads
        self._branches: dict[str, _Branch] = {}
        self._paths: dict[str, tuple[str, str]] = {}  # branch -> its directory and configs directory
        self._records: dict[str, Record] = {}
        self._listed: tuple[object, list[str]] = (None, [])  # (the lake directory's mtime, its branches)
        self._lock = threading.Lock()
        self._temp = tempfile.mkdtemp(prefix="lakegate-duckdb-")
        self._cleanup = weakref.finalize(self, shutil.rmtree, self._temp, ignore_errors=True)

    def with_pending(self, pending: Sequence[FileEntry]) -> "DuckDBBackend":
        """A new backend over the same lake that already shows `pending` (close it after use)."""
        return DuckDBBackend(self.lake, memory_limit=self.memory_limit, threads=self.threads, pending=pending)

    # -- branches -------------------------------------------------------------------------

    def branches(self) -> list[str]:
        """The branches of the lake (listed again only when the lake directory changes)."""
        if self.catalog is None:
            return []
        try:
            stamp = os.stat(self.lake).st_mtime_ns
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
        if not os.path.isdir(directory):
            known = ", ".join(self.branches()) or "none"
            raise DialectError(f"Schema '{branch}' does not exist: no branch '{branch}' in the lake "
                               f"(branches: {known})", error_name="SCHEMA_NOT_FOUND")
        self._paths[branch] = found  # only branches that exist
        record = self._records.setdefault(branch, Record(self.lake, branch))
        try:
            return record.generation(), os.stat(configs).st_mtime_ns
        except FileNotFoundError:
            return record.generation(), None

    def _connect(self) -> duckdb.DuckDBPyConnection:
        return duckdb.connect(":memory:", config={
            "threads": self.threads, "memory_limit": self.memory_limit, "temp_directory": self._temp,
            "autoinstall_known_extensions": False, "autoload_known_extensions": False,
            "python_enable_replacements": False})

    def _lock_down(self, connection: duckdb.DuckDBPyConnection) -> None:
        connection.execute("SET TimeZone = 'UTC'")
        if self.lake is not None:
            connection.execute("SET allowed_directories = ?", [[str(self.lake) + "/"]])
        connection.execute("SET enable_external_access = false")
        connection.execute("SET lock_configuration = true")

    def _state(self, branch: str) -> _Branch:
        with self._lock:
            stamp = self._stamp(branch)
            state = self._branches.get(branch)
            if state is None:
                connection = self._connect()
                self._lock_down(connection)
                state = self._branches[branch] = _Branch(connection, stamp=object())
            if state.stamp != stamp:
                self._load_views(state, branch, stamp)
            return state

    def _load_views(self, state: _Branch, branch: str, stamp: object) -> None:
        """Replace the views by those of the record's current snapshot. A file that cannot be read
        is left out (queries of its job fail, `Catalog.view_sql`); a file replaced meanwhile (a
        writer committed after the snapshot was read) means a newer snapshot is taken."""
        if self.catalog is None:
            state.stamp = stamp
            return
        root = paths.branch_dir(self.lake, branch)
        while True:
            snapshot = self.catalog.snapshot(branch, self._records[branch])
            files = {str(paths.reader_path(root, e.path)): e.where for e in snapshot.files}
            state.files = {**state.listed, **files}  # queries still running may name the last files
            schema = self.catalog.schema(branch, snapshot)
            unreadable: set[str] = set()
            failed = self._swap_views(state, self.catalog.view_sql(branch, snapshot))
            while failed is not None:
                named = {path for path in files if path in failed}
                if named <= unreadable:
                    raise state.failure(duckdb.Error(failed))
                if not all(map(os.path.exists, named)) and self._records[branch].generation() != snapshot.generation:
                    break  # a writer replaced the file: take the newer snapshot
                unreadable |= named  # corrupt, or missing although the record holds it
                failed = self._swap_views(state, self.catalog.view_sql(branch, snapshot, unreadable=unreadable))
            if failed is None:
                break
        state.files, state.listed = {**state.listed, **files}, files
        state.schema, state.stamp = schema, (snapshot.generation, stamp[1])
        state.version = hashlib.sha1(repr(sorted((t, sorted(c.items())) for t, c in schema.items()))
                                     .encode()).hexdigest()

    @staticmethod
    def _swap_views(state: _Branch, views: dict[str, str]) -> str | None:
        """Replace the branch's views in one transaction; the error text if one cannot be made."""
        cursor = state.connection.cursor()
        try:
            cursor.execute("BEGIN")
            for name in set(state.schema) - set(views):
                cursor.execute(f"DROP VIEW IF EXISTS {_quote_ident(name)}")
            for name, select in views.items():
                cursor.execute(f"CREATE OR REPLACE VIEW {_quote_ident(name)} AS {select}")
            cursor.execute("COMMIT")
            return None
        except duckdb.Error as error:
            cursor.execute("ROLLBACK")
            return str(error)
        finally:
            cursor.close()

    def schema(self, branch: str = "main") -> dict[str, dict[str, str]]:
        """Table -> column -> Trino type name of `branch` (empty without a lake)."""
        return self._state(branch).schema

    def connection(self, branch: str = "main") -> duckdb.DuckDBPyConnection:
        """A new cursor on the branch's locked-down DuckDB database (raw DuckDB SQL, for tests and tools)."""
        return self._state(branch).connection.cursor()

    # -- queries --------------------------------------------------------------------------

    def translate(self, sql: str, *, branch: str = "main", scope: Scope | None = None,
                  params: Sequence[object] = ()) -> Translation:
        """The translation of one query over `branch`'s schema (cached by text, scope, params and schema)."""
        return self._translate(self._state(branch), sql, scope, params)

    @staticmethod
    def _translate(state: _Branch, sql: str, scope: Scope | None, params: Sequence[object]) -> Translation:
        return translate(sql, state.schema, scope=scope, params=params, schema_version=state.version)

    def execute(self, sql: str, *, branch: str = "main", scope: Scope | None = None,
                params: Sequence[object] = ()) -> QueryResult:
        """Translate and start one Trino-dialect query on `branch`, restricted to `scope`, with
        `params` bound to its `?`. Raises DialectError (with position) when refused or failing."""
        if not isinstance(sql, str):
            sql = guard.check_text(sql)  # bytes: decoded (or refused) first
        kind = guard.classify(sql)
        state = self._state(branch)
        if kind in ("show", "describe"):
            answer = introspection.answer(guard.check_text(sql), state.schema, schemas=self.branches() or [branch])
            return _static(answer.columns, answer.rows)
        if kind == "explain":
            return self._explain(guard.check_text(sql), state, scope, params)
        translation = self._translate(state, sql, scope, params)
        run = self._start(branch, state, translation.duckdb_sql)
        return QueryResult(columns=list(translation.columns), batches=run.batches(),
                           duckdb_sql=translation.duckdb_sql, _cancel=run.cancel)

    def _start(self, branch: str, state: _Branch, duckdb_sql: str, retries: int = RETRIES) -> _Run:
        """Bind the query on a new cursor. A query that finds a listed file gone before its first
        row (a writer replaced it after the query's views were read) starts again, up to `retries`
        times, on the branch's views as they are now."""
        def again(error: BaseException) -> _Run | None:
            if not state.vanished(error):
                return None
            if retries == 0:
                raise state.failure(error, vanished=True)
            return self._start(branch, self._state(branch), duckdb_sql, retries - 1)

        cursor = state.connection.cursor()
        try:
            relation = cursor.sql(self._statement(state, cursor, duckdb_sql))
        except BaseException as error:
            cursor.close()
            if not isinstance(error, duckdb.Error):
                raise
            restarted = again(error)
            if restarted is None:
                raise state.failure(error) from None
            return restarted
        return _Run(cursor, relation, describe=state.failure, again=again)

    def _statement(self, state: _Branch, cursor: duckdb.DuckDBPyConnection, duckdb_sql: str) -> object:
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
            raise DialectError(f"internal error: the translation is not one SELECT ({kinds}); refused",
                               error_name="GENERIC_INTERNAL_ERROR")
        return statements[0]

    def _explain(self, sql: str, state: _Branch, scope: Scope | None, params: Sequence[object]) -> QueryResult:
        query, analyze = guard.explained_query(sql)
        start = sql.rfind(query)
        try:
            translation = self._translate(state, query, scope, params)
        except DialectError as error:
            if error.line is not None and error.column is not None:  # position in the whole EXPLAIN text
                before = sql[:start]
                line = before.count("\n")
                column = error.column + (len(before) - before.rfind("\n") - 1 if error.line == 1 else 0)
                raise DialectError(error.message, line=error.line + line, column=column,
                                   error_name=error.error_name) from None
            raise
        cursor = state.connection.cursor()
        try:
            self._single_select(cursor, translation.duckdb_sql)
            rows = cursor.execute(("EXPLAIN ANALYZE " if analyze else "EXPLAIN ") + translation.duckdb_sql).fetchall()
        except duckdb.Error as error:
            raise state.failure(error) from None
        finally:
            cursor.close()
        return _static([("Query Plan", "varchar")], [("\n".join(str(row[-1]).rstrip() for row in rows),)])

    def close(self) -> None:
        """Close every branch database and remove the spill directory."""
        with self._lock:
            for state in self._branches.values():
                state.connection.close()
            self._branches.clear()
            for record in self._records.values():
                record.close()
            self._records.clear()
        self._cleanup()
