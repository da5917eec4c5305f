"""Trino's functions/datetime.md. Date and time functions and operators (the format and parse functions are in
datetime_formats.py).

from_unixtime_nanos: nanoseconds since the epoch as a timestamp(9) with time
zone in the session zone, held as dialect/wide_timestamps.py describes.

Source: trinodb/trino core/trino-main/src/main/java/io/trino/operator/scalar/DateTimeFunctions.java
(fromUnixtimeNanosLong; FromUnixtimeNanosDecimal rounds a decimal HALF_UP to whole nanoseconds) and
operator/scalar/timestamptz/ToUnixTime.java; cases in tests/dialect/cases/datetime.yaml.
"""

from __future__ import annotations

import re

from lakegate.dialect import intervals, pico_times, times, zones
from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import wide_timestamps as wide
from lakegate.dialect import write_casts as casts
from lakegate.dialect.functions.arguments import KINDS, fixed, literal_int, literal_str, need
from lakegate.dialect.registry import overload, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype

# === date and time ================================================================================
_UNITS = ("millisecond", "second", "minute", "hour", "day", "week", "month", "quarter", "year")

_DATE_UNITS = ("day", "week", "month", "quarter", "year")


def _unit(call: Call, index: int) -> None:
    """The unit must be a literal; one the value's type does not have fails when the call runs
    (`_unit_failure`), as in Trino: not under TRY, on NULL arguments or on no rows."""
    if literal_str(call, index) is None:
        call.fail("the unit must be a literal string in lakegate", "NOT_SUPPORTED")


def _unit_failure(g, node, args, values) -> str | None:
    """Trino's run-time INVALID_FUNCTION_ARGUMENT of a unit that the type of `values` (date,
    timestamp or timestamp with time zone) does not have, NULL when an argument is NULL; None when
    the unit is valid."""
    temporal = tt.common_super_type(*map(ttype, values)) if len(values) > 1 else ttype(values[0])
    unit = args[0].name
    if temporal is None or unit.lower() in (_DATE_UNITS if temporal.base == "date" else _UNITS):
        return None
    kind = "DATE" if temporal.base == "date" else "TIMESTAMP"
    nulls = " OR ".join(f"({g.sql(a)}) IS NULL" for a in args[1:])
    failure = g.fail(tf.string(f"'{unit}' is not a valid {kind} field"))
    return f"CASE WHEN {nulls} THEN NULL ELSE {tf.cast(failure, ttype(node))} END"


def _is_time(t: TType | None) -> bool:
    return t is not None and t.base == "time"


def _is_text(t: TType | None) -> bool:
    return t is not None and KINDS["string"](t)


def _time_unit(call: Call) -> None:
    """The unit of date_trunc, date_add or date_diff on a time: millisecond to hour (TimeFunctions)."""
    unit = literal_str(call, 0)
    if unit is None:
        call.fail("the unit must be a literal string in lakegate", "NOT_SUPPORTED")
    if unit.lower() not in times.UNIT_MICROS:
        call.fail(f"'{unit}' is not a valid Time field", "INVALID_FUNCTION_ARGUMENT")


def _date_diff(call: Call) -> TType:
    if len(call.types) == 3 and (_is_time(call.types[1]) or _is_time(call.types[2])):
        common = tt.common_super_type(call.types[1], call.types[2]) if None not in call.types else None
        if not _is_time(common) or not _is_text(call.types[0]):
            call.mismatch()
        _time_unit(call)
        return tt.BIGINT
    types = need(call, "string", "temporal", "temporal")
    common_type = tt.common_super_type(types[1], types[2])
    if common_type is None:
        call.mismatch()
    _unit(call, 0)
    return tt.BIGINT


def _render_date_diff(g, node, args) -> str:
    """Whole units between the values, as Trino counts them (DateDiff): on timestamps with time zone
    of at most millisecond precision, days and longer units between the wall times in the first
    value's zone, shorter ones elapsed (Joda's chronology of that zone); above, all in UTC
    (io.trino.operator.scalar.timestamptz.DateDiff: its short and long implementations differ).
    Values of more than millisecond precision are floored to milliseconds first."""
    if (failure := _unit_failure(g, node, args, args[1:])) is not None:
        return failure
    unit = args[0].name.lower()
    a, b = g.sql(args[1]), g.sql(args[2])
    first = ttype(args[1])
    common = tt.common_super_type(first, ttype(args[2]))
    if pico_times.is_wide(common):  # whole units between the picoseconds, truncated toward zero
        size = pico_times.UNIT_PICOS[unit]
        first_picos, second_picos = pico_times.picos(a, first), pico_times.picos(b, ttype(args[2]))
        return f"CAST(({second_picos} - {first_picos}) // {size} AS BIGINT)"
    if common is not None and common.base == "time":
        return f"CAST({times.diff(unit, a, b)} AS BIGINT)"
    if common is not None and common.base == "timestamp_tz":
        zone = tt.zone_of(first) if first.base == "timestamp_tz" else g.time_zone
        zone = zone if unit in _DATE_UNITS and common.args[0] <= 3 else zones.UTC
        a, b = (zones.local(g.coerce(arg, common), zone) for arg in args[1:])
    if max(t.args[0] if t.args else 0 for t in map(ttype, args[1:])) > 3:
        a, b = f"date_trunc('millisecond', {a})", f"date_trunc('millisecond', {b})"
    return f"CAST(date_sub({tf.string(unit)}, {a}, {b}) AS BIGINT)"


def _date_add(call: Call) -> TType:
    if len(call.types) == 3 and _is_time(call.types[2]):
        amount = call.types[1]
        if amount is None or not (amount.is_integral or amount.is_unknown) or not _is_text(call.types[0]):
            call.mismatch()
        _time_unit(call)
        return call.types[2]
    types = need(call, "string", "integral", "temporal")
    _unit(call, 0)
    return types[2]


_INTERVAL_OF = {
    "millisecond": "to_milliseconds",
    "second": "to_seconds",
    "minute": "to_minutes",
    "hour": "to_hours",
    "day": "to_days",
    "week": "to_weeks",
    "month": "to_months",
    "quarter": None,
    "year": "to_years",
}


def _int_amount(g, amount: str, t: TType) -> str:
    """date_add's amount, which Trino takes as an integer: past its range a timestamp fails with
    INVALID_FUNCTION_ARGUMENT (NULL inside try()), a date with GENERIC_INTERNAL_ERROR (try() lets it
    through), both "integer overflow", as the real Trino 476 answers."""
    if t.base == "date":
        overflow = f"error({tf.string('GENERIC_INTERNAL_ERROR: integer overflow')})"
    else:
        overflow = g.fail(tf.string("integer overflow"))
    return f"CASE WHEN ({amount}) NOT BETWEEN -2147483648 AND 2147483647 THEN {overflow} ELSE {amount} END"


def _render_date_add(g, node, args) -> str:
    if ttype(node).base != "time" and (failure := _unit_failure(g, node, args, args[2:])) is not None:
        return failure
    unit = args[0].name.lower()
    amount, value = g.sql(args[1]), g.sql(args[2])
    if pico_times.is_wide(ttype(node)):
        return pico_times.add(unit, amount, value)
    if ttype(node).base == "time":
        return times.add(unit, amount, value, ttype(node).args[0])
    amount = _int_amount(g, amount, ttype(node))
    interval = (
        f"to_months(3 * CAST({amount} AS INTEGER))"
        if unit == "quarter"
        else f"{_INTERVAL_OF[unit]}"
        f"(CAST({amount} AS {'INTEGER' if unit in ('month', 'year', 'week', 'day') else 'BIGINT'}))"
    )
    t = ttype(node)
    if t.base == "timestamp_tz" and unit in _DATE_UNITS:  # calendar units in the value's zone
        zone = tt.zone_of(t)
        return tf.cast(zones.instant(f"({zones.local(value, zone)} + {interval})", zone), t)
    sql = f"({value} + {interval})"
    if t.base == "timestamp" and t.args[0] > 6:  # the nanoseconds below the microsecond stay (DateAdd)
        return casts.with_nanos(sql, g.sql(args[2].this))
    if t.base == "timestamp" and t.args[0] < 3 and unit == "millisecond":  # rounded to p digits (DateAdd)
        return casts.round_timestamp(sql, t.args[0])
    if t.base == "timestamp_tz" and t.args[0] < 3 and unit == "millisecond":  # the instant, rounded as well
        return f"CAST({casts.round_timestamp(sql, t.args[0])} AS TIMESTAMPTZ)"
    return tf.cast(sql, t)


def _date_trunc(call: Call) -> TType:
    if len(call.types) == 2 and _is_time(call.types[1]):
        if not _is_text(call.types[0]):
            call.mismatch()
        _time_unit(call)
        return call.types[1]
    types = need(call, "string", "temporal")
    _unit(call, 0)
    return types[1]


def _timezone(call: Call) -> TType:
    if len(call.types) != 1 or call.types[0] is None or call.types[0].base not in ("timestamp_tz", "unknown"):
        call.mismatch()  # a timestamp would be read in the session zone: refused as the other kinds are
    if call.types[0].base == "timestamp_tz":
        call.analyzer.zone(call.types[0], call.node, "timezone(...)")
    return tt.VARCHAR


def _render_timezone(g, node, args) -> str:
    zone = tt.zone_of(ttype(args[0]))
    if zone is None:  # NULL
        return "CAST(NULL AS VARCHAR)"
    return f"CASE WHEN {g.sql(args[0])} IS NULL THEN NULL ELSE {tf.string(zone)} END"


def _render_date_trunc(g, node, args) -> str:
    if ttype(node).base != "time" and (failure := _unit_failure(g, node, args, args[1:])) is not None:
        return failure
    unit, value = args[0].name.lower(), g.sql(args[1])
    t = ttype(node)
    if pico_times.is_wide(t):
        return pico_times.truncate(unit, value)
    if t.base == "time":
        return times.truncate(unit, value)
    if t.base == "timestamp_tz":  # on the wall time in the value's zone (Joda's ZonedDateTimeField.roundFloor)
        wall = zones.local(value, tt.zone_of(t))
        truncated = f"date_trunc({tf.string(unit)}, {wall})"
        if unit in _DATE_UNITS:
            return zones.instant(truncated, tt.zone_of(t))
        return f"({value} - ({wall} - {truncated}))"  # shorter units keep the value's offset
    return tf.cast(f"date_trunc({tf.string(unit)}, {value})", t)


# from_iso8601_date parses as Joda's ISODateTimeFormat.dateElementParser (Trino's DateTimeFunctions):
# the longest of yyyy[-MM[-dd]], xxxx-Www[-e] and yyyy-DDD wins, the first on a tie; a field may have
# fewer digits than its width, a year a sign. Years outside 1..9999 (which Python's dates, and so the
# results, cannot hold) are refused at run time.
_ISO_DAY = r"^([+-]?[0-9]{1,9})(?:-([0-9]{1,2})(?:-([0-9]{1,2}))?)?$"

_ISO_WEEK = r"^([+-]?[0-9]{1,9})-W([0-9]{1,2})(?:-([0-9]))?$"

_ISO_ORDINAL = r"^([+-]?[0-9]{1,9})-([0-9]{3})$"


def _iso_parts(value: str, pattern: str) -> tuple[str, str, str]:
    """Year, second and third field of `pattern`'s match as integers (the missing ones 1)."""
    fields = [f"CAST(regexp_extract({value}, {tf.string(pattern)}, {i}) AS BIGINT)" for i in (1, 2)]
    third = f"CAST(coalesce(nullif(regexp_extract({value}, {tf.string(pattern)}, 3), ''), '1') AS BIGINT)"
    if pattern == _ISO_DAY:
        fields[1] = f"CAST(coalesce(nullif(regexp_extract({value}, {tf.string(pattern)}, 2), ''), '1') AS BIGINT)"
    return fields[0], fields[1], third


def _from_unixtime(call: Call) -> TType:
    """from_unixtime(x) is in the session zone, from_unixtime(x, zone) in the zone a literal names,
    from_unixtime(x, hours, minutes) at that offset (literals: DateTimeFunctions.fromUnixTime)."""
    if len(call.args) == 3:
        need(call, "number", "integral", "integral")
        hours, minutes = literal_int(call, 1), literal_int(call, 2)
        if hours is None or minutes is None:
            call.fail("unsupported in lakegate: from_unixtime with an offset that is not literal", "NOT_SUPPORTED")
        total = hours * 60 + minutes
        if abs(total) > 14 * 60:
            call.fail(f"Invalid offset minutes {total}", "INVALID_FUNCTION_ARGUMENT")
        sign = "-" if total < 0 else "+"
        return tt.timestamp(3, True, zones.canonical(f"{sign}{abs(total) // 60:02d}:{abs(total) % 60:02d}"))
    need(call, "number", "string", optional=1)
    if len(call.args) == 1:
        return tt.timestamp(3, True, call.analyzer.time_zone)
    zone = call.literal(1)
    if zone is None or not zone.is_string:
        call.fail("unsupported in lakegate: from_unixtime with a zone that is not a literal", "NOT_SUPPORTED")
    return tt.timestamp(3, True, call.analyzer.zone_literal(zone))


def _render_from_unixtime(g, node, args) -> str:
    seconds = f"CAST({g.sql(args[0])} AS DOUBLE)"  # as Java's Math.round: half up, NaN is 0
    millis = f"CAST(CASE WHEN isnan({seconds}) THEN 0 ELSE floor({seconds} * 1000 + 0.5) END AS BIGINT)"
    return f"timezone('UTC', epoch_ms({millis}))"


def _to_unixtime(call: Call) -> TType:
    types = need(call, "temporal")
    if types[0].base == "date":
        call.mismatch()
    return tt.DOUBLE


def _render_to_unixtime(g, node, args) -> str:
    """A timestamp is an instant in the session zone (Trino coerces it to timestamp with time zone)."""
    return f"epoch({g.coerce(args[0], tt.timestamp(6, True))})"


def _field(call: Call) -> TType:
    name = call.name
    first = call.types[0] if len(call.types) == 1 else None
    if first is not None and first.base == "time" and name in ("hour", "minute", "second", "millisecond"):
        return tt.BIGINT  # of a time (DateTimeFunctions: hourFromTime, ...)
    if first is not None and first.base in intervals.FIELDS:
        return tt.BIGINT if name in intervals.FIELDS[first.base] else call.mismatch()
    types = need(call, "temporal")
    if types[0].base == "date" and name in ("hour", "minute", "second", "millisecond"):
        call.mismatch()
    return tt.BIGINT


_FIELD_OF = {
    "year": "year",
    "quarter": "quarter",
    "month": "month",
    "week": "week",
    "week_of_year": "week",
    "day": "day",
    "day_of_month": "day",
    "day_of_week": "isodow",
    "dow": "isodow",
    "day_of_year": "doy",
    "doy": "doy",
    "year_of_week": "isoyear",
    "yow": "isoyear",
    "hour": "hour",
    "minute": "minute",
    "second": "second",
    "millisecond": "millisecond",
}


def _render_field(g, node, args) -> str:
    name = node.name.lower()
    if ttype(args[0]).base in intervals.FIELDS:
        return intervals.field(g.sql(args[0]), ttype(args[0]).base, name)
    if pico_times.is_wide(ttype(args[0])):
        return pico_times.field(g.sql(args[0]), name)
    value = tf.field_time(g, args[0])
    part = _FIELD_OF[name]
    if ttype(args[0]).base == "unknown":  # a NULL literal: DuckDB cannot choose date_part's overload
        return "CAST(NULL AS BIGINT)"
    if name == "millisecond":
        return f"CAST(date_part('millisecond', {value}) % 1000 AS BIGINT)"
    return f"CAST(date_part({tf.string(part)}, {value}) AS BIGINT)"


def _render_from_iso8601_date(g, node, args) -> str:
    v = '"_iso"'
    y, m, d = _iso_parts(v, _ISO_DAY)
    wy, w, e = _iso_parts(v, _ISO_WEEK)
    oy, doy, _ = _iso_parts(v, _ISO_ORDINAL)
    week_one = f"(make_date({wy}, 1, 4) - CAST(isodow(make_date({wy}, 1, 4)) - 1 AS INTEGER))"
    week_date = f"({week_one} + CAST(7 * ({w} - 1) + {e} - 1 AS INTEGER))"
    ordinal_date = f"(make_date({oy}, 1, 1) + CAST({doy} - 1 AS INTEGER))"
    quoted = f"'\"' || {v} || '\"'"
    invalid = g.fail(f"'Invalid format: ' || {quoted}")
    out_of_range = g.fail(f"'Cannot parse ' || {quoted} || ': a field value is out of range'")
    too_far = g.fail(f"'from_iso8601_date of a year outside 1..9999: ' || {quoted}", "NOT_SUPPORTED")
    body = (
        f"CASE WHEN {v} IS NULL THEN NULL "
        f"WHEN NOT regexp_full_match({v}, '[+-]?[0-9]{{1,9}}(-.*)?') THEN {invalid} "
        f"WHEN CAST(regexp_extract({v}, '^[+-]?[0-9]+') AS BIGINT) NOT BETWEEN 1 AND 9999 THEN {too_far} "
        f"WHEN regexp_full_match({v}, {tf.string(_ISO_DAY)}) THEN "
        f"coalesce(try(make_date({y}, {m}, {d})), {out_of_range}) "
        f"WHEN regexp_full_match({v}, {tf.string(_ISO_WEEK)}) THEN CASE "
        f"WHEN {w} BETWEEN 1 AND week(make_date({wy}, 12, 28)) AND {e} BETWEEN 1 AND 7 THEN {week_date} "
        f"ELSE {out_of_range} END "
        f"WHEN regexp_full_match({v}, {tf.string(_ISO_ORDINAL)}) THEN CASE "
        f"WHEN {doy} >= 1 AND year({ordinal_date}) = {oy} THEN {ordinal_date} ELSE {out_of_range} END "
        f"ELSE {invalid} END"
    )
    return f"list_transform([{g.sql(args[0])}], lambda {v}: {body})[1]"


def _zone_argument(call: Call, source: str) -> TType:
    """at_timezone(timestamp with time zone, zone) and with_timezone(timestamp, zone): a literal zone."""
    types = need(call, source, "string")
    zone = call.literal(1)
    if zone is None or not zone.is_string:
        call.fail(f"unsupported in lakegate: {call.name} with a zone that is not a literal", "NOT_SUPPORTED")
    return tt.timestamp(types[0].args[0] if types[0].args else 3, True, call.analyzer.zone_literal(zone))


def _to_iso8601(call: Call) -> TType:
    """varchar(16) of a date; of a timestamp(p) varchar(1 + 6 + 15 + min(p, 1) + p), and 6 more with
    a time zone (Trino's RESULT_LENGTH of ToIso8601)."""
    (t,) = need(call, "temporal")
    if t.base == "date" or t.is_unknown:
        return tt.varchar(16)
    precision = t.args[0]
    return tt.varchar(1 + 6 + 15 + min(precision, 1) + precision + (6 if t.base == "timestamp_tz" else 0))


def _render_to_iso8601(g, node, args) -> str:
    """Dates as uuuu-MM-dd; timestamps as uuuu-MM-dd'T'HH:mm:ss with p fraction digits; of a timestamp
    with time zone the wall time in the value's zone and the zone's offset then (`Z` for zero;
    io.trino.operator.scalar.timestamptz.ToIso8601)."""
    t = ttype(args[0])
    if t.base in ("date", "unknown"):
        return casts.date_text(f"CAST({g.sql(args[0])} AS DATE)")
    if t.base == "timestamp":
        return f"replace({casts.timestamp_text(g.sql(args[0]), t.args[0])}, ' ', 'T')"
    sql, zone = g.sql(args[0]), tt.zone_of(t)
    text = f"replace({casts.timestamp_text(zones.local(sql, zone), t.args[0])}, ' ', 'T')"
    minutes = f"(CAST(epoch({zones.local(sql, zone)}) - epoch({zones.local(sql, zones.UTC)}) AS BIGINT) // 60)"
    offset = (
        f"CASE WHEN {minutes} = 0 THEN 'Z' ELSE CASE WHEN {minutes} < 0 THEN '-' ELSE '+' END || "
        f"lpad(CAST(abs({minutes}) // 60 AS VARCHAR), 2, '0') || ':' || "
        f"lpad(CAST(abs({minutes}) % 60 AS VARCHAR), 2, '0') END"
    )
    return f"({text} || {offset})"


# === date and time (io.trino.operator.scalar.DateTimeFunctions, HumanReadableSeconds,
# timestamp/ToIso8601, timestamptz/ToIso8601) =====================================================
def _render_human_readable_seconds(g, node, args) -> str:
    """HumanReadableSeconds: Math.round(|x|) seconds as weeks, days, hours, minutes and seconds,
    the zero parts left out, '0 seconds' for none; NaN and infinities fail."""
    x = f"CAST({g.sql(args[0])} AS DOUBLE)"
    whole = f"floor(abs({x}))"
    rounded = f"TRY_CAST({whole} + CASE WHEN abs({x}) - {whole} >= 0.5 THEN 1 ELSE 0 END AS BIGINT)"
    total = f"(CASE WHEN abs({x}) >= 9.223372036854775807e18 THEN 9223372036854775807 ELSE {rounded} END)"  # saturates
    parts = [
        (f"{total} // 604800", "week"),
        (f"{total} % 604800 // 86400", "day"),
        (f"{total} % 86400 // 3600", "hour"),
        (f"{total} % 3600 // 60", "minute"),
        (f"{total} % 60", "second"),
    ]
    rendered = ", ".join(
        f"CASE WHEN {n} > 0 THEN CAST({n} AS VARCHAR) || ' {unit}' || CASE WHEN {n} = 1 THEN '' ELSE 's' END END"
        for n, unit in parts
    )
    text = f"concat_ws(', ', {rendered})"
    invalid = g.fail(f"'Invalid argument found: ' || {casts.approx_text(x, tt.DOUBLE)}")
    return (
        f"CASE WHEN {x} IS NULL THEN NULL WHEN NOT isfinite({x}) THEN {invalid} "
        f"WHEN {total} = 0 THEN '0 seconds' ELSE {text} END"
    )


#: io.airlift.units.Duration: milliseconds per unit.
_DURATION_MILLIS = {
    "ns": "1.0e-6",
    "us": "1.0e-3",
    "ms": "1.0",
    "s": "1000.0",
    "m": "60000.0",
    "h": "3600000.0",
    "d": "86400000.0",
}


def _render_parse_duration(g, node, args) -> str:
    """io.airlift.units.Duration.valueOf(text).toMillis(): a decimal number, optional whitespace and a
    unit; the milliseconds are floor(value * millis-per-unit + 0.5)."""
    text = g.sql(args[0])
    pattern = (
        "[ \\t\\n\\x0B\\f\\r]*([0-9]+([.][0-9]+)?)[ \\t\\n\\x0B\\f\\r]*"
        f"({'|'.join(_DURATION_MILLIS)})[ \\t\\n\\x0B\\f\\r]*"
    )
    number = f"CAST(regexp_extract({text}, {tf.string(pattern)}, 1) AS DOUBLE)"
    unit = f"regexp_extract({text}, {tf.string(pattern)}, 3)"
    factor = "CASE " + " ".join(f"WHEN {unit} = '{u}' THEN {m}" for u, m in _DURATION_MILLIS.items()) + " END"
    millis = f"floor({number} * {factor} + 0.5)"
    invalid = g.fail(f"'duration is not a valid data duration string: ' || {text}")
    return (
        f"CASE WHEN {text} IS NULL THEN NULL WHEN NOT regexp_full_match({text}, {tf.string(pattern)}) THEN {invalid} "
        f"WHEN {millis} > 9223372036854775807 THEN {g.fail(tf.string('duration is too large'))} "
        f"ELSE to_milliseconds(CAST({millis} AS BIGINT)) END"
    )


#: The ISO 8601 date-times lakegate reads: a calendar date, optionally 'T' and hours[:minutes[:seconds
#: [.fraction]]], and no offset (the session zone, UTC) or 'Z'.
_ISO_DATETIME = (
    "([0-9]{4})-([0-9]{2})-([0-9]{2})(?:T([0-9]{2})(?::([0-9]{2})(?::([0-9]{2})(?:[.,]([0-9]{1,3}))?)?)?)?Z?"
)


def _from_iso8601_timestamp(call: Call) -> TType:
    """timestamp(3) with time zone: UTC for a text ending in Z, else the session zone (Joda reads a
    text without offset in it). The zone must be known from the query: a text that is not a literal
    is answered in a UTC session only (there both forms give UTC)."""
    need(call, "string")
    text, zone = literal_str(call, 0), call.analyzer.time_zone
    offset = re.search(r"T[0-9:.,]+([+-][0-9]{2}(?::?[0-9]{2})?)$", text.strip()) if text is not None else None
    if offset is not None:  # a literal's offset is the value's zone (Joda's withOffsetParsed)
        try:
            zone = zones.canonical(offset.group(1))
        except ValueError:
            call.fail(f'Invalid format: "{text}"', "INVALID_FUNCTION_ARGUMENT")
        call.node.meta["iso_text"] = text.strip()[: offset.start(1)]
    elif text is not None and text.rstrip().endswith("Z"):
        zone = zones.UTC
    elif text is None and zone != zones.UTC:
        call.fail(
            "unsupported in lakegate: from_iso8601_timestamp of a value that is not a literal outside a UTC "
            "session (a value with Z is in UTC, one without an offset in the session zone)",
            "NOT_SUPPORTED",
        )
    return tt.timestamp(3, True, zone)


def _render_from_iso8601_timestamp(g, node, args) -> str:
    """DateTimeFunctions.fromISO8601Timestamp (Joda's ISODateTimeFormat.dateTimeParser) for the
    common forms; other forms and offsets other than Z are refused: Trino keeps the offset as the
    value's zone, which lakegate's values carry when a literal names it (then read without it)."""
    text = tf.string(node.meta["iso_text"]) if "iso_text" in node.meta else g.sql(args[0])
    pattern = tf.string(_ISO_DATETIME)

    def part(index: int, default: str = "0") -> str:
        return f"CAST(coalesce(nullif(regexp_extract({text}, {pattern}, {index}), ''), '{default}') AS INTEGER)"

    millis = f"CAST(rpad(coalesce(nullif(regexp_extract({text}, {pattern}, 7), ''), '0'), 3, '0') AS INTEGER)"
    value = f"make_timestamp({part(1)}, {part(2)}, {part(3)}, {part(4)}, {part(5)}, {part(6)} + {millis} / 1000.0)"
    unsupported = g.fail(
        f"'from_iso8601_timestamp of ' || {text} || ' is not supported in lakegate "
        "(only yyyy-MM-dd[THH[:mm[:ss[.SSS]]]] with Z or no offset)'",
        "NOT_SUPPORTED",
    )
    out_of_range = g.fail(f"'Cannot parse \"' || {text} || '\": a field value is out of range'")
    valid = (
        f"{part(2)} BETWEEN 1 AND 12 AND {part(3)} BETWEEN 1 AND day(last_day(make_date({part(1)}, {part(2)}, 1))) "
        f"AND {part(4)} <= 23 AND {part(5)} <= 59 AND {part(6)} <= 59"
    )
    return (
        f"CASE WHEN {text} IS NULL THEN NULL WHEN NOT regexp_full_match({text}, {pattern}) THEN {unsupported} "
        f"WHEN NOT ({part(2)} BETWEEN 1 AND 12) OR NOT ({valid}) THEN {out_of_range} "
        f"ELSE {zones.instant(value, tt.zone_of(ttype(node)))} END"
    )


def _from_unixtime_nanos(call: Call) -> tt.TType:
    types = call.types
    if len(types) != 1 or types[0] is None or not (types[0].is_integral or types[0].is_decimal or types[0].is_unknown):
        call.mismatch()
    return tt.timestamp(9, True, call.analyzer.time_zone)


def _render_from_unixtime_nanos(g, node, args) -> str:
    """The whole nanoseconds (DuckDB's CAST of a decimal to BIGINT rounds half away from zero, as Trino's
    MathFunctions.Round.roundShort) as a wide value (wide_timestamps.py)."""
    return wide.of_nanoseconds(f"CAST({g.sql(args[0])} AS BIGINT)")


def _to_unixtime_wide(call: Call) -> tt.TType | None:
    zoned = len(call.types) == 1 and call.types[0] is not None and call.types[0].base == "timestamp_tz"
    return tt.DOUBLE if zoned and wide.is_wide(call.types[0]) else None


def _render_to_unixtime_wide(g, node, args) -> str:
    return wide.to_unixtime(g.sql(args[0]))


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "date_diff",
        "datetime",
        "date_diff(unit, timestamp1, timestamp2) -> bigint",
        _date_diff,
        _render_date_diff,
        notes="Counts whole units between the values, as Trino does (DuckDB's date_diff counts "
        "boundaries; lakegate uses date_sub).",
    )
    register(
        "date_add", "datetime", "date_add(unit, value, timestamp) -> same as timestamp", _date_add, _render_date_add
    )
    register("date_trunc", "datetime", "date_trunc(unit, x) -> same as x", _date_trunc, _render_date_trunc)
    register(
        "from_unixtime",
        "datetime",
        "from_unixtime(unixtime) -> timestamp(3) with time zone",
        _from_unixtime,
        _render_from_unixtime,
        notes=(
            "from_unixtime(x) is in the session time zone; from_unixtime(x, zone) and (x, hours, "
            "minutes) take literals."
        ),
    )

    register(
        "from_iso8601_date",
        "datetime",
        "from_iso8601_date(string) -> date",
        lambda c: need(c, "string") and tt.DATE,
        _render_from_iso8601_date,
        notes="Joda's ISO 8601 date forms, as Trino: 2020-05-11, 2020-05, 2020, 2020-W10[-5], 2020-130.",
    )
    register("to_unixtime", "datetime", "to_unixtime(timestamp) -> double", _to_unixtime, _render_to_unixtime)
    register(
        "now",
        "datetime",
        "now() -> timestamp(3) with time zone",
        lambda c: fixed(tt.timestamp(3, True, c.analyzer.time_zone))(c),
        lambda g, node, args: "date_trunc('millisecond', current_timestamp)",
    )
    register(
        "current_timezone",
        "datetime",
        "current_timezone() -> varchar",
        fixed(tt.VARCHAR),
        lambda g, node, args: tf.string(g.time_zone),
    )

    register(
        "at_timezone",
        "datetime",
        "at_timezone(timestamp(p) with time zone, zone) -> timestamp(p) with time zone",
        lambda c: _zone_argument(c, "instant"),
        lambda g, node, args: g.coerce(args[0], ttype(node)),
        notes="The same instant in another zone (a timestamp is read in the session zone); the zone must be a literal.",
    )
    register(
        "timezone",
        "datetime",
        "timezone(timestamp(p) with time zone) -> varchar",
        _timezone,
        _render_timezone,
        notes="The zone of the value, which lakegate knows from its type; of a time with time zone, its offset.",
    )
    register(
        "with_timezone",
        "datetime",
        "with_timezone(timestamp(p), zone) -> timestamp(p) with time zone",
        lambda c: _zone_argument(c, "timestamp"),
        lambda g, node, args: zones.instant(f"CAST({g.sql(args[0])} AS TIMESTAMP)", tt.zone_of(ttype(node))),
        notes="The wall time read in the zone; the zone must be a literal.",
    )

    register(
        "to_iso8601",
        "datetime",
        "to_iso8601(x) -> varchar",
        _to_iso8601,
        _render_to_iso8601,
        notes="Of a timestamp with time zone, with its zone's offset (Z for zero).",
    )
    for _part in ("hour", "minute"):
        register(
            f"timezone_{_part}",
            "datetime",
            f"timezone_{_part}(timestamp with time zone) -> bigint",
            fixed(tt.BIGINT, "instant"),
            lambda g, node, args, part=_part: tf.zone_offset(g, args[0], part),
        )
    register(
        "date",
        "datetime",
        "date(x) -> date",
        lambda c: (
            tt.DATE
            if len(c.args) == 1
            and c.types[0] is not None
            and c.types[0].base in ("varchar", "timestamp", "timestamp_tz", "date", "unknown")
            else c.mismatch()
        ),
        lambda g, node, args: casts.cast_value(g, g.sql(args[0]), ttype(args[0]), tt.DATE),
    )
    register(
        "last_day_of_month",
        "datetime",
        "last_day_of_month(x) -> date",
        fixed(tt.DATE, "temporal"),
        lambda g, node, args: f"last_day({tf.wall_time(g, args[0])})",
    )
    for _name in _FIELD_OF:
        register(_name, "datetime", f"{_name}(x) -> bigint", _field, _render_field)

    register(
        "to_milliseconds",
        "datetime",
        "to_milliseconds(interval) -> bigint",
        lambda c: tt.BIGINT if need(c, "any")[0].base in ("interval_ds", "unknown") else c.mismatch(),
        lambda g, node, args: f"CAST(epoch_ms({g.sql(args[0])}) AS BIGINT)",
    )
    register(
        "human_readable_seconds",
        "datetime",
        "human_readable_seconds(double) -> varchar",
        fixed(tt.VARCHAR, "number"),
        _render_human_readable_seconds,
    )
    register(
        "parse_duration",
        "datetime",
        "parse_duration(string) -> interval day to second",
        fixed(tt.INTERVAL_DS, "string"),
        _render_parse_duration,
    )
    register(
        "from_iso8601_timestamp",
        "datetime",
        "from_iso8601_timestamp(string) -> timestamp(3) with time zone",
        _from_iso8601_timestamp,
        _render_from_iso8601_timestamp,
        notes="yyyy-MM-dd[THH[:mm[:ss[.SSS]]]] with Z (UTC), no offset (the session zone) or, in a literal, "
        "an offset (its zone).",
    )

    register(
        "from_unixtime_nanos",
        "datetime",
        "from_unixtime_nanos(unixtime) -> timestamp(9) with time zone",
        _from_unixtime_nanos,
        _render_from_unixtime_nanos,
        notes="In the session time zone, held as every timestamp(p > 6) with time zone (dialect/wide_timestamps.py).",
    )

    overload(
        "to_unixtime",
        _to_unixtime_wide,
        _render_to_unixtime_wide,
        "to_unixtime(timestamp(p > 6) with time zone) -> double",
    )
