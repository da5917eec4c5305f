"""SHOW and DESCRIBE answered from a branch's schema, with Trino's result columns and order.

Supported: SHOW CATALOGS, SHOW SCHEMAS, SHOW TABLES, SHOW COLUMNS FROM t and DESCRIBE t (each with
the optional FROM/IN and LIKE 'pattern' [ESCAPE 'c'] Trino allows). Other SHOW statements are
NOT_SUPPORTED. Shared by `lakegate query` and the SQL server.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Mapping, Sequence

from sqlglot.dialects.trino import Trino
from sqlglot.errors import TokenError
from sqlglot.tokens import Token, TokenType

from lakegate.dialect.errors import DialectError

#: The catalog name lakegate answers to (Trino clients address tables as catalog.schema.table).
CATALOG = "lakegate"


@dataclass
class Answer:
    """A SHOW / DESCRIBE result: (name, Trino type) columns and rows of Python values."""

    columns: list[tuple[str, str]]
    rows: list[tuple]


def _tokens(text: str) -> list[Token]:
    try:
        tokens = Trino().tokenize(text)
    except TokenError as error:
        raise DialectError(f"syntax error: {error}", error_name="SYNTAX_ERROR") from None
    while tokens and tokens[-1].token_type == TokenType.SEMICOLON:
        tokens.pop()
    if len(tokens) == 2 and tokens[0].token_type == TokenType.SHOW and tokens[1].token_type == TokenType.STRING:
        return tokens[:1] + _tokens(tokens[1].text)  # sqlglot reads SHOW's rest as one string
    return tokens


def _like(pattern: str, escape: str | None) -> re.Pattern:
    parts, i = [], 0
    while i < len(pattern):
        char = pattern[i]
        if escape and char == escape and i + 1 < len(pattern):
            parts.append(re.escape(pattern[i + 1]))
            i += 2
            continue
        parts.append(".*" if char == "%" else "." if char == "_" else re.escape(char))
        i += 1
    return re.compile("".join(parts), re.S)


class _Reader:
    def __init__(self, tokens: list[Token]):
        self.tokens, self.pos = tokens, 0

    def word(self) -> str:
        return self.tokens[self.pos].text.upper() if self.pos < len(self.tokens) else ""

    def take(self, *words: str) -> bool:
        if self.word() in words and self.tokens[self.pos].token_type != TokenType.STRING:
            self.pos += 1
            return True
        return False

    def name(self) -> list[str]:
        parts = []
        while self.pos < len(self.tokens) and self.tokens[self.pos].token_type != TokenType.STRING:
            token = self.tokens[self.pos]
            quoted = token.token_type == TokenType.IDENTIFIER
            parts.append(token.text if quoted else token.text.lower())
            self.pos += 1
            if not (self.pos < len(self.tokens) and self.tokens[self.pos].token_type == TokenType.DOT):
                break
            self.pos += 1
        if not parts:
            self.fail("a name")
        return parts

    def string(self) -> str:
        if self.pos >= len(self.tokens) or self.tokens[self.pos].token_type != TokenType.STRING:
            self.fail("a string literal")
        self.pos += 1
        return self.tokens[self.pos - 1].text

    def like(self) -> re.Pattern | None:
        if not self.take("LIKE"):
            return None
        pattern = self.string()
        return _like(pattern, self.string() if self.take("ESCAPE") else None)

    def end(self) -> None:
        if self.pos < len(self.tokens):
            self.fail("the end of the statement")

    def fail(self, expected: str) -> None:
        token = self.tokens[self.pos] if self.pos < len(self.tokens) else None
        found = f"'{token.text}'" if token else "the end"
        raise DialectError(f"syntax error: expected {expected}, found {found}", error_name="SYNTAX_ERROR")


def _table(schema: Mapping[str, Mapping[str, str]], parts: Sequence[str]) -> tuple[str, Mapping[str, str]]:
    wanted = parts[-1]
    for table, columns in schema.items():
        if table.lower() == wanted.lower():
            return table, columns
    raise DialectError(f"Table '{'.'.join(parts)}' does not exist", error_name="TABLE_NOT_FOUND")


def _filtered(names: Sequence[str], pattern: re.Pattern | None) -> list[tuple]:
    return [(n,) for n in sorted(names) if pattern is None or pattern.fullmatch(n)]


def answer(sql: str, schema: Mapping[str, Mapping[str, str]], *, schemas: Sequence[str] = ("main",),
           catalog: str = CATALOG) -> Answer:
    """Answer one SHOW or DESCRIBE statement over `schema` (table -> column -> Trino type);
    `schemas` are the names SHOW SCHEMAS lists (the lake's branches)."""
    reader = _Reader(_tokens(sql))
    if reader.take("DESCRIBE", "DESC"):
        if reader.word() in ("INPUT", "OUTPUT") and len(reader.tokens) > reader.pos + 1:
            raise DialectError(f"DESCRIBE {reader.word()} is handled by the server (prepared statements)",
                               error_name="NOT_SUPPORTED")
        parts = reader.name()
        reader.end()
        return _columns(schema, parts, None)
    if not reader.take("SHOW"):
        raise DialectError("not a SHOW or DESCRIBE statement", error_name="NOT_SUPPORTED")
    if reader.take("TABLES"):
        if reader.take("FROM", "IN"):
            reader.name()
        pattern = reader.like()
        reader.end()
        return Answer([("Table", "varchar")], _filtered(list(schema), pattern))
    if reader.take("COLUMNS"):
        if not reader.take("FROM", "IN"):
            reader.fail("FROM")
        parts = reader.name()
        pattern = reader.like()
        reader.end()
        return _columns(schema, parts, pattern)
    if reader.take("SCHEMAS"):
        if reader.take("FROM", "IN"):
            reader.name()
        pattern = reader.like()
        reader.end()
        return Answer([("Schema", "varchar")], _filtered(list(schemas), pattern))
    if reader.take("CATALOGS"):
        pattern = reader.like()
        reader.end()
        return Answer([("Catalog", "varchar")], _filtered([catalog], pattern))
    raise DialectError(f"unsupported in lakegate: SHOW {reader.word()}".rstrip(), line=1, column=1,
                       error_name="NOT_SUPPORTED")


def _columns(schema: Mapping[str, Mapping[str, str]], parts: Sequence[str], pattern: re.Pattern | None) -> Answer:
    _, columns = _table(schema, parts)
    rows = [(name, trino_type, "", "") for name, trino_type in columns.items()
            if pattern is None or pattern.fullmatch(name)]
    return Answer([("Column", "varchar"), ("Type", "varchar"), ("Extra", "varchar"), ("Comment", "varchar")], rows)
