"""Trino's functions/comparison.md. Comparison functions: greatest and least."""

from __future__ import annotations

from lakegate.dialect import transforms as tf
from lakegate.dialect.functions.arguments import common
from lakegate.dialect.functions.rendering import nested, not_nan, ordered_pick, refuse_nested_floats
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


def _greatest(call: Call) -> TType:
    if not call.args or None in call.types:
        call.mismatch()
    t = common(call)
    if t.base in ("map", "json", "varbinary", "boolean") or t.base in ("row", "array") and nested(t):
        call.mismatch()
    refuse_nested_floats(call, t)
    return t


def _render_greatest(g, node, args) -> str:
    t = ttype(node)
    name = node.name.lower()
    values = [g.coerce(a, t) for a in args]
    if t.base in ("array", "row"):  # AbstractGreatestLeast compares each argument with the one kept
        return _null_if_any_null(values, ordered_pick(f"[{', '.join(values)}]", t, name == "greatest"))
    if name == "greatest" and t.is_approx:  # NaN only when all are NaN (MinMaxCompare, above)
        nan = tf.cast("'NaN'", t)
        return _null_if_any_null(values, f"coalesce(greatest({', '.join(not_nan(v) for v in values)}), {nan})")
    return _null_if_any_null(values, f"{name}({', '.join(values)})")


def _null_if_any_null(values: list[str], sql: str) -> str:
    """`sql`, or NULL when a value is NULL, every value evaluated first: Trino evaluates all the
    arguments of greatest and least (one failing fails the call even beside a NULL)."""
    return f"CASE WHEN list_count([{', '.join(values)}]) < {len(values)} THEN NULL ELSE {sql} END"


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
