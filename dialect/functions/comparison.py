"""Trino's functions/comparison.md. Comparison functions: greatest and least."""

from __future__ import annotations

from lakegate.dialect import transforms as tf
from lakegate.dialect.functions.arguments import common
from lakegate.dialect.functions.rendering import nested, not_nan, null_if_any_null, ordered_pick
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


def _greatest(call: Call) -> TType:
    if not call.args or None in call.types:
        call.mismatch()
    t = common(call)
    if t.base in ("map", "json", "varbinary", "boolean") or t.base in ("row", "array") and nested(t):
        call.mismatch()
    return t


def _render_greatest(g, node, args) -> str:
    t = ttype(node)
    name = node.name.lower()
    values = [g.coerce(a, t) for a in args]
    if t.base in ("array", "row"):  # AbstractGreatestLeast compares each argument with the one kept
        return null_if_any_null(g, args, ordered_pick(f"[{', '.join(values)}]", t, name == "greatest"))
    if name == "greatest" and t.is_approx:  # NaN only when all are NaN (MinMaxCompare, above)
        nan = tf.cast("'NaN'", t)
        return null_if_any_null(g, args, f"coalesce(greatest({', '.join(not_nan(v) for v in values)}), {nan})")
    return null_if_any_null(g, args, f"{name}({', '.join(values)})")


def install() -> None:
    """Register the functions of this page (called by pages.py)."""
    register(
        "greatest",
        "conditional",
        "greatest(value1, value2, ...) -> common type",
        _greatest,
        _render_greatest,
        notes="NULL when any argument is NULL, as in Trino (DuckDB ignores NULLs).",
    )
    register(
        "least",
        "conditional",
        "least(value1, value2, ...) -> common type",
        _greatest,
        _render_greatest,
        notes="NULL when any argument is NULL, as in Trino (DuckDB ignores NULLs).",
    )
