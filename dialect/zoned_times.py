"""Trino's time(p) with time zone (p = 0..12) in DuckDB, exactly: a STRUCT of two integers.

Trino holds the local time of day in picoseconds and the offset in minutes (-14:00 .. +14:00), and
compares, orders and takes differences by the time at offset +00:00 modulo a day
(io.trino.spi.type.TimeWithTimeZoneTypes.normalize): `TIME '01:00 +01:00' = TIME '00:00 +00:00'`.
DuckDB's TIMETZ holds microseconds only and tells those two values apart, so lakegate holds
`STRUCT(utc_ps BIGINT, offset_min SMALLINT)`: `utc_ps` the picoseconds of the day at +00:00 (the
normalised time, first, so that DuckDB orders the struct as Trino orders the values, ties of one
instant in two offsets aside, which Trino leaves unordered), `offset_min` the offset. Comparisons
are written on `utc_ps` alone (write_operators); what would compare whole structs (GROUP BY,
DISTINCT, set operations, IN, joins on USING, values nested in arrays, maps or rows) is refused by
name (analysis_checks). The helpers return DuckDB SQL text from DuckDB SQL text.
"""

from __future__ import annotations

import re

from lakegate.dialect.errors import DialectError

PICOS_PER_SECOND = 10**12
PICOS_PER_MINUTE = 60 * PICOS_PER_SECOND
PICOS_PER_DAY = 86_400 * PICOS_PER_SECOND
MAX_OFFSET_MINUTES = 14 * 60
MAX_PRECISION = 12

#: The DuckDB type holding a time with time zone.
DUCKDB_TYPE = 'STRUCT("utc_ps" BIGINT, "offset_min" SMALLINT)'

#: Trino's text of a time with time zone (DateTimes.TIME_WITH_TIME_ZONE_PATTERN): h:m[:s[.f]], then
#: optional spaces and an offset +hh:mm, or no offset (the session zone's).
_TEXT = re.compile(r"([0-9]{1,2}):([0-9]{1,2})(?::([0-9]{1,2})(?:[.]([0-9]+))?)?(?: *([+-])([0-9]{2}):([0-9]{2}))?")
#: The same in SQL, for casts of varchar values (Java's trim: characters up to U+0020 around it).
TEXT_PATTERN = (
    "^[\\x00-\\x20]*([0-9]{1,2}):([0-9]{1,2})(?::([0-9]{1,2})(?:[.]([0-9]{1,12}))?)?"
    "(?: *([+-])([0-9]{2}):([0-9]{2}))?[\\x00-\\x20]*$"
)


def _string(value: str) -> str:
    return "'" + value.replace("'", "''") + "'"


def make(utc_sql: str, offset_sql: str) -> str:
    """The struct of a normalised time (0 <= utc_sql < one day, in picoseconds) and an offset in minutes."""
    return f'struct_pack("utc_ps" := CAST({utc_sql} AS BIGINT), "offset_min" := CAST({offset_sql} AS SMALLINT))'


def utc(sql: str) -> str:
    """The picoseconds of the day at offset +00:00 (what Trino compares)."""
    return f"struct_extract({sql}, 'utc_ps')"


def offset(sql: str) -> str:
    """The offset in minutes."""
    return f"CAST(struct_extract({sql}, 'offset_min') AS BIGINT)"


def modulo_day(sql: str) -> str:
    """`sql` picoseconds floored modulo a day (Math.floorMod)."""
    return f"((({sql}) % {PICOS_PER_DAY} + {PICOS_PER_DAY}) % {PICOS_PER_DAY})"


def local(sql: str) -> str:
    """The local time of day of a value, in picoseconds."""
    return modulo_day(f"{utc(sql)} + {offset(sql)} * {PICOS_PER_MINUTE}")


def of_local(local_sql: str, offset_sql: str) -> str:
    """The value of a local time of day in picoseconds (0 <= local_sql < one day) at an offset in minutes."""
    return make(modulo_day(f"{local_sql} - ({offset_sql}) * {PICOS_PER_MINUTE}"), offset_sql)


def rounded_picos(picos_sql: str, precision: int) -> str:
    """Non-negative picoseconds rounded HALF_UP to `precision` digits, modulo a day (Trino wraps a time
    rounded up to 24:00 around to 00:00)."""
    if precision >= 12:
        return picos_sql
    unit = 10 ** (12 - precision)
    return f"(((({picos_sql}) + {unit // 2}) // {unit}) * {unit} % {PICOS_PER_DAY})"


def round_to(sql: str, precision: int, source: int) -> str:
    """CAST(time(source) with time zone AS time(precision) with time zone): the local time rounded HALF_UP,
    the offset kept (TimeWithTimeZoneOperators / TimeWithTimeZoneToTimeWithTimeZoneCast)."""
    if precision >= source:
        return sql
    return of_local(rounded_picos(local(sql), precision), offset(sql))


def literal(text: str, precision: int, session_offset: int | None) -> tuple[int, int] | None:
    """The (utc_ps, offset_min) of Trino's text of a time with time zone rounded to `precision`, the
    session's offset when the text has none; None when Trino refuses the text (or needs an offset and
    `session_offset` is None)."""
    match = _TEXT.fullmatch(text)
    if match is None:
        return None
    hour, minute, second = int(match[1]), int(match[2]), int(match[3] or 0)
    if hour > 23 or minute > 59 or second > 59:
        return None
    fraction = match[4] or ""
    if match[5] is None:
        if session_offset is None:
            return None
        minutes = session_offset
    else:
        minutes = int(match[6]) * 60 + int(match[7])
        if int(match[7]) > 59 or minutes > MAX_OFFSET_MINUTES:
            return None
        minutes = -minutes if match[5] == "-" else minutes
    picos = ((hour * 60 + minute) * 60 + second) * PICOS_PER_SECOND
    if fraction:
        value = int(fraction)
        digits = len(fraction)
        if digits > 12:
            return None
        picos += value * 10 ** (12 - digits)
    unit = 10 ** (12 - precision)
    picos = (picos + unit // 2) // unit * unit % PICOS_PER_DAY
    return (picos - minutes * PICOS_PER_MINUTE) % PICOS_PER_DAY, minutes


def literal_precision(text: str) -> int | None:
    """The precision of a TIME literal with an offset (its fraction's digit count,
    DateTimes.extractTimePrecision); None when the text has no offset."""
    match = _TEXT.fullmatch(text)
    if match is None or match[5] is None:
        return None
    return len(match[4] or "")


def offset_of(zone: str) -> int | None:
    """The offset in minutes of a session zone that has one offset (UTC or +hh:mm); None for a region."""
    if zone == "UTC":
        return 0
    if zone[:1] not in ("+", "-"):
        return None
    minutes = int(zone[1:3]) * 60 + int(zone[4:6])
    return -minutes if zone[0] == "-" else minutes


def offset_text_of(minutes: int) -> str:
    """+hh:mm of an offset in minutes, as Python text."""
    return f"{'-' if minutes < 0 else '+'}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"


def constant(value: tuple[int, int]) -> str:
    """DuckDB SQL of a constant (utc_ps, offset_min)."""
    return make(str(value[0]), str(value[1]))


def parse(sql: str, precision: int, session_offset: str, bad: str) -> str:
    """CAST(varchar AS time(precision) with time zone) (TimeWithTimeZoneOperators.castFromVarchar): the
    fraction's digits rounded HALF_UP, 24:00 wrapped to 00:00, `session_offset` (SQL of minutes) when the
    text gives none; `bad` otherwise."""
    pattern = _string(TEXT_PATTERN)

    def part(index: int) -> str:
        return f"CAST(coalesce(nullif(regexp_extract({sql}, {pattern}, {index}), ''), '0') AS BIGINT)"

    hour, minute, second = part(1), part(2), part(3)
    picos = f"CAST(rpad(regexp_extract({sql}, {pattern}, 4), 12, '0') AS BIGINT)"
    total = f"((({hour} * 60 + {minute}) * 60 + {second}) * {PICOS_PER_SECOND} + {picos})"
    sign = f"regexp_extract({sql}, {pattern}, 5)"
    size = f"({part(6)} * 60 + {part(7)})"
    minutes = f"(CASE WHEN {sign} = '' THEN {session_offset} WHEN {sign} = '-' THEN -{size} ELSE {size} END)"
    valid = (
        f"regexp_matches({sql}, {pattern}) AND {hour} <= 23 AND {minute} <= 59 AND {second} <= 59 "
        f"AND {part(7)} <= 59 AND {size} <= {MAX_OFFSET_MINUTES}"
    )
    return f"CASE WHEN {valid} THEN {of_local(rounded_picos(total, precision), minutes)} ELSE {bad} END"


def _two(sql: str) -> str:
    return f"lpad(CAST({sql} AS VARCHAR), 2, '0')"


def time_text(picos_sql: str, precision: int) -> str:
    """HH:MM:SS and exactly `precision` fraction digits of a time of day in picoseconds (truncated)."""
    seconds = f"(({picos_sql}) // {PICOS_PER_SECOND})"
    text = f"{_two(f'{seconds} // 3600')} || ':' || {_two(f'{seconds} // 60 % 60')} || ':' || {_two(f'{seconds} % 60')}"
    if precision == 0:
        return text
    digits = f"(({picos_sql}) % {PICOS_PER_SECOND}) // {10 ** (12 - precision)}"
    return f"{text} || '.' || lpad(CAST({digits} AS VARCHAR), {precision}, '0')"


def offset_text(minutes_sql: str) -> str:
    """+hh:mm of an offset in minutes (-00:35 for minus 35 minutes)."""
    size = f"abs({minutes_sql})"
    sign = f"CASE WHEN {minutes_sql} < 0 THEN '-' ELSE '+' END"
    return f"{sign} || {_two(f'{size} // 60')} || ':' || {_two(f'{size} % 60')}"


def text(sql: str, precision: int) -> str:
    """Trino's text of a time(p) with time zone: HH:MM:SS[.f...]+hh:mm (TimeWithTimeZoneOperators.castToVarchar)."""
    return f"{time_text(local(sql), precision)} || {offset_text(offset(sql))}"


def to_time_micros(sql: str, precision: int) -> str:
    """The local time of day rounded HALF_UP to `precision` <= 6, as microseconds (CAST to time(p))."""
    return f"({rounded_picos(local(sql), precision)} // 1000000)"


def of_time_micros(micros_sql: str, offset_minutes: int | None) -> str:
    """CAST(time(p <= 6) AS time with time zone) at a fixed session offset; refused in a session zone whose
    offset changes (Trino takes it at the session's start)."""
    if offset_minutes is None:
        raise DialectError(
            "unsupported in lakegate: a time coerced to time with time zone in a session zone whose offset changes",
            error_name="NOT_SUPPORTED",
        )
    return of_local(f"(({micros_sql}) * 1000000)", str(offset_minutes))


#: Units of date_trunc, date_add and date_diff on a time with time zone, in picoseconds.
UNIT_PICOS = {
    "millisecond": 10**9,
    "second": PICOS_PER_SECOND,
    "minute": PICOS_PER_MINUTE,
    "hour": 60 * PICOS_PER_MINUTE,
}


def truncate(unit: str, sql: str) -> str:
    """date_trunc(unit, time with time zone): the local time floored to the unit, the offset kept."""
    size = UNIT_PICOS[unit]
    return of_local(f"({local(sql)} // {size} * {size})", offset(sql))


def field(sql: str, name: str) -> str:
    """hour, minute, second, millisecond of the local time, timezone_hour and timezone_minute of the
    offset (truncated toward zero: -00:35 is 0 and -35), as BIGINT."""
    if name == "timezone_hour":
        return f"CAST(trunc({offset(sql)} / 60) AS BIGINT)"
    if name == "timezone_minute":
        return f"CAST({offset(sql)} - trunc({offset(sql)} / 60) * 60 AS BIGINT)"
    return clock_field(local(sql), name)


def clock_field(picos_sql: str, name: str) -> str:
    """hour, minute, second or millisecond of a time of day in picoseconds, as BIGINT."""
    part = {
        "hour": f"// {60 * PICOS_PER_MINUTE}",
        "minute": f"// {PICOS_PER_MINUTE} % 60",
        "second": f"// {PICOS_PER_SECOND} % 60",
        "millisecond": f"% {PICOS_PER_SECOND} // 1000000000",
    }[name]
    return f"CAST(({picos_sql}) {part} AS BIGINT)"


def interval_picos(interval_sql: str) -> str:
    """A day-to-second interval (DuckDB INTERVAL of milliseconds) modulo a day, in picoseconds."""
    return f"((epoch_us({interval_sql}) % 86400000000) * 1000000)"


def add_picos(sql: str, delta_sql: str, precision: int) -> str:
    """The value moved by `delta_sql` picoseconds (any sign) modulo a day, rounded HALF_UP to the
    precision when it is under 3 (TimeWithTimeZoneOperators.add: milliseconds onto picoseconds)."""
    moved = modulo_day(f"{local(sql)} + ({delta_sql}) % {PICOS_PER_DAY}")
    return of_local(rounded_picos(moved, precision) if precision < 3 else moved, offset(sql))


def difference_picos(left: str, right: str) -> str:
    """left - right on the normalised times, in picoseconds (negative when left is earlier)."""
    return f"({utc(left)} - {utc(right)})"
