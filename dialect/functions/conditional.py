"""Trino's functions/conditional.md. Conditional expressions written as function calls: coalesce, nullif, if,
try.
"""

from __future__ import annotations

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import write_casts as casts
from lakegate.dialect import write_operators as ops
from lakegate.dialect.errors import DialectError
from lakegate.dialect.functions.arguments import common, need, same
from lakegate.dialect.functions.rendering import sqls
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


# === conditional ==================================================================================
def _coalesce(call: Call) -> TType:
    if not call.args or None in call.types:
        call.mismatch()
    return common(call)


def _render_coalesce(g, node, args) -> str:
    t = ttype(node)
    return f"coalesce({', '.join(g.coerce(a, t) for a in args)})"


def _nullif(call: Call) -> TType:
    a, b = need(call, "any", "any")
    if tt.common_super_type(a, b) is None:
        call.mismatch()
    return a


def _render_nullif(g, node, args) -> str:
    """NULL when the values are equal by Trino's `=`, else the first: NaN equals nothing, not even
    NaN, and arrays, maps and rows with NULL elements are not equal (DuckDB's nullif says both are)."""
    first, second = sqls(g, args)
    t = tt.common_super_type(ttype(args[0]), ttype(args[1]))
    if t is None or t.base not in ("double", "real", "array", "map", "row"):
        return f"nullif({first}, {second})"
    equal = ops.trino_equal(g.coerce(args[0], t), g.coerce(args[1], t), t)
    return f"CASE WHEN ({equal}) IS TRUE THEN NULL ELSE {first} END"


def _render_typeof(g, node, args) -> str:
    """The type's name, known when the query is translated; the argument is still evaluated, as
    Trino does: its failure is the query's (or NULL under TRY), and an aggregate in it keeps the
    query an aggregation."""
    name = tf.string(str(ttype(args[0])))
    value = g.sql(args[0])
    if g.in_try:  # inside try() a failure is a NULL: it must make try() NULL, a NULL value must not
        g.in_try, depth = 0, g.in_try
        try:
            can_fail = g.sql(args[0]) != value
        finally:
            g.in_try = depth
        if can_fail:
            raise DialectError(
                "unsupported in lakegate: typeof() inside try() of an expression that can fail",
                error_name="NOT_SUPPORTED",
            )
    return f"CASE WHEN ({value}) IS NULL THEN {name} ELSE {name} END"


def _render_try(g, node, args) -> str:
    """DuckDB's TRY(...) around the argument, whose failures it catches: any failure makes the whole
    try() NULL, as in Trino. Where TRY cannot wrap it (aggregates, windows, subqueries), each
    failure is a NULL where it happens."""
    outer = g.catching
    for catching in (g.in_try + 1, outer):
        g.in_try += 1
        g.catching = catching
        try:
            sql = g.sql(args[0])
        finally:
            g.in_try -= 1
            g.catching = outer
        wrapped = casts.try_wrap(sql)
        if wrapped != sql:
            return wrapped
    return sql


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register("coalesce", "conditional", "coalesce(value1, value2[, ...]) -> common type", _coalesce, _render_coalesce)
    register("nullif", "conditional", "nullif(value1, value2) -> type of value1", _nullif, _render_nullif)
    register(
        "try",
        "conditional",
        "try(expression) -> same",
        same("any"),
        _render_try,
        notes="NULL instead of failing on division by zero, invalid casts, out-of-range subscripts and "
        "invalid function arguments.",
    )
    register(
        "typeof",
        "conditional",
        "typeof(expression) -> varchar",
        lambda c: tt.VARCHAR if len(c.args) == 1 and c.types[0] is not None else c.mismatch(),
        lambda g, node, args: _render_typeof(g, node, args),
        notes="The Trino type name, computed when the query is translated; the argument is evaluated as in Trino.",
    )
    register(
        "row",
        "conditional",
        "row(value1, ...) -> row",
        lambda c: tt.row([(None, t) for t in c.types]) if c.types and None not in c.types else c.mismatch(),
        lambda g, node, args: f"row({', '.join(sqls(g, args))})",
    )
