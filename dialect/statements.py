"""The one reader of the statements lakegate answers besides queries: SHOW, DESCRIBE, USE, SET /
RESET SESSION, PREPARE, DEALLOCATE PREPARE, START TRANSACTION / COMMIT / ROLLBACK and CALL.

`Reader` walks a statement token by token (sqlglot's Trino tokenizer, every statement read word by
word), reading names as Trino does (unquoted parts lower-cased) and reporting a syntax error with
the line and column of the token it did not expect. Which statement a text is comes from its first
words (`guard.first_words`, `guard.classify`); what each statement means is its answerer's (the
engine's sessions, planner and system tables).
"""

from __future__ import annotations

import re

from sqlglot.dialects.trino import Trino
from sqlglot.errors import TokenError
from sqlglot.tokens import Token, TokenType

from lakegate.dialect.errors import DialectError


class _Tokenizer(Trino.Tokenizer):
    COMMANDS: set = set()  # read every statement token by token (sqlglot keeps the rest of some as one string)


def like_pattern(pattern: str, escape: str | None = None) -> re.Pattern:
    """A LIKE pattern (`%`, `_`, with `escape` before a literal one) as a regular expression to fullmatch."""
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


class Reader:
    """The tokens of one statement (a trailing `;` dropped) and the position of the next one."""

    def __init__(self, sql: str):
        self.sql = sql
        try:
            tokens = _Tokenizer().tokenize(sql)
        except TokenError as error:
            raise DialectError(f"syntax error: {error}", error_name="SYNTAX_ERROR") from None
        while tokens and tokens[-1].token_type == TokenType.SEMICOLON:
            tokens.pop()
        self.tokens, self.pos = tokens, 0

    def skip_words(self, count: int) -> None:
        """Skip the tokens of the statement's first `count` words (a token may hold several)."""
        while count > 0 and self.peek() is not None:
            count -= len(self.peek().text.split())
            self.pos += 1

    def peek(self) -> Token | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def word(self) -> str:
        """The next token upper-cased ("" at the end or for a string literal)."""
        token = self.peek()
        return token.text.upper() if token is not None and token.token_type != TokenType.STRING else ""

    def take(self, *words: str) -> bool:
        if self.word() in words:
            self.pos += 1
            return True
        return False

    def expect(self, *words: str) -> None:
        if not self.take(*words):
            self.fail(" or ".join(words))

    def identifier(self) -> tuple[str, bool]:
        """One name: (text, quoted); unquoted names are lower-cased, as Trino does."""
        token = self.peek()
        if token is None or token.token_type in (TokenType.STRING, TokenType.DOT, TokenType.EQ, TokenType.COMMA):
            self.fail("a name")
        self.pos += 1
        quoted = token.token_type == TokenType.IDENTIFIER
        return (token.text if quoted else token.text.lower()), quoted

    def name(self) -> list[tuple[str, bool]]:
        """A dotted name: its parts as `identifier` reads them."""
        parts = [self.identifier()]
        while self.peek() is not None and self.peek().token_type == TokenType.DOT:
            self.pos += 1
            parts.append(self.identifier())
        return parts

    def parts(self) -> list[str]:
        """A dotted name's parts, without whether they were quoted."""
        return [text for text, _ in self.name()]

    def string(self) -> str:
        """A string literal's value."""
        token = self.peek()
        if token is None or token.token_type != TokenType.STRING:
            self.fail("a string literal")
        self.pos += 1
        return token.text

    def like(self) -> re.Pattern | None:
        """An optional `LIKE 'pattern' [ESCAPE 'c']`, as `like_pattern`."""
        if not self.take("LIKE"):
            return None
        pattern = self.string()
        return like_pattern(pattern, self.string() if self.take("ESCAPE") else None)

    def rest(self) -> str:
        """The text from the current token on (without a trailing `;`)."""
        token = self.peek()
        if token is None:
            self.fail("a statement")
        return self.sql[token.start : self.tokens[-1].end + 1]

    def end(self) -> None:
        if self.peek() is not None:
            self.fail("the end of the statement")

    def fail(self, expected: str) -> None:
        """Raise SYNTAX_ERROR at the next token."""
        token = self.peek()
        if token is None:
            line, column, found = None, None, "the end"
        else:
            line, column, found = token.line, max(1, token.col - len(token.text) + 1), f"'{token.text}'"
        raise DialectError(
            f"syntax error: expected {expected}, found {found}", line=line, column=column, error_name="SYNTAX_ERROR"
        )
