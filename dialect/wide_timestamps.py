"""Trino's timestamp(p) with time zone for p = 7..12, and timestamp(p) for p = 10..12, in DuckDB, exactly: a
STRUCT of the instant (the wall time) floored to the microsecond and the picoseconds of that microsecond.

Trino holds such a value as a LongTimestampWithTimeZone (epoch milliseconds, picoseconds of the
millisecond, zone). lakegate holds `STRUCT(us TIMESTAMPTZ, ps INTEGER)`: `us` the instant floored to the
microsecond, a TIMESTAMPTZ as every timestamp(p <= 6) with time zone (so each zone-dependent operation of
those applies to it unchanged: dialect/zones.py), and `ps` the picoseconds below it (0 .. 999,999, a
multiple of 10^(12 - p)). The zone is static, in the expression's Trino type, as for every zoned
timestamp. DuckDB compares and orders structs field by field, so =, <, BETWEEN, ORDER BY, GROUP BY,
DISTINCT, min and max are Trino's on the instant. Trino's date and time functions read the microseconds
of such a value (LongTimestampWithTimeZone's epoch micros, floored): the analysis gives them `us`
(type_rules.FloorMicros). Casts round HALF_UP, ties toward the later instant (Timestamps.round). A
timestamp(10..12) is the same struct of its wall time, `STRUCT(us TIMESTAMP, ps INTEGER)` (timestamp(7..9)
stays DuckDB's TIMESTAMP_NS). The helpers return DuckDB SQL text from DuckDB SQL text.
"""

from __future__ import annotations

import datetime as dt
import re
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

from sqlglot import exp

from lakegate.dialect import zones
from lakegate.dialect.guard import trino_name
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import WIDE_TIME_OPERATIONS, Analysis, FloorMicros

PICOS_PER_MICRO = 1_000_000


def is_wide(t: TType | None) -> bool:
    """Whether `t` is held as a struct: a timestamp(7..12) with time zone or a timestamp(10..12)."""
    return t is not None and (t.base == "timestamp_tz" and t.args[0] > 6 or t.base == "timestamp" and t.args[0] > 9)


def make(micros_sql: str, picos_sql: str, zoned: bool = True) -> str:
    """The value of an instant (TIMESTAMPTZ; a wall time, TIMESTAMP, when not `zoned`) floored to the
    microsecond and the picoseconds below it; NULL when the instant is NULL."""
    duck = "TIMESTAMPTZ" if zoned else "TIMESTAMP"
    if micros_sql.startswith(f"{duck} '"):  # a constant
        return f'struct_pack("us" := {micros_sql}, "ps" := CAST({picos_sql} AS INTEGER))'
    return (
        f"CASE WHEN ({micros_sql}) IS NOT NULL THEN struct_pack("
        f'"us" := CAST({micros_sql} AS {duck}), "ps" := CAST({picos_sql} AS INTEGER)) END'
    )


def shown(sql: str, zone: str | None) -> str:
    """A result value: its microseconds and picoseconds (ordered as the value), its wall time (in `zone`
    when zoned) in epoch microseconds and the zone's name, which gateway/engine/trino_values.py writes as
    Trino's text."""
    wall = f"epoch_us({micros(sql) if zone is None else zones.local(micros(sql), zone)})"
    name = "NULL" if zone is None else f"'{zone}'"
    return (
        f'CASE WHEN ({sql}) IS NOT NULL THEN struct_pack("us" := {micros(sql)}, "ps" := {picos(sql)}, '
        f'"wall" := {wall}, "zone" := {name}) END'
    )


def micros(sql: str) -> str:
    """The instant floored to the microsecond (TIMESTAMPTZ): what Trino's functions read."""
    return f"struct_extract({sql}, 'us')"


def picos(sql: str) -> str:
    """The picoseconds below the microsecond (0 .. 999,999)."""
    return f"struct_extract({sql}, 'ps')"


def widen(sql: str) -> str:
    """A timestamp(p <= 6) with time zone (TIMESTAMPTZ) as a wide value."""
    return make(sql, "0")


def _nanos_parts(sql: str) -> tuple[str, str]:
    """A TIMESTAMP_NS as its microseconds (TIMESTAMP, floored) and the picoseconds below them."""
    nanos = f"epoch_ns({sql})"
    floored = f"(({nanos}) - ((({nanos}) % 1000) + 1000) % 1000) // 1000"
    return f"make_timestamp({floored})", f"((({nanos}) % 1000) + 1000) % 1000 * 1000"


def coerce(sql: str, source: TType, zone: str, zoned: bool = True) -> str:
    """A value of `source` as a wide value (a zoned one, or a wall time when not `zoned`): a wide one of
    that kind unchanged (its precision is the struct's), a timestamp or date as a wall time, read in
    `zone` when zoned (the session zone, as Trino's implicit coercion and casts), a timestamp with time
    zone as its wall time in its own zone when not (`zone` is then its zone)."""
    if is_wide(source) and (source.base == "timestamp_tz") == zoned:
        return sql
    if source.base == "timestamp_tz":
        if zoned:
            return widen(sql)
        if is_wide(source):
            return make(zones.local(micros(sql), zone), picos(sql), zoned=False)
        return make(zones.local(sql, zone), "0", zoned=False)
    if is_wide(source):
        wall, below = micros(sql), picos(sql)
    elif source.base == "timestamp" and source.args[0] > 6:
        wall, below = _nanos_parts(sql)
    else:
        wall, below = f"CAST({sql} AS TIMESTAMP)", "0"
    return of_wall(wall, below, zone) if zoned else make(wall, below, zoned=False)


def of_nanoseconds(nanos_sql: str) -> str:
    """The value of whole nanoseconds since the epoch (BIGINT)."""
    floored = f"(({nanos_sql}) - ((({nanos_sql}) % 1000) + 1000) % 1000)"
    return make(f"make_timestamp({floored} // 1000)", f"((({nanos_sql}) % 1000) + 1000) % 1000 * 1000")


def round_to(sql: str, precision: int, source: int, zoned: bool = True) -> str:
    """CAST to timestamp(precision) [with time zone]: the picoseconds rounded HALF_UP to `precision`
    digits, a carry moving the microsecond (TimestampWithTimeZoneToTimestampWithTimeZoneCast,
    TimestampToTimestampCast); for precision <= 6 the TIMESTAMPTZ (TIMESTAMP) of the rounded value (the
    picoseconds then decide only a tie at the microsecond)."""
    if precision >= source:
        return sql
    if precision >= 6:
        unit = 10 ** (12 - precision)
        rounded = f"(({picos(sql)} + {unit // 2}) // {unit} * {unit})"
        carry = f"({rounded} // {PICOS_PER_MICRO})"
        moved = f"({micros(sql)} + to_microseconds({carry}))"
        if precision == 6:
            return moved
        return make(moved, f"{rounded} % {PICOS_PER_MICRO}", zoned)
    # below microseconds a unit is a whole number of microseconds, and half of it too: the
    # picoseconds never move the rounded value
    unit = 10 ** (6 - precision)
    epoch = f"epoch_us({micros(sql)})"
    shifted = f"(({epoch}) + {unit // 2})"
    duck = "TIMESTAMPTZ" if zoned else "TIMESTAMP"
    return f"CAST(make_timestamp({shifted} - ({shifted} % {unit} + {unit}) % {unit}) AS {duck})"


def fraction_digits(sql: str, precision: int) -> str:
    """The 7th to `precision`th fraction digits of a value, as text."""
    return f"left(lpad(CAST({picos(sql)} AS VARCHAR), 6, '0'), {precision - 6})"


def to_unixtime(sql: str) -> str:
    """to_unixtime: epoch milliseconds / 1000.0 + picoseconds of the millisecond / 1e12, in doubles
    (DateTimeFunctions.toUnixTime of a LongTimestampWithTimeZone)."""
    us = f"epoch_us({micros(sql)})"
    millis = f"(({us}) - ((({us}) % 1000) + 1000) % 1000) // 1000"
    below = f"(((({us}) % 1000) + 1000) % 1000 * {PICOS_PER_MICRO} + {picos(sql)})"
    return f"(CAST({millis} AS DOUBLE) / 1000.0 + CAST({below} AS DOUBLE) / 1e12)"


#: A wall time as Trino's timestamp literals write it (years 1..9999 here; others are read in SQL).
_WALL = re.compile(
    r"([0-9]{4})-([0-9]{1,2})-([0-9]{1,2})(?: ([0-9]{1,2}):([0-9]{1,2})(?::([0-9]{1,2})(?:[.]([0-9]{1,12}))?)?)?"
)


def constant(local: str, precision: int, zone: str) -> str | None:
    """DuckDB SQL of the value a literal's wall time `local` names in `zone`, rounded HALF_UP to
    `precision` digits, computed here (java.time's reading: a wall time in a gap moves forward by the
    gap, one in an overlap is the earlier instant, as Python's fold=0); None when Python cannot read it."""
    match = _WALL.fullmatch(local.strip())
    if match is None:
        return None
    digits = match[7] or ""
    unit = 10 ** (12 - precision)
    fraction = (int(digits.ljust(12, "0") or 0) + unit // 2) // unit * unit
    try:
        wall = dt.datetime(*(int(part or 0) for part in match.groups()[:6]))
        tzinfo = dt.UTC if zone == zones.UTC else _offset(zone) if zones.is_offset(zone) else ZoneInfo(zone)
        moved = dt.timedelta(microseconds=fraction // PICOS_PER_MICRO)
        instant = wall.replace(tzinfo=tzinfo).astimezone(dt.UTC) + moved
    except (ValueError, OverflowError, ZoneInfoNotFoundError):
        return None
    text = instant.strftime("%Y-%m-%d %H:%M:%S.%f")
    return make(f"TIMESTAMPTZ '{text}+00'", str(fraction % PICOS_PER_MICRO))


def _offset(zone: str) -> dt.timezone:
    minutes = int(zone[1:3]) * 60 + int(zone[4:6])
    return dt.timezone(dt.timedelta(minutes=-minutes if zone[0] == "-" else minutes))


def of_wall(wall_micros_sql: str, picos_sql: str, zone: str) -> str:
    """The value of a wall time in `zone` (TIMESTAMP floored to the microsecond, and picoseconds)."""
    return make(zones.instant(f"CAST({wall_micros_sql} AS TIMESTAMP)", zone), picos_sql)


#: The functions of a zone's offset at the instant: they read the microseconds too.
ZONE_READERS = frozenset({"timezone_hour", "timezone_minute"})
#: The functions written for such operands besides those that read their microseconds
#: (analysis_checks.MICROS_READERS and ZONE_READERS).
FUNCTIONS = ZONE_READERS | frozenset(
    "min max count arbitrary any_value coalesce typeof to_unixtime from_unixtime_nanos at_timezone".split()
)
#: The expressions written for such operands (functions: only FUNCTIONS and the readers).
OPERATIONS = (
    *WIDE_TIME_OPERATIONS,
    exp.Column,
    exp.AtTimeZone,
    exp.Distinct,
    exp.Subquery,
    FloorMicros,
)


def check_use(analyzer: Analysis, node: exp.Expression, readers: frozenset[str]) -> None:
    """Refuse `node` when it takes a timestamp(7..12) with time zone operand in a way not written for it
    (NOT_SUPPORTED naming the construct); `readers` are the functions that read its microseconds."""
    if isinstance(node, OPERATIONS):
        return
    if isinstance(node, exp.Anonymous) and node.name.lower() in FUNCTIONS | readers:
        return
    for child in node.iter_expressions():
        t = child.meta.get("t") if child._meta else None
        if is_wide(t):
            analyzer.unsupported(
                f"{trino_name(node)} of {t} (lakegate translates casts, comparisons, ordering, min, max, "
                "interval arithmetic, AT TIME ZONE and the date and time functions for p > 6)",
                node,
            )
