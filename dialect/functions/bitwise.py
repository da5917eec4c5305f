"""Trino's functions/bitwise.md. Bitwise functions (io.trino.operator.scalar.BitwiseFunctions: bigint in, bigint
out).
"""

from __future__ import annotations

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.arguments import fixed, need
from lakegate.dialect.functions.rendering import sqls
from lakegate.dialect.registry import Render, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


# --- bitwise (io.trino.operator.scalar.BitwiseFunctions: bigint in, bigint out) ------------------
def _bigints(g, args) -> list[str]:
    return [f"CAST({g.sql(a)} AS BIGINT)" for a in args]


def _render_bit_count(g, node, args) -> str:
    """Trino's bitCount: `x` as a `bits`-bit two's complement number; bits outside 2..64 or an `x`
    that does not fit are INVALID_FUNCTION_ARGUMENT."""
    x, bits = _bigints(g, args)
    low = f"((CAST(1 AS HUGEINT) << ({bits} - 1)) - 1)"
    checks = [
        (
            f"{bits} NOT BETWEEN 2 AND 64",
            f"{tf.string('Bits specified in bit_count must be between 2 and 64, got ')} || {bits}",
        ),
        (
            f"{x} > {low} OR {x} < -{low} - 1",
            f"{tf.string('Number must be representable with the bits specified. ')} || {x} || "
            f"{tf.string(' cannot be represented with ')} || {bits} || {tf.string(' bits')}",
        ),
    ]
    whens = " ".join(f"WHEN {condition} THEN {g.fail(message)}" for condition, message in checks)
    return (
        f"CASE WHEN {x} IS NULL OR {bits} IS NULL THEN NULL {whens} "
        f"ELSE bit_count(CAST(CAST({x} AS HUGEINT) & ((CAST(1 AS HUGEINT) << {bits}) - 1) AS UBIGINT)) END"
    )


# === math (io.trino.operator.scalar.MathFunctions, BitwiseFunctions, WilsonInterval,
# ArrayVectorFunctions, DataSizeFunctions) ======================================================
_WIDTH = {"tinyint": 8, "smallint": 16, "integer": 32, "bigint": 64}

_U64 = 2**64 - 1


def _shift(call: Call) -> TType:
    value, _ = need(call, "integral", "integer")  # BitwiseFunctions: the shift is an integer
    return tt.BIGINT if value.is_unknown else value


def _signed(sql: str, width: int) -> str:
    """The low `width` bits of the non-negative HUGEINT `sql` as a two's complement number."""
    low = f"(({sql}) & {2**width - 1})"
    return f"({low} - CASE WHEN {low} >= {2 ** (width - 1)} THEN {2**width} ELSE 0 END)"


def _render_shift(kind: str) -> Render:
    """BitwiseFunctions: the value's own width (tinyint 8 ... bigint 64 bits); a shift of 64 or
    more gives 0 (-1 for an arithmetic shift of a negative value); below 64, Java's `<<`, `>>>`
    and `>>` on a long (the shift taken modulo 64)."""

    def render(g, node, args) -> str:
        value, shift = sqls(g, args)
        t = ttype(node)
        width = _WIDTH[t.base]
        s = f"(CAST({shift} AS BIGINT) & 63)"
        bits = f"(CAST({value} AS HUGEINT) & {_U64})"
        if kind == "left":
            shifted, wide = _signed(f"{bits} << {s}", width), "0"
        elif kind == "logical":
            low = f"({bits} & {2**width - 1})"
            shifted = f"CASE WHEN {s} = 0 THEN {value} ELSE {low} >> {s} END"
            wide = "0"
        else:
            shifted, wide = f"(CAST({value} AS BIGINT) >> {s})", f"CASE WHEN {value} >= 0 THEN 0 ELSE -1 END"
        return tf.cast(f"CASE WHEN {shift} >= 64 THEN {wide} ELSE {shifted} END", t)

    return render


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "bitwise_and",
        "math",
        "bitwise_and(x, y) -> bigint",
        fixed(tt.BIGINT, "integral", "integral"),
        lambda g, node, args: "({} & {})".format(*_bigints(g, args)),
    )
    register(
        "bitwise_or",
        "math",
        "bitwise_or(x, y) -> bigint",
        fixed(tt.BIGINT, "integral", "integral"),
        lambda g, node, args: "({} | {})".format(*_bigints(g, args)),
    )
    register(
        "bitwise_xor",
        "math",
        "bitwise_xor(x, y) -> bigint",
        fixed(tt.BIGINT, "integral", "integral"),
        lambda g, node, args: "xor({}, {})".format(*_bigints(g, args)),
    )
    register(
        "bitwise_not",
        "math",
        "bitwise_not(x) -> bigint",
        fixed(tt.BIGINT, "integral"),
        lambda g, node, args: "(~{})".format(*_bigints(g, args)),
    )
    register(
        "bit_count", "math", "bit_count(x, bits) -> bigint", fixed(tt.BIGINT, "integral", "integral"), _render_bit_count
    )

    for _name, _kind in (
        ("bitwise_left_shift", "left"),
        ("bitwise_right_shift", "logical"),
        ("bitwise_right_shift_arithmetic", "arithmetic"),
    ):
        register(_name, "math", f"{_name}(value, shift) -> same as value", _shift, _render_shift(_kind))
