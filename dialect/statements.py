"""The one reader of statements: each statement text is read once into a `Statement` (its kind,
its text and, for a query or EXPLAIN, its parsed tree), which every later step is handed.

`read(sql)` reads the text once (`guard.examine_text`): its kind comes from the statement's first
words and the one table of statement kinds (`guard.STATEMENTS`), each kind with the one owner that
answers it (`KINDS`), and the refusal of running the text as a query (size, nesting, writes,
unknown statements) is kept for that owner to raise (`Statement.check`); nothing reads the text
for its kind or checks it again.

`Reader` walks the non-query statements (SHOW, DESCRIBE, USE, SET / RESET SESSION,
PREPARE, DEALLOCATE PREPARE, START TRANSACTION / COMMIT / ROLLBACK, CALL) token by token (sqlglot's
Trino tokenizer, every statement read word by word), reading names as Trino does (unquoted parts
lower-cased) and reporting a syntax error with the line and column of the token it did not expect.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from functools import lru_cache

from sqlglot import exp
from sqlglot.dialects.trino import Trino
from sqlglot.errors import TokenError
from sqlglot.tokens import Token, TokenType

from lakegate.dialect import guard
from lakegate.dialect.errors import DialectError
from lakegate.dialect.translate import parse

#: Every kind of statement `read` gives, and the one owner that answers it.
KINDS = {
    "query": "the backend: translated to DuckDB (or forwarded to a Trino cluster)",
    "explain": "the backend: the plan of the query it explains",
    "show": "the engine's system tables (SystemCatalog.show)",
    "describe": "the engine's system tables (SystemCatalog.show)",
    "describe_prepared": "the planner: DESCRIBE INPUT / OUTPUT of a prepared statement",
    "execute": "the planner: EXECUTE / EXECUTE IMMEDIATE, the prepared statement with its values",
    "session": "the engine's sessions (session.answer): USE, SET / RESET SESSION, PREPARE, COMMIT, ...",
    "call": "the server's queries (CALL system.runtime.kill_query)",
    "other": "nobody: refused in Trino's terms (writes, DDL, SET ROLE, unknown statements)",
}


@dataclass(frozen=True, eq=False)
class Statement:
    """One statement as read once: its text, its kind (one of `KINDS`), its name as Trino's messages
    say it, and for a query or EXPLAIN the query text (`body`, at `offset` of `text`) and its tree.

    `tree` is parsed on first use and shared by every reader of the same text: change a copy
    (`Statement.rewritten` holds a changed tree). `edits` say how the changed tree differs from
    `text` as same-length text edits, for a backend that sends text (the forwarding backend).
    """

    text: str
    kind: str
    name: str
    body: str
    offset: int = 0
    analyze: bool = False  # EXPLAIN ANALYZE
    planned: exp.Expression | None = None
    edits: tuple[tuple[int, int, str], ...] = ()
    refusal: DialectError | None = None

    def check(self) -> None:
        """Raise the refusal of running this text as a query, decided when it was read (`guard.examine_text`):
        too large or too deep, more than one statement, a write or another statement that is not a query."""
        if self.refusal is not None:
            refusal = self.refusal
            raise DialectError(refusal.message, line=refusal.line, column=refusal.column, error_name=refusal.error_name)

    @property
    def tree(self) -> exp.Expression:
        """The parse of `body` (or the rewritten tree); DialectError positioned in `text`."""
        if self.planned is not None:
            return self.planned
        if self.edits:
            raise RuntimeError("a statement's edits must be applied to its tree before it is read")
        try:
            return parsed(self.body)
        except DialectError as error:
            raise shifted(error, self.text, self.offset) from None

    def rewritten(self, tree: exp.Expression, edits: tuple[tuple[int, int, str], ...]) -> Statement:
        """This statement with `tree` (a changed copy of `tree`) and the text `edits` that make it."""
        return replace(self, planned=tree, edits=edits)

    def with_edits(self, edits: tuple[tuple[int, int, str], ...]) -> Statement:
        """This statement with text `edits` whose tree is not made yet (the process that parses the
        text applies them: `planner.with_edits_applied`)."""
        return replace(self, edits=edits)

    @property
    def is_rewritten(self) -> bool:
        return self.planned is not None

    def edited_text(self) -> str:
        """`text` with `edits` applied (same length and line breaks)."""
        text = self.text
        for start, end, replacement in sorted(self.edits, reverse=True):
            text = text[:start] + replacement + text[end:]
        return text


@lru_cache(maxsize=512)
def parsed(text: str) -> exp.Expression:
    """The parse of one query text, shared by every reader of the same text (do not change it); a
    statement that is not a query behind a query's first words (WITH ... INSERT) is refused by its name."""
    tree = parse(text)
    if not isinstance(tree, (exp.Query, exp.Values)):
        guard.refuse_statement_tree(tree)
    return tree


def read(sql: str | bytes) -> Statement:
    """Read one statement text, once: its kind (one of `KINDS`, from the table of statement kinds,
    `guard.STATEMENTS`), name and refusal as a query (`Statement.check`); the tree is parsed when
    asked. Bytes are decoded (SYNTAX_ERROR if not UTF-8)."""
    sql = guard.decoded(sql)
    (kind, name, start, _, _), refusal = guard.examine_text(sql)
    body, offset, analyze = sql, 0, False
    if kind == "describe" and name.split()[1:] in (["INPUT"], ["OUTPUT"]) and _names_prepared(sql):
        kind = "describe_prepared"
    elif kind == "explain":
        body, analyze = guard.explained_query(sql, start)
        offset = sql.rfind(body)
    return Statement(sql, kind, name, body, offset, analyze, refusal=refusal)


def _names_prepared(sql: str) -> bool:
    """Whether `DESCRIBE INPUT|OUTPUT x` names a prepared statement (not a table called input or output)."""
    try:
        reader = Reader(sql)
    except DialectError:
        return True  # the planner reports the syntax error
    reader.skip_words(2)
    return len(reader.tokens) == reader.pos + 1


def shifted(error: DialectError, sql: str, offset: int) -> DialectError:
    """`error` (positioned in the text at `offset` of `sql`) positioned in `sql`."""
    if error.line is None or error.column is None or offset == 0:
        return error
    line0 = sql.count("\n", 0, offset) + 1
    column0 = offset - (sql.rfind("\n", 0, offset) + 1) + 1
    column = error.column + (column0 - 1 if error.line == 1 else 0)
    return DialectError(error.message, line=error.line + line0 - 1, column=column, error_name=error.error_name)


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
        escape = self.string() if self.take("ESCAPE") else None
        if escape is not None and len(escape) != 1:
            raise DialectError("Escape string must be a single character", error_name="INVALID_FUNCTION_ARGUMENT")
        return like_pattern(pattern, escape)

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
