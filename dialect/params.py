"""`?` parameters: bound as typed Trino literal nodes of the AST (never pasted into SQL text), and the
values of an `EXECUTE ... USING` list read back from the Trino literals clients send.

Python value -> Trino literal: None -> NULL, bool -> BOOLEAN, int -> INTEGER or BIGINT (by range),
float -> DOUBLE (`1.5E0`), Decimal -> DECIMAL(p,s) of its digits (`1.25`), str -> VARCHAR, bytes -> VARBINARY,
datetime -> TIMESTAMP(6) (WITH TIME ZONE when aware), date -> DATE, time -> TIME(6), UUID -> UUID,
list -> ARRAY, tuple -> ROW, dict -> MAP, TypedLiteral -> its type, as the trino client formats them.
"""

from __future__ import annotations

import datetime as dt
import math
import re
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from decimal import Decimal
from numbers import Integral
from zoneinfo import ZoneInfo

import sqlglot
from sqlglot import exp
from sqlglot.errors import ParseError, TokenError
from sqlglot.tokens import TokenType

from lakegate.dialect.errors import DialectError
from lakegate.dialect.trino_types import decimal_literal_type

_MARK = "lakegate_param_"
_EXECUTE = re.compile(r"\s*EXECUTE\b", re.I)
_ISO_DATE = re.compile(r"[0-9]{4}-[0-9]{2}-[0-9]{2}")
_NON_FINITE = {math.inf: "Infinity", -math.inf: "-Infinity"}


@dataclass(frozen=True)
class TypedLiteral:
    """A Trino typed literal kept as its type and text, for values Python cannot hold exactly
    (`TIMESTAMP '2024-01-02 03:04:05.123'` is TypedLiteral('timestamp(3)', '2024-01-02 03:04:05.123'))."""

    type: str
    text: str


def _cast(text: str, type_sql: str) -> exp.Cast:
    try:
        to = exp.DataType.build(type_sql, dialect="trino")
    except (ParseError, TokenError, ValueError):
        raise DialectError(f"unknown type '{type_sql}' of a parameter", error_name="INVALID_PARAMETER_USAGE") from None
    return exp.Cast(this=exp.Literal.string(text), to=to)


def _timestamp_text(value: dt.datetime | dt.time) -> str:
    return value.strftime("%Y-%m-%d %H:%M:%S.%f" if isinstance(value, dt.datetime) else "%H:%M:%S.%f")


def _zone(value: dt.datetime) -> str:
    if isinstance(value.tzinfo, ZoneInfo):
        return value.tzinfo.key
    offset = value.utcoffset()
    if offset == dt.timedelta(0) and value.tzname() in ("UTC", "UTC+00:00", None):
        return "UTC"
    minutes = int(offset.total_seconds() // 60)
    return f"{'+' if minutes >= 0 else '-'}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"


def literal(value: object) -> exp.Expression:
    """The Trino literal AST node for one Python value (see the module docstring for the types)."""
    if value is None:
        return exp.Null()
    if isinstance(value, bool):
        return exp.Boolean(this=value)
    if isinstance(value, Integral):  # int, numpy integers
        value = int(value)
        if not -(2**63) <= value < 2**63:
            raise DialectError(
                f"Invalid numeric literal: {value} (beyond the bigint range)", error_name="INVALID_LITERAL"
            )
        if value == -(2**63):
            return _cast(str(value), "BIGINT")
        number = exp.Literal.number(abs(value))
        return exp.Neg(this=number) if value < 0 else number
    if isinstance(value, float):  # float, numpy.float64
        if not math.isfinite(value):
            return _cast(_NON_FINITE.get(value, "NaN"), "DOUBLE")
        text = repr(abs(float(value)))  # a literal with an exponent is a DOUBLE in Trino: 1.5E0
        number = exp.Literal.number(text if "e" in text else f"{text}E0")
        return exp.Neg(this=number) if math.copysign(1.0, value) < 0 else number
    if isinstance(value, Decimal):
        if not value.is_finite():
            raise DialectError(f"Invalid decimal literal: {value}", error_name="INVALID_LITERAL")
        text = format(abs(value), "f")
        try:
            decimal_type = str(decimal_literal_type(text))
        except ValueError as error:
            raise DialectError(str(error), error_name="INVALID_LITERAL") from None
        if "." not in text:  # DECIMAL '5' is decimal(1,0), the literal 5 an integer
            return _cast(format(value, "f"), decimal_type)
        number = exp.Literal.number(text)  # a literal with a point is a DECIMAL in Trino: 1.25
        return exp.Neg(this=number) if value.is_signed() else number
    if isinstance(value, str):
        return exp.Literal.string(value)
    if isinstance(value, (bytes, bytearray, memoryview)):
        return exp.HexString(this=bytes(value).hex())
    if isinstance(value, dt.datetime):
        if value.tzinfo is None:
            return _cast(_timestamp_text(value), "TIMESTAMP(6)")
        return _cast(f"{_timestamp_text(value)} {_zone(value)}", "TIMESTAMP(6) WITH TIME ZONE")
    if isinstance(value, dt.date):
        return _cast(value.isoformat(), "DATE")
    if isinstance(value, dt.time):
        if value.tzinfo is not None:
            raise DialectError("a time with a time zone cannot be a parameter", error_name="INVALID_PARAMETER_USAGE")
        return _cast(_timestamp_text(value), "TIME(6)")
    if isinstance(value, uuid.UUID):
        return _cast(str(value), "UUID")
    if isinstance(value, TypedLiteral):
        return _cast(value.text, value.type)
    if isinstance(value, list):
        return exp.Array(expressions=[literal(v) for v in value])
    if isinstance(value, tuple):  # ROW(...) and MAP(...) as the translator's parser reads them: plain calls
        return exp.Anonymous(this="ROW", expressions=[literal(v) for v in value])
    if isinstance(value, dict):
        return exp.Anonymous(this="MAP", expressions=[literal(list(value)), literal(list(value.values()))])
    raise DialectError(
        f"a value of Python type {type(value).__name__} cannot be a query parameter",
        error_name="INVALID_PARAMETER_USAGE",
    )


def _in_text_order(placeholders: list[exp.Placeholder], expression: exp.Expression) -> list[exp.Placeholder]:
    """The placeholders in the order they appear in the SQL text (the AST's argument order is not
    the text's: a SELECT keeps LIMIT before FROM), found by generating the query once with each
    placeholder named."""
    for i, node in enumerate(placeholders):
        node.set("this", f"{_MARK}{i}")
    text = expression.sql(dialect="trino")
    order = sorted(range(len(placeholders)), key=lambda i: text.find(f":{_MARK}{i}"))
    return [placeholders[i] for i in order]


def bind(expression: exp.Expression, params: Sequence[object]) -> exp.Expression:
    """Replace the `?` placeholders of `expression` (in place, and return it) by the literals of
    `params`, in text order. A count that differs from the number of `?` is an
    INVALID_PARAMETER_USAGE error naming both."""
    placeholders = [node for node in expression.find_all(exp.Placeholder) if not node.this]
    if len(placeholders) != len(params):
        raise DialectError(
            f"Incorrect number of parameters: expected {len(placeholders)} but found {len(params)}",
            error_name="INVALID_PARAMETER_USAGE",
        )
    if not placeholders:
        return expression
    nodes = [literal(value) for value in params]
    if len(placeholders) > 1:
        placeholders = _in_text_order(placeholders, expression)
    for placeholder, node in zip(placeholders, nodes):
        if placeholder is expression:
            expression = node
        else:
            placeholder.replace(node)
    return expression


# --- EXECUTE ... USING ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Execute:
    """An `EXECUTE name USING ...` or `EXECUTE IMMEDIATE 'statement' USING ...`."""

    name: str | None  # the prepared statement's name (EXECUTE name)
    statement: str | None  # the statement text (EXECUTE IMMEDIATE)
    params: list[object]


def _value(node: exp.Expression) -> object:
    """The Python value of one Trino literal node (see `literal`, which it inverts)."""
    if isinstance(node, exp.Paren):
        return _value(node.this)
    if isinstance(node, exp.Null):
        return None
    if isinstance(node, exp.Boolean):
        return bool(node.this)
    if isinstance(node, exp.Neg):
        value = _value(node.this)
        if isinstance(value, (int, float, Decimal)) and not isinstance(value, bool):
            return -value
    elif isinstance(node, exp.Literal):
        text = node.name
        if node.is_string:
            return text
        if "e" in text.lower():
            return float(text)
        return Decimal(text) if "." in text else int(text)
    elif isinstance(node, exp.HexString):
        return bytes.fromhex(node.name)
    elif isinstance(node, exp.Cast) and isinstance(node.this, exp.Literal) and node.this.is_string:
        to = node.to
        text = node.this.name
        if to.is_type(exp.DataType.Type.DOUBLE):
            return float(text)
        if to.is_type(exp.DataType.Type.DECIMAL) and to.expressions:
            pass  # DECIMAL(p,s) 'text' is not Trino syntax; keep the cast as written
        elif to.is_type(exp.DataType.Type.DECIMAL):
            return Decimal(text.strip())
        elif to.is_type(exp.DataType.Type.DATE):
            return _date(text)
        elif to.is_type(exp.DataType.Type.UUID):
            return uuid.UUID(text.strip())
        return TypedLiteral(to.sql(dialect="trino").lower(), text)
    elif isinstance(node, exp.Anonymous) and not node.expressions and node.name.lower() in ("infinity", "nan"):
        return math.inf if node.name.lower() == "infinity" else math.nan
    elif isinstance(node, exp.Array):
        return [_value(e) for e in node.expressions]
    elif isinstance(node, exp.Struct) or (isinstance(node, exp.Anonymous) and node.name.lower() == "row"):
        return tuple(_value(e) for e in node.expressions)
    elif isinstance(node, exp.Map) or (isinstance(node, exp.Anonymous) and node.name.lower() == "map"):
        parts = [node.args.get("keys"), node.args.get("values")] if isinstance(node, exp.Map) else node.expressions
        if len(parts) != 2 or not all(isinstance(part, exp.Array) for part in parts):
            raise DialectError(
                "a MAP parameter is written MAP(ARRAY[...], ARRAY[...])", error_name="INVALID_PARAMETER_USAGE"
            )
        keys, values = _value(parts[0]), _value(parts[1])
        if len(keys) != len(values):
            raise DialectError("MAP keys and values differ in number", error_name="INVALID_PARAMETER_USAGE")
        return dict(zip(keys, values))
    raise DialectError(
        f"a parameter must be a literal, not '{node.sql(dialect='trino')}'", error_name="INVALID_PARAMETER_USAGE"
    )


def _date(text: str) -> dt.date | TypedLiteral:
    """The date of a DATE literal's text; any other text ('999-01-01', '2024-02-30') stays typed text,
    so the query answers (or refuses) it exactly as the same literal written inline."""
    try:
        return dt.date.fromisoformat(text.strip()) if _ISO_DATE.fullmatch(text.strip()) else TypedLiteral("date", text)
    except ValueError:
        return TypedLiteral("date", text)


def parse_execute(text: str) -> Execute:
    """Read `EXECUTE name [USING lit, ...]` or `EXECUTE IMMEDIATE 'sql' [USING lit, ...]`."""
    head = _EXECUTE.match(text)
    if not head:
        raise DialectError(
            "syntax error: expected EXECUTE name [USING ...]", line=1, column=1, error_name="SYNTAX_ERROR"
        )
    body = text[head.end() :]
    try:
        tokens = sqlglot.Dialect.get_or_raise("trino").tokenize(body)
    except TokenError as error:
        raise DialectError(f"syntax error: {error}", error_name="SYNTAX_ERROR") from None
    while tokens and tokens[-1].token_type == TokenType.SEMICOLON:
        tokens.pop()
    immediate = bool(tokens) and tokens[0].text.upper() == "IMMEDIATE" and tokens[0].token_type != TokenType.STRING
    target = tokens[1] if immediate and len(tokens) > 1 else tokens[0] if tokens else None
    if target is None or target.token_type != (TokenType.STRING if immediate else TokenType.VAR):
        what = "the statement as a string literal" if immediate else "a prepared statement name"
        raise DialectError(
            f"syntax error: EXECUTE{' IMMEDIATE' if immediate else ''} takes {what}", error_name="SYNTAX_ERROR"
        )
    rest = tokens[tokens.index(target) + 1 :]
    params: list[object] = []
    if rest:
        if rest[0].text.upper() != "USING" or len(rest) < 2:
            raise DialectError(f"syntax error: expected USING, found '{rest[0].text}'", error_name="SYNTAX_ERROR")
        try:
            select = sqlglot.parse_one("SELECT " + body[rest[1].start : rest[-1].end + 1], read="trino")
        except (ParseError, TokenError) as error:
            raise DialectError(
                f"syntax error in the USING list: {str(error).splitlines()[0]}", error_name="SYNTAX_ERROR"
            ) from None
        params = [_value(e) for e in select.expressions]
    return Execute(name=None if immediate else target.text, statement=target.text if immediate else None, params=params)


def parse_using(text: str) -> list[object]:
    """The parameter values of an EXECUTE statement's USING list, as Python values (see `_value`)."""
    return parse_execute(text).params
