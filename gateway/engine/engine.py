"""The Engine: the one object that owns a lake's backend, its catalog, the session defaults and the
limits, and answers statements as the SQL server does. `lakegate query`, `lakegate serve` (through
`server.app.create_app`), the metrics engine, the demo and the dashboard use it, so they agree on
catalog names, on what SHOW, DESCRIBE and `information_schema` answer, and on every error.

Each statement is read once (`statements.read`: its kind, text and tree) and dispatched here by
its kind to the one owner of that kind (`statements.KINDS`): session statements to the sessions,
CALL to the server's queries (`kill_queries`), everything else to the planner.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from lakegate.dialect.scope import Scope
from lakegate.dialect.statements import Statement, read
from lakegate.gateway.engine import session as sessions
from lakegate.gateway.engine.backend import Backend, DuckDBBackend, QueryResult
from lakegate.gateway.engine.isolated_backend import IsolatedBackend
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.planner import Planner, static_result
from lakegate.gateway.engine.session import Answer, Session
from lakegate.gateway.engine.system_tables import CATALOG, SystemCatalog
from lakegate.lake.record import FileEntry

#: The session user of a caller that names none (`lakegate query`).
DEFAULT_USER = "lakegate"
#: How the server kills one of its queries: (query id, message or None, the caller's session).
Kill = Callable[[str, str | None, Session], None]


class Engine:
    """A lake's backend with its catalog, system tables and statement planner.

    Only the server has running queries to list and kill (`list_queries`, `kill_queries`). The
    backend stays open when the engine closes unless the engine opened it.
    """

    def __init__(
        self,
        backend: Backend,
        *,
        catalog: str = CATALOG,
        limits: Limits = Limits(),
        owns_backend: bool = False,
    ):
        self.backend, self.catalog, self.limits = backend, catalog, limits
        self.system_catalog = SystemCatalog(
            backend, catalog=catalog, memory_limit=getattr(backend, "memory_limit", "1GB")
        )
        self._planner = Planner(backend, self.system_catalog)
        self._owns_backend = owns_backend
        self._kill: Kill | None = None

    @classmethod
    def open(cls, lake: Path | None, *, limits: Limits = Limits(), isolated: bool = False) -> Engine:
        """An engine over the embedded DuckDB backend of `lake` (None: no tables, constant queries only);
        `isolated`: each query runs in a worker process (`IsolatedBackend`), as the commands run them."""
        backend = IsolatedBackend(lake, limits=limits) if isolated else DuckDBBackend(lake, limits=limits)
        return cls(backend, limits=limits, owns_backend=True)

    def session(
        self,
        *,
        user: str = DEFAULT_USER,
        branch: str | None = None,
        scope: Scope | None = None,
        time_zone: str | None = None,
    ) -> Session:
        """A session in this engine's catalog, on `branch` (DialectError SCHEMA_NOT_FOUND when the lake
        has no such branch), restricted to `scope` (its batch and job also shown as session properties), in
        the zone `time_zone` (None: UTC)."""
        if branch is not None:
            branch = self.system_catalog.schema_name(self.catalog, branch)
        properties = {
            name: value
            for name, value in (("batch_id", scope and scope.batch_id), ("job_id", scope and scope.job_id))
            if value is not None
        }
        return Session(
            user=user,
            catalog=self.catalog,
            schema=branch,
            time_zone=time_zone,
            properties=properties,
            restriction=scope,
        )

    def answer(self, statement: str | Statement, session: Session) -> Answer:
        """Answer a statement that needs no query: a session statement (USE, SET SESSION, PREPARE, ...:
        kind 'session' in `guard.STATEMENTS`), or CALL system.runtime.kill_query (a server's query)."""
        statement = statement if isinstance(statement, Statement) else read(statement)
        if statement.kind == "call":
            query_id, message = sessions.kill_query_arguments(statement.text, session)
            if self._kill is None:  # no query runs outside the server
                raise sessions.query_not_found(query_id)
            self._kill(query_id, message, session)
            return Answer([], [], update_type="CALL")
        return sessions.answer(statement, session, self.system_catalog.resolve_schema)

    def execute(self, sql: str | Statement, session: Session, params: Sequence[object] = ()) -> QueryResult:
        """Run one statement (its text, or as `statements.read` read it) as the server would answer
        it; DialectError when refused or failing. A session statement is answered (its effect is the
        client's to keep)."""
        statement = sql if isinstance(sql, Statement) else read(sql)
        if statement.kind in ("session", "call"):
            return static_result(self.answer(statement, session))
        return self._planner.start(statement, session, params)

    def kill_queries(self, kill: Kill) -> None:
        """Let CALL system.runtime.kill_query reach the server's queries (`kill`)."""
        self._kill = kill

    def list_queries(self, queries: Callable[[str | None], list[tuple]]) -> None:
        """Let system.runtime.queries list `queries(user)`: the server's running queries."""
        self.system_catalog.queries = queries

    def with_pending(self, pending: Sequence[FileEntry]) -> Engine:
        """An engine that also sees `pending` files (staged, not yet committed: DuckDB backend only)."""
        backend = self.backend.with_pending(pending)  # type: ignore[attr-defined]
        return Engine(backend, catalog=self.catalog, limits=self.limits, owns_backend=True)

    def close(self) -> None:
        self.system_catalog.close()
        if self._owns_backend:
            self.backend.close()
