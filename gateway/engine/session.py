"""Client sessions: the `X-Trino-*` request headers read into a `Session`, and the statements that
change a session answered with the response headers that carry the change back to the client.

The server keeps no session state: catalog, schema, session properties, prepared statements and
the transaction id live in the client, which sends them with every request (notes, sections 2-3
and 9). Session properties `batch_id` and `job_id` narrow every lake table to one batch / job
(dialect/scope.py). PREPARE is stateless: its SQL travels in `X-Trino-Added-Prepare` and comes
back in `X-Trino-Prepared-Statement`. Transactions are accepted and do nothing (the lake is read-only).
"""

from __future__ import annotations

import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from urllib.parse import quote_plus, unquote_plus

from sqlglot.tokens import TokenType

from lakegate.dialect import zones
from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope
from lakegate.dialect.statements import Reader, Statement

#: Session properties lakegate knows: name -> description (both varchar, default NULL).
PROPERTIES = {
    "batch_id": "Narrow every lake table to the rows of this batch",
    "job_id": "Narrow every lake table to the rows of this job",
    "time_zone_id": "The session time zone, set by SET TIME ZONE (overrides X-Trino-Time-Zone)",
}


class HeaderError(ValueError):
    """A request header that cannot be read (answered with HTTP 400)."""


@dataclass
class Session:
    """What one request says about its client's session."""

    user: str
    catalog: str | None = None
    schema: str | None = None
    source: str | None = None
    time_zone: str | None = None
    properties: dict[str, str] = field(default_factory=dict)
    prepared: dict[str, str] = field(default_factory=dict)
    transaction_id: str | None = None
    #: A scope set in-process by its caller (a metric's job, with its staged statuses): wins over the properties.
    restriction: Scope | None = None

    def scope(self) -> Scope | None:
        """The scope every lake table is restricted to (None: the whole branch)."""
        if self.restriction is not None:
            return self.restriction
        batch_id, job_id = self.properties.get("batch_id"), self.properties.get("job_id")
        return Scope(batch_id, job_id) if batch_id is not None or job_id is not None else None

    def zone(self) -> str:
        """The session time zone as Trino names it: SET TIME ZONE's, else X-Trino-Time-Zone's, else UTC
        (DialectError NOT_SUPPORTED, Trino's "Time zone not supported", for a zone Trino does not know)."""
        name = self.properties.get("time_zone_id") or self.time_zone or zones.UTC
        try:
            return zones.canonical(name.strip())
        except ValueError as error:
            raise DialectError(str(error), error_name="NOT_SUPPORTED") from None

    def prepared_statement(self, name: str) -> str:
        """The SQL of the prepared statement `name` (from X-Trino-Prepared-Statement)."""
        statement = self.prepared.get(name, self.prepared.get(name.lower()))
        if statement is None:
            raise DialectError(f"Prepared statement not found: {name}", error_name="NOT_FOUND")
        return statement


def _pairs(value: str | None, header: str) -> dict[str, str]:
    """`name=url-encoded value,...` as a dict."""
    pairs = {}
    for item in (value or "").split(","):
        if not item.strip():
            continue
        name, equals, text = item.partition("=")
        if not equals or not name.strip():
            raise HeaderError(f"Invalid {header} header: expected name=value, got {item.strip()!r}")
        pairs[unquote_plus(name.strip())] = unquote_plus(text.strip())
    return pairs


def from_headers(headers: Mapping[str, str], user: str | None = None) -> Session:
    """The session of a request. `user` (the authenticated user) is the session user; without it
    X-Trino-User is. Unknown session properties are an INVALID_SESSION_PROPERTY error at query
    time (`check_properties`); malformed headers raise HeaderError."""
    user = user or headers.get("x-trino-user")
    if not user:
        raise HeaderError("User must be set (X-Trino-User header)")
    transaction = headers.get("x-trino-transaction-id")
    return Session(
        user=user,
        catalog=headers.get("x-trino-catalog") or None,
        schema=headers.get("x-trino-schema") or None,
        source=headers.get("x-trino-source"),
        time_zone=headers.get("x-trino-time-zone"),
        properties=_pairs(headers.get("x-trino-session"), "X-Trino-Session"),
        prepared=_pairs(headers.get("x-trino-prepared-statement"), "X-Trino-Prepared-Statement"),
        transaction_id=None if transaction in (None, "", "NONE") else transaction,
    )


def check_properties(session: Session) -> None:
    """Refuse session properties lakegate does not know (as Trino refuses unknown ones), and a session
    time zone Trino does not know."""
    session.zone()
    for name in session.properties:
        if name not in PROPERTIES:
            raise DialectError(
                f"Session property '{name}' does not exist (lakegate knows {', '.join(PROPERTIES)})",
                error_name="INVALID_SESSION_PROPERTY",
            )


@dataclass
class Answer:
    """A statement answered at once: result columns (name, Trino type), rows, the response headers
    that update the client's session, and Trino's updateType."""

    columns: list[tuple[str, str]]
    rows: list[tuple]
    headers: list[tuple[str, str]] = field(default_factory=list)
    update_type: str | None = None


def _done(update_type: str, *headers: tuple[str, str]) -> Answer:
    """What Trino answers to a session statement: one boolean column `result`, true."""
    return Answer([("result", "boolean")], [(True,)], list(headers), update_type)


# --- reading the statements ------------------------------------------------------------------


def answer(
    statement: Statement,
    session: Session,
    resolve_schema: Callable[[str | None, tuple[str, bool]], tuple[str, str]],
) -> Answer:
    """Answer a session statement (kind 'session' in the table of statement kinds, `guard.STATEMENTS`).
    `resolve_schema(catalog, (schema, quoted))` checks a USE target and returns the (catalog,
    schema) names to set (DialectError when either does not exist)."""
    tokens = Reader(statement.text)
    name = statement.name
    tokens.skip_words(len(name.split()))
    if name == "USE":
        parts = tokens.name()
        tokens.end()
        if len(parts) > 2:
            raise DialectError(
                f"USE takes schema or catalog.schema, not '{'.'.join(p for p, _ in parts)}'",
                line=1,
                column=5,
                error_name="SYNTAX_ERROR",
            )
        catalog = parts[0][0] if len(parts) == 2 else session.catalog
        catalog, schema = resolve_schema(catalog, parts[-1])
        if not schema.isascii():  # HTTP headers carry ASCII only
            raise DialectError(
                f"unsupported in lakegate: USE of the schema '{schema}', whose name is not ASCII; "
                "qualify the table names instead",
                error_name="NOT_SUPPORTED",
            )
        return _done("USE", ("X-Trino-Set-Catalog", catalog), ("X-Trino-Set-Schema", schema))
    if name == "SET SESSION":
        prop = _property(tokens.name())
        tokens.expect("=")
        token = tokens.peek()
        if token is None or token.token_type != TokenType.STRING or tokens.pos != len(tokens.tokens) - 1:
            raise DialectError(
                f"Session property '{prop}' must be set to a varchar literal ('...')",
                error_name="INVALID_SESSION_PROPERTY",
            )
        return _done("SET SESSION", ("X-Trino-Set-Session", f"{prop}={quote_plus(token.text)}"))
    if name == "SET TIME ZONE":
        return _set_time_zone(tokens)
    if name == "RESET SESSION":
        prop = _property(tokens.name())
        tokens.end()
        return _done("RESET SESSION", ("X-Trino-Clear-Session", prop))
    if name == "PREPARE":
        statement, _ = tokens.identifier()
        tokens.expect("FROM")
        return _done("PREPARE", ("X-Trino-Added-Prepare", f"{statement}={quote_plus(tokens.rest())}"))
    if name == "DEALLOCATE PREPARE":
        statement, _ = tokens.identifier()
        tokens.end()
        session.prepared_statement(statement)
        return _done("DEALLOCATE", ("X-Trino-Deallocated-Prepare", statement))
    if name == "START TRANSACTION":
        if session.transaction_id is not None:
            raise DialectError("Nested transactions not supported", error_name="NOT_SUPPORTED")
        return _done("START TRANSACTION", ("X-Trino-Started-Transaction-Id", str(uuid.uuid4())))
    if name in ("COMMIT", "ROLLBACK"):
        tokens.take("WORK")
        tokens.end()
        if session.transaction_id is None:
            raise DialectError("No transaction in progress", error_name="NOT_IN_TRANSACTION")
        return _done(name, ("X-Trino-Clear-Transaction-Id", "true"))
    raise DialectError("not a session statement", error_name="NOT_SUPPORTED")


def _set_time_zone(tokens: Reader) -> Answer:
    """SET TIME ZONE LOCAL (back to the client's zone) or SET TIME ZONE 'zone' (a region or an offset);
    Trino keeps it as the session property time_zone_id (io.trino.execution.SetTimeZoneTask)."""
    token = tokens.peek()
    if token is not None and token.text.upper() == "LOCAL":
        tokens.pos += 1
        tokens.end()
        return _done("SET TIME ZONE", ("X-Trino-Clear-Session", "time_zone_id"))
    if token is None or token.token_type != TokenType.STRING or tokens.pos != len(tokens.tokens) - 1:
        raise DialectError(
            "unsupported in lakegate: SET TIME ZONE takes LOCAL or a zone literal ('America/New_York', '-08:00')",
            error_name="NOT_SUPPORTED",
        )
    try:
        zone = zones.canonical(token.text)
    except ValueError as error:
        raise DialectError(str(error), error_name="NOT_SUPPORTED") from None
    return _done("SET TIME ZONE", ("X-Trino-Set-Session", f"time_zone_id={quote_plus(zone)}"))


def _property(parts: list[tuple[str, bool]]) -> str:
    name = ".".join(text for text, _ in parts)
    if name not in PROPERTIES:
        raise DialectError(
            f"Session property '{name}' does not exist (lakegate knows {', '.join(PROPERTIES)})",
            error_name="INVALID_SESSION_PROPERTY",
        )
    return name


def kill_query_arguments(sql: str, session: Session) -> tuple[str, str | None]:
    """(query_id, message) of `CALL system.runtime.kill_query(query_id => '...', message => '...')`
    (arguments named or positional); PROCEDURE_NOT_FOUND for any other procedure."""
    tokens = Reader(sql)
    tokens.skip_words(1)
    name = [text for text, _ in tokens.name()]
    full = ([session.catalog or ""] if len(name) == 2 else []) + name
    if [part.lower() for part in full] != ["system", "runtime", "kill_query"]:
        raise DialectError(f"Procedure not registered: {'.'.join(name)}", error_name="PROCEDURE_NOT_FOUND")
    tokens.expect("(")
    names = ("query_id", "message")
    arguments: dict[str, str | None] = {}
    while tokens.word() != ")":
        key = names[len(arguments)] if len(arguments) < len(names) else "?"
        following = tokens.tokens[tokens.pos + 1] if tokens.pos + 1 < len(tokens.tokens) else None
        if following is not None and following.text == "=>":
            key = tokens.identifier()[0]
            tokens.pos += 1
        token = tokens.peek()
        if token is None or (token.token_type != TokenType.STRING and token.text.upper() != "NULL"):
            tokens.fail("a string literal")
        tokens.pos += 1
        if key not in names or key in arguments:
            raise DialectError(f"Invalid argument for kill_query: {key}", error_name="INVALID_PROCEDURE_ARGUMENT")
        arguments[key] = token.text if token.token_type == TokenType.STRING else None
        if not tokens.take(","):
            break
    tokens.expect(")")
    tokens.end()
    if not arguments.get("query_id"):
        raise DialectError("kill_query needs a query_id", error_name="INVALID_PROCEDURE_ARGUMENT")
    return arguments["query_id"], arguments.get("message")


def query_not_found(query_id: str) -> DialectError:
    """What kill_query answers for a query that is not there."""
    return DialectError(f"Target query not found: {query_id}", error_name="NOT_FOUND")
