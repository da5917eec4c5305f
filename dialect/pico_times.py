"""Trino's time(p) for p = 7..12 in DuckDB, exactly: a BIGINT of picoseconds of the day.

DuckDB's TIME holds microseconds (dialect/times.py keeps time(p <= 6) in it); Trino's time(7..12)
holds picoseconds (io.trino.spi.type.LongTimestamp's unit, the one dialect/zoned_times.py uses for
time with time zone). A BIGINT orders, groups and compares as Trino's time does, so comparisons,
ORDER BY, GROUP BY, DISTINCT, min and max need nothing; what DuckDB would read as a number (functions
not written for it, values nested in arrays, maps or rows) is refused by name (`check_use`). Rounding
is HALF_UP and wraps at midnight, as for the other times (TimeOperators). The helpers return DuckDB
SQL text from DuckDB SQL text.
"""

from __future__ import annotations

from typing import Any

from sqlglot import exp

from lakegate.dialect import times, zoned_times
from lakegate.dialect import trino_types as tt
from lakegate.dialect.guard import trino_name
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import WIDE_TIME_OPERATIONS

PICOS_PER_DAY = zoned_times.PICOS_PER_DAY
PICOS_PER_MICRO = 1_000_000
#: The units of date_trunc, date_add and date_diff, in picoseconds.
UNIT_PICOS = zoned_times.UNIT_PICOS


def is_wide(t: TType | None) -> bool:
    """Whether `t` is a time(7..12), held as picoseconds."""
    return t is not None and t.base == "time" and t.args[0] > 6


def picos(sql: str, t: TType) -> str:
    """The picoseconds of the day of a time(p) of any precision."""
    return sql if is_wide(t) else f"({times.micros(sql)} * {PICOS_PER_MICRO})"


def of_picos(picos_sql: str, precision: int) -> str:
    """A time(precision) of picoseconds of the day already rounded to it (0 <= picos_sql < one day)."""
    if precision > 6:
        return f"CAST({picos_sql} AS BIGINT)"
    return times.of_micros(f"CAST(({picos_sql}) // {PICOS_PER_MICRO} AS BIGINT)")


def round_time(sql: str, source: TType, precision: int) -> str:
    """CAST(time(source) AS time(precision)), either side wide: rounded HALF_UP, modulo a day."""
    if precision >= source.args[0]:
        return of_picos(picos(sql, source), precision)
    return of_picos(zoned_times.rounded_picos(picos(sql, source), precision), precision)


def cast_to(node: exp.Expression, target: TType) -> None:
    """Put Trino's CAST of the analyzed time `node` to time(p > 6) `target` in its place (a set
    operation's branch: DuckDB cannot cast its TIME to the picoseconds)."""
    cast = exp.Cast(to=exp.DataType.build("bigint"))
    node.replace(cast)
    cast.set("this", node)
    cast.meta.update({"from": node.meta["t"], "t": target})


def literal(text: str) -> int:
    """The picoseconds of a TIME literal's text (valid, infer_casts._time_literal_type)."""
    value = zoned_times.literal(text.strip(), zoned_times.MAX_PRECISION, 0)
    assert value is not None
    return value[0]


def parse(sql: str, precision: int, bad: str) -> str:
    """CAST(varchar AS time(precision > 6)): the fraction rounded HALF_UP, 24:00 wrapped to 00:00
    (TimeOperators.castFromVarchar); `bad` when Trino refuses the text."""
    pattern = "'" + times.TIME_TEXT + "'"

    def part(index: int) -> str:
        return f"CAST(coalesce(nullif(regexp_extract({sql}, {pattern}, {index}), ''), '0') AS BIGINT)"

    hour, minute, second = part(1), part(2), part(4)
    fraction = f"CAST(rpad(regexp_extract({sql}, {pattern}, 6), 12, '0') AS BIGINT)"
    total = f"((({hour} * 60 + {minute}) * 60 + {second}) * {zoned_times.PICOS_PER_SECOND} + {fraction})"
    valid = f"regexp_matches({sql}, {pattern}) AND {hour} <= 23 AND {minute} <= 59 AND {second} <= 59"
    return f"CASE WHEN {valid} THEN {of_picos(zoned_times.rounded_picos(total, precision), precision)} ELSE {bad} END"


def text(sql: str, precision: int) -> str:
    """Trino's text of a time(p > 6): HH:MM:SS and exactly p fraction digits."""
    return zoned_times.time_text(sql, precision)


def of_timestamp(epoch_picos: str, precision: int, negative: str) -> str:
    """CAST(timestamp AS time(precision)) from the timestamp's epoch picoseconds: the time of day rounded
    HALF_UP, modulo a day; before 1970 a value with a fraction of a second is a second early, as the real
    Trino 476 answers (times.of_timestamp); `negative` when that falls before midnight."""
    second = zoned_times.PICOS_PER_SECOND
    fraction = f"((({epoch_picos}) % {second} + {second}) % {second})"
    early = f"CASE WHEN ({epoch_picos}) < 0 AND {fraction} <> 0 THEN {second} ELSE 0 END"
    day = f"({zoned_times.modulo_day(epoch_picos)} - {early})"
    half = 10 ** (12 - precision) // 2 if precision < 12 else 0
    rounded = of_picos(zoned_times.rounded_picos(day, precision), precision)
    midnight = of_picos("0", precision)
    return f"CASE WHEN {day} >= 0 THEN {rounded} WHEN {day} + {half} >= 0 THEN {midnight} ELSE {negative} END"


def field(sql: str, name: str) -> str:
    """hour, minute, second or millisecond of a time(p > 6), as BIGINT."""
    return zoned_times.clock_field(sql, name)


def truncate(unit: str, sql: str) -> str:
    """date_trunc(unit, time(p > 6)): floored to the unit."""
    size = UNIT_PICOS[unit]
    return f"(({sql}) // {size} * {size})"


def add(unit: str, amount: str, sql: str) -> str:
    """date_add(unit, amount, time(p > 6)): the amount modulo a day of units, added modulo a day."""
    size = UNIT_PICOS[unit]
    return moved(sql, f"((CAST({amount} AS BIGINT) % {PICOS_PER_DAY // size}) * {size})")


def moved(sql: str, delta_sql: str) -> str:
    """A time(p > 6) moved by `delta_sql` picoseconds (any sign) modulo a day (TimeOperators.add)."""
    return zoned_times.modulo_day(f"({sql}) + ({delta_sql}) % {PICOS_PER_DAY}")


def difference(left_picos: str, right_picos: str) -> str:
    """time - time: an interval day to second of the difference rounded HALF_UP to milliseconds."""
    shifted = f"(({left_picos}) - ({right_picos}) + 500000000)"
    millis = f"(({shifted} - ({shifted} % 1000000000 + 1000000000) % 1000000000) // 1000000000)"
    return f"to_milliseconds({millis})"


#: The expressions written for time(p > 6) operands, and the functions.
_OPERATIONS = (
    *WIDE_TIME_OPERATIONS,
    exp.Coalesce,
    exp.Column,
    exp.AtTimeZone,
    exp.Distinct,
    exp.Subquery,
    exp.Max,
    exp.Min,
    exp.Count,
)
_FUNCTIONS = frozenset(
    "min max min_by max_by count arbitrary any_value coalesce typeof hour minute second millisecond date_trunc "
    "date_add date_diff".split()
)


def check_use(analyzer: Any, node: exp.Expression, t: TType) -> None:
    """Refuse `node` (of type `t`) when it holds a time(p > 6) nested in another type, or uses one as an
    operand in a way not written for it (DuckDB would read the picoseconds as a number)."""
    if any(is_wide(inner) for inner in tt.inner_types(t)):
        analyzer.unsupported(f"{t} (lakegate holds time(p > 6) only as a plain value)", node)
    children = [child for child in node.iter_expressions() if child._meta and is_wide(child.meta.get("t"))]
    if not children:
        return
    if isinstance(node, _OPERATIONS) and not (isinstance(node, exp.In) and node.args.get("query")):
        return
    if isinstance(node, exp.Anonymous) and node.name.lower() in _FUNCTIONS:
        return
    analyzer.unsupported(
        f"{trino_name(node)} of {children[0].meta['t']} (lakegate translates casts, comparisons, ordering, "
        "grouping, min, max, fields, date_trunc, date_add, date_diff and interval arithmetic for p > 6)",
        node,
    )
