"""The char(n) overloads of Trino's string functions (issue 14 family 5), added with
`registry.overload` to the varchar functions of lakegate.dialect.functions. A char(n) value is its
text padded to n characters (dialect/chars.py); Trino keeps it without trailing spaces, so each
overload below is written from the Trino function applied to that trimmed value
(trinodb/trino core/trino-main/src/main/java/io/trino/operator/scalar/StringFunctions.java, checked by
core/trino-main/src/test/java/io/trino/operator/scalar/TestStringFunctions.java: testCharLength,
testCharLeftTrim and the substr cases of char, trinodb/trino#3599).
"""

from __future__ import annotations

from collections.abc import Callable

from sqlglot import exp

import lakegate.dialect.functions_scalar  # noqa: F401  (its overloads first: these wrap them)
from lakegate.dialect import chars
from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.analyze import Call, ttype
from lakegate.dialect.registry import SUPPORTED, Render, overload
from lakegate.dialect.trino_types import TType

_TEXT = ("char", "varchar", "unknown")


def _char_call(result: Callable[[TType], TType], *rest: tuple[str, ...], optional: int = 0):
    """Accept calls whose first argument is char(x) and whose other arguments have the given bases;
    the result type from x's type. The call is marked as translated for char (analyze._check_char_use)."""

    def accepts(call: Call) -> TType | None:
        types = call.types
        if not types or types[0] is None or types[0].base != "char":
            return None
        if not len(rest) - optional <= len(types) - 1 <= len(rest):
            return None
        if any(t is None or t.base not in bases for t, bases in zip(types[1:], rest)):
            return None
        call.node.meta["char"] = True
        return result(types[0])

    return accepts


_INTEGRAL = ("tinyint", "smallint", "integer", "bigint", "unknown")


def _varchar_of(t: TType) -> TType:
    return tt.varchar(t.args[0])


def _trimmed(sql: str) -> str:
    """Trino's stored value of a char: its padded text without the trailing spaces (Chars.trimTrailingSpaces)."""
    return f"rtrim({sql}, ' ')"


def _trim(kind: str) -> Render:
    """trim, ltrim and rtrim of a char (StringFunctions.charTrim, charLeftTrim, charRightTrim): the
    function applied to the stored value; with characters to remove, trailing spaces trimmed after."""

    def render(g, node, args):
        value = _trimmed(g.sql(args[0]))
        if len(args) == 1:
            return f"{kind}({value}, {tf.string(tf.WHITESPACE)})"
        trimmed = f"{kind}({value}, {g.sql(args[1])})"
        return trimmed if kind == "ltrim" else _trimmed(trimmed)

    return render


def _substr(g, node, args) -> str:
    """substr(char(x), start[, length]): the varchar substr of the padded value (StringFunctions.charSubstring)."""
    return tf.substring_from(g, exp.Substring(this=args[0], start=args[1], length=args[2] if len(args) == 3 else None))


def _concat(g, node, args) -> str:
    """concat(char(x), char(y)): the left value padded to x, then the right one (StringFunctions.concat);
    the padded right one reads the same once the result is padded to x + y."""
    left, right = (g.coerce(a, tt.as_char(ttype(a))) for a in args)
    return f"({left} || {right})"


def _concat_type(call: Call) -> TType | None:
    types = call.types
    if len(types) != 2 or "char" not in (t.base for t in types if t is not None):
        return None
    if any(t is None or t.base not in _TEXT for t in types):
        return None
    t = chars.concat_type(types[0], types[1])
    if t is None:
        call.fail(f"concat of {types[0]} and {types[1]} (longer than char(65536))", "NOT_SUPPORTED")
    call.node.meta["char"] = True
    return t


overload(
    "length",
    _char_call(lambda t: tt.BIGINT),
    lambda g, node, args: f"CAST(length({g.sql(args[0])}) AS BIGINT)",
    "length(char(x)) -> bigint (x: StringFunctions.charLength)",
)
for _name in ("lower", "upper"):
    overload(
        _name,
        _char_call(lambda t: t),
        lambda g, node, args, name=_name: f"{name}({g.sql(args[0])})",
        f"{_name}(char(x)) -> char(x)",
    )
for _name in ("trim", "ltrim", "rtrim"):
    overload(
        _name,
        _char_call(_varchar_of, _TEXT, optional=1),
        _trim(_name),
        f"{_name}(char(x)[, characters]) -> varchar(x) (trailing spaces are not part of a char value)",
    )
for _name in ("substr", "substring"):
    overload(
        _name,
        _char_call(_varchar_of, _INTEGRAL, _INTEGRAL, optional=1),
        _substr,
        f"{_name}(char(x), start[, length]) -> varchar(x) (of the padded value: StringFunctions.charSubstring)",
    )
overload(
    "concat",
    _concat_type,
    _concat,
    "concat(char(x), char(y)) -> char(x + y) (two arguments; varchar and NULL coerced to char)",
)
overload(
    "lpad",
    _char_call(lambda t: tt.VARCHAR, _INTEGRAL, ("varchar", "unknown")),
    SUPPORTED["lpad"].render,
    "lpad(char(x), size, padstring) -> varchar (of the padded value: StringFunctions.leftPad, trinodb/trino#16907)",
)
