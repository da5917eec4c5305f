"""Trino's time(p) (without time zone) in DuckDB's TIME, which holds microseconds: p <= 6 only.

A time is computed here as its microseconds of the day (DuckDB's epoch_us of a TIME). Trino rounds
HALF_UP to the target precision and wraps a value rounded up to 24:00 around to 00:00
(io.trino.operator.scalar.time.TimeOperators: castFromVarchar and castToTime take the rounded
picoseconds modulo a day). The helpers return DuckDB SQL text from DuckDB SQL text.
"""

from __future__ import annotations

MICROS_PER_DAY = 86_400_000_000

#: Trino's DateTimes.TIME_PATTERN without the offset (parseTime refuses one): h:m[:s[.f]], then
#: optional white space; hours <= 23, minutes and seconds <= 59, at most 12 fraction digits.
TIME_TEXT = "^([0-9]{1,2}):([0-9]{1,2})(:([0-9]{1,2})([.]([0-9]{1,12}))?)?[ \\t\\n\\x0b\\f\\r]*$"


def _string(value: str) -> str:
    return "'" + value.replace("'", "''") + "'"


def micros(sql: str) -> str:
    """The microseconds of the day of DuckDB TIME `sql`."""
    return f"epoch_us({sql})"


def of_micros(sql: str) -> str:
    """DuckDB TIME of microseconds of the day `sql` (0 <= sql < one day)."""
    return f"(TIME '00:00:00' + to_microseconds({sql}))"


def rounded(micros_sql: str, precision: int) -> str:
    """Non-negative microseconds rounded HALF_UP to `precision` digits, modulo a day, as TIME."""
    if precision >= 6:
        return of_micros(f"(({micros_sql}) % {MICROS_PER_DAY})")
    unit = 10 ** (6 - precision)
    return of_micros(f"(((({micros_sql}) + {unit // 2}) // {unit}) * {unit} % {MICROS_PER_DAY})")


def round_time(sql: str, precision: int, source: int) -> str:
    """CAST(time(source) AS time(precision)): unchanged when not narrower (TimeOperators.castToTime)."""
    return sql if precision >= source else rounded(micros(sql), precision)


def of_timestamp(sql: str, precision: int, negative: str) -> str:
    """CAST(timestamp(q <= 6) AS time(precision)): the time of day, rounded HALF_UP to the precision,
    modulo a day (io.trino.operator.scalar.timestamp.TimestampToTimeCast). Before 1970 a value with a
    fraction of a second is a second early, as the real Trino 476 answers (it adds the fraction's
    truncated, negative remainder to the floored second); `negative` when that falls before midnight
    and does not round up to it (Trino's "value must be >= 0")."""
    epoch = f"epoch_us({sql})"
    fraction = f"(({epoch} % 1000000 + 1000000) % 1000000)"
    early = f"CASE WHEN {epoch} < 0 AND {fraction} <> 0 THEN 1000000 ELSE 0 END"
    day_micros = f"(({epoch} % {MICROS_PER_DAY} + {MICROS_PER_DAY}) % {MICROS_PER_DAY} - {early})"
    half = 10 ** (6 - precision) // 2 if precision < 6 else 0
    return (
        f"CASE WHEN {day_micros} >= 0 THEN {rounded(day_micros, precision)} "
        f"WHEN {day_micros} + {half} >= 0 THEN TIME '00:00:00' ELSE {negative} END"
    )


def parse(sql: str, precision: int, bad: str) -> str:
    """CAST(varchar AS time(precision)) (TimeOperators.castFromVarchar over DateTimes.parseTime): the
    fraction's digits rounded HALF_UP to the precision, 24:00 wrapped to 00:00; `bad` otherwise."""
    pattern = _string(TIME_TEXT)

    def part(index: int) -> str:
        return f"CAST(coalesce(nullif(regexp_extract({sql}, {pattern}, {index}), ''), '0') AS BIGINT)"

    hour, minute, second = part(1), part(2), part(4)
    fraction = f"rpad(regexp_extract({sql}, {pattern}, 6), 12, '0')"
    picos = f"CAST({fraction} AS BIGINT)"  # the fraction as picoseconds
    unit = 10 ** (12 - precision)
    fraction_micros = f"((({picos} + {unit // 2}) // {unit}) * {10 ** (6 - precision)})"
    total = f"((({hour} * 60 + {minute}) * 60 + {second}) * 1000000 + {fraction_micros})"
    valid = f"regexp_matches({sql}, {pattern}) AND {hour} <= 23 AND {minute} <= 59 AND {second} <= 59"
    return f"CASE WHEN {valid} THEN {of_micros(f'({total} % {MICROS_PER_DAY})')} ELSE {bad} END"


def text(sql: str, precision: int) -> str:
    """Trino's text of a time(p): HH:MM:SS and exactly p fraction digits (TimeOperators.castToVarchar)."""
    stamp = f"(DATE '1970-01-01' + {sql})"
    if precision == 0:
        return f"strftime({stamp}, '%H:%M:%S')"
    return f"left(strftime({stamp}, '%H:%M:%S.%f'), {9 + precision})"


#: The units of date_trunc, date_add and date_diff on a time, in microseconds (TimeFunctions, TimeField).
UNIT_MICROS = {"millisecond": 1_000, "second": 1_000_000, "minute": 60_000_000, "hour": 3_600_000_000}


def truncate(unit: str, sql: str) -> str:
    """date_trunc(unit, time): the time floored to the unit (TimeFunctions.truncate)."""
    size = UNIT_MICROS[unit]
    return of_micros(f"({micros(sql)} // {size} * {size})")


def add(unit: str, amount: str, sql: str, precision: int) -> str:
    """date_add(unit, amount, time(p)): the amount modulo a day of units, added modulo a day, rounded
    HALF_UP to p when p < 3 (TimeFunctions.dateAdd, TimeOperators.add)."""
    size = UNIT_MICROS[unit]
    delta = f"((CAST({amount} AS BIGINT) % {MICROS_PER_DAY // size}) * {size})"
    total = f"((({micros(sql)} + {delta}) % {MICROS_PER_DAY} + {MICROS_PER_DAY}) % {MICROS_PER_DAY})"
    return rounded(total, precision) if precision < 3 else of_micros(total)


def diff(unit: str, first: str, second: str) -> str:
    """date_diff(unit, time1, time2): whole units from time1 to time2, truncated toward zero
    (TimeFunctions.dateDiff)."""
    return f"(({micros(second)} - {micros(first)}) // {UNIT_MICROS[unit]})"
