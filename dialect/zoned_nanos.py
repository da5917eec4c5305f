"""timestamp(9) with time zone, as from_unixtime_nanos gives it (nanosecond robot
data). DuckDB has no nanosecond TIMESTAMPTZ, so such a value is held as a TIMESTAMP_NS of its UTC
instant, its zone kept in its Trino type as for every zoned timestamp (dialect/zones.py), and shown
in that zone with nine fraction digits (gateway/engine/trino_values.py).

Only what that representation answers exactly is translated: the values themselves as results,
comparisons of two such values (=, <, BETWEEN, IN, IS [NOT] DISTINCT FROM; instants, as Trino
compares them), IS NULL, ORDER BY, GROUP BY and DISTINCT, min / max / count / arbitrary, typeof,
to_unixtime, AT TIME ZONE, and CAST to timestamp(p), date and varchar (of the wall time in the value's zone, as
TimestampWithTimeZoneToTimestampCast and friends; the timestamp(9) functions then apply). Everything
else on them (fields, arithmetic, date functions, comparisons with other types) and every other way
to a timestamp(7..9) with time zone (literals, casts) is refused with NOT_SUPPORTED naming the
construct.
"""

from __future__ import annotations

from typing import Any

from sqlglot import exp

from lakegate.dialect import trino_types as tt
from lakegate.dialect import zones
from lakegate.dialect.guard import COMPARISON_OPERATORS, trino_name
from lakegate.dialect.trino_types import TType

#: The functions that give or take such values.
FUNCTIONS = frozenset({"from_unixtime_nanos", "min", "max", "count", "arbitrary", "typeof", "to_unixtime"})
#: The aggregates (and from_unixtime_nanos) whose result is such a value.
_PRODUCERS = frozenset({"from_unixtime_nanos", "min", "max", "arbitrary"})
#: Trino's operators, by the sqlglot node that parses them.
_OPERATORS = {
    **COMPARISON_OPERATORS,
    exp.Between: "BETWEEN",
    exp.In: "IN",
    exp.Add: "+",
    exp.Sub: "-",
    exp.Mul: "*",
    exp.Div: "/",
}
_COMPARISONS = (*COMPARISON_OPERATORS, exp.Between, exp.In)
#: The expressions that pass such a value through unchanged.
_CARRIERS = (exp.Alias, exp.Paren, exp.Column, exp.Window, exp.AtTimeZone, exp.Distinct, exp.Ordered, exp.Is)


def is_zoned_nanos(t: TType | None) -> bool:
    """Whether `t` is a timestamp(7..9) with time zone."""
    return t is not None and t.base == "timestamp_tz" and t.args[0] > 6


def produces(node: exp.Expression) -> bool:
    """Whether `node` may have a timestamp(7..9) with time zone type (else the analyzer refuses it)."""
    if isinstance(node, exp.Anonymous):
        return node.name.lower() in _PRODUCERS
    return isinstance(node, _CARRIERS)


def check_use(analyzer: Any, node: exp.Expression, t: TType) -> None:
    """Refuse `node` (of type `t`) when it uses a timestamp(7..9) with time zone operand in a way not
    written for it (`analyzer.unsupported` raises NOT_SUPPORTED naming the construct)."""
    types = [child.meta.get("t") if child._meta else None for child in node.iter_expressions()]
    if not any(is_zoned_nanos(t) for t in types):
        return
    if isinstance(node, (exp.Cast, exp.TryCast)) and (t.base in ("timestamp", "date") or t == tt.VARCHAR):
        return
    name = f"operator '{_OPERATORS[type(node)]}'" if type(node) in _OPERATORS else trino_name(node)
    if isinstance(node, _COMPARISONS) and not (isinstance(node, exp.In) and node.args.get("query")):
        if all(t is None or is_zoned_nanos(t) or t.is_unknown for t in types):
            return
        others = sorted({str(t) for t in types if t is not None and not is_zoned_nanos(t) and not t.is_unknown})
        what = f"{name} on timestamp(9) with time zone and {', '.join(others)}"
    elif isinstance(node, _CARRIERS) or (isinstance(node, exp.Anonymous) and node.name.lower() in FUNCTIONS):
        return
    else:
        what = f"{name} on timestamp(9) with time zone"
    analyzer.unsupported(
        f"{what} (lakegate translates only comparisons of two such values, min, max, count, arbitrary, "
        "typeof, to_unixtime, AT TIME ZONE, ordering and casts to timestamp, date and varchar for them)",
        node,
    )


def wall_time(sql: str, zone: str) -> str:
    """The wall time (TIMESTAMP_NS) in `zone` of the instant `sql` (a TIMESTAMP_NS in UTC): the instant
    plus the zone's offset then, read by ICU from the instant floored to the microsecond (offsets
    change on whole seconds)."""
    if zone == zones.UTC:
        return sql
    nanos = f"epoch_ns({sql})"
    micros = f"(({nanos}) - ((({nanos}) % 1000) + 1000) % 1000) // 1000"
    offset = f"(epoch_us({zones.local(f'CAST(make_timestamp({micros}) AS TIMESTAMPTZ)', zone)}) - {micros})"
    return f"make_timestamp_ns({nanos} + 1000 * {offset})"
