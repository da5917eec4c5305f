"""Trino's session functions `current_catalog`, `current_schema`, `current_user` and `current_path`
(SQL-standard special forms: no parentheses), bound to the values of the session that runs the query.

Each becomes a varchar literal (NULL for a catalog or schema the session has not set; `current_path`
is the empty path ''), as Trino 476 answers them: `SELECT current_schema` with no schema set is NULL
of type varchar, named `_col0`. `current_schema` and `current_path` are special forms even where a
column of that name exists, as in Trino; quoted (`"current_user"`) or qualified, they are columns.
`current_timezone()` (dialect/functions/datetime.py) and `current_groups()` (dialect/functions/session.py)
are ordinary functions.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlglot import exp
from sqlglot.dialects.trino import Trino
from sqlglot.tokens import TokenType

from lakegate.dialect.errors import DialectError

#: The special forms, as Trino spells them.
NAMES = ("current_catalog", "current_schema", "current_user", "current_path")


@dataclass(frozen=True)
class SessionNames:
    """What the session functions answer: the session user, and its catalog and schema (None: not set)."""

    user: str
    catalog: str | None = None
    schema: str | None = None


def used(sql: str | bytes) -> bool:
    """Whether `sql` (text, or the bytes a client sent) may call a session function (a cheap test)."""
    return (b"current_" if isinstance(sql, bytes) else "current_") in sql.lower()


def _where(sql: str, offset: int) -> tuple[int, int]:
    return sql.count("\n", 0, offset) + 1, offset - (sql.rfind("\n", 0, offset) + 1) + 1


def _first_session_function(sql: str) -> int | None:
    """Refuse `current_user()` and its siblings as Trino's parser does; the offset of the first
    special form in `sql` (None: none)."""
    first = None
    tokens = Trino().tokenize(sql)
    for token, following in zip(tokens, [*tokens[1:], None]):
        if token.token_type == TokenType.IDENTIFIER or token.text.lower() not in NAMES:
            continue
        first = token.start if first is None else first
        if following is not None and following.token_type == TokenType.L_PAREN:
            line, column = _where(sql, following.start)
            raise DialectError(
                f"mismatched input '('. {token.text} is written without parentheses",
                line=line,
                column=column,
                error_name="SYNTAX_ERROR",
            )
    return first


def _special(node: exp.Expression) -> str | None:
    """The session function `node` is, if it is one."""
    if isinstance(node, exp.CurrentCatalog):
        return "current_catalog"
    if isinstance(node, exp.CurrentSchema):
        return "current_schema"
    if isinstance(node, exp.CurrentUser):
        return "current_user"
    if (
        isinstance(node, exp.Column)
        and not node.table
        and isinstance(node.this, exp.Identifier)
        and not node.this.quoted
        and node.this.this.lower() in ("current_schema", "current_path")
    ):
        return node.this.this.lower()
    return None


def called(tree: exp.Expression) -> list[str]:
    """The session functions `tree` calls, in order."""
    return [name for node in tree.walk() if (name := _special(node)) is not None]


def bind(tree: exp.Expression, sql: str, names: SessionNames | None) -> bool:
    """Replace every session function in `tree` (parsed from `sql`) by its value in `names`; whether
    any was replaced. Without `names` (a translation outside any session) they are refused."""
    if not used(sql):
        return False
    offset = _first_session_function(sql)
    found = [(node, name) for node in list(tree.walk()) if (name := _special(node)) is not None]
    if not found:
        return False
    if names is None:
        line, column = _where(sql, offset) if offset is not None else (None, None)
        # the first in the text, where the position points (the tree's walk may meet another first)
        name = next((n for n in NAMES if offset is not None and sql[offset:].lower().startswith(n)), found[0][1])
        raise DialectError(
            f"unsupported in lakegate: {name} outside a session (it is answered by lakegate query and serve)",
            line=line,
            column=column,
            error_name="NOT_SUPPORTED",
        )
    values = {"current_catalog": names.catalog, "current_schema": names.schema, "current_user": names.user}
    for node, name in found:
        value = values.get(name, "")
        literal = exp.Null() if value is None else exp.Literal.string(value)
        node.replace(exp.Cast(this=literal, to=exp.DataType.build("VARCHAR")))
    return True
