"""From one read statement (`statements.Statement`) and its session to a running result.

The Engine answers session statements and CALL itself; every other kind comes here: EXECUTE /
EXECUTE IMMEDIATE (the statement and its USING values), DESCRIBE INPUT / OUTPUT of a prepared
statement, SHOW / DESCRIBE (`SystemCatalog.show`), and queries and EXPLAIN.

A query's table names are resolved against the session (`SystemCatalog.resolve`): every table it reads
must live in one branch (then the backend runs it on that branch, restricted to the session's
scope) or be a system table (then it runs over the materialised system tables); a query that
reads no table runs on the session's branch. The statement's tree is rewritten: qualifiers
(`lake.main.odom`, `"feature/x".odom`, `information_schema.tables`, `main.odom.x`) are dropped and
`version()` becomes its value. The parsed nodes keep their positions, so errors the dialect
reports still point into the user's original SQL; the same rewrite as same-length text edits
(`Statement.edits`, qualifiers blanked) is kept for a backend that sends text.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import lru_cache

import pyarrow as pa
from sqlglot import exp
from sqlglot.dialects.trino import Trino
from sqlglot.tokens import TokenType

from lakegate.dialect import trino_types as tt
from lakegate.dialect.errors import DialectError
from lakegate.dialect.params import parse_execute
from lakegate.dialect.session_functions import SessionNames
from lakegate.dialect.statements import Reader, Statement, parsed, read
from lakegate.dialect.translate import parse
from lakegate.gateway.engine.backend import Backend, QueryResult
from lakegate.gateway.engine.session import Answer, Session, check_properties
from lakegate.gateway.engine.system_tables import SystemCatalog, TableRef
from lakegate.gateway.engine.trino_values import arrow_type

#: Query texts longer than this (characters) are checked and parsed by the backend's worker
#: process when it has one (`query_names`): parsing one here would hold this process's GIL for up to
#: a second (1 MB), slowing every other query the server answers.
REMOTE_PARSE_CHARS = 64 * 1024
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
    start: int  # offset of the first part in the query text
    name_start: int  # offset of the table part: [start, name_start) is the qualifier dropped


@dataclass(frozen=True)
class _Names:
    tables: tuple[_Reference, ...]
    columns: tuple[_Reference, ...]  # columns written `schema.table.column` (or longer)
    ctes: frozenset[str]
    versions: tuple[tuple[int, int], ...]  # (start, end) of each `version()` call in the query text


def _part(identifier: exp.Identifier) -> str:
    return identifier.this if identifier.quoted else identifier.this.lower()


def _reference(*identifiers: exp.Expression | None) -> _Reference | None:
    """The reference made of these name parts (the last one is the table), if all are in the text."""
    idents = [p for p in identifiers if isinstance(p, exp.Identifier)]
    if not idents or any("start" not in ident.meta for ident in idents):
        return None  # a name sqlglot made up (not in the text): nothing to resolve
    return _Reference(tuple(_part(p) for p in idents), idents[0].meta["start"], idents[-1].meta["start"])


def _table_reference(table: exp.Table) -> _Reference | None:
    if not isinstance(table.this, exp.Identifier):
        return None
    return _reference(table.args.get("catalog"), table.args.get("db"), table.this)


def _column_reference(column: exp.Column) -> _Reference | None:
    if not isinstance(column.args.get("db"), exp.Identifier):
        return None
    return _reference(column.args.get("catalog"), column.args.get("db"), column.args.get("table"))


def _version_call(node: exp.Expression, query: str) -> tuple[int, int] | None:
    """(start, end) in `query` of a `version()` call (the name, quoted or not, then `(` and `)`)."""
    if not isinstance(node, exp.Anonymous) or node.expressions or node.name.lower() != "version":
        return None
    meta = node.this.meta if isinstance(node.this, exp.Identifier) else node.meta
    if "start" not in meta:
        return None
    tokens = Trino().tokenize(query[meta["start"] :])[:3]
    if [token.token_type for token in tokens[1:]] != [TokenType.L_PAREN, TokenType.R_PAREN]:
        return None
    return meta["start"], meta["start"] + tokens[2].end


def query_names(statement: Statement) -> _Names:
    """What the planner reads of a query's text, for a backend that plans it in another process
    (`Backend.query_names`): the refusal its reading decided raised (`Statement.check`), then its text
    parsed, in that order, as the planner does (the same errors), then its table references, qualified
    columns, CTEs and `version()`."""
    statement.check()
    statement.tree  # noqa: B018 -- parse errors, positioned in the statement's text
    return _names_of(statement.body)


def with_edits_applied(statement: Statement) -> Statement:
    """A statement the planner gave its `edits` without parsing it (`Statement.with_edits`), with the
    tree those edits stand for: qualifiers dropped, `version()` replaced (`_unqualified`)."""
    if not statement.edits or statement.is_rewritten:
        return statement
    tree = replace(statement, edits=()).tree
    return statement.rewritten(_unqualified(tree, statement.body), statement.edits)


@lru_cache(maxsize=512)
def _names_of(query: str) -> _Names:
    """`_names` of a query text's shared parse (cached: a repeated query is walked once)."""
    return _names(parsed(query), query)


def _names(tree: exp.Expression, query: str) -> _Names:
    """The table references, schema-qualified columns, CTE names and `version()` calls of a query's tree."""
    tables = [ref for table in tree.find_all(exp.Table) if (ref := _table_reference(table)) is not None]
    columns = [ref for column in tree.find_all(exp.Column) if (ref := _column_reference(column)) is not None]
    ctes = frozenset(cte.alias_or_name.lower() for cte in tree.find_all(exp.CTE))
    versions = []
    if "version" in query.lower():
        versions = [span for node in tree.find_all(exp.Anonymous) if (span := _version_call(node, query)) is not None]
    return _Names(tuple(sorted(tables, key=lambda r: r.start)), tuple(columns), ctes, tuple(sorted(versions)))


def _unqualified(tree: exp.Expression, query: str) -> exp.Expression:
    """A copy of `tree` with the qualifiers of its tables and columns dropped (each was resolved to a
    table the query reads) and each `version()` call replaced by its value."""
    tree = tree.copy()
    for table in list(tree.find_all(exp.Table)):
        reference = _table_reference(table)
        if reference is not None and len(reference.parts) > 1:
            table.set("catalog", None)
            table.set("db", None)
    for column in list(tree.find_all(exp.Column)):
        if _column_reference(column) is not None:
            column.set("catalog", None)
            column.set("db", None)
    for node in list(tree.find_all(exp.Anonymous)):
        if _version_call(node, query) is not None:
            node.replace(_version_value())
    return tree


@lru_cache(maxsize=1)
def _version_tree() -> exp.Expression:
    return parse(f"SELECT {_VERSION}").expressions[0]


def _version_value() -> exp.Expression:
    return _version_tree().copy()


def _where(sql: str, offset: int) -> tuple[int, int]:
    line = sql.count("\n", 0, offset) + 1
    return line, offset - (sql.rfind("\n", 0, offset) + 1) + 1


def _blank(text: str) -> str:
    return "".join("\n" if char == "\n" else " " for char in text)


@dataclass
class _Plan:
    statement: Statement  # what to run: the tree with its qualifiers resolved and dropped
    branch: str | None  # the branch whose tables it reads
    system: list[TableRef]  # the system tables it reads


class Planner:
    """Starts statements over `backend` and the system tables of `system_catalog`."""

    def __init__(self, backend: Backend, system_catalog: SystemCatalog):
        self.backend, self.system_catalog = backend, system_catalog

    def start(self, statement: Statement, session: Session, params: Sequence[object] = ()) -> QueryResult:
        """Start one statement (anything but a session statement or CALL); DialectError when it is
        refused or fails to start."""
        check_properties(session)
        kind = statement.kind
        if kind == "execute":
            if params:
                raise DialectError("EXECUTE cannot be a prepared statement", error_name="NOT_SUPPORTED")
            execute = parse_execute(statement.text)
            text = execute.statement if execute.statement is not None else session.prepared_statement(execute.name)
            inner = read(text)
            if inner.kind == "execute":
                raise DialectError("EXECUTE of an EXECUTE statement is not supported", error_name="NOT_SUPPORTED")
            return self.start(inner, session, execute.params)
        if kind == "describe_prepared":
            return static_result(self._describe_prepared(statement, session))
        if kind in ("show", "describe"):
            if params:
                raise DialectError(
                    f"Incorrect number of parameters: expected 0 but found {len(params)}",
                    error_name="INVALID_PARAMETER_USAGE",
                )
            statement.check()
            return static_result(self.system_catalog.show(statement, session))
        if kind in ("query", "explain"):
            return self._query(statement, session, params)
        if kind in ("session", "call"):
            raise DialectError(
                "a session statement or CALL cannot be run by EXECUTE; send it on its own", error_name="NOT_SUPPORTED"
            )
        statement.check()  # refuses writes and unknown statements with Trino's message
        raise DialectError("unsupported in lakegate: this statement", line=1, column=1, error_name="NOT_SUPPORTED")

    # -- queries ----------------------------------------------------------------------------

    def _query(self, statement: Statement, session: Session, params: Sequence[object]) -> QueryResult:
        remote = len(statement.text) > REMOTE_PARSE_CHARS and hasattr(self.backend, "query_names")
        if not remote:
            statement.check()
        plan = self._plan(statement, session, remote=remote)
        branch = plan.branch if plan.branch is not None or plan.system else self._default_branch(session)
        names = _session_names(session)
        if branch is not None:
            return self.backend.execute(
                plan.statement,
                branch=branch,
                scope=session.scope(),
                params=params,
                time_zone=session.zone(),
                session=names,
            )
        if statement.kind == "explain":
            raise DialectError(
                "unsupported in lakegate: EXPLAIN of a query over system tables",
                line=1,
                column=1,
                error_name="NOT_SUPPORTED",
            )
        return self.system_catalog.run(
            plan.statement, plan.system, params, user=session.user, time_zone=session.zone(), session=names
        )

    def _default_branch(self, session: Session) -> str | None:
        """Where a query that reads no table runs: the session's branch, else any branch (None: the
        lake has none)."""
        branches = self.system_catalog.branches()
        if session.schema is not None and (session.catalog or "").lower() == self.system_catalog.catalog:
            try:
                schema = self.system_catalog.schema_name(self.system_catalog.catalog, session.schema)
            except DialectError:
                schema = None
            if schema in branches:
                return schema
        return branches[0] if branches else None

    def _plan(self, statement: Statement, session: Session, *, remote: bool = False) -> _Plan:
        """Resolve the tables of the statement's query and drop their qualifiers from its tree.
        `remote`: the backend's worker checks and parses the text (`query_names`), and drops the
        qualifiers from the tree it runs (`with_edits_applied`); this process never parses it."""
        sql, offset = statement.text, statement.offset
        if remote:
            tree, names = None, self.backend.query_names(statement)  # type: ignore[attr-defined]
        else:
            tree = statement.tree  # parse errors raised here
            names = _names_of(statement.body)
        edits: list[tuple[int, int, str]] = []  # (start, end, replacement) of the same length, in `sql`
        branch: str | None = None
        system: dict[str, TableRef] = {}
        read_tables: set[TableRef] = set()
        for reference in names.tables:
            start = offset + reference.start
            line, column = _where(sql, start)
            try:
                table = self.system_catalog.resolve(reference.parts, session, line=line, column=column)
            except DialectError:
                if len(reference.parts) == 1 and reference.parts[0].lower() in names.ctes:
                    continue  # a CTE's name
                raise
            read_tables.add(table)
            if len(reference.parts) > 1:
                if table.table.lower() in names.ctes:
                    raise DialectError(
                        f"unsupported in lakegate: the WITH query '{table.table}' has the name of the "
                        f"table '{table}' that this query also reads; rename the WITH query",
                        line=line,
                        column=column,
                        error_name="NOT_SUPPORTED",
                    )
                edits.append(_unqualify(sql, start, offset + reference.name_start))
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
        for reference in names.columns:  # schema.table.column: the table must be one the query reads
            start = offset + reference.start
            line, column = _where(sql, start)
            try:
                table = self.system_catalog.resolve(reference.parts, session, line=line, column=column)
            except DialectError:
                table = None
            if table not in read_tables:
                raise DialectError(
                    f"Column prefix '{'.'.join(reference.parts)}' cannot be resolved (no such table in FROM)",
                    line=line,
                    column=column,
                    error_name="COLUMN_NOT_FOUND",
                )
            edits.append(_unqualify(sql, start, offset + reference.name_start))
        for start, end in names.versions:
            edits.append((offset + start, offset + end + 1, _VERSION + " " * (end + 1 - start - len(_VERSION))))
        if edits:
            statement = (
                statement.with_edits(tuple(edits))
                if tree is None
                else statement.rewritten(_unqualified(tree, statement.body), tuple(edits))
            )
        return _Plan(statement, branch, list(system.values()))

    # -- prepared statements ----------------------------------------------------------------

    def _describe_prepared(self, statement: Statement, session: Session) -> Answer:
        what = statement.name.split()[1]  # INPUT or OUTPUT
        reader = Reader(statement.text)
        reader.skip_words(2)
        name = reader.peek().text
        reader.identifier()  # a name, not a string or a symbol
        prepared = read(session.prepared_statement(name))
        count = _parameter_count(prepared)
        if what == "INPUT":
            return Answer([("Position", "bigint"), ("Type", "varchar")], [(i, "unknown") for i in range(count)])
        if prepared.kind not in ("query", "show", "describe", "explain"):
            return Answer(_DESCRIBE_OUTPUT, [])
        result = self.start(prepared, session, [None] * count)
        result.cancel()
        aliased = _aliased(prepared, len(result.columns))
        rows = [
            (column, "", "", "", trino_type, _type_size(trino_type), alias)
            for (column, trino_type), alias in zip(result.columns, aliased)
        ]
        return Answer(_DESCRIBE_OUTPUT, rows)


def _unqualify(sql: str, start: int, name_start: int) -> tuple[int, int, str]:
    """The text edit that blanks out the qualifier `catalog.schema.` before a name (line breaks kept)."""
    return start, name_start, _blank(sql[start:name_start])


def _session_names(session: Session) -> SessionNames:
    """What current_user, current_catalog and current_schema answer: Trino lower-cases the session's
    catalog and schema names (as sent, whether they exist or not) and keeps the user as it is."""
    catalog, schema = session.catalog, session.schema
    return SessionNames(session.user, catalog and catalog.lower(), schema and schema.lower())


def _parameter_count(statement: Statement) -> int:
    if statement.kind not in ("query", "explain"):
        return 0
    return sum(1 for node in statement.tree.find_all(exp.Placeholder) if not node.this)


def _aliased(statement: Statement, count: int) -> list[bool]:
    """Whether each output column of a query has an alias (`AS name`), as DESCRIBE OUTPUT says."""
    try:
        tree = statement.tree
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
