"""From one statement text and its session to a running result: the server's planner.

Session statements and CALL are answered by the server before a query starts (`session.answer`,
`server`); everything else comes here: EXECUTE / EXECUTE IMMEDIATE (the statement and its USING
values), DESCRIBE INPUT / OUTPUT of a prepared statement, SHOW / DESCRIBE (`SystemCatalog.show`), and
queries and EXPLAIN.

A query's table names are resolved against the session (`SystemCatalog.resolve`): every table it reads
must live in one branch (then the backend runs it on that branch, restricted to the session's
scope) or be a system table (then it runs over the materialised system tables); a query that
reads no table runs on the session's branch. Qualifiers (`lake.main.odom`, `"feature/x".odom`,
`information_schema.tables`, `main.odom.x`) are blanked out of the SQL text, so that every other
character keeps its line and column: errors the dialect reports still point into the user's
original SQL. `version()` is replaced the same way, by a literal as long as the call.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import pyarrow as pa
from sqlglot import exp
from sqlglot.dialects.trino import Trino
from sqlglot.tokens import TokenType

from lakegate.dialect import guard
from lakegate.dialect import trino_types as tt
from lakegate.dialect.errors import DialectError
from lakegate.dialect.params import parse_execute
from lakegate.dialect.session_functions import SessionNames
from lakegate.dialect.statements import Reader
from lakegate.dialect.translate import parse
from lakegate.gateway.engine.backend import Backend, QueryResult
from lakegate.gateway.engine.session import Answer, Session, check_properties
from lakegate.gateway.engine.system_tables import SystemCatalog, TableRef
from lakegate.gateway.engine.trino_values import arrow_type

#: The Trino release whose behaviour lakegate follows, reported by /v1/info and `version()`.
TRINO_VERSION = "476"
#: What `version()` becomes: a varchar expression no longer than the call's text `version()`.
_VERSION = f"'{TRINO_VERSION}'||''"
_DESCRIBE_OUTPUT = [
    ("Column Name", "varchar"),
    ("Catalog", "varchar"),
    ("Schema", "varchar"),
    ("Table", "varchar"),
    ("Type", "varchar"),
    ("Type Size", "bigint"),
    ("Aliased", "boolean"),
]


def static_result(answer: Answer) -> QueryResult:
    """A result computed in Python (varchar, bigint and boolean columns) as a QueryResult."""
    arrays = [
        pa.array([row[i] for row in answer.rows], arrow_type(tt.parse_type(trino_type)))
        for i, (_, trino_type) in enumerate(answer.columns)
    ]
    batch = pa.record_batch(arrays, names=[name for name, _ in answer.columns])
    return QueryResult(columns=list(answer.columns), batches=iter([batch]))


@dataclass(frozen=True)
class _Reference:
    """A (possibly qualified) table name in the SQL text, or the table qualifier of a column."""

    parts: tuple[str, ...]  # [[catalog.]schema.]table as Trino reads them: unquoted parts lower-cased
    start: int  # offset of the first part in the text
    name_start: int  # offset of the table part: [start, name_start) is the qualifier to blank out


@dataclass(frozen=True)
class _Parsed:
    tables: tuple[_Reference, ...]
    columns: tuple[_Reference, ...]  # columns written `schema.table.column` (or longer)
    ctes: frozenset[str]
    versions: tuple[tuple[int, int], ...]  # (start, end) of each `version()` call


def _part(identifier: exp.Identifier) -> str:
    return identifier.this if identifier.quoted else identifier.this.lower()


def _reference(*identifiers: exp.Expression | None) -> _Reference | None:
    """The reference made of these name parts (the last one is the table), if all are in the text."""
    idents = [p for p in identifiers if isinstance(p, exp.Identifier)]
    if not idents or any("start" not in ident.meta for ident in idents):
        return None  # a name sqlglot made up (not in the text): nothing to resolve
    return _Reference(tuple(_part(p) for p in idents), idents[0].meta["start"], idents[-1].meta["start"])


@lru_cache(maxsize=512)
def _parse(sql: str) -> _Parsed:
    """The table references, schema-qualified columns, CTE names and `version()` calls of one
    query text (cached)."""
    tree = parse(sql)
    tables, columns = [], []
    for table in tree.find_all(exp.Table):
        if isinstance(table.this, exp.Identifier):
            reference = _reference(table.args.get("catalog"), table.args.get("db"), table.this)
            if reference is not None:
                tables.append(reference)
    for column in tree.find_all(exp.Column):
        if isinstance(column.args.get("db"), exp.Identifier):
            reference = _reference(column.args.get("catalog"), column.args.get("db"), column.args.get("table"))
            if reference is not None:
                columns.append(reference)
    ctes = frozenset(cte.alias_or_name.lower() for cte in tree.find_all(exp.CTE))
    versions = []
    if "version" in sql.lower():
        tokens = Trino().tokenize(sql)
        for first, second, third in zip(tokens, tokens[1:], tokens[2:]):
            if (
                first.token_type in (TokenType.VAR, TokenType.IDENTIFIER)
                and first.text.lower() == "version"
                and second.token_type == TokenType.L_PAREN
                and third.token_type == TokenType.R_PAREN
            ):
                versions.append((first.start, third.end))
    return _Parsed(tuple(sorted(tables, key=lambda r: r.start)), tuple(columns), ctes, tuple(versions))


def _where(sql: str, offset: int) -> tuple[int, int]:
    line = sql.count("\n", 0, offset) + 1
    return line, offset - (sql.rfind("\n", 0, offset) + 1) + 1


def _blank(text: str) -> str:
    return "".join("\n" if char == "\n" else " " for char in text)


def _shifted(error: DialectError, sql: str, offset: int) -> DialectError:
    """`error` (positioned in the text at `offset` of `sql`) positioned in `sql`."""
    if error.line is None or error.column is None or offset == 0:
        return error
    line0, column0 = _where(sql, offset)
    column = error.column + (column0 - 1 if error.line == 1 else 0)
    return DialectError(error.message, line=error.line + line0 - 1, column=column, error_name=error.error_name)


@dataclass
class _Plan:
    sql: str  # the text to run (same length and line breaks as the original)
    branch: str | None  # the branch whose tables it reads
    system: list[TableRef]  # the system tables it reads


class Planner:
    """Starts statements over `backend` and the system tables of `metadata`."""

    def __init__(self, backend: Backend, metadata: SystemCatalog):
        self.backend, self.metadata = backend, metadata

    def start(self, sql: str, session: Session, params: Sequence[object] = ()) -> QueryResult:
        """Start one statement (anything but a session statement or CALL); DialectError when it is
        refused or fails to start."""
        check_properties(session)
        kind = guard.classify(sql)
        if _is_execute(sql):
            if params:
                raise DialectError("EXECUTE cannot be a prepared statement", error_name="NOT_SUPPORTED")
            execute = parse_execute(sql)
            statement = execute.statement if execute.statement is not None else session.prepared_statement(execute.name)
            if _is_execute(statement):
                raise DialectError("EXECUTE of an EXECUTE statement is not supported", error_name="NOT_SUPPORTED")
            return self.start(statement, session, execute.params)
        if kind == "describe":
            prepared = _described_statement(sql)
            if prepared is not None:
                return static_result(self._describe_prepared(*prepared, session))
        if kind in ("show", "describe"):
            if params:
                raise DialectError(
                    f"Incorrect number of parameters: expected 0 but found {len(params)}",
                    error_name="INVALID_PARAMETER_USAGE",
                )
            return static_result(self.metadata.show(guard.check_text(sql), session))
        if kind in ("query", "explain"):
            return self._query(sql, session, params, kind)
        if kind in ("session", "call"):
            raise DialectError(
                "a session statement or CALL cannot be run by EXECUTE; send it on its own", error_name="NOT_SUPPORTED"
            )
        guard.check_text(sql)  # refuses writes and unknown statements with Trino's message
        _check_statement_start(sql)
        raise DialectError("unsupported in lakegate: this statement", line=1, column=1, error_name="NOT_SUPPORTED")

    # -- queries ----------------------------------------------------------------------------

    def _query(self, sql: str, session: Session, params: Sequence[object], kind: str) -> QueryResult:
        sql = guard.check_text(sql)
        offset = 0
        query = sql
        if kind == "explain":
            query = guard.explained_query(sql)[0]
            offset = sql.rfind(query)
        plan = self._plan(sql, query, offset, session)
        branch = plan.branch if plan.branch is not None or plan.system else self._default_branch(session)
        names = _session_names(session)
        if branch is not None:
            return self.backend.execute(
                plan.sql, branch=branch, scope=session.scope(), params=params, time_zone=session.zone(), session=names
            )
        if kind == "explain":
            raise DialectError(
                "unsupported in lakegate: EXPLAIN of a query over system tables",
                line=1,
                column=1,
                error_name="NOT_SUPPORTED",
            )
        return self.metadata.run(
            plan.sql, plan.system, params, user=session.user, time_zone=session.zone(), session=names
        )

    def _default_branch(self, session: Session) -> str | None:
        """Where a query that reads no table runs: the session's branch, else any branch (None: the
        lake has none)."""
        branches = self.metadata.branches()
        if session.schema is not None and (session.catalog or "").lower() == self.metadata.catalog:
            try:
                schema = self.metadata.schema_name(self.metadata.catalog, session.schema)
            except DialectError:
                schema = None
            if schema in branches:
                return schema
        return branches[0] if branches else None

    def _plan(self, sql: str, query: str, offset: int, session: Session) -> _Plan:
        """Resolve the tables of `query` (the text at `offset` of `sql`) and rewrite `sql`."""
        try:
            parsed = _parse(query)
        except DialectError as error:
            raise _shifted(error, sql, offset) from None
        edits: list[tuple[int, int, str]] = []  # (start, end, replacement) of the same length
        branch: str | None = None
        system: dict[str, TableRef] = {}
        read: set[TableRef] = set()
        for reference in parsed.tables:
            start = offset + reference.start
            line, column = _where(sql, start)
            try:
                table = self.metadata.resolve(reference.parts, session, line=line, column=column)
            except DialectError:
                if len(reference.parts) == 1 and reference.parts[0].lower() in parsed.ctes:
                    continue  # a CTE's name
                raise
            read.add(table)
            if len(reference.parts) > 1:
                if table.table.lower() in parsed.ctes:
                    raise DialectError(
                        f"unsupported in lakegate: the WITH query '{table.table}' has the name of the "
                        f"table '{table}' that this query also reads; rename the WITH query",
                        line=line,
                        column=column,
                        error_name="NOT_SUPPORTED",
                    )
                edits.append(self._unqualify(sql, start, offset + reference.name_start))
            if table.system:
                known = system.setdefault(table.table.lower(), table)
                if known != table:
                    raise DialectError(
                        f"unsupported in lakegate: a query reads one table named '{table.table}', "
                        f"not both {known} and {table}",
                        line=line,
                        column=column,
                        error_name="NOT_SUPPORTED",
                    )
            elif branch is None:
                branch = table.schema
            elif branch != table.schema:
                raise DialectError(
                    f"unsupported in lakegate: a query reads the tables of one schema (branch); this one "
                    f"reads '{branch}' and '{table.schema}'",
                    line=line,
                    column=column,
                    error_name="NOT_SUPPORTED",
                )
            if branch is not None and system:
                raise DialectError(
                    "unsupported in lakegate: a query cannot read lake tables and system tables together",
                    line=line,
                    column=column,
                    error_name="NOT_SUPPORTED",
                )
        for reference in parsed.columns:  # schema.table.column: the table must be one the query reads
            start = offset + reference.start
            line, column = _where(sql, start)
            try:
                table = self.metadata.resolve(reference.parts, session, line=line, column=column)
            except DialectError:
                table = None
            if table not in read:
                raise DialectError(
                    f"Column prefix '{'.'.join(reference.parts)}' cannot be resolved (no such table in FROM)",
                    line=line,
                    column=column,
                    error_name="COLUMN_NOT_FOUND",
                )
            edits.append(self._unqualify(sql, start, offset + reference.name_start))
        for start, end in parsed.versions:
            edits.append((offset + start, offset + end + 1, _VERSION + " " * (end + 1 - start - len(_VERSION))))
        for start, end, text in sorted(edits, reverse=True):
            sql = sql[:start] + text + sql[end:]
        return _Plan(sql, branch, list(system.values()))

    @staticmethod
    def _unqualify(sql: str, start: int, name_start: int) -> tuple[int, int, str]:
        """The edit that blanks out the qualifier `catalog.schema.` before a name (line breaks kept)."""
        return start, name_start, _blank(sql[start:name_start])

    # -- prepared statements ----------------------------------------------------------------

    def _describe_prepared(self, what: str, name: str, session: Session) -> Answer:
        statement = session.prepared_statement(name)
        count = _parameter_count(statement)
        if what == "INPUT":
            return Answer([("Position", "bigint"), ("Type", "varchar")], [(i, "unknown") for i in range(count)])
        kind = guard.classify(statement)
        if kind not in ("query", "show", "describe", "explain"):
            return Answer(_DESCRIBE_OUTPUT, [])
        result = self.start(statement, session, [None] * count)
        result.cancel()
        aliased = _aliased(statement, len(result.columns))
        rows = [
            (column, "", "", "", trino_type, _type_size(trino_type), alias)
            for (column, trino_type), alias in zip(result.columns, aliased)
        ]
        return Answer(_DESCRIBE_OUTPUT, rows)


def _session_names(session: Session) -> SessionNames:
    """What current_user, current_catalog and current_schema answer: Trino lower-cases the session's
    catalog and schema names (as sent, whether they exist or not) and keeps the user as it is."""
    catalog, schema = session.catalog, session.schema
    return SessionNames(session.user, catalog and catalog.lower(), schema and schema.lower())


#: The words a Trino 476 statement may start with, in the order its parser lists them when another
#: word starts one (a query may also start with SELECT, VALUES, TABLE or a parenthesis).
_STATEMENT_STARTS = (
    "ALTER ANALYZE CALL COMMENT COMMIT CREATE DEALLOCATE DELETE DENY DESC DESCRIBE DROP EXECUTE EXPLAIN GRANT "
    "INSERT MERGE PREPARE REFRESH RESET REVOKE ROLLBACK SET SHOW START TRUNCATE UPDATE USE WITH"
).split()


def _check_statement_start(sql: str) -> None:
    """A statement whose first word starts no Trino statement is Trino's SYNTAX_ERROR at that word."""
    tokens = [token for token in Trino().tokenize(sql) if token.token_type != TokenType.L_PAREN]
    if not tokens or tokens[0].text.upper() in (*_STATEMENT_STARTS, "SELECT", "VALUES", "TABLE"):
        return
    line, column = _where(sql, tokens[0].start)
    expecting = ", ".join(f"'{word}'" for word in _STATEMENT_STARTS)
    raise DialectError(
        f"mismatched input '{tokens[0].text}'. Expecting: {expecting}, <query>",
        line=line,
        column=column,
        error_name="SYNTAX_ERROR",
    )


def _is_execute(sql: str) -> bool:
    return guard.first_words(sql, 1) == ["EXECUTE"]


def _described_statement(sql: str) -> tuple[str, str] | None:
    """('INPUT' | 'OUTPUT', statement name as written) of `DESCRIBE INPUT|OUTPUT name`, else None."""
    words = guard.first_words(sql, 2)
    if words[:1] not in (["DESCRIBE"], ["DESC"]) or words[1:] not in (["INPUT"], ["OUTPUT"]):
        return None
    reader = Reader(sql)
    reader.skip_words(2)
    if len(reader.tokens) != reader.pos + 1:
        return None  # DESCRIBE of a table called input or output
    name = reader.peek().text
    reader.identifier()  # a name, not a string or a symbol
    return words[1], name


def _parameter_count(statement: str) -> int:
    if guard.classify(statement) not in ("query", "explain"):
        return 0
    return sum(1 for node in parse(statement).find_all(exp.Placeholder) if not node.this)


def _aliased(statement: str, count: int) -> list[bool]:
    """Whether each output column of a query has an alias (`AS name`), as DESCRIBE OUTPUT says."""
    try:
        tree = parse(statement)
    except DialectError:
        return [False] * count
    if (
        isinstance(tree, exp.Query)
        and isinstance(tree, exp.Select)
        and len(tree.expressions) == count
        and not any(isinstance(e, exp.Star) for e in tree.expressions)
    ):
        return [isinstance(e, exp.Alias) for e in tree.expressions]
    return [False] * count


def _type_size(trino_type: str) -> int:
    """Trino's fixed size in bytes of a type (0 for variable-width types), for DESCRIBE OUTPUT."""
    t = tt.parse_type(trino_type)
    base, args = t.base, t.args
    sizes = {
        "bigint": 8,
        "integer": 4,
        "smallint": 2,
        "tinyint": 1,
        "double": 8,
        "real": 4,
        "boolean": 1,
        "date": 4,
        "uuid": 16,
        "interval_ds": 8,
        "interval_ym": 4,
        "time": 8,
        "time_tz": 8,
    }
    if base == "decimal":
        return 8 if args[0] <= 18 else 16
    if base == "timestamp":
        return 8 if args[0] <= 6 else 12
    if base == "timestamp_tz":
        return 8 if args[0] <= 3 else 12
    return sizes.get(base, 0)
