"""The dialect layer's entry point: one Trino-dialect SQL text in, one DuckDB SQL text out (or a
DialectError naming the construct and its position), cached.

Pipeline: text checks -> parse (sqlglot, Trino) -> one statement -> read-only guard -> scope
rewrite -> `?` parameters -> Trino SQL for forwarding -> name resolution and Trino type inference
(`analyze`) -> DuckDB SQL by the named transforms (`transforms`).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from sqlglot import exp
from sqlglot.dialects.trino import Trino
from sqlglot.errors import ParseError, TokenError
from sqlglot.tokens import TokenType

from lakegate.dialect import guard, session_functions, syntax_errors, write_casts, write_operators
from lakegate.dialect import params as parameters
from lakegate.dialect import scope as scoping
from lakegate.dialect import trino_types as tt
from lakegate.dialect.analyze import analyze
from lakegate.dialect.errors import DialectError
from lakegate.dialect.functions import pages
from lakegate.dialect.transforms import Writer
from lakegate.dialect.tree_rewrites import finalize, hoist_derived_order
from lakegate.dialect.unparsed import unparsed_construct

if TYPE_CHECKING:
    from lakegate.dialect.scope import Scope

pages.install()  # the function registry, from the one list of function modules
#: The modules whose named transforms (`transforms.transform`) the Writer uses beside its own.
WRITERS = (write_operators, write_casts)

#: Number of translations kept in the cache.
CACHE_SIZE = 1024


@dataclass(frozen=True)
class Translation:
    """One translated query."""

    duckdb_sql: str  # one DuckDB statement
    trino_sql: str  # the scoped, parameter-bound query in Trino dialect
    columns: tuple[tuple[str, str], ...]  # output (name, Trino type name)
    zones: tuple[str | None, ...] = ()  # per output column, the zone its timestamp with time zone values carry


class _Parser(Trino.Parser):
    # Every `name(...)` call parses as a plain function call, so that the registry in
    # dialect/functions/ decides what each Trino function means (sqlglot's own function classes would
    # carry other dialects' semantics into the translation).
    # grouping(...) is not a function but the GROUPING operation, checked against the GROUP BY keys.
    FUNCTIONS: dict = {"GROUPING": lambda args: exp.Grouping(expressions=args)}
    # Keep only the special call syntaxes Trino has (CAST(x AS t), EXTRACT(f FROM x), ...).
    FUNCTION_PARSERS = {
        name: parser
        for name, parser in Trino.Parser.FUNCTION_PARSERS.items()
        if name
        in (
            "CAST",
            "TRY_CAST",
            "EXTRACT",
            "POSITION",
            "SUBSTRING",
            "TRIM",
            "LISTAGG",
            "JSON_QUERY",
            "JSON_VALUE",
            "JSON_TABLE",
        )
    }

    def raise_error(self, message: str, token=None) -> None:
        """sqlglot's raise_error, with the offending token (None: the end of the text) recorded for
        syntax_errors.parse_error."""
        # sqlglot names the token before the one it stopped at when it says what should follow it
        offending = self._curr if not token or token is self._prev else token
        try:
            super().raise_error(message, token) if token else super().raise_error(message)
        except ParseError as error:
            raise syntax_errors.mark(error, self.sql, offending) from None
        if self.errors:
            syntax_errors.mark(self.errors[-1], self.sql, offending)

    FUNCTION_PARSERS["NORMALIZE"] = lambda self: self._parse_normalize()
    FUNCTION_PARSERS["JSON_QUERY"] = lambda self: self._parse_sql_json(exp.JSONExtract)
    FUNCTION_PARSERS["JSON_VALUE"] = lambda self: self._parse_sql_json(exp.JSONValue)
    FUNCTION_PARSERS["JSON_EXISTS"] = lambda self: self._parse_sql_json(None)
    FUNCTION_PARSERS["JSON_ARRAY"] = lambda self: self._parse_json_array()
    FUNCTION_PARSERS["JSON_OBJECT"] = lambda self: self._parse_json_object()
    # SqlBase.g4 #jsonQuery: [ARRAY] after CONDITIONAL too (sqlglot spells it WRAPPED)
    JSON_QUERY_OPTIONS = {
        key: ("WRAPPER", ("ARRAY", "WRAPPER"), ("CONDITIONAL", "WRAPPER"), ("CONDITIONAL", "ARRAY", "WRAPPER"))
        + (("UNCONDITIONAL", "WRAPPER"), ("UNCONDITIONAL", "ARRAY", "WRAPPER"))
        for key in ("WITH", "WITHOUT")
    }

    def _parse_on_handling(self, on: str, *values: str):
        # SqlBase.g4 #emptyBehavior / #jsonQueryBehavior: EMPTY ARRAY and EMPTY OBJECT are two words
        for value in ("EMPTY ARRAY", "EMPTY OBJECT") if "EMPTY" in values else ():
            if self._match_text_seq(*value.split(), "ON", on):
                return f"{value} ON {on}"
        return super()._parse_on_handling(on, *values)

    def _parse_passing(self) -> list:
        # PASSING value [FORMAT JSON [ENCODING e]] AS name, ... (SqlBase.g4 #jsonPathInvocation)
        if not self._match_text_seq("PASSING"):
            return []

        def argument():
            value = self._parse_format_json(self._parse_bitwise())
            if self._match_text_seq("ENCODING"):
                self._parse_var()
            self._match(TokenType.ALIAS)
            return exp.alias_(value, self._parse_id_var(any_token=False) or "")

        return self._parse_csv(argument)

    def _parse_sql_json(self, kind):
        """json_query / json_value / json_exists with Trino's clauses (SqlBase.g4 #jsonQuery,
        #jsonValue, #jsonExists); json_exists is a plain call, its ON ERROR behaviour in meta."""
        this = self._parse_bitwise()  # FORMAT JSON is how a string input is read anyway
        encoding = self._match_text_seq("FORMAT", "JSON") and self._match_text_seq("ENCODING") and self._parse_var()
        if not self._match(TokenType.COMMA):  # the path is required (SqlBase.g4 #jsonPathInvocation)
            self.raise_error(f"mismatched input '{self._curr.text if self._curr else '<EOF>'}'. Expecting: ','")
        path = self._parse_bitwise()
        passing = self._parse_passing()
        if kind is None:
            node = exp.Anonymous(this="json_exists", expressions=[this, path])
            for value in ("TRUE", "FALSE", "UNKNOWN", "ERROR"):
                if self._match_text_seq(value, "ON", "ERROR"):
                    node.meta["on_error"] = value
        elif kind is exp.JSONValue:
            returning = self._match(TokenType.RETURNING) and self._parse_types()
            node = exp.JSONValue(this=this, path=path, returning=returning, on_condition=self._parse_on_condition())
        else:
            returning = self._match(TokenType.RETURNING) and self._parse_format_json(self._parse_types())
            node = exp.JSONExtract(
                this=this,
                expression=path,
                option=self._parse_var_from_options(self.JSON_QUERY_OPTIONS, raise_unmatched=False),
                json_query=True,
                quote=self._parse_json_query_quote(),
                on_condition=self._parse_on_condition(),
            )
            node.set("returning", returning or None)
        for clause, value in (("passing", passing and exp.Tuple(expressions=passing)), ("encoding", encoding)):
            if value:
                node.meta[clause] = True
                if kind is not None:
                    node.set(clause, value)  # refused by the analyzer, naming the clause
        return node

    def _parse_json_array(self) -> exp.Expression:
        # JSON_ARRAY([value [FORMAT JSON], ... [NULL | ABSENT ON NULL]] [RETURNING type [FORMAT JSON]])
        # (SqlBase.g4 #jsonArray); the clauses are kept in meta, the elements as plain arguments.
        values = [] if self._curr.token_type == TokenType.R_PAREN else self._parse_csv(self._parse_json_element)
        node = exp.Anonymous(this="json_array", expressions=values)
        for value in ("NULL", "ABSENT"):
            if self._match_text_seq(value, "ON", "NULL"):
                node.meta["null"] = value
        return self._parse_json_returning(node)

    def _parse_json_object(self) -> exp.Expression:
        # JSON_OBJECT([member, ... [NULL | ABSENT ON NULL] [WITH | WITHOUT UNIQUE [KEYS]]] [RETURNING type
        # [FORMAT JSON]]) (SqlBase.g4 #jsonObject; a member is `[KEY] key VALUE value` or `key : value`):
        # the keys and values alternate as plain arguments, the clauses are kept in meta.
        args = []
        while args or self._curr.token_type not in (TokenType.R_PAREN, TokenType.RETURNING):
            self._match_text_seq("KEY")
            key = self._parse_bitwise()
            if not (self._match(TokenType.COLON) or self._match_text_seq("VALUE")):
                self.raise_error("mismatched input. Expecting: ':', 'VALUE'")
            args += [key, self._parse_json_element()]
            if not self._match(TokenType.COMMA):
                break
        node = exp.Anonymous(this="json_object", expressions=args)
        for value in ("NULL", "ABSENT"):
            if self._match_text_seq(value, "ON", "NULL"):
                node.meta["null"] = value
        for value in ("WITH", "WITHOUT"):
            if self._match_text_seq(value, "UNIQUE"):
                self._match_text_seq("KEYS")
                node.meta["unique"] = value
        return self._parse_json_returning(node)

    def _parse_json_returning(self, node: exp.Anonymous) -> exp.Anonymous:
        if self._match(TokenType.RETURNING):
            node.meta["returning"] = self._parse_types()
            if self._match_text_seq("FORMAT", "JSON"):
                node.meta["returning_format"] = self._match_text_seq("ENCODING") and self._parse_var().name or "JSON"
        return node

    def _parse_json_element(self):
        value = self._parse_lambda()  # a whole expression, as in any call (SqlBase.g4 #jsonValueExpression)
        if value is not None and self._match_text_seq("FORMAT", "JSON"):
            value.meta["format_json"] = self._match_text_seq("ENCODING") and self._parse_var().name or True
        return value

    def _parse_normalize(self) -> exp.Expression:
        # NORMALIZE(value [, NFC | NFD | NFKC | NFKD]) (SqlBase.g4 #normalize): the form keyword is
        # the string argument AstBuilder.visitNormalize passes as written; a string, NULL or any other
        # form is a syntax error, as in the real Trino 476.
        value = self._parse_lambda()
        args = [value] if value is not None else []
        if value is not None and self._match(TokenType.COMMA):
            form = self._curr
            keyword = form and form.token_type not in (TokenType.STRING, TokenType.IDENTIFIER)
            if not (keyword and form.text.upper() in ("NFC", "NFD", "NFKC", "NFKD")):
                written = {TokenType.STRING: "'{}'", TokenType.IDENTIFIER: '"{}"'}.get(form and form.token_type, "{}")
                text = written.format(form.text) if form else "<EOF>"
                self.raise_error(f"mismatched input '{text}'. Expecting: 'NFC', 'NFD', 'NFKC', 'NFKD'")
            self._advance()
            if self._curr and self._curr.token_type != TokenType.R_PAREN:
                self.raise_error(f"mismatched input '{self._curr.text}'. Expecting: ')'")
            args.append(exp.Literal.string(form.text))
        return exp.Anonymous(this="normalize", expressions=args)

    def _parse_types(self, check_func: bool = False, **kwargs):
        # In a Trino expression a type name is only ever followed by a string (DATE '2024-01-01'; SqlBase.g4
        # #typeConstructor), so `ARRAY[`, `ROW(`, `date(`, `decimal(` ... start a constructor or a call.
        # sqlglot first reads them as a type, parsing every argument before it backs off and parses them
        # again: twice the work per nesting level, 2^depth for nested calls.
        if (
            check_func
            and self._next
            and (
                (self._curr.token_type == TokenType.ARRAY and self._next.token_type == TokenType.L_BRACKET)
                or (self._curr.token_type in self.TYPE_TOKENS and self._next.token_type == TokenType.L_PAREN)
            )
        ):
            return None
        return super()._parse_types(check_func=check_func, **kwargs)

    def _parse_in(self, this, alias: bool = False):
        # DuckDB's `x IN [1, 2]`; Trino's predicate is `IN (...)` (SqlBase.g4 #inList, #inSubquery)
        if self._curr and self._curr.token_type == TokenType.L_BRACKET:
            self.raise_error("mismatched input '['. Expecting: '('")
        return super()._parse_in(this, alias)

    def _parse_table(self, *args, **kwargs):
        # SqlBase.g4 #relationPrimary: a table is named, never a parameter (`FROM ?`)
        if self._curr is not None and self._curr.token_type == TokenType.PLACEHOLDER:
            raise _mismatched(
                self._curr, "Expecting: '(', 'JSON_TABLE', 'LATERAL', 'TABLE', 'UNNEST', <identifier>", sql=self.sql
            )
        return super()._parse_table(*args, **kwargs)

    def _parse_version(self):
        # SqlBase.g4 #queryPeriod: FOR (TIMESTAMP | VERSION) AS OF expression, which the lake's
        # tables do not support, as Trino's Hive connector
        if self._curr is not None and self._curr.text.upper() == "FOR" and self._next is not None:
            if self._next.text.upper() not in ("TIMESTAMP", "VERSION"):
                raise _mismatched(self._next, "Expecting: 'TIMESTAMP', 'VERSION'", sql=self.sql)
            raise DialectError("This connector does not support versioned tables", error_name="NOT_SUPPORTED")
        return super()._parse_version()

    def _parse_join(self, skip_join_token: bool = False, parse_bracket: bool = False, alias_tokens=None):
        # SqlBase.g4 #joinRelation: a JOIN other than CROSS or NATURAL needs ON or USING (sqlglot
        # reads `a JOIN b` as a cross join, and DuckDB's `a POSITIONAL JOIN b` as `a AS positional JOIN b`)
        comma = self._curr is not None and self._curr.token_type == TokenType.COMMA
        join = super()._parse_join(skip_join_token, parse_bracket, alias_tokens)
        if (
            join is not None
            and not comma
            and not skip_join_token
            and join.args.get("kind") != "CROSS"
            and not join.args.get("method")
            and not join.args.get("on")
            and not join.args.get("using")
        ):
            if self._curr is None or self._curr.token_type == TokenType.SENTINEL:
                end = self._prev
                raise DialectError(
                    "mismatched input '<EOF>'. Expecting: 'ON', 'USING'",
                    line=end.line,
                    column=end.col + 1,
                    error_name="SYNTAX_ERROR",
                )
            raise _mismatched(self._curr, "Expecting: 'ON', 'USING'", sql=self.sql)
        return join


class _Generator(Trino.Generator):
    # The SQL/JSON clauses _Parser keeps in meta, written back (the query forwarded to Trino).
    def anonymous_sql(self, expression: exp.Anonymous) -> str:
        name, meta = expression.name.lower(), expression.meta_get
        clauses = ("on_error", "null", "returning")
        if name != "json_object" and (
            name not in ("json_array", "json_exists")
            or not (
                any(meta(c) is not None for c in clauses)
                or any(a.meta_get("format_json") for a in expression.expressions)
            )
        ):
            return super().anonymous_sql(expression)
        args = []
        for arg in expression.expressions:
            form = arg.meta_get("format_json")
            encoding = "" if form is True else f" ENCODING {form}"
            args.append(self.sql(arg) + (f" FORMAT JSON{encoding}" if form else ""))
        if name == "json_object":  # keys and values alternate: `key : value`
            args = [f"{key} : {value}" for key, value in zip(args[::2], args[1::2])]
        text = ", ".join(args)
        if meta("on_error"):
            text += f" {meta('on_error')} ON ERROR"
        if meta("null"):
            text += f" {meta('null')} ON NULL"
        if meta("unique"):
            text += f" {meta('unique')} UNIQUE KEYS"
        if meta("returning") is not None:
            text += f" RETURNING {self.sql(meta('returning'))}"
            form = meta("returning_format")
            text += "" if not form else " FORMAT JSON" + ("" if form == "JSON" else f" ENCODING {form}")
        return f"{name.upper()}({text.strip()})"

    def jsonextract_sql(self, expression: exp.JSONExtract) -> str:
        sql = super().jsonextract_sql(expression)
        returning = expression.args.get("returning")
        if not expression.args.get("json_query") or returning is None:
            return sql
        path = self.sql(expression, "expression")
        at = sql.index(path, len("JSON_QUERY(") + len(self.sql(expression, "this"))) + len(path)
        return f"{sql[:at]} RETURNING {self.sql(returning)}{sql[at:]}"


class LakegateTrino(Trino):
    """Trino as sqlglot reads it, with function calls left uninterpreted."""

    INDEX_OFFSET = 0
    Parser = _Parser
    Generator = _Generator


_cache: OrderedDict = OrderedDict()
_schemas: OrderedDict = OrderedDict()
_lock = threading.Lock()


def translate(
    sql: str,
    schema: Mapping[str, Mapping[str, str]],
    *,
    scope: Scope | None = None,
    params: Sequence[object] = (),
    schema_version: object = None,
    time_zone: str = "UTC",
    session: session_functions.SessionNames | None = None,
    tree: exp.Expression | None = None,
    rewrite: Hashable = (),
) -> Translation:
    """Translate one Trino query over `schema` (table -> column -> Trino type name) to DuckDB.

    `scope` restricts every table to a batch or job, `params` bind the `?` placeholders, `time_zone`
    is the session zone (a canonical zone: dialect/zones.py), `session` what `current_user`,
    `current_catalog` and `current_schema` answer (None: they are refused), and
    `schema_version` (any hashable) identifies the schema for the cache; without it the schema's
    content is hashed. `tree` is `sql` as its reader already parsed it (`statements.Statement`: a
    tree equal to the parse of `sql`, or its rewrite), translated from a copy (None: `sql` is parsed
    here); `rewrite` names what the reader changed in `tree` (`Statement.edits`), for the cache. Raises
    DialectError with Trino's error name and the position in `sql`.
    """
    schema_key = schema_version if schema_version is not None else _schema_key(schema)
    session = session if session_functions.used(sql) else None  # one cache entry for every session otherwise
    key = (sql, rewrite, schema_key, _hashable(scope), _params_key(params), time_zone, session)
    with _lock:
        hit = _cache.get(key)
        if hit is not None:
            _cache.move_to_end(key)
            return hit
    result = _translate(sql, schema, schema_key, scope, params, time_zone, session, tree)
    with _lock:
        _cache[key] = result
        if len(_cache) > CACHE_SIZE:
            _cache.popitem(last=False)
    return result


def clear_cache() -> None:
    """Forget every cached translation."""
    with _lock:
        _cache.clear()
        _schemas.clear()
    tt.parse_type.cache_clear()


def _schema_key(schema: Mapping[str, Mapping[str, str]]) -> tuple:
    return tuple((table, tuple(columns.items())) for table, columns in schema.items())


def _hashable(value: object) -> object:
    try:
        hash(value)
        return value
    except TypeError:
        return repr(value)


def _params_key(params: Sequence[object]) -> tuple:
    try:
        hash(tuple(params))
        return tuple((type(p), p) for p in params)
    except TypeError:
        return tuple((type(p), repr(p)) for p in params)


def _typed_schema(schema: Mapping[str, Mapping[str, str]], key: object) -> dict[str, list[tuple[str, tt.TType]]]:
    with _lock:
        typed = _schemas.get(key)
    if typed is not None:
        return typed
    typed = {}
    for table, columns in schema.items():
        cols = []
        for name, type_name in columns.items():
            try:
                cols.append((name, tt.in_zone(tt.parse_type(type_name), "UTC")))  # instants shown in UTC
            except ValueError:
                raise DialectError(
                    f"column '{name}' of table '{table}' has an unknown type '{type_name}'",
                    error_name="GENERIC_USER_ERROR",
                ) from None
        typed[table.lower()] = cols
    with _lock:
        _schemas[key] = typed
        if len(_schemas) > 64:
            _schemas.popitem(last=False)
    return typed


#: DuckDB-only operators that sqlglot's Trino tokenizer accepts, with the hint shown (SqlBase.g4 has none of them).
_DUCKDB_OPERATORS = {
    TokenType.DCOLON: "'::' casts are not Trino syntax (use CAST(x AS type))",
    TokenType.NULLSAFE_EQ: "use IS NOT DISTINCT FROM",
    TokenType.DARROW: "use json_extract_scalar",
    TokenType.L_BRACE: "Trino has no struct literals (use ROW(...))",
}
_SET_OPERATIONS = {TokenType.UNION, TokenType.INTERSECT, TokenType.EXCEPT}


def _mismatched(token, hint: str = "", text: str | None = None, sql: str = "") -> DialectError:
    """Trino's SYNTAX_ERROR "mismatched input 'x'" at the start of `token` (or of its `text` suffix)."""
    text = sql[token.start : token.end + 1] if text is None else text
    return syntax_errors.mismatched(sql, token.end + 1 - len(text), text, hint)


def _refuse_duckdb_syntax(tokens: list, sql: str) -> None:
    """Refuse DuckDB syntax that sqlglot's Trino reader accepts but Trino's grammar (trinodb/trino
    core/trino-grammar/src/main/antlr4/io/trino/grammar/sql/SqlBase.g4) does not: `::`, `==`, `//`, `**`,
    `<=>`, `->>`, `{...}` struct literals, `UNION BY NAME` and `LIMIT n%` / `LIMIT n PERCENT`."""
    for i, token in enumerate(tokens):
        kind, following = token.token_type, tokens[i + 1] if i + 1 < len(tokens) else None
        adjacent = following is not None and following.start == token.end + 1
        if kind in _DUCKDB_OPERATORS:
            raise _mismatched(token, _DUCKDB_OPERATORS[kind], sql=sql)
        if kind == TokenType.EQ and token.text == "==":
            raise _mismatched(token, "use '='", text="=", sql=sql)
        if kind in (TokenType.SLASH, TokenType.STAR) and adjacent and following.token_type == kind:
            raise _mismatched(
                following,
                "use power(a, b)" if kind == TokenType.STAR else "integer division is a / b on integers",
                sql=sql,
            )
        if kind in _SET_OPERATIONS:
            by = (
                (tokens[i + 2] if i + 2 < len(tokens) else None)
                if following is not None and following.token_type in (TokenType.ALL, TokenType.DISTINCT)
                else following
            )
            if by is not None and by.text.upper() == "BY":
                raise _mismatched(by, "UNION BY NAME is DuckDB syntax", sql=sql)
        if (
            kind == TokenType.LIMIT
            and following is not None
            and i + 2 < len(tokens)
            and tokens[i + 2].token_type in (TokenType.MOD, TokenType.PERCENT)
        ):
            raise _mismatched(tokens[i + 2], "LIMIT takes a row count (Trino has no LIMIT n PERCENT)", sql=sql)


#: Tokens that cannot start an expression or a select item: after SELECT [DISTINCT] or a comma Trino stops at them.
_NOT_AN_ITEM = {
    getattr(TokenType, name)
    for name in (
        "FROM WHERE GROUP_BY ORDER_BY HAVING LIMIT JOIN UNION INTERSECT EXCEPT ON R_PAREN R_BRACKET COMMA SEMICOLON "
        "WINDOW OFFSET FETCH INNER LEFT RIGHT FULL CROSS USING QUALIFY WHEN THEN ELSE END"
    ).split()
    if hasattr(TokenType, name)
}


#: Tokens after which Trino's grammar wants an expression or an item.
_ITEM_BEFORE = {
    getattr(TokenType, name)
    for name in (
        "SELECT COMMA GROUP_BY ORDER_BY PARTITION_BY HAVING WHERE AND OR ON LIMIT OFFSET WHEN THEN ELSE ALIAS IS NOT"
    ).split()
    if hasattr(TokenType, name)
}


#: Tokens that never end a Trino statement (sqlglot reads some of them as names).
_NOT_LAST = {
    getattr(TokenType, name)
    for name in "UNION INTERSECT EXCEPT LEFT RIGHT FULL JOIN FROM DISTINCT IN".split()
    if hasattr(TokenType, name)
}


def _refuse_missing_item(tokens: list, sql: str) -> None:
    """Trino's grammar wants an item after SELECT [DISTINCT], a comma, GROUP BY, ORDER BY, WHERE, ...;
    sqlglot's takes an empty select list, a trailing comma and an empty GROUP BY."""
    if tokens and tokens[-1].token_type == TokenType.DOT:  # `x.` at the end: Trino's parser stops at the dot,
        starts_item = len(tokens) > 2 and tokens[-3].token_type in (TokenType.SELECT, TokenType.COMMA)
        opened = sum((t.token_type == TokenType.L_PAREN) - (t.token_type == TokenType.R_PAREN) for t in tokens)
        if not starts_item and opened <= 0:  # but not in a select item `t.` (`t.*`), nor inside brackets
            raise _mismatched(tokens[-1], sql=sql)
        raise syntax_errors.mismatched(sql, -1, "<EOF>")
    set_all = len(tokens) > 1 and tokens[-1].token_type == TokenType.ALL and tokens[-2].token_type in _SET_OPERATIONS
    if tokens and tokens[-1].token_type in _NOT_LAST or set_all:
        raise syntax_errors.mismatched(sql, -1, "<EOF>")
    for i, token in enumerate(tokens):
        if token.token_type not in _ITEM_BEFORE:
            continue
        following = tokens[i + 1] if i + 1 < len(tokens) else None
        if (
            following is not None
            and token.token_type == TokenType.SELECT
            and following.token_type == TokenType.DISTINCT
        ):
            following = tokens[i + 2] if i + 2 < len(tokens) else None
        if following is None:
            raise syntax_errors.mismatched(sql, -1, "<EOF>")
        if following.token_type in _NOT_AN_ITEM:
            text = sql[following.start : following.end + 1].split()[0]  # GROUP of the one token GROUP BY
            raise syntax_errors.mismatched(sql, following.start, text)


#: Reserved words that Trino's grammar follows with `(` only.
_CALL_WORDS = ("UNNEST", "EXISTS", "CAST", "EXTRACT", "USING")


def _refuse_lone_group_order(tokens: list, sql: str) -> None:
    """GROUP and ORDER are reserved in Trino (never a name): without BY after them Trino stops at what follows,
    where sqlglot reads them as an alias; so do CROSS, NATURAL, INNER and OUTER without JOIN,
    the words of _CALL_WORDS without (."""
    for i, token in enumerate(tokens):
        if token.token_type == TokenType.VAR and token.text.upper() in ("GROUP", "ORDER"):
            if token.text.upper() == "GROUP" and i and tokens[i - 1].text.upper() == "WITHIN":
                continue  # listagg(...) WITHIN GROUP (ORDER BY ...)
            wanted = "BY"
        elif token.token_type in (TokenType.CROSS, TokenType.NATURAL, TokenType.INNER, TokenType.OUTER):
            wanted = "JOIN"
        elif token.token_type != TokenType.IDENTIFIER and token.text.upper() in _CALL_WORDS:
            wanted = "("
        else:
            continue
        following = tokens[i + 1] if i + 1 < len(tokens) else None
        if following is None:
            raise syntax_errors.mismatched(sql, -1, "<EOF>", f"Expecting: '{wanted}'")
        if following.text.upper() != wanted:
            raise _mismatched(following, f"Expecting: '{wanted}'", sql=sql)


_JOIN_WORDS = {TokenType.JOIN, TokenType.LEFT, TokenType.RIGHT, TokenType.FULL, TokenType.INNER, TokenType.CROSS}
_RELATION_ENDS = {
    getattr(TokenType, name)
    for name in (
        "WHERE GROUP_BY ORDER_BY HAVING LIMIT OFFSET FETCH WINDOW UNION INTERSECT EXCEPT R_PAREN COMMA SEMICOLON"
    ).split()
}


def _refuse_join_without_criteria(tokens: list, sql: str) -> None:
    """Trino's JOIN (but CROSS and NATURAL) needs ON or USING after its relation; sqlglot's makes a cross join."""
    for i, token in enumerate(tokens):
        before = tokens[i - 1].token_type if i else None
        if token.token_type != TokenType.JOIN or before in (TokenType.CROSS, TokenType.NATURAL):
            continue
        depth = 0
        for following in tokens[i + 1 :]:
            kind = following.token_type
            if depth == 0 and kind in (TokenType.ON, TokenType.USING) or depth == 0 and kind in _JOIN_WORDS:
                break  # criteria, or a join of joins (Trino's grammar nests it): sqlglot's parse decides
            if depth == 0 and kind in _RELATION_ENDS:
                raise _mismatched(following, "Expecting: 'ON', 'USING'", sql=sql, text=following.text.split()[0])
            depth += (kind in (TokenType.L_PAREN, TokenType.L_BRACKET)) - (
                kind in (TokenType.R_PAREN, TokenType.R_BRACKET)
            )
        else:
            raise syntax_errors.mismatched(sql, -1, "<EOF>", "Expecting: 'ON', 'USING'")


_CLAUSES = {TokenType.SELECT, TokenType.FROM, TokenType.WHERE, TokenType.HAVING, TokenType.GROUP_BY}
_CLAUSES |= {TokenType.ORDER_BY, TokenType.ON, TokenType.JOIN}


def _refuse_condition_cut_short(tokens: list, sql: str) -> None:
    """A WHERE or HAVING condition that ends in `IN` or `name(`: Trino's parser stops at that `IN` or `(`."""
    if len(tokens) < 2:
        return
    last = tokens[-1]
    cut = last.token_type == TokenType.IN or (
        last.token_type == TokenType.L_PAREN and tokens[-2].token_type in (TokenType.VAR, TokenType.IDENTIFIER)
    )
    clause = next((t.token_type for t in reversed(tokens) if t.token_type in _CLAUSES), None)
    if cut and clause in (TokenType.WHERE, TokenType.HAVING):
        raise _mismatched(last, sql=sql)


def _refuse_lenient_syntax(tokens: list, sql: str) -> None:
    """Trino's SYNTAX_ERROR for texts sqlglot's grammar reads and Trino's does not (a construct unparsed.py
    names is refused by that name instead, as when sqlglot cannot parse it)."""
    try:
        _refuse_condition_cut_short(tokens, sql)
        _refuse_missing_item(tokens, sql)
        _refuse_lone_group_order(tokens, sql)
        _refuse_join_without_criteria(tokens, sql)
    except DialectError:
        construct = unparsed_construct(sql)
        if construct is not None:
            raise DialectError(f"unsupported in lakegate: {construct}", error_name="NOT_SUPPORTED") from None
        raise


def parse(sql: str) -> exp.Expression:
    """Parse exactly one Trino statement (a trailing `;` is allowed)."""
    dialect = LakegateTrino()
    try:
        tokens = dialect.tokenize(sql)
        _refuse_duckdb_syntax(tokens, sql)
        _refuse_lenient_syntax(tokens, sql)
        statements = [
            s for s in dialect.parser().parse(tokens, sql) if s is not None and not isinstance(s, exp.Semicolon)
        ]  # `; -- comment` is no statement
    except ParseError as error:
        construct = unparsed_construct(sql)
        if construct is not None:
            raise DialectError(f"unsupported in lakegate: {construct}", error_name="NOT_SUPPORTED") from None
        raise syntax_errors.parse_error(error, sql) from None
    except TokenError:
        raise syntax_errors.tokenize_error(sql, parse) from None
    except RecursionError:
        raise DialectError("syntax error: the query is nested too deeply", error_name="SYNTAX_ERROR") from None
    if not statements:
        raise syntax_errors.mismatched(sql, -1, "<EOF>")
    opened = sum(t.token_type in (TokenType.L_PAREN, TokenType.L_BRACKET) for t in tokens)
    if opened > sum(t.token_type in (TokenType.R_PAREN, TokenType.R_BRACKET) for t in tokens):
        raise syntax_errors.mismatched(sql, -1, "<EOF>")  # sqlglot reads a bracket left open; Trino wants it closed
    if len(statements) > 1:  # Trino's grammar takes one statement: it stops at the `;` before the second
        separator = next(t for i, t in enumerate(tokens) if t.token_type == TokenType.SEMICOLON and i + 1 < len(tokens))
        raise _mismatched(separator, sql=sql)
    return statements[0]


def _translate(
    sql: str,
    schema: Mapping[str, Mapping[str, str]],
    schema_key: object,
    scope: Scope | None,
    params: Sequence[object],
    time_zone: str,
    session: session_functions.SessionNames | None = None,
    given: exp.Expression | None = None,
) -> Translation:
    if given is None:  # text only: checked here; a tree comes from its reader, which checked its text
        sql = guard.check_text(sql)
    tree = parse(sql) if given is None else given.copy()
    guard.check(tree)
    if scope is not None:
        tree = scoping.restrict(tree, scope, tables=schema)
    tree = parameters.bind(tree, params)
    rewritten = scope is not None or bool(params) or ";" in sql  # Trino refuses a trailing ';'
    rewritten |= session_functions.bind(tree, sql, session)
    if isinstance(tree, exp.Values):
        rewritten = True
        tree = exp.select("*").from_(
            exp.Subquery(
                this=tree,
                alias=exp.TableAlias(
                    this=exp.to_identifier("_values"),
                    columns=[
                        exp.to_identifier(f"_col{i}")
                        for i in range(
                            len(tree.expressions[0].expressions) if isinstance(tree.expressions[0], exp.Tuple) else 1
                        )
                    ],
                ),
            )
        )
    if not isinstance(tree, exp.Query):
        raise DialectError(
            f"unsupported in lakegate: statement {tree.key.upper()} (only queries are translated)",
            line=1,
            column=1,
            error_name="NOT_SUPPORTED",
        )
    rewritten |= hoist_derived_order(tree)
    # the text as given is the Trino SQL unless a rewrite changed the tree (regenerating costs ~1 ms)
    trino_sql = tree.sql(dialect=LakegateTrino) if rewritten else sql.strip()
    try:
        outputs = analyze(tree, _typed_schema(schema, schema_key), sql, time_zone)
    except RecursionError:
        raise DialectError(
            "unsupported in lakegate: the query is nested too deeply", error_name="NOT_SUPPORTED"
        ) from None
    finalize(tree, outputs)
    try:
        duckdb_sql = Writer(time_zone=time_zone).generate(tree, copy=False)
    except RecursionError:
        raise DialectError(
            "unsupported in lakegate: the query is nested too deeply", error_name="NOT_SUPPORTED"
        ) from None
    columns = tuple((name if name is not None else f"_col{i}", str(t)) for i, (name, _, t) in enumerate(outputs))
    zones = tuple(tt.zone_of(t) if t.base == "timestamp_tz" and t.args[0] <= 6 else None for _, _, t in outputs)
    return Translation(duckdb_sql=duckdb_sql, trino_sql=trino_sql, columns=columns, zones=zones)
