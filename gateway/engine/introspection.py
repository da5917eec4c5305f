"""SHOW and DESCRIBE answered from a branch's schema, with Trino's result columns and order.

Supported: SHOW CATALOGS, SHOW SCHEMAS, SHOW TABLES, SHOW COLUMNS FROM t and DESCRIBE t (each with
the optional FROM/IN and LIKE 'pattern' [ESCAPE 'c'] Trino allows). Other SHOW statements are
NOT_SUPPORTED. What a backend answers to a caller without a session (metrics, the dashboard);
`lakegate query` and the SQL server answer these statements through the Engine's system tables.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from lakegate.dialect.errors import DialectError
from lakegate.dialect.statements import Reader

#: The lake's catalog name (Trino clients address tables as catalog.schema.table).
CATALOG = "lake"


@dataclass
class ShowAnswer:
    """A SHOW / DESCRIBE result: (name, Trino type) columns and rows of Python values."""

    columns: list[tuple[str, str]]
    rows: list[tuple]


def _table(schema: Mapping[str, Mapping[str, str]], parts: Sequence[str]) -> tuple[str, Mapping[str, str]]:
    wanted = parts[-1]
    for table, columns in schema.items():
        if table.lower() == wanted.lower():
            return table, columns
    raise DialectError(f"Table '{'.'.join(parts)}' does not exist", error_name="TABLE_NOT_FOUND")


def _filtered(names: Sequence[str], pattern: re.Pattern | None) -> list[tuple]:
    return [(n,) for n in sorted(names) if pattern is None or pattern.fullmatch(n)]


def answer(
    sql: str, schema: Mapping[str, Mapping[str, str]], *, schemas: Sequence[str] = ("main",), catalog: str = CATALOG
) -> ShowAnswer:
    """Answer one SHOW or DESCRIBE statement over `schema` (table -> column -> Trino type);
    `schemas` are the names SHOW SCHEMAS lists (the lake's branches)."""
    reader = Reader(sql)
    if reader.take("DESCRIBE", "DESC"):
        if reader.word() in ("INPUT", "OUTPUT") and len(reader.tokens) > reader.pos + 1:
            raise DialectError(
                f"DESCRIBE {reader.word()} is handled by the server (prepared statements)", error_name="NOT_SUPPORTED"
            )
        parts = reader.parts()
        reader.end()
        return _columns(schema, parts, None)
    if not reader.take("SHOW"):
        raise DialectError("not a SHOW or DESCRIBE statement", error_name="NOT_SUPPORTED")
    if reader.take("TABLES"):
        if reader.take("FROM", "IN"):
            reader.parts()
        pattern = reader.like()
        reader.end()
        return ShowAnswer([("Table", "varchar")], _filtered(list(schema), pattern))
    if reader.take("COLUMNS"):
        if not reader.take("FROM", "IN"):
            reader.fail("FROM")
        parts = reader.parts()
        pattern = reader.like()
        reader.end()
        return _columns(schema, parts, pattern)
    if reader.take("SCHEMAS"):
        if reader.take("FROM", "IN"):
            reader.parts()
        pattern = reader.like()
        reader.end()
        return ShowAnswer([("Schema", "varchar")], _filtered(list(schemas), pattern))
    if reader.take("CATALOGS"):
        pattern = reader.like()
        reader.end()
        return ShowAnswer([("Catalog", "varchar")], _filtered([catalog], pattern))
    raise DialectError(
        f"unsupported in lakegate: SHOW {reader.word()}".rstrip(), line=1, column=1, error_name="NOT_SUPPORTED"
    )


def _columns(schema: Mapping[str, Mapping[str, str]], parts: Sequence[str], pattern: re.Pattern | None) -> ShowAnswer:
    _, columns = _table(schema, parts)
    rows = [
        (name, trino_type, "", "") for name, trino_type in columns.items() if pattern is None or pattern.fullmatch(name)
    ]
    return ShowAnswer([("Column", "varchar"), ("Type", "varchar"), ("Extra", "varchar"), ("Comment", "varchar")], rows)
