"""The forwarding backend: run lakegate's queries on a real Trino cluster instead of embedded DuckDB.

`TrinoBackend` implements the `Backend` interface with the official `trino` client. Each query is
checked by the read-only guard, restricted to its scope and bound to its parameters here, and the
resulting Trino-dialect text is sent to the cluster, in the catalog and schema the branch maps to
(see `trino_ddl.schema_name`, or an explicit map). Pages stream back as Arrow record batches typed
from the result's Trino types, so the metrics engine and the server treat them like DuckDB's.

The text sent is the user's text with only the scope and parameter edits spliced in (a lake table
`odom o` becomes `(SELECT * FROM odom WHERE batch_id = 'B') o`, each `?` its literal, a trailing `;`
dropped), so an error position the cluster reports maps back exactly to the user's SQL.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlparse

import pyarrow as pa
import requests
import trino
from sqlglot import exp
from sqlglot.tokens import TokenType

from lakegate.dialect import guard, session_functions
from lakegate.dialect import params as parameters
from lakegate.dialect.errors import ERROR_CODES, DialectError
from lakegate.dialect.scope import Scope, restrict
from lakegate.dialect.session_functions import SessionNames
from lakegate.dialect.statements import Statement, read
from lakegate.dialect.translate import LakegateTrino, parse
from lakegate.dialect.trino_types import TType, parse_type
from lakegate.gateway.engine.backend import QueryResult
from lakegate.gateway.engine.trino_ddl import quote_ident, quote_text, schema_name
from lakegate.gateway.engine.trino_values import arrow_type

#: Rows fetched from the cluster per record batch.
BATCH_ROWS = 10_000
#: Seconds the cluster's schema list and a branch's tables are trusted before they are asked again
#: (they change only when `lakegate trino-ddl` registers a lake; a query plans with several lookups).
LISTING_TTL = 1.0


# --- the forwarded text ---------------------------------------------------------------------------


def _offset(text: str, line: int, column: int) -> int:
    """The character offset of a 1-based (line, column) in `text`, clamped to the text."""
    start = 0
    for _ in range(line - 1):
        found = text.find("\n", start)
        if found < 0:
            return len(text)
        start = found + 1
    return min(start + max(column, 1) - 1, len(text))


def _line_column(text: str, offset: int) -> tuple[int, int]:
    return text.count("\n", 0, offset) + 1, offset - (text.rfind("\n", 0, offset) + 1) + 1


@dataclass(frozen=True)
class Forwarded:
    """The text one query is sent as, and the edits that map its positions back to the user's text."""

    user_sql: str
    sql: str
    #: (sent start, sent end, user start, user end) of each replaced span, in text order; None when
    #: the text had to be regenerated and positions cannot be mapped back.
    edits: tuple[tuple[int, int, int, int], ...] | None = ()

    def user_position(self, line: int, column: int) -> tuple[int | None, int | None]:
        """The (line, column) in the user's SQL of a position in the sent text (a position inside
        an inserted span maps to the start of what it replaced)."""
        if self.edits is None:
            return None, None
        offset, shift = _offset(self.sql, line, column), 0
        for sent_start, sent_end, user_start, user_end in self.edits:
            if offset < sent_start:
                break
            if offset < sent_end:
                return _line_column(self.user_sql, user_start)
            shift = sent_end - user_end
        return _line_column(self.user_sql, min(offset - shift, len(self.user_sql)))


def _span(table: exp.Table) -> tuple[int, int] | None:
    """Start and end offsets of a table reference's (qualified) name in the text it was parsed from."""
    parts = [table.args.get(key) for key in ("catalog", "db", "this")]
    metas = [part.meta for part in parts if part is not None]
    if not metas or not all("start" in meta and "end" in meta for meta in metas):
        return None
    return min(meta["start"] for meta in metas), table.this.meta["end"] + 1


def _scoped_reference(text: str, table: exp.Table, span: tuple[int, int], scope: Scope) -> str:
    name = text[span[0] : span[1]]
    condition = scope.predicate().sql(dialect=LakegateTrino)
    alias = "" if table.args.get("alias") else " " + text[table.this.meta["start"] : table.this.meta["end"] + 1]
    return f"(SELECT * FROM {name} WHERE {condition}){alias}"


def _edits(
    text: str, tree: exp.Expression, scope: Scope | None, params: Sequence[object], tables: set[str]
) -> list[tuple[int, int, str]] | None:
    """(start, end, replacement) edits of one statement's text; None when a position is unknown."""
    edits = []
    before = list(tree.find_all(exp.Table))
    if scope is not None:
        restrict(tree, scope, tables)
        kept = {id(node) for node in tree.find_all(exp.Table)}
        for table in before:
            if id(table) not in kept:
                span = _span(table)
                if span is None:
                    return None
                edits.append((*span, _scoped_reference(text, table, span, scope)))
    parameters.bind(tree, params)  # checks the count and the values
    tokens = LakegateTrino().tokenize(text)
    marks = [token for token in tokens if token.token_type == TokenType.PLACEHOLDER and token.text == "?"]
    if len(marks) != len(params):
        return None
    for token, value in zip(marks, params):
        edits.append((token.start, token.end + 1, parameters.literal(value).sql(dialect=LakegateTrino)))
    edits += [(token.start, token.end + 1, "") for token in tokens if token.token_type == TokenType.SEMICOLON]
    return sorted(edits)


def forwarded_sql(
    sql: str | bytes | Statement,
    *,
    scope: Scope | None = None,
    params: Sequence[object] = (),
    tables: set[str] | Callable[[exp.Expression], set[str]] = frozenset(),
) -> Forwarded:
    """The Trino text to send for one query (its text, or the statement as the planner read and
    rewrote it: its text edits spliced in): guard-checked (read-only: queries, SHOW, DESCRIBE,
    EXPLAIN), every lake table in `tables` restricted to `scope`, `?` bound to `params`. `tables`
    may be a function of the parsed query. Raises DialectError with the position in `sql`."""
    statement = sql if isinstance(sql, Statement) else read(sql)
    statement.check()
    text = statement.edited_text()  # the planner's edits keep length, lines and tokens: nothing to check again
    kind, start = statement.kind, statement.offset
    body = text[start : start + len(statement.body)]
    tree = statement.tree.copy()  # the shared tree stays as read
    guard.check(tree)
    if kind in ("show", "describe"):
        scope, params = None, ()
    if scope is not None and scope.predicate() is None:
        scope = None
    chosen = (tables(tree) if callable(tables) else set(tables)) if scope is not None else set()
    edits = _edits(body, tree, scope, params, chosen)
    if edits is None:  # no exact positions: send the regenerated text, report no positions
        tree = parse(body)
        if scope is not None:
            restrict(tree, scope, chosen)
        regenerated = parameters.bind(tree, params).sql(dialect=LakegateTrino)
        return Forwarded(text, text[:start] + regenerated, None)
    pieces, mapped, position, shift = [text[:start]], [], 0, start
    for edit_start, edit_end, replacement in edits:
        pieces.append(body[position:edit_start])
        sent_start = edit_start + shift
        pieces.append(replacement)
        shift += len(replacement) - (edit_end - edit_start)
        mapped.append((sent_start, sent_start + len(replacement), edit_start + start, edit_end + start))
        position = edit_end
    pieces.append(body[position:])
    return Forwarded(text, "".join(pieces), tuple(mapped))


# --- values ---------------------------------------------------------------------------------------


def _converter(t: TType) -> Callable[[Any], Any] | None:
    """How to turn one client value of `t` into what `pa.array` takes (None: as it is)."""
    base, args = t.base, t.args
    if base == "uuid":
        return lambda v: None if v is None else str(v)
    if base == "interval_ym":
        return lambda v: None if v is None else (v.years * 12 + v.months, 0, 0)
    if base in ("array", "map", "row"):
        inner = [_converter(f) for f in (args if base != "row" else [f for _, f in args])]
        if all(convert is None for convert in inner):
            return None
        inner = [convert or _same for convert in inner]
        if base == "array":
            return lambda v: None if v is None else [inner[0](x) for x in v]
        if base == "map":
            return lambda v: None if v is None else [(inner[0](k), inner[1](x)) for k, x in v.items()]
        return lambda v: None if v is None else tuple(convert(x) for convert, x in zip(inner, v))
    return None


def _same(value: Any) -> Any:
    return value


@dataclass(frozen=True)
class _Column:
    name: str
    trino_type: str
    arrow: pa.DataType
    convert: Callable[[Any], Any] | None


def _result_column(name: str, type_name: str) -> _Column:
    try:
        t = parse_type(type_name)
        return _Column(name, str(t), arrow_type(t), _converter(t))
    except ValueError:
        raise DialectError(
            f"result column '{name}' has type {type_name}, which lakegate cannot carry (cast it to varchar)",
            error_name="NOT_SUPPORTED",
        ) from None


def _batch(columns: list[_Column], rows: list[list[Any]]) -> pa.RecordBatch:
    values = list(zip(*rows)) if rows else [()] * len(columns)
    arrays = []
    for column, column_values in zip(columns, values):
        if column.convert is not None:
            column_values = [column.convert(v) for v in column_values]
        arrays.append(pa.array(column_values, type=column.arrow))
    return pa.RecordBatch.from_arrays(arrays, schema=pa.schema([(c.name, c.arrow) for c in columns]))


# --- errors ---------------------------------------------------------------------------------------


class RemoteQueryError(DialectError):
    """An error the Trino cluster reported for a forwarded query: its error name, code and type,
    and its position mapped back to the user's SQL."""

    def __init__(
        self,
        message: str,
        *,
        line: int | None,
        column: int | None,
        error_name: str,
        error_code: int | None,
        error_type: str | None,
        query_id: str | None,
    ):
        super().__init__(message, line=line, column=column, error_name=error_name)
        self.remote_code, self.error_type, self.query_id = error_code, error_type, query_id

    @property
    def error_code(self) -> int:
        return self.remote_code if self.remote_code is not None else ERROR_CODES.get(self.error_name, 0)


def _strip_location(message: str) -> str:
    """Trino's message without its `line L:C: ` prefix (positions are reported separately)."""
    head, _, rest = message.partition(": ")
    words = head.split(" ")
    if rest and len(words) == 2 and words[0] == "line" and words[1].replace(":", "").isdigit():
        return rest
    return message


# --- the backend ----------------------------------------------------------------------------------


class _Session(requests.Session):
    """An HTTP session whose own `verify` (a CA bundle, or False) wins over REQUESTS_CA_BUNDLE and
    CURL_CA_BUNDLE, which plain requests sessions let override it."""

    def merge_environment_settings(self, url, proxies, stream, verify, cert):  # noqa: ANN001, ANN201
        settings = super().merge_environment_settings(url, proxies, stream, verify, cert)
        if self.verify is not True:
            settings["verify"] = self.verify
        return settings


class TrinoBackend:
    """Forward queries to the Trino cluster at `url` (`http[s]://host:port`) as `user`.

    A branch maps to schema `schema_map[branch]` of `catalog`, else `schema_map['*']` with
    `{branch}` replaced by the branch name (`'*': '{branch}'` for another lakegate server), else
    `trino_ddl.schema_name(branch, schema_prefix)` (the schemas `lakegate trino-ddl` creates);
    `mapped_only` lists only the branches of `schema_map` (a recorded registration's).
    Authentication: `password` (HTTP Basic, needs https) or `jwt`; `verify` is False, True or a
    CA bundle path. Results are read in UTC, like the DuckDB backend's.
    """

    def __init__(
        self,
        url: str,
        *,
        user: str = "lakegate",
        catalog: str = "hive",
        schema_map: Mapping[str, str] | None = None,
        schema_prefix: str = "",
        mapped_only: bool = False,
        password: str | None = None,
        jwt: str | None = None,
        verify: bool | str = True,
        request_timeout: float = 60.0,
    ):
        parsed = urlparse(url)
        if parsed.scheme not in ("http", "https") or not parsed.hostname:
            raise ValueError(f"--trino-url {url!r} is not an http:// or https:// URL")
        if password is not None and jwt is not None:
            raise ValueError("give a password or a JWT, not both")
        if (password is not None or jwt is not None) and parsed.scheme != "https":
            raise ValueError(f"credentials need an https:// URL (the trino client refuses to send them to {url})")
        self.url, self.user, self.catalog = url, user, catalog
        self.schema_map, self.schema_prefix = dict(schema_map or {}), schema_prefix
        self.mapped_only = mapped_only
        schema_name("main", schema_prefix)  # checks the prefix
        self._host, self._scheme = parsed.hostname, parsed.scheme
        self._port = parsed.port or (443 if parsed.scheme == "https" else 8080)
        self._auth = (
            trino.auth.BasicAuthentication(user, password)
            if password is not None
            else trino.auth.JWTAuthentication(jwt)
            if jwt is not None
            else None
        )
        self._verify, self._timeout = verify, request_timeout
        self._local = threading.local()
        self._connections: list = []
        self._listings: dict[str | None, tuple[float, Any]] = {}
        self._runs: set[_Run] = set()
        self._lock = threading.Lock()

    # -- branches -------------------------------------------------------------------------

    def schema_for(self, branch: str) -> str:
        """The cluster schema that holds `branch`."""
        if branch in self.schema_map:
            return self.schema_map[branch]
        if "*" in self.schema_map:
            return self.schema_map["*"].replace("{branch}", branch)
        return schema_name(branch, self.schema_prefix)

    def branches(self) -> list[str]:
        """The branches whose schemas exist in the catalog: those `schema_map` names, and unless
        `mapped_only`, every other schema with the schema prefix (the prefix taken off)."""
        rows = self._listed(None, lambda: self._query(None, f"SHOW SCHEMAS FROM {quote_ident(self.catalog)}"))
        schemas = {row[0] for row in rows} - {"information_schema"}
        named = {schema: branch for branch, schema in self.schema_map.items() if branch != "*"}
        found = {named[schema] for schema in schemas if schema in named}
        if not self.mapped_only:
            prefix = self.schema_prefix
            found |= {s[len(prefix) :] for s in schemas if s not in named and s.startswith(prefix) and s != prefix}
        return sorted(found)

    def run(self, sql: str) -> list[list[Any]]:
        """Every row of one statement sent as it is, unchecked: lakegate's own DDL and catalog
        queries (`trino_registration`), never a user's text. DialectError when it fails."""
        return self._query(None, sql)

    # -- connections ----------------------------------------------------------------------

    def _connection(self, branch: str | None):
        """This thread's connection for `branch` (its own HTTP session, kept alive between queries)."""
        connections = self._local.__dict__.setdefault("connections", {})
        connection = connections.get(branch)
        if connection is None:
            session = _Session()
            session.verify = self._verify
            connection = trino.dbapi.connect(
                host=self._host,
                port=self._port,
                http_scheme=self._scheme,
                user=self.user,
                catalog=self.catalog,
                schema=self.schema_for(branch) if branch is not None else None,
                auth=self._auth,
                http_session=session,
                source="lakegate",
                timezone="UTC",
                request_timeout=self._timeout,
            )
            connections[branch] = connection
            with self._lock:
                self._connections.append(connection)
        return connection

    def _failure(self, error: BaseException, forwarded: Forwarded | None) -> DialectError:
        """The DialectError for an error of the client or the cluster."""
        if isinstance(error, DialectError):
            return error
        if isinstance(error, trino.exceptions.TrinoQueryError):
            line = column = None
            if error.error_location is not None and forwarded is not None:
                line, column = forwarded.user_position(*error.error_location)
            return RemoteQueryError(
                _strip_location(error.message),
                line=line,
                column=column,
                error_name=error.error_name or "GENERIC_INTERNAL_ERROR",
                error_code=error.error_code,
                error_type=error.error_type,
                query_id=error.query_id,
            )
        if isinstance(error, (requests.ConnectionError, trino.exceptions.TrinoConnectionError)):
            reason = re.search(r"\[Errno -?\d+\] [^'\")]+", str(error))
            return DialectError(
                f"cannot reach the Trino cluster at {self.url}" + (f": {reason.group(0)}" if reason else ""),
                error_name="GENERIC_INTERNAL_ERROR",
            )
        return DialectError(f"the Trino cluster at {self.url} failed: {error}", error_name="GENERIC_INTERNAL_ERROR")

    def _query(self, branch: str | None, sql: str) -> list[list[Any]]:
        """Every row of one internal query."""
        cursor = self._connection(branch).cursor()
        try:
            cursor.execute(sql)
            return cursor.fetchall()
        except (trino.exceptions.Error, trino.exceptions.HttpError, requests.RequestException) as error:
            raise self._failure(error, None) from None

    # -- schema ---------------------------------------------------------------------------

    def _listed(self, key: str | None, ask: Callable[[], Any]) -> Any:
        """`ask()`, or its answer for `key` (None: the schema list; else a branch) from the last
        LISTING_TTL seconds."""
        with self._lock:
            cached = self._listings.get(key)
        if cached is not None and time.monotonic() - cached[0] <= LISTING_TTL:
            return cached[1]
        answer = ask()
        with self._lock:
            self._listings[key] = (time.monotonic(), answer)
        return answer

    def schema(self, branch: str = "main") -> dict[str, dict[str, str]]:
        """Table -> column -> Trino type name of the branch's schema in the cluster."""
        return {table: dict(columns) for table, columns in self._listed(branch, lambda: self._schema(branch)).items()}

    def _schema(self, branch: str) -> dict[str, dict[str, str]]:
        rows = self._query(
            branch,
            "SELECT table_name, column_name, data_type "
            f"FROM {quote_ident(self.catalog)}.information_schema.columns "
            f"WHERE table_schema = {quote_text(self.schema_for(branch))} "
            "ORDER BY table_name, ordinal_position",
        )
        schema: dict[str, dict[str, str]] = {}
        for table, column, type_name in rows:
            try:
                type_name = str(parse_type(type_name))
            except ValueError:
                pass  # a type lakegate does not model is listed as the cluster names it
            schema.setdefault(table, {})[column] = type_name
        return schema

    def _scoped_tables(self, branch: str, scope: Scope) -> set[str]:
        """The tables of the branch that have the scope's columns."""
        wanted = scope.columns()
        return {table for table, columns in self.schema(branch).items() if all(c in columns for c in wanted)}

    # -- queries --------------------------------------------------------------------------

    def forward(
        self,
        sql: str | bytes | Statement,
        *,
        branch: str = "main",
        scope: Scope | None = None,
        params: Sequence[object] = (),
    ) -> Forwarded:
        """The text `execute` sends for one query."""
        return forwarded_sql(
            sql,
            scope=scope,
            params=params,
            tables=lambda tree: self._scoped_tables(branch, scope) if scope else set(),
        )

    def execute(
        self,
        sql: str | bytes | Statement,
        *,
        branch: str = "main",
        scope: Scope | None = None,
        params: Sequence[object] = (),
        time_zone: str = "UTC",
        session: SessionNames | None = None,
    ) -> QueryResult:
        """Send one Trino-dialect query, restricted to `scope` with `params` bound, to the cluster;
        its rows stream back as Arrow batches. Raises DialectError (remote errors as
        RemoteQueryError, positions in `sql`); the cluster is read in UTC, so another session zone is
        refused, and so are the session functions (the cluster would answer with its own catalog and
        schema names, not lakegate's; `session` is not used)."""
        if time_zone != "UTC":
            raise DialectError(
                f"unsupported in lakegate: session time zone '{time_zone}' with the Trino backend (it reads in UTC)",
                error_name="NOT_SUPPORTED",
            )
        statement = sql if isinstance(sql, Statement) else read(sql)
        statement.check()
        called = session_functions.called(statement.tree) if session_functions.used(statement.text) else []
        if called:
            raise DialectError(
                f"unsupported in lakegate: {called[0]} with the Trino backend", error_name="NOT_SUPPORTED"
            )
        forwarded = self.forward(statement, branch=branch, scope=scope, params=params)
        cursor = self._connection(branch).cursor()
        try:
            cursor.execute(forwarded.sql)
            description = cursor.description or []
        except (trino.exceptions.Error, trino.exceptions.HttpError, requests.RequestException) as error:
            raise self._failure(error, forwarded) from None
        columns = [_result_column(d[0], d[1]) for d in description]
        run = _Run(self, cursor, columns, forwarded)
        return QueryResult(columns=[(c.name, c.trino_type) for c in columns], batches=run.batches(), _cancel=run.cancel)

    def stop_all(self) -> None:
        """Cancel every query being read (the server is stopping)."""
        with self._lock:
            runs = list(self._runs)
        for run in runs:
            run.cancel()

    def close(self) -> None:
        """Close every connection's HTTP session."""
        with self._lock:
            connections, self._connections = self._connections, []
        for connection in connections:
            connection.close()
        self._local = threading.local()


class _Run:
    """One forwarded query being read."""

    def __init__(self, backend: TrinoBackend, cursor, columns: list[_Column], forwarded: Forwarded):
        self.backend, self.cursor, self.columns, self.forwarded = backend, cursor, columns, forwarded
        self.canceled = False

    def cancel(self) -> None:
        self.canceled = True
        try:
            self.cursor.cancel()
        except (trino.exceptions.Error, trino.exceptions.HttpError, requests.RequestException):
            pass  # the query is over or the cluster is gone: nothing runs for us

    def batches(self) -> Iterator[pa.RecordBatch]:
        empty, done = True, False
        with self.backend._lock:
            self.backend._runs.add(self)
        try:
            while True:
                if self.canceled:
                    raise DialectError("Query was canceled", error_name="USER_CANCELED")
                rows = self.cursor.fetchmany(BATCH_ROWS)
                if not rows:
                    break
                empty = False
                yield _batch(self.columns, rows)
            done = True
        except (trino.exceptions.Error, trino.exceptions.HttpError, requests.RequestException) as error:
            done = True
            if self.canceled:
                raise DialectError("Query was canceled", error_name="USER_CANCELED") from None
            raise self.backend._failure(error, self.forwarded) from None
        finally:
            with self.backend._lock:
                self.backend._runs.discard(self)
            if not done:  # the reader stopped early: the cluster need not go on
                self.cancel()
        if empty:
            yield _batch(self.columns, [])
