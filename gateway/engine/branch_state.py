"""A branch's state in the DuckDB backend: its attached database, its views and those of each scope,
the cursors kept for reuse, and how DuckDB's errors about its files are told to clients."""

from __future__ import annotations

import re
import threading
from collections import OrderedDict
from dataclasses import dataclass, field

import duckdb

from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine.failures import duckdb_failure
from lakegate.lake.record import Snapshot
from lakegate.lake.storage import LOCAL

#: Cursors a branch keeps for reuse: a new cursor and its `USE` cost a fast query much of its CPU.
IDLE_CURSORS = 4

#: DuckDB's words for a Parquet file it could not decode without naming the file (a damaged page
#: header reaches its Thrift reader).
_PARQUET_DAMAGE = re.compile(r"TProtocolException|don't know what type|[Pp]arquet|[Tt]hrift|[Cc]orrupt")


@dataclass
class ScopeViews:
    """The views of one scope at one generation of the record, in their own DuckDB schema: made
    table by table as queries name them (`DuckDBBackend._scope_views`), all over one snapshot."""

    name: str  # the DuckDB schema
    snapshot: Snapshot  # the scope's files
    files: dict[str, str]  # reader path -> "table T, batch B, job J"
    used: float  # time.monotonic() of its last query
    made: set[str] | None = None  # the tables whose views exist (None: not even the schema yet)
    lock: threading.Lock = field(default_factory=threading.Lock)  # held while views are added


@dataclass
class BranchState:
    """One branch of the lake as the backend holds it (`DuckDBBackend._state`)."""

    database: duckdb.DuckDBPyConnection  # the backend's one database
    name: str  # the branch's attached database in it
    stamp: object = None
    used: float = 0.0  # time.monotonic() of its last query
    schema: dict[str, dict[str, str]] = field(default_factory=dict)
    version: str = ""
    statements: OrderedDict = field(default_factory=OrderedDict)  # DuckDB SQL -> its checked Statement
    files: dict[str, str] = field(default_factory=dict)  # reader path -> "table T, batch B, job J" (last 2 loads)
    listed: dict[str, str] = field(default_factory=dict)  # the same, of the views' files only
    views: set[str] = field(default_factory=set)  # the branch-wide views made
    loaded: bool = False  # whether they are those of the stamp's generation
    scopes: OrderedDict = field(default_factory=OrderedDict)  # (generation, batch, job) -> its ScopeViews
    #: The tables scoped queries named, of job scopes (True) and of batch scopes (False): a scope's
    #: first views are made with them, in one transaction (one per view costs about twice as much).
    scoped_tables: dict[bool, set[str]] = field(default_factory=lambda: {True: set(), False: set()})
    idle: list = field(default_factory=list)  # (cursor, its scope schema or None) kept for reuse (`recycle`)
    idle_lock: threading.Lock = field(default_factory=threading.Lock)

    def cursor(self, schema: str | None = None) -> duckdb.DuckDBPyConnection:
        """A cursor whose table names resolve in `schema` (a scope's views), or by default in the
        branch's attached database: a recycled one (one already there first), or a new one."""
        with self.idle_lock:
            kept = next((i for i in range(len(self.idle) - 1, -1, -1) if self.idle[i][1] == schema), -1)
            cursor, where = self.idle.pop(kept) if self.idle else (None, None)
        if cursor is None:
            cursor, where = self.database.cursor(), None
            cursor.execute(f"USE {self.name}")
        if where != schema:
            cursor.execute(f"USE {self.name}" if schema is None else f"SET search_path = '{schema}'")
        return cursor

    def recycle(self, cursor: duckdb.DuckDBPyConnection, schema: str | None = None) -> None:
        """Keep a cursor whose query read all its rows (no settings of its own but its table names:
        the branch's views, or those of the scope `schema`) for the next query, up to IDLE_CURSORS."""
        with self.idle_lock:
            if len(self.idle) < IDLE_CURSORS:
                self.idle.append((cursor, schema))
                return
        cursor.close()

    def close_idle(self) -> None:
        """Close the cursors kept for reuse."""
        with self.idle_lock:
            idle, self.idle = self.idle, []
        for cursor, _ in idle:
            cursor.close()

    def failure(self, error: BaseException, *, vanished: bool = False) -> DialectError:
        """The DialectError for a DuckDB error: a listed file is named by its table, batch and job
        (HIVE_BAD_DATA when it cannot be read, HIVE_FILE_NOT_FOUND when writers kept replacing
        it), never by its path."""
        message = str(error)
        files = self.known()
        named = [path for path in files if path in message]
        if not named and _PARQUET_DAMAGE.search(message):  # a damaged file the message does not name
            damaged = [path for path in files if LOCAL.damage(path) is not None]
            if damaged:
                return DialectError(
                    f"Cannot read the Parquet file of {files[damaged[0]]}: it is corrupt (ingest the job again)",
                    error_name="HIVE_BAD_DATA",
                )
        if not named:
            return duckdb_failure(error)
        for path in named:
            message = message.replace(f"'{path}'", path).replace(f'"{path}"', path).replace(path, files[path])
        if vanished:
            return DialectError(
                f"The data of {files[named[0]]} was replaced while the query read it, "
                "again and again; run the query again",
                error_name="HIVE_FILE_NOT_FOUND",
            )
        first = message.strip().splitlines()[0].split(": ", 1)[-1]
        return DialectError(f"Cannot read the Parquet file of {files[named[0]]}: {first}", error_name="HIVE_BAD_DATA")

    def vanished(self, error: BaseException) -> bool:
        """Whether the error is about a listed file that is gone (a writer replaced it)."""
        message = str(error)
        return any(path in message and not LOCAL.exists(path) for path in self.known())

    def known(self) -> dict[str, str]:
        """Every file the views list (branch-wide and scoped): reader path -> how messages name it."""
        return {
            **self.files,
            **{path: where for entry in list(self.scopes.values()) for path, where in entry.files.items()},
        }
