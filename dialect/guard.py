"""The read-only guard: only queries reach DuckDB.

`STATEMENTS` is the one table of statement kinds: a statement's first words -> its kind and how
running it as a query is refused. `examine_text` reads a raw text once, before parsing, for
`statements.read` (the one reader): its kind (`statement_kind`) and its refusal as a query
(encoding, size, nesting depth, statement kind, one statement only, a first word that starts no
Trino statement), which the statement's owner raises. `check_text` is that refusal for a caller
with text only (`translate(sql)`). `check` runs on the parsed Trino AST (no writes, no file or
DuckDB-internal functions, no table functions but UNNEST).
"""

from __future__ import annotations

import re
from typing import NamedTuple

from sqlglot import exp
from sqlglot.dialects.trino import Trino
from sqlglot.errors import TokenError
from sqlglot.tokens import TokenType

from lakegate.dialect import unparsed
from lakegate.dialect.errors import DialectError

#: Largest query text accepted, in UTF-8 bytes (Trino's default `query.max-length` is 1,000,000).
MAX_TEXT_BYTES = 1_000_000
#: Deepest nesting of brackets and CASE expressions accepted: sqlglot's recursive parser fails at
#: about 45 levels under Python's default recursion limit; up to 32 every construct parses and
#: translates in milliseconds (tests/dialect/test_limits.py).
MAX_NESTING = 32
#: Most tokens accepted in one query text: about 1 s to parse and translate (a 1 MB text can hold
#: 250,000 tokens, which would take sqlglot over 10 s).
MAX_TOKENS = 20_000

#: First words of statements that change something or reach outside the lake: refused by name.
_REFUSED_WORDS = {
    "INSERT",
    "UPDATE",
    "DELETE",
    "MERGE",
    "TRUNCATE",
    "CREATE",
    "DROP",
    "ALTER",
    "COMMENT",
    "GRANT",
    "REVOKE",
    "DENY",
    "ANALYZE",
    "VACUUM",
    "CHECKPOINT",
    "FORCE",
    "REFRESH",
    "COPY",
    "ATTACH",
    "DETACH",
    "INSTALL",
    "LOAD",
    "UNLOAD",
    "PRAGMA",
    "EXPORT",
    "IMPORT",
    "SET",
    "RESET",
    "BEGIN",
    "END",
    "ABORT",
    "SUMMARIZE",
    "PIVOT",
    "UNPIVOT",
    "FROM",
}
#: The one table of statement kinds: a statement's name (its first word, or first two or three) ->
#: its kind (one of `statements.KINDS`, each with its one owner) and how running its text as a query
#: is refused: "session" (NOT_SUPPORTED: a session statement, the server's to answer), "denied"
#: (PERMISSION_DENIED: not read-only), None (it runs). The longest name matching the first two words
#: wins; EXPLAIN of anything but a query is refused by the explained statement's name; a first word
#: not here starts no statement lakegate knows (Trino's SYNTAX_ERROR at it, unless Trino's grammar
#: starts a statement with it: `_STATEMENT_STARTS`).
STATEMENTS: dict[str, tuple[str, str | None]] = {
    **dict.fromkeys(("SELECT", "WITH", "VALUES", "TABLE"), ("query", None)),
    "SHOW": ("show", None),
    "DESCRIBE": ("describe", None),  # DESCRIBE INPUT / OUTPUT of a prepared statement: "describe_prepared"
    "DESC": ("describe", None),
    "EXPLAIN": ("explain", None),
    **dict.fromkeys(
        (
            "USE",
            "SET SESSION",
            "RESET SESSION",
            "SET TIME ZONE",
            "PREPARE",
            "DEALLOCATE PREPARE",
            "START TRANSACTION",
            "COMMIT",
            "ROLLBACK",
        ),
        ("session", "session"),
    ),
    "EXECUTE": ("execute", "session"),
    **dict.fromkeys(("SET PATH", "SET ROLE", "DEALLOCATE"), ("other", "session")),  # session statements not answered
    "CALL": ("call", "denied"),
    **dict.fromkeys(sorted(_REFUSED_WORDS), ("other", "denied")),
}
#: The names of `STATEMENTS` by their first two words.
_BY_WORDS = {tuple(name.split()[:2]): name for name in STATEMENTS}
#: The words a Trino 476 statement may start with, in the order its parser lists them when another
#: word starts one (a query may also start with SELECT, VALUES, TABLE or a parenthesis).
_STATEMENT_STARTS = (
    "ALTER ANALYZE CALL COMMENT COMMIT CREATE DEALLOCATE DELETE DENY DESC DESCRIBE DROP EXECUTE EXPLAIN GRANT "
    "INSERT MERGE PREPARE REFRESH RESET REVOKE ROLLBACK SET SHOW START TRUNCATE UPDATE USE WITH"
).split()

#: Second words that belong to a statement's name in messages (CREATE TABLE, SET SESSION, ...).
_NAME_WORDS = {
    "TABLE",
    "VIEW",
    "SCHEMA",
    "DATABASE",
    "MACRO",
    "FUNCTION",
    "SEQUENCE",
    "INDEX",
    "TYPE",
    "SECRET",
    "MATERIALIZED",
    "OR",
    "TEMP",
    "TEMPORARY",
    "ROLE",
    "SESSION",
    "TRANSACTION",
    "TIME",
    "PATH",
    "CHECKPOINT",
    "TABLES",
    "SCHEMAS",
    "CATALOGS",
    "COLUMNS",
    "FUNCTIONS",
    "STATS",
    "GRANTS",
    "INPUT",
    "OUTPUT",
    "IMMEDIATE",
    "PREPARE",
    "VARIABLE",
    "EXTENSIONS",
}

#: Statement node types that are never a query.
_STATEMENT_NODES = tuple(
    getattr(exp, name)
    for name in (
        "Insert",
        "Update",
        "Delete",
        "Merge",
        "Create",
        "Drop",
        "Alter",
        "Copy",
        "Command",
        "Set",
        "Pragma",
        "Use",
        "Transaction",
        "Commit",
        "Rollback",
        "Attach",
        "Detach",
        "Install",
        "LoadData",
        "Export",
        "Into",
        "Grant",
        "Revoke",
        "TruncateTable",
        "Analyze",
        "Summarize",
        "Refresh",
        "Comment",
        "Cache",
        "Uncache",
        "Declare",
    )
    if hasattr(exp, name)
)

#: DuckDB functions that read files, run SQL, or expose settings and internals; refused anywhere.
_DENIED_FUNCTIONS = {
    "glob",
    "sniff_csv",
    "query",
    "query_table",
    "getenv",
    "current_setting",
    "getvariable",
    "set_variable",
    "which_secret",
    "load_aws_credentials",
    "json_execute_serialized_sql",
    "json_serialize_sql",
    "json_deserialize_sql",
    "json_serialize_plan",
    "checkpoint",
    "force_checkpoint",
    "enable_logging",
    "disable_logging",
    "truncate_duckdb_logs",
    "sql_auto_complete",
    "test_all_types",
    "summary",
    "st_read",
}
_DENIED_PREFIXES = (
    "read_",
    "parquet_",
    "duckdb_",
    "pragma_",
    "sqlite_",
    "postgres_",
    "mysql_",
    "iceberg_",
    "delta_",
    "ducklake_",
    "arrow_scan",
    "pandas_",
    "python_",
)

#: One lexeme of a query text: blanks, a comment, a string, a quoted name, a word, a number, any other character.
_LEXEME = re.compile(r"""\s+|--[^\n]*|/\*.*?(?:\*/|\Z)|'(?:[^']|'')*'?|"(?:[^"]|"")*"?|\w+|.""", re.S)
_SKIP = re.compile(r"(?:\s+|--[^\n]*(?:\n|$)|/\*.*?\*/|\()*", re.S)
_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_EXPLAIN_OPTIONS = re.compile(r"\s*\(\s*(?:TYPE|FORMAT)\b[^)]*\)", re.I)


def _where(sql: str, offset: int) -> tuple[int, int]:
    """1-based line and column of a character offset in `sql`."""
    line = sql.count("\n", 0, offset) + 1
    return line, offset - (sql.rfind("\n", 0, offset) + 1) + 1


def _node_where(node: exp.Expression) -> tuple[int | None, int | None]:
    """Line and column where a parsed node starts, from the first position sqlglot recorded in it."""
    for child in node.walk(bfs=False):
        meta = child.meta if child._meta else None
        if meta and "line" in meta and "col" in meta:
            width = meta.get("end", 0) - meta.get("start", 0)
            return meta["line"], max(1, meta["col"] - width)
    return None, None


def _words(sql: str, offset: int, count: int) -> list[tuple[str, int]]:
    """Up to `count` leading words from `offset`, skipping blanks, comments and opening parentheses."""
    words = []
    while len(words) < count:
        offset = _SKIP.match(sql, offset).end()
        match = _WORD.match(sql, offset)
        if not match:
            break
        words.append((match.group().upper(), match.start()))
        offset = match.end()
    return words


class Kind(NamedTuple):
    """A statement's kind as the table of statement kinds (`STATEMENTS`) gives it."""

    kind: str  # one of statements.KINDS
    name: str  # the statement's name as its owner reads it (USE, SET TIME ZONE, SHOW TABLES, ...)
    start: int  # the offset of its first word
    refused: str | None  # how running it as a query is refused: "session", "denied", "syntax", or None
    said: str  # its name in refusal messages (the first word, and the second when it names the statement)


def statement_kind(sql: str, offset: int = 0) -> Kind:
    """The kind of the statement starting at `offset`, from its first words (blanks, comments and
    opening parentheses skipped) and the one table of statement kinds, `STATEMENTS`."""
    words = _words(sql, offset, 2)
    if not words:
        return Kind("other", "", offset, "syntax", "")
    first, start = words[0]
    second = words[1][0] if len(words) > 1 else ""
    said = f"{first} {second}" if second in _NAME_WORDS else first
    said = "SET TIME ZONE" if said == "SET TIME" else said
    key = _BY_WORDS.get((first, second)) or _BY_WORDS.get((first,))
    if key is None:
        return Kind("other", said, start, "syntax", said)
    if key == "EXPLAIN":
        rest, _ = _explain_parts(sql, start)
        inner = statement_kind(sql, rest)
        if inner.kind != "query":
            said = f"EXPLAIN {inner.said}".strip()
            return Kind("other", said, inner.start, "denied", said)
    kind, refused = STATEMENTS[key]
    said = first if kind in ("query", "explain") else said
    return Kind(kind, key if kind in ("session", "execute") else said, start, refused, said)


def _explain_parts(sql: str, start: int) -> tuple[int, bool]:
    """For `EXPLAIN [ANALYZE] [VERBOSE] [(options)] statement` at `start`: where the statement
    begins and whether it is EXPLAIN ANALYZE."""
    rest, analyze = start + len("EXPLAIN"), False
    for word, at in _words(sql, rest, 2):
        if word not in ("ANALYZE", "VERBOSE"):
            break
        analyze |= word == "ANALYZE"
        rest = at + len(word)
    options = _EXPLAIN_OPTIONS.match(sql, rest)
    return (options.end() if options else rest), analyze


def explained_query(sql: str, start: int | None = None) -> tuple[str, bool]:
    """For an EXPLAIN statement (its first word at `start`, if the caller read it): the text of the
    query it explains and whether it is EXPLAIN ANALYZE."""
    if start is None:
        kind, _, start, _, _ = statement_kind(sql)
        if kind != "explain":
            raise DialectError("not an EXPLAIN of a query", error_name="GENERIC_USER_ERROR")
    rest, analyze = _explain_parts(sql, start)
    return sql[rest:].strip(), analyze


def _refuse_statement(refused: str, name: str, sql: str, start: int) -> None:
    """Refuse statement `name` at `start` of `sql`: "session" (a session statement) or "denied" (not read-only)."""
    line, column = _where(sql, start)
    if refused == "session":
        raise DialectError(
            f"{name} is a session statement, handled by the server, not a query",
            line=line,
            column=column,
            error_name="NOT_SUPPORTED",
        )
    raise DialectError(
        f"Access Denied: {name} statements are not allowed: lakegate serves the lake read-only "
        "and runs queries only (SELECT, WITH, VALUES, SHOW, DESCRIBE, EXPLAIN)",
        line=line,
        column=column,
        error_name="PERMISSION_DENIED",
    )


def _check_size(sql: str) -> None:
    """Refuse more than MAX_TOKENS tokens (comments count) or brackets and CASE nested deeper than MAX_NESTING, by
    one linear scan of the lexemes, before sqlglot's recursive parser sees the text."""
    depth = tokens = 0
    for lexeme in _LEXEME.finditer(sql):
        text = lexeme.group()
        if text[0].isspace():
            continue
        tokens += 1
        word = text.upper()
        if text in "([" or word == "CASE":
            depth += 1
        elif (text in ")]" or word == "END") and depth:
            depth -= 1
        if depth > MAX_NESTING or tokens > MAX_TOKENS:
            line, column = _where(sql, lexeme.start())
            if tokens > MAX_TOKENS:
                raise DialectError(
                    f"Query text has more than {MAX_TOKENS} tokens (lakegate's limit)",
                    line=line,
                    column=column,
                    error_name="QUERY_TEXT_TOO_LARGE",
                )
            raise DialectError(
                f"statement is too large (stack overflow while parsing): brackets and CASE "
                f"nested more than {MAX_NESTING} levels deep (lakegate's limit)",
                line=line,
                column=column,
                error_name="SYNTAX_ERROR",
            )


def _refuse_no_statement(sql: str) -> None:
    """Trino's SYNTAX_ERROR for a text that does not start with a statement's keyword: its first
    token, or '<EOF>' for a text of blanks and comments."""
    first = next(
        (
            lexeme
            for lexeme in _LEXEME.finditer(sql)
            if not lexeme.group()[0].isspace()
            and not lexeme.group().startswith("--")
            and not (lexeme.group().startswith("/*") and lexeme.group().endswith("*/") and len(lexeme.group()) > 3)
        ),
        None,
    )
    line, column = _where(sql, first.start() if first else len(sql))
    token = first.group() if first else "<EOF>"
    if token.startswith("/*") or token[0] in "'\"" and token.count(token[0]) % 2:
        token = token[0]  # an unterminated comment, string or identifier: Trino stops at its first character
    raise DialectError(
        f"mismatched input '{token}'. Expecting: a query (SELECT, WITH, VALUES, TABLE), SHOW, DESCRIBE or EXPLAIN",
        line=line,
        column=column,
        error_name="SYNTAX_ERROR",
    )


def _check_single_statement(sql: str) -> None:
    if ";" not in sql.rstrip().rstrip(";"):
        return
    try:
        tokens = Trino().tokenize(sql)
    except TokenError:
        return  # the parser reports the syntax error with its position
    for token, following in zip(tokens, tokens[1:]):
        if token.token_type == TokenType.SEMICOLON and following.token_type != TokenType.SEMICOLON:
            line, column = following.line, max(1, following.col - len(following.text) + 1)
            raise DialectError(
                "Access Denied: multiple statements in one query text are not allowed",
                line=line,
                column=column,
                error_name="PERMISSION_DENIED",
            )


def decoded(sql: str | bytes) -> str:
    """A query text as `str`: bytes are decoded as UTF-8 (SYNTAX_ERROR at the first bad byte)."""
    if not isinstance(sql, (bytes, bytearray)):
        return sql
    try:
        return bytes(sql).decode("utf-8")
    except UnicodeDecodeError as error:
        good = bytes(sql[: error.start]).decode("utf-8")
        line, column = _where(good, len(good))
        raise DialectError(
            f"the query text is not valid UTF-8 (byte {error.start})",
            line=line,
            column=column,
            error_name="SYNTAX_ERROR",
        ) from None


def _check_text_size(sql: str) -> None:
    """Refuse lone surrogates, texts over MAX_TEXT_BYTES or MAX_TOKENS, NUL characters and brackets and CASE
    nested deeper than MAX_NESTING."""
    try:
        size = len(sql.encode("utf-8"))
    except UnicodeEncodeError as error:
        line, column = _where(sql, error.start)
        raise DialectError(
            "the query text is not valid Unicode (a lone surrogate character)",
            line=line,
            column=column,
            error_name="SYNTAX_ERROR",
        ) from None
    if size > MAX_TEXT_BYTES:
        raise DialectError(
            f"Query text length ({size}) exceeds the maximum length ({MAX_TEXT_BYTES})",
            error_name="QUERY_TEXT_TOO_LARGE",
        )
    nul = sql.find("\x00")
    if nul >= 0:
        line, column = _where(sql, nul)
        raise DialectError(
            "the query text contains a NUL character", line=line, column=column, error_name="SYNTAX_ERROR"
        )
    _check_size(sql)


def _refuse_unknown_statement(sql: str, word: str, start: int) -> None:
    """Trino's SYNTAX_ERROR for a statement whose first word (`word` at `start`, as the table of kinds read
    it) starts no Trino statement: the message names the token Trino's parser stops at, and what it
    expected there (after an opening parenthesis, a query)."""
    try:
        tokens = Trino().tokenize(sql)
    except TokenError:
        tokens = []
    first = next((token for token in tokens if token.token_type != TokenType.L_PAREN), None)
    if first is not None:
        word, start = first.text, first.start
    if word.upper() in (*_STATEMENT_STARTS, "SELECT", "VALUES", "TABLE"):
        return
    line, column = _where(sql, start)
    opened = bool(tokens) and tokens[0].token_type == TokenType.L_PAREN
    expecting = (
        "'(', 'SELECT', 'TABLE', 'VALUES'" if opened else ", ".join(f"'{w}'" for w in _STATEMENT_STARTS) + ", <query>"
    )
    raise DialectError(
        f"mismatched input '{word}'. Expecting: {expecting}",
        line=line,
        column=column,
        error_name="SYNTAX_ERROR",
    )


def _refuse(sql: str, kind: Kind) -> None:
    """Refuse, in Trino's terms, a text of `kind` (as `statement_kind` read it) run as a query."""
    _check_text_size(sql)
    if not kind.said:
        _refuse_no_statement(sql)
    if kind.kind == "other" and kind.said == "FROM":
        line, column = _where(sql, kind.start)
        raise DialectError(
            "syntax error: a query starts with SELECT, WITH, VALUES or TABLE, not FROM",
            line=line,
            column=column,
            error_name="SYNTAX_ERROR",
        )
    if kind.refused in ("session", "denied"):
        _refuse_statement(kind.refused, kind.said, sql, kind.start)
    _check_single_statement(sql)
    if kind.refused == "syntax":
        _refuse_unknown_statement(sql, sql[kind.start : kind.start + len(kind.said.split()[0])], kind.start)


def examine_text(sql: str) -> tuple[Kind, DialectError | None]:
    """One reading of a statement text: its kind from the table of statement kinds (`statement_kind`)
    and the refusal of running it as a query (None: it may run).

    The refusal covers lone surrogates, texts over MAX_TEXT_BYTES or MAX_TOKENS, NUL characters,
    brackets and CASE nested deeper than MAX_NESTING, more than one statement, and every statement that
    is not a query (SHOW, DESCRIBE and EXPLAIN of a query pass; session statements get NOT_SUPPORTED,
    writes, CALL and the rest PERMISSION_DENIED; a text with no statement's first word, or a first
    word that starts no Trino statement, SYNTAX_ERROR).
    """
    kind = statement_kind(sql)
    try:
        _refuse(sql, kind)
    except DialectError as error:
        return kind, error
    return kind, None


def check_text(sql: str | bytes) -> str:
    """Check a query text before parsing (`examine_text`'s refusal raised) and return it as `str`; for a
    caller that has only the text (`statements.read` reads it once for everyone else)."""
    sql = decoded(sql)
    _, refusal = examine_text(sql)
    if refusal is not None:
        raise refusal
    return sql


def _function_name(node: exp.Expression) -> str:
    if isinstance(node, exp.Anonymous):
        return str(node.name).lower()
    return node.sql_name().lower() if isinstance(node, exp.Func) else ""


#: Trino's words for syntax that sqlglot parses into nodes named otherwise.
_TRINO_SYNTAX = {
    exp.HexString: "binary literal X'...' (varbinary)",
    exp.ByteString: "binary literal X'...' (varbinary)",
    exp.UnicodeString: "Unicode string literal U&'...'",
    exp.JSONValue: "function 'json_value'",
    exp.GroupingSets: "GROUPING SETS",
    exp.Aliases: "row_expression.* AS (column_alias, ...)",
}
#: Trino's comparison operators, by the sqlglot node that parses them.
COMPARISON_OPERATORS = {
    exp.EQ: "=",
    exp.NEQ: "<>",
    exp.GT: ">",
    exp.GTE: ">=",
    exp.LT: "<",
    exp.LTE: "<=",
    exp.NullSafeEQ: "IS NOT DISTINCT FROM",
    exp.NullSafeNEQ: "IS DISTINCT FROM",
}
_LEADING_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def trino_name(node: exp.Expression) -> str:
    """What Trino calls the construct `node` ("function 'json_object'", "JSON literal", ...), never
    sqlglot's class name: a function is named as sqlglot's Trino writer spells it."""
    if isinstance(node, exp.ParseJSON) and node.args.get("is_literal"):
        return "JSON literal"
    if type(node) in _TRINO_SYNTAX:
        return _TRINO_SYNTAX[type(node)]
    if isinstance(node, exp.Anonymous):
        return f"function '{str(node.name).lower()}'"
    if isinstance(node, exp.Func):
        name = _LEADING_NAME.match(node.sql(dialect="trino"))
        return f"function '{(name.group() if name else node.sql_name()).lower()}'"
    return f"syntax {node.key.upper()}"


def _denied(name: str) -> bool:
    return name in _DENIED_FUNCTIONS or name.startswith(_DENIED_PREFIXES)


def _fail(message: str, node: exp.Expression, error_name: str = "PERMISSION_DENIED") -> None:
    line, column = _node_where(node)
    raise DialectError(message, line=line, column=column, error_name=error_name)


#: Statement nodes of session statements (their refusal is NOT_SUPPORTED, as the table of kinds says).
_SESSION_NODES = (exp.Use, exp.Transaction, exp.Commit, exp.Rollback)


def refuse_statement_tree(tree: exp.Expression) -> None:
    """Refuse a parsed statement that is not a query, named by its node (WITH ... INSERT: INSERT); SHOW,
    DESCRIBE and EXPLAIN pass (they are not queries, but read-only). A statement sqlglot keeps as text
    (`exp.Command`) is named by that text's first words, as the table of kinds names it."""
    if isinstance(tree, (exp.Describe, exp.Show)):
        return
    if isinstance(tree, exp.Command):
        kind = statement_kind(tree.sql(dialect="trino"))
        if kind.kind in ("show", "describe", "explain") or not kind.said:
            return
        name, refused = kind.said, kind.refused
    else:
        session = isinstance(tree, _SESSION_NODES) or (
            isinstance(tree, exp.Set) and any(item.text("kind").upper() == "SESSION" for item in tree.expressions)
        )
        name, refused = tree.key.upper(), "session" if session else "denied"
    _refuse_statement("session" if refused == "session" else "denied", name, "", 0)


def check(expression: exp.Expression) -> None:
    """Refuse a parsed statement unless it is a read-only query over tables, UNNEST and Trino functions.

    Refused: any statement that is not SELECT / WITH / VALUES / set operation (writes, DDL, COPY,
    ATTACH, SET, PRAGMA, ... by name), DuckDB's file, SQL-running and internals functions
    (read_csv, read_parquet, glob, query, getenv, duckdb_settings, ...) anywhere in the query, and
    every table function except UNNEST (`FROM read_csv('x')`, `FROM TABLE(...)`).
    """
    if not isinstance(expression, (exp.Query, exp.Values)):
        refuse_statement_tree(expression)
        return
    for node in expression.walk():
        if isinstance(node, _STATEMENT_NODES):
            _fail(f"Access Denied: {node.key.upper()} is not allowed inside a query", node)
        elif isinstance(node, (exp.Table, exp.Lateral)):
            source = node.this
            if isinstance(source, exp.JSONTable):
                _fail(f"unsupported in lakegate: {unparsed.JSON_TABLE}", source, "NOT_SUPPORTED")
            if isinstance(source, exp.Func) and not isinstance(source, exp.Unnest):
                name = _function_name(source)
                label = "TABLE(...)" if name == "table" else f"'{name}'"
                _fail(
                    f"Access Denied: table function {label} is not allowed (only UNNEST and tables of the lake)", source
                )
            if isinstance(node, exp.Table) and any(sep in node.name for sep in "/\\"):
                _fail(f"Access Denied: reading files is not allowed: '{node.name}'", node)
        elif isinstance(node, exp.Func):
            name = _function_name(node)
            if _denied(name):
                _fail(f"Access Denied: function '{name}' is not allowed (it reads files or DuckDB internals)", node)
