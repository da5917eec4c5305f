"""Trino's functions/window.md. Window functions: ranking and value functions."""

from __future__ import annotations

from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.arguments import common, fixed, need, same
from lakegate.dialect.functions.rendering import agg_as, checked
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


# === window =======================================================================================
def _lag(call: Call) -> TType:
    types = need(call, "any", "integral", "any", optional=2)
    if len(types) == 3 and tt.common_super_type(types[0], types[2]) is None:
        call.mismatch()
    return common(call, [types[0], types[2]]) if len(types) == 3 else types[0]


def _render_lag(g, node, args) -> str:
    """lag / lead; a NULL or negative offset fails (io.trino.operator.window.LagFunction,
    LeadFunction; the real Trino 476: "Offset must not be null")."""
    t = ttype(node)
    offsets = [
        checked(
            g,
            g.sql(a),
            [(f"({g.sql(a)}) IS NULL", "Offset must not be null"), (f"({g.sql(a)}) < 0", "Offset must be at least 0")],
        )
        for a in args[1:2]
    ]
    parts = [g.coerce(args[0], t)] + offsets + [g.coerce(a, t) for a in args[2:]]
    return g.agg(node, node.name.lower(), parts)


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    for _name in ("row_number", "rank", "dense_rank"):
        register(_name, "window", f"{_name}() -> bigint", fixed(tt.BIGINT), agg_as(_name), kind="window")
    register("ntile", "window", "ntile(n) -> bigint", fixed(tt.BIGINT, "integral"), agg_as("ntile"), kind="window")
    register(
        "percent_rank", "window", "percent_rank() -> double", fixed(tt.DOUBLE), agg_as("percent_rank"), kind="window"
    )
    register("cume_dist", "window", "cume_dist() -> double", fixed(tt.DOUBLE), agg_as("cume_dist"), kind="window")
    register("lag", "window", "lag(x[, offset[, default]]) -> same", _lag, _render_lag, kind="window")
    register("lead", "window", "lead(x[, offset[, default]]) -> same", _lag, _render_lag, kind="window")
    register(
        "first_value", "window", "first_value(x) -> same", same("any"), agg_as("first_value", False), kind="window"
    )
    register("last_value", "window", "last_value(x) -> same", same("any"), agg_as("last_value", False), kind="window")
    register(
        "nth_value",
        "window",
        "nth_value(x, offset) -> same",
        same("any", "integral"),
        agg_as("nth_value", False),
        kind="window",
    )
