"""sqlglot's parse and tokenize failures as Trino's SYNTAX_ERROR: `mismatched input 'x'` at the line and
column of the offending token (`<EOF>` after the last character), never sqlglot's own wording."""

from __future__ import annotations

import re
from collections.abc import Callable

from sqlglot.dialects.trino import Trino
from sqlglot.errors import ParseError, TokenError
from sqlglot.tokens import Token, TokenType

from lakegate.dialect.errors import DialectError

#: A binary literal X'...' with a character that is not a hexadecimal digit.
_BAD_BINARY = re.compile(r"(?<![\w'])[xX]'(?=[^']*')(?![0-9a-fA-F\s]*')")

#: The key of a sqlglot error dict that the dialect's parser adds: the offending token's offset in the
#: SQL text (-1: the end of the text) and its text as written.
OFFSET, TEXT = "lakegate_offset", "lakegate_text"


def position(sql: str, offset: int) -> tuple[int, int]:
    """The 1-based (line, column) of character `offset` of `sql` (`len(sql)`: just after the end)."""
    line = sql.count("\n", 0, offset) + 1
    return line, offset - (sql.rfind("\n", 0, offset) + 1) + 1


def mark(error: ParseError, sql: str, token: Token | None) -> ParseError:
    """`error` with the offending `token` (None or a sentinel: the end of the text) recorded for `parse_error`."""
    at_end = token is None or not token or token.token_type == TokenType.SENTINEL
    for detail in error.errors:
        detail[OFFSET] = -1 if at_end else token.start
        detail[TEXT] = "<EOF>" if at_end else sql[token.start : token.end + 1]
    return error


def mismatched(sql: str, offset: int, text: str, hint: str = "") -> DialectError:
    """Trino's SYNTAX_ERROR `mismatched input 'text'` at character `offset` of `sql` (-1: the end)."""
    line, column = position(sql, len(sql) if offset < 0 else offset)
    message = f"mismatched input '{text}'" + (f". {hint}" if hint else "")
    return DialectError(message, line=line, column=column, error_name="SYNTAX_ERROR")


def parse_error(error: ParseError, sql: str) -> DialectError:
    """The SYNTAX_ERROR for a ParseError of the dialect's parser: its own `mismatched input ...` messages
    kept, any other sqlglot description replaced by `mismatched input` of the token it stopped at."""
    detail = error.errors[0] if error.errors else {}
    description = detail.get("description") or ""
    if OFFSET not in detail:  # not raised through the dialect's parser: no token to name
        return DialectError("mismatched input '<EOF>'", line=1, column=1, error_name="SYNTAX_ERROR")
    hint = ""
    if description.startswith("mismatched input"):
        hint = description.partition(". ")[2]
    return mismatched(sql, detail[OFFSET], detail[TEXT], hint)


def tokenize_error(sql: str, parse: Callable[[str], object] | None = None) -> DialectError:
    """The SYNTAX_ERROR for text sqlglot's tokenizer cannot read: Trino stops at the quote that opens an
    unterminated string or quoted identifier, and at the `*` of an unterminated `/*` comment, unless the
    text before it is wrong already (`parse`, the dialect's parse, raises for that text before its end)."""
    binary = _BAD_BINARY.search(sql)
    offset = _unterminated(sql)
    if binary is not None and (offset is None or binary.start() < offset):
        line, column = position(sql, binary.start())
        return DialectError(
            "Binary literal can only contain hexadecimal digits", line=line, column=column, error_name="SYNTAX_ERROR"
        )
    if offset is None:
        return mismatched(sql, 0, sql.split(None, 1)[0] if sql.strip() else "<EOF>")
    if parse is not None:
        try:
            parse(sql[:offset])
        except DialectError as earlier:
            if earlier.error_name == "SYNTAX_ERROR" and (earlier.line, earlier.column) < position(sql, offset):
                return earlier
    if sql.startswith("/*", offset):  # Trino reads `/` and `*`: a division after an operand, else no expression
        return mismatched(sql, offset + 1, "*") if _after_operand(sql[:offset]) else mismatched(sql, offset, "/")
    return mismatched(sql, offset, sql[offset])


#: Tokens that end an operand, after which `/` is a division.
_OPERAND_ENDS = {
    TokenType.NUMBER,
    TokenType.STRING,
    TokenType.VAR,
    TokenType.IDENTIFIER,
    TokenType.R_PAREN,
    TokenType.R_BRACKET,
    TokenType.NULL,
    TokenType.TRUE,
    TokenType.FALSE,
    TokenType.END,
}


def _after_operand(text: str) -> bool:
    """Whether `text` (the SQL before an unterminated comment) ends with an operand."""
    try:
        tokens = Trino().tokenize(text)
    except TokenError:
        return False
    alias = len(tokens) > 1 and tokens[-2].token_type == TokenType.ALIAS  # `AS c`: a name, not an operand
    return bool(tokens) and tokens[-1].token_type in _OPERAND_ENDS and not alias


def _unterminated(sql: str) -> int | None:
    """The offset where an unterminated quoted string, quoted identifier or block comment starts."""
    i, n = 0, len(sql)
    while i < n:
        char = sql[i]
        if char in "'\"`":
            end = i + 1
            while True:
                end = sql.find(char, end)
                if end < 0:  # Trino's lexer reads the longest string it can: the last quote opens none
                    return sql.rfind(char)
                if sql.startswith(char * 2, end):
                    end += 2
                    continue
                break
            i = end + 1
        elif sql.startswith("--", i):
            newline = sql.find("\n", i)
            i = n if newline < 0 else newline + 1
        elif sql.startswith("/*", i):
            end = sql.find("*/", i + 2)
            if end < 0:
                return i
            i = end + 2
        else:
            i += 1
    return None
