"""Argument checks shared by the function pages: a call's arity and argument kinds, its literal arguments, and
the result type rules built from them (`fixed`, `same`).
"""

from __future__ import annotations

from collections.abc import Callable

from sqlglot import exp

from lakegate.dialect import trino_types as tt
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call

# --- argument checks -----------------------------------------------------------------------------
KINDS: dict[str, Callable[[TType], bool]] = {
    "any": lambda t: True,
    "number": lambda t: t.is_numeric or t.is_unknown,
    "integral": lambda t: t.is_integral or t.is_unknown,
    "integer": lambda t: t.base in ("tinyint", "smallint", "integer", "unknown"),  # not bigint: no implicit narrowing
    "approx": lambda t: t.is_numeric or t.is_unknown,
    "string": lambda t: t.base in ("varchar", "unknown"),
    "boolean": lambda t: t.base in ("boolean", "unknown"),
    "array": lambda t: t.base in ("array", "unknown"),
    "temporal": lambda t: t.base in ("date", "timestamp", "timestamp_tz", "unknown"),
    "zoned": lambda t: t.base in ("timestamp_tz", "unknown"),
    "instant": lambda t: t.base in ("timestamp", "timestamp_tz", "unknown"),
    "timestamp": lambda t: t.base in ("timestamp", "unknown"),
    "orderable": lambda t: t.base not in ("map", "json", "varbinary"),
    "json": lambda t: t.base in ("varchar", "json", "unknown"),
}


def need(call: Call, *kinds: str, optional: int = 0) -> list[TType]:
    """Check the call's arity (len(kinds), the last `optional` may be left out) and argument kinds."""
    count = len(call.args)
    if not len(kinds) - optional <= count <= len(kinds):
        call.mismatch()
    for t, kind in zip(call.types, kinds):
        if t is None or not KINDS[kind](t):
            call.mismatch()
        if kind in ("temporal", "zoned") and t.base == "timestamp_tz":  # computed in the values' zone
            call.analyzer.zone(t, call.node, f"{call.name}()")
    return call.types  # type: ignore[return-value]


def fixed(result: TType, *kinds: str, optional: int = 0) -> Callable[[Call], TType]:
    def infer(call: Call) -> TType:
        need(call, *kinds, optional=optional)
        return result

    return infer


def same(*kinds: str, optional: int = 0) -> Callable[[Call], TType]:
    """Result type is the first argument's type (NULL literal: unknown)."""

    def infer(call: Call) -> TType:
        return need(call, *kinds, optional=optional)[0]

    return infer


def as_double(*kinds: str) -> Callable[[Call], TType]:
    return fixed(tt.DOUBLE, *kinds)


def common(call: Call, types: list[TType] | None = None) -> TType:
    result = tt.common_super_type_of(types if types is not None else call.types)
    if result is None:
        call.mismatch()
    return result


def literal_int(call: Call, index: int) -> int | None:
    """The integer literal at `index` (a negative one is a Neg of the literal), None otherwise."""
    lit = call.literal(index)
    if lit is None or lit.is_string:
        return None
    try:
        value = int(lit.name)
    except ValueError:
        return None
    return -value if isinstance(lit, exp.Neg) else value


def literal_str(call: Call, index: int) -> str | None:
    lit = call.literal(index)
    return lit.name if lit is not None and lit.is_string else None


# === array ========================================================================================
def array_arg(call: Call, index: int = 0) -> TType:
    t = call.types[index]
    if t is None or t.base not in ("array", "unknown"):
        call.mismatch()
    return t if t.base == "array" else tt.array(tt.UNKNOWN)


VARBINARY = tt.VARBINARY


def binary_args(call: Call, count: int) -> bool:
    """Whether the call has `count` arguments, the first varbinary and none of another type than
    varbinary or NULL."""
    types = call.types
    return (
        len(types) == count
        and types[0] is not None
        and types[0].base == "varbinary"
        and all(t is not None and t.base in ("varbinary", "unknown") for t in types)
    )


# === varbinary (io.trino.operator.scalar.VarbinaryFunctions, HmacFunctions) =====================
KINDS_BINARY = ("varbinary", "unknown")


def binary_in(result: TType) -> Callable[[Call], TType]:
    """One varbinary argument; the result type."""

    def infer(call: Call) -> TType:
        if len(call.args) != 1 or call.types[0] is None or call.types[0].base not in KINDS_BINARY:
            call.mismatch()
        return result

    return infer


# --- helpers ---------------------------------------------------------------------------------------
def map_arg(call: Call, index: int = 0) -> TType:
    t = call.types[index] if index < len(call.types) else None
    if t is None or t.base != "map":
        call.mismatch()
    return t


def plain_key(call: Call, key: TType) -> None:
    """Keys lakegate's maps hold exactly: not maps or JSON (Trino's map keys must be comparable), and
    not arrays or rows (DuckDB map keys lose their type in the result encoding)."""
    if key.base in ("map", "json"):
        call.mismatch()
    if key.base in ("array", "row"):
        call.fail(f"unsupported in lakegate: a map with {key.base} keys", "NOT_SUPPORTED")
