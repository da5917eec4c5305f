"""The casts of time(7..12) (dialect/pico_times.py), and of times to timestamps, which take the session's date.

Trino's CAST(time(p) AS timestamp(q)) and CAST(time(p) with time zone AS timestamp(q)) put the time of
day (the local time of a time with time zone) on the session's date, the date the query starts on in the
session zone, rounded HALF_UP to q digits (a time rounded up to 24:00 moves to the next day); to
timestamp(q) with time zone, a time is read in the session zone, and a time with time zone is the
instant of its time at +00:00 on that date, in its own offset (what the real Trino 476 answers:
TIME '23:34:56-08:35' on 2026-11-29 in UTC is 2026-11-28 23:34:56 -08:35).
"""

from __future__ import annotations

from typing import Any

from lakegate.dialect import pico_times, zoned_times, zones
from lakegate.dialect import trino_types as tt
from lakegate.dialect.trino_types import TType


def handles(source: TType, target: TType) -> bool:
    """Whether `cast` writes CAST(source AS target)."""
    if target.base == "varchar":
        return False
    if source.base in ("time", "time_tz") and target.base in ("timestamp", "timestamp_tz"):
        return True
    if source.base == "timestamp" and 6 < source.args[0] <= 9 and target.base in ("time", "time_tz"):
        return True
    return pico_times.is_wide(source) or pico_times.is_wide(target)


def _session_day_picos(g: Any) -> str:
    """The session's date in the session zone, as picoseconds since 1970-01-01."""
    day = f"CAST({zones.local('current_timestamp', g.time_zone)} AS DATE)"
    return f"(CAST(epoch_us(CAST({day} AS TIMESTAMP)) AS HUGEINT) * {pico_times.PICOS_PER_MICRO})"


def _timestamp_of_picos(epoch_picos: str, precision: int) -> str:
    """A timestamp(precision <= 9) of epoch picoseconds, rounded HALF_UP to the precision."""
    unit = 10 ** (12 - precision)
    rounded = f"(({epoch_picos}) + {unit // 2}) // {unit}"
    if precision > 6:
        return f"make_timestamp_ns(CAST({rounded} * {10 ** (9 - precision)} AS BIGINT))"
    return f"make_timestamp(CAST({rounded} * {10 ** (6 - precision)} AS BIGINT))"


def _epoch_picos(sql: str, source: TType) -> str:
    """The epoch picoseconds of a timestamp(p <= 9)."""
    if source.args[0] > 6:
        return f"(CAST(epoch_ns({sql}) AS HUGEINT) * 1000)"
    return f"(CAST(epoch_us({sql}) AS HUGEINT) * {pico_times.PICOS_PER_MICRO})"


def cast(g: Any, sql: str, source: TType, target: TType) -> str:
    """Trino's CAST(sql AS target) for the casts `handles` names (infer_casts allowed them)."""
    precision = target.args[0]
    if source.base in ("time", "time_tz") and target.base in ("timestamp", "timestamp_tz"):
        day = _session_day_picos(g)
        if source.base == "time_tz" and target.base == "timestamp_tz":  # the instant at +00:00, in its offset
            stamp = _timestamp_of_picos(f"{day} + {zoned_times.utc(sql)}", precision)
            return f"CAST({stamp} AS TIMESTAMPTZ)"
        of_day = zoned_times.local(sql) if source.base == "time_tz" else pico_times.picos(sql, source)
        stamp = _timestamp_of_picos(f"{day} + {of_day}", precision)
        if target.base == "timestamp_tz":
            return zones.instant(stamp, tt.zone_of(target))
        return stamp
    if source.base == "time" and target.base == "time":
        return pico_times.round_time(sql, source, precision)
    if source.base == "varchar":
        message = f"'Value cannot be cast to time: ' || {sql}"
        return pico_times.parse(sql, precision, g.fail(message, "INVALID_CAST_ARGUMENT"))
    if source.base in ("time", "timestamp") and target.base == "time_tz":  # at the session zone's offset
        of_day = (
            pico_times.picos(sql, source)
            if source.base == "time"
            else zoned_times.modulo_day(_epoch_picos(sql, source))
        )
        rounded = zoned_times.rounded_picos(of_day, precision)
        return zoned_times.of_local(rounded, str(zoned_times.offset_of(g.time_zone)))
    if source.base == "time_tz":  # to time(p > 6): its local time
        return pico_times.of_picos(zoned_times.rounded_picos(zoned_times.local(sql), precision), precision)
    if source.base == "timestamp":
        negative = g.fail("'value must be >= 0'", "GENERIC_INTERNAL_ERROR")
        return pico_times.of_timestamp(_epoch_picos(sql, source), precision, negative)
    if source.base == "timestamp_tz":  # its wall time's time of day (p <= 6, no rounding to p > 6)
        wall = zones.local(sql, tt.zone_of(source))
        return pico_times.of_picos(zoned_times.modulo_day(_epoch_picos(wall, tt.timestamp(6))), precision)
    raise AssertionError(f"CAST({source} AS {target})")
