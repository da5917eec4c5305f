"""DuckDB SQL of CAST and TRY_CAST with Trino's rules, as named transforms of the Writer
(transforms.py): range checks, rounding, text of numbers and timestamps as Trino writes them,
timestamps past microseconds.
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import chars, ipaddresses, pico_times, registry, time_casts, times, zoned_times, zones
from lakegate.dialect import trino_types as tt
from lakegate.dialect import wide_timestamps as wide
from lakegate.dialect.transforms import Writer, cast, quote, string, transform
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import FloorMicros, ShownWide, ttype

RANGES = {
    "tinyint": (-(2**7), 2**7 - 1),
    "smallint": (-(2**15), 2**15 - 1),
    "integer": (-(2**31), 2**31 - 1),
    "bigint": (-(2**63), 2**63 - 1),
}


# --- casts ---------------------------------------------------------------------------------------
@transform(exp.Cast)
def trino_cast(g: Writer, node: exp.Cast) -> str:
    if node.meta.get("trimmed"):
        return chars.trimmed(g, node)
    if "time_tz" in node.meta:  # a TIME literal with an offset, computed at analysis
        return zoned_times.constant(node.meta["time_tz"])
    if "time_ps" in node.meta:  # a TIME literal of more than six fraction digits, computed at analysis
        return f"CAST({node.meta['time_ps']} AS BIGINT)"
    if "ip" in node.meta:  # an IPADDRESS literal, read at analysis
        return ipaddresses.constant(node.meta["ip"])
    return cast_value(g, *cast_operand(g, node), ttype(node))


def cast_operand(g: Writer, node: exp.Cast) -> tuple[str, TType]:
    """The operand of a cast as SQL and its type; a text literal cast to timestamp with time zone as
    its wall time (the zone it names is the target's: analyze._cast_zone)."""
    local = node.meta.get("local")
    if local is None:
        return g.sql(node.this), node.meta["from"]
    if wide.is_wide(ttype(node)):
        return wide_literal(g, local, ttype(node)), ttype(node)
    wall = tt.timestamp(ttype(node).args[0])
    return parse_varchar(g, string(local), wall), wall


@transform(exp.TryCast)
def trino_try_cast(g: Writer, node: exp.TryCast) -> str:
    # only the conversion yields NULL: a failure of the operand itself fails the query, as in Trino
    # (a text literal read as a zoned timestamp's wall time is part of the conversion)
    own = node.meta.get("local") is None
    if own:
        operand, source = cast_operand(g, node)
    g.in_try += 1
    try:
        if not own:
            operand, source = cast_operand(g, node)
        target = ttype(node)
        sql = cast_value(g, operand, source, target)
    finally:
        g.in_try -= 1
    return try_wrap(sql)


def row_whole_in_try(g: Writer, present: list[str], row: str, target: TType) -> str:
    """Inside try() a row whose field conversion fails (a NULL field where `present`, one SQL
    condition per field, says the source has a value) is NULL, as Trino's whole conversion fails."""
    if not g.in_try:
        return row
    checks = [
        f"(({condition}) IS NOT TRUE OR struct_extract({row}, {string(name or f'field{index}')}) IS NOT NULL)"
        for index, (condition, (name, t)) in enumerate(zip(present, target.args))
        if t.base != "json"
    ]
    return f"CASE WHEN {' AND '.join(checks)} THEN {row} END" if checks else row


def whole_in_try(g: Writer, expected: str, elements: str) -> str:
    """Inside try() an element whose conversion fails is NULL; Trino's conversion of the whole array
    fails there, so the array is NULL when it holds fewer non-NULL elements than `expected` (outside
    try() a failing element raises)."""
    if not g.in_try:
        return elements
    return f"CASE WHEN list_count({elements}) = {expected} THEN {elements} END"


def try_wrap(sql: str) -> str:
    """DuckDB's TRY(...) around `sql` unless it contains what TRY refuses (aggregates, windows,
    volatile functions); the transforms already yield NULL for Trino's own failures inside try."""
    lowered = sql.lower()
    if " over (" in lowered or "error(" in lowered or "random()" in lowered or "(select" in lowered:
        return sql
    for name in _AGGREGATE_NAMES:
        if f"{name}(" in lowered:
            return sql
    return f"TRY({sql})"


_AGGREGATE_NAMES = (
    "sum",
    "avg",
    "count",
    "min",
    "max",
    "any_value",
    "arg_max",
    "arg_min",
    "list",
    "array_agg",
    "quantile",
    "stddev",
    "var_",
    "corr",
    "covar",
    "bool_",
    "string_agg",
    "approx",
    "geometric",
    "kurtosis",
    "skewness",
    "regr_",
    "bit_",
    "first",
    "last",
    "entropy",
    "mode",
    "median",
    "product",
)


_INTEGRAL_RANGE = {"tinyint": "TINYINT", "smallint": "SMALLINT", "integer": "INT", "bigint": "BIGINT"}


def cast_value(g: Writer, sql: str, source: TType, target: TType) -> str:
    """Trino's CAST(sql AS target) for a value of type `source`."""
    if source == target:
        return sql
    if source.is_unknown:
        return cast("NULL", target)
    wide_operand = wide.is_wide(source) or wide.is_wide(target)
    if target.base in ("timestamp", "timestamp_tz", "date") and wide_operand and source.base != "varchar":
        return wide_cast(g, sql, source, target)
    if target.base == "char":  # truncated or padded with spaces: the padded text the client gets
        return chars.pad(sql, target.args[0])
    if target.base == "json":
        return registry.JSON_CASTS["to_json"](g, sql, source)
    if "ipaddress" in (source.base, target.base):
        return ipaddresses.cast(g, sql, source, target)
    if source.base == "json":
        return registry.JSON_CASTS["from_json"](g, sql, target)
    if target.base == "varchar":
        text = varchar_of(g, sql, source)
        length = tt.varchar_length(target)
        if length is None:
            return text
        if source.base in ("varchar", "char"):  # a char's padded text (CharacterStringCasts.charToVarcharCast)
            return f"left({text}, {length})"
        message = f"'Value ' || ({text}) || ' cannot be represented as varchar({length})'"
        return f"CASE WHEN length({text}) > {length} THEN {g.fail(message, 'INVALID_CAST_ARGUMENT')} ELSE {text} END"
    if target.base == "varbinary":
        return f"encode({sql})"  # varchar: its UTF-8 bytes
    if time_casts.handles(source, target):  # time(7..12), and times to timestamps (the session's date)
        return time_casts.cast(g, sql, source, target)
    if source.base == "varchar":
        return parse_varchar(g, sql, target)
    if target.is_integral and source.is_approx:
        return checked_cast(g, f"round({sql})", source, target)
    if target.is_decimal and source.is_approx:
        # Trino converts the shortest decimal text of the float (BigDecimal.valueOf(double),
        # Float.toString: io.trino.type.DecimalCasts), HALF_UP; DuckDB would convert its binary value
        text = real_text(sql) if source.base == "real" else f"CAST({sql} AS VARCHAR)"
        return checked_cast(g, fixed_text(text), source, target)
    if target.is_integral and (source.is_integral or source.is_decimal) or target.is_decimal and source.is_numeric:
        return checked_cast(g, sql, source, target)
    if "time_tz" in (source.base, target.base):
        return _zoned_time(g, sql, source, target)
    if target.base == "time" and source.base == "timestamp_tz":  # its time of day in its zone, rounded HALF_UP
        zoned = TType("time_tz", source.args[:1])
        return _zoned_time(g, _zoned_time(g, sql, source, zoned), zoned, target)
    if target.base == "time" and source.base in ("time", "timestamp"):  # p <= 6 (analyze._cast)
        if source.base == "time":
            return times.round_time(sql, target.args[0], source.args[0])
        return times.of_timestamp(sql, target.args[0], g.fail("'value must be >= 0'", "GENERIC_INTERNAL_ERROR"))
    if target.base == "timestamp" and source.base in ("timestamp", "date"):
        precision = target.args[0]
        if source.base == "timestamp" and precision < source.args[0]:
            return round_timestamp(sql, precision, source.args[0])
        if precision > 6 and tt.duckdb_type(source) != "TIMESTAMP_NS":
            return as_nanoseconds(g, sql)
        return cast(sql, target)
    if target.base == "timestamp" and source.base == "timestamp_tz":
        local = zones.local(sql, tt.zone_of(source))
        if target.args[0] < source.args[0]:  # rounded HALF_UP (TimestampWithTimeZoneToTimestampCast)
            return round_timestamp(local, target.args[0])
        return cast(local, target)
    if target.base == source.base == "timestamp_tz" and target.args[0] < source.args[0]:
        # the instant rounded HALF_UP (TimestampWithTimeZoneToTimestampWithTimeZoneCast)
        return f"CAST({round_timestamp(sql, target.args[0])} AS TIMESTAMPTZ)"
    if target.base == "timestamp_tz" and source.base in ("timestamp", "date"):
        sql = zoned_precision(sql, source, target.args[0])
        return zones.instant(f"CAST({sql} AS TIMESTAMP)", tt.zone_of(target))
    if target.base == "date" and source.base == "timestamp" and source.args[0] > 6:
        return f"CAST({floor_micros(sql)} AS DATE)"  # DuckDB would round to the nearest microsecond
    if target.base == "date" and source.base == "timestamp_tz":
        return f"CAST({zones.local(sql, tt.zone_of(source))} AS DATE)"
    if target.base == "array":
        inner = cast_value(g, '"_e"', source.element, target.element)
        if inner == cast('"_e"', target.element):
            return cast(sql, target)
        return whole_in_try(g, f"list_count({sql})", f'list_transform({sql}, lambda "_e": {inner})')
    if target.base == "row":
        fields, present = [], []
        for index, ((_, s), (name, t)) in enumerate(zip(source.args, target.args)):
            src_name = source.args[index][0]
            value = f"struct_extract({sql}, {string(src_name) if src_name else index + 1})"
            fields.append(f"{quote(name or f'field{index}')} := {cast_value(g, value, s, t)}")
            present.append(f"{value} IS NOT NULL")
        return row_whole_in_try(g, present, f"struct_pack({', '.join(fields)})", target)
    return cast(sql, target)


def wide_cast(g: Writer, sql: str, source: TType, target: TType) -> str:
    """CAST from or to the timestamps held as structs (wide_timestamps.py), other than to varchar: the
    value as one of the target's kind (a timestamp or date is a wall time in the target's zone, a
    timestamp with time zone its wall time in its own zone), rounded HALF_UP where the target holds
    fewer digits."""
    if target.base == "date":
        micros = wide.micros(sql)
        return f"CAST({micros if source.base == 'timestamp' else zones.local(micros, tt.zone_of(source))} AS DATE)"
    zoned = target.base == "timestamp_tz"
    zone = tt.zone_of(target) if zoned else tt.zone_of(source)
    value = wide.coerce(sql, source, zone, zoned)
    if target.base == "timestamp" and 6 < target.args[0] <= 9:  # DuckDB's TIMESTAMP_NS, within its range
        unit = 10 ** (12 - target.args[0])
        below = f"(({wide.picos(value)} + {unit // 2}) // {unit} * {unit} // 1000)"
        return f"make_timestamp_ns(epoch_ns({as_nanoseconds(g, wide.micros(value))}) + {below})"
    return wide.round_to(value, target.args[0], source.args[0] if source.base != "date" else 0, zoned)


def wide_literal(g: Writer, local: str, target: TType) -> str:
    """A text literal's wall time (`local`, its zone stripped) as a timestamp(7..12) with time zone: the
    seconds read as a timestamp, the fraction's digits rounded HALF_UP to the target's precision."""
    value = wide.constant(local, target.args[0], tt.zone_of(target))
    if value is not None:
        return value
    seconds, dot, digits = local.rpartition(".")
    if not dot or not digits.isdigit() or len(digits) > 12:
        seconds, digits = local, ""
    unit = 10 ** (12 - target.args[0])
    fraction = (int(digits.ljust(12, "0") or 0) + unit // 2) // unit * unit
    wall = parse_varchar(g, string(seconds), tt.timestamp(0))
    micros, picos = divmod(fraction, wide.PICOS_PER_MICRO)
    return wide.of_wall(f"({wall} + to_microseconds({micros}))", str(picos), tt.zone_of(target))


def _zoned_time(g: Writer, sql: str, source: TType, target: TType) -> str:
    """CAST between time with time zone and itself, or time, or from timestamp(p <= 6) [with time zone]
    (infer_casts.castable): the local time rounded HALF_UP to the target's precision; a time or timestamp
    takes the session zone's offset, a timestamp with time zone its zone's offset at the instant its wall time
    names in UTC (what the real Trino 476 answers: 09:00 on 2020-03-08 in Los Angeles is -08:00, though the
    clocks moved to -07:00 at 02:00 that day)."""
    if source.base == "time":  # p <= 6, in a session zone of one offset (infer_casts._check_time_cast)
        zoned = zoned_times.of_time_micros(times.micros(sql), zoned_times.offset_of(g.time_zone))
        return zoned_times.round_to(zoned, target.args[0], source.args[0])
    if target.base == "time":  # p <= 6
        return times.of_micros(zoned_times.to_time_micros(sql, target.args[0]))
    if source.base in ("timestamp", "timestamp_tz"):  # the time of day, rounded HALF_UP; the zone's offset then
        below = "0"  # the picoseconds below the microsecond of a timestamp(7..12)
        if wide.is_wide(source):
            sql, below = wide.micros(sql), wide.picos(sql)
        elif source.base == "timestamp" and source.args[0] > 6:
            sql, below = floor_micros(sql), f"((epoch_ns({sql}) % 1000) + 1000) % 1000 * 1000"
        wall, minutes = sql, str(zoned_times.offset_of(g.time_zone))
        if source.base == "timestamp_tz":  # the offset at the instant that the wall time names in UTC (Trino 476)
            wall = zones.local(sql, tt.zone_of(source))
            named = f"CAST({wall} AS TIMESTAMPTZ)"
            minutes = f"((epoch_us({zones.local(named, tt.zone_of(source))}) - epoch_us({named})) // 60000000)"
        day = times.MICROS_PER_DAY
        picos = f"(((epoch_us({wall}) % {day}) + {day}) % {day} * 1000000 + {below})"
        return zoned_times.of_local(zoned_times.rounded_picos(picos, target.args[0]), minutes)
    return zoned_times.round_to(sql, target.args[0], source.args[0])


def _cast_name(t: TType) -> str:
    """A numeric type as Trino's cast messages name it: INTEGER, DECIMAL(5, 2)."""
    return f"DECIMAL({t.args[0]}, {t.args[1]})" if t.is_decimal else t.base.upper()


def checked_cast(g: Writer, sql: str, source: TType, target: TType) -> str:
    """A numeric CAST that can overflow: Trino's error (NUMERIC_VALUE_OUT_OF_RANGE for integers,
    INVALID_CAST_ARGUMENT for decimals and doubles) instead of DuckDB's."""
    if _fits(source, target):
        return cast(sql, target)
    duck = tt.duckdb_type(target)
    if target.is_integral and not source.is_approx:
        error_name, message = "NUMERIC_VALUE_OUT_OF_RANGE", f"'Out of range for {target}: ' || ({sql})"
    elif target.is_decimal and (source.is_integral or source.is_decimal):  # DecimalCasts, DecimalConversions
        error_name = "INVALID_CAST_ARGUMENT"
        message = f"'Cannot cast {_cast_name(source)} ''' || ({sql}) || ''' to {_cast_name(target)}'"
    else:
        error_name, message = "INVALID_CAST_ARGUMENT", f"'Cannot cast {source} ''' || ({sql}) || ''' to {target}'"
    return (
        f"CASE WHEN ({sql}) IS NOT NULL AND TRY_CAST({sql} AS {duck}) IS NULL THEN "
        f"{g.fail(message, error_name)} ELSE CAST({sql} AS {duck}) END"
    )


def _fits(source: TType, target: TType) -> bool:
    """Whether every value of `source` converts to `target` without overflow."""
    if source.is_integral and target.is_integral:
        return RANGES[source.base][1] <= RANGES[target.base][1]
    if (source.is_integral or source.is_decimal) and target.is_decimal:
        digits = tt.INTEGRAL[source.base] if source.is_integral else source.args[0] - source.args[1]
        return digits <= target.args[0] - target.args[1]
    if source.is_decimal and target.is_integral:
        return source.args[0] - source.args[1] < len(str(RANGES[target.base][1]))
    return False


def floor_div(sql: str, divisor: int) -> str:
    """Integer `sql` divided by `divisor`, rounded toward negative infinity (DuckDB's // truncates)."""
    return f"(({sql}) - ((({sql}) % {divisor}) + {divisor}) % {divisor}) // {divisor}"


def floor_micros(sql: str) -> str:
    """A TIMESTAMP_NS floored to a microsecond TIMESTAMP: Trino's timestamp(p > 6) functions read the
    epoch microseconds (LongTimestamp.getEpochMicros) and keep or drop the rest; DuckDB's own
    conversion rounds to the nearest microsecond (23:59:59.9999999 would become the next day)."""
    return f"make_timestamp({floor_div(f'epoch_ns({sql})', 1000)})"


def with_nanos(micros_sql: str, source_sql: str) -> str:
    """Microsecond TIMESTAMP `micros_sql` as TIMESTAMP_NS, with the nanoseconds below the microsecond
    of TIMESTAMP_NS `source_sql` (Trino's timestamp(p > 6) arithmetic keeps its picosOfMicro)."""
    return f"make_timestamp_ns(epoch_ns({micros_sql}) + ((epoch_ns({source_sql}) % 1000) + 1000) % 1000)"


#: The days DuckDB's TIMESTAMP_NS holds whole (int64 nanoseconds: 1677-09-21 to 2262-04-11).
NANOSECOND_RANGE = ("1677-09-22", "2262-04-11")


def as_nanoseconds(g: Writer, sql: str) -> str:
    """TIMESTAMP or DATE `sql` as TIMESTAMP_NS, or NOT_SUPPORTED outside its range (Trino's reaches
    further; DuckDB's own message would not say why)."""
    low, high = NANOSECOND_RANGE
    message = string(f"unsupported in lakegate: timestamp(p) with p > 6 outside [{low}, {high})")
    return (
        f"CASE WHEN ({sql}) >= TIMESTAMP '{low}' AND ({sql}) < TIMESTAMP '{high}' "
        f"THEN CAST({sql} AS TIMESTAMP_NS) ELSE {g.fail(message, 'NOT_SUPPORTED')} END"
    )


def round_timestamp(sql: str, precision: int, source: int = 6) -> str:
    """A timestamp(source) rounded HALF_UP to `precision` fractional digits, before 1970 too (Trino's
    timestamp(p) casts: io.trino.spi.type.Timestamps.round)."""
    digits = 9 if source > 6 else 6
    unit = 10 ** (digits - precision)
    shifted = f"(epoch_{'ns' if digits == 9 else 'us'}({sql}) + {unit // 2})"  # then floored to a multiple of unit
    rounded = f"{shifted} - ((({shifted} % {unit}) + {unit}) % {unit})"
    if digits == 6:
        return f"make_timestamp({rounded})"
    return f"make_timestamp_ns({rounded})" if precision > 6 else f"make_timestamp(({rounded}) // 1000)"


def parse_varchar(g: Writer, sql: str, target: TType) -> str:
    """CAST(varchar AS target) accepting exactly what Trino accepts (Java's trim + parse), failing
    with INVALID_CAST_ARGUMENT otherwise (DuckDB alone would accept '1.5', ' 1_000', 'yes' ...)."""
    name = _INTEGRAL_RANGE.get(target.base, target.base.upper())
    bad = g.fail(f"'Cannot cast ''' || {sql} || ''' to {name}'", "INVALID_CAST_ARGUMENT")
    if target.is_integral:
        pattern = "^[\\x00-\\x20]*([+-]?[0-9]+)[\\x00-\\x20]*$"
        converted = cast(f"regexp_extract({sql}, {string(pattern)}, 1)", target)
        return (  # digits past the type's range fail as text that is no number does
            f"CASE WHEN regexp_matches({sql}, {string(pattern)}) AND TRY_{converted} IS NOT NULL "
            f"THEN {converted} ELSE {bad} END"
        )
    if target.is_approx or target.is_decimal:
        number = "[+-]?([0-9]+[.]?[0-9]*|[.][0-9]+)([eE][+-]?[0-9]+)?"
        if target.is_approx:
            number = f"([+-]?(NaN|Infinity)|{number}[fFdD]?)"
        pattern = f"^[\\x00-\\x20]*{number}[\\x00-\\x20]*$"
        value = (
            f"regexp_replace(trim({sql}, chr(32) || chr(9) || chr(10) || chr(13)), '[fFdD]$', '')"
            if target.is_approx
            else f"trim({sql}, chr(32) || chr(9) || chr(10) || chr(13))"
        )
        converted = cast(value, target)
        if target.is_decimal:  # DecimalCasts.varcharToShortDecimal / varcharToLongDecimal
            head = f"'Cannot cast VARCHAR ''' || {sql} || ''' to {_cast_name(target)}. '"
            bad = g.fail(f"{head} || 'Value is not a number.'", "INVALID_CAST_ARGUMENT")
            too_large = g.fail(f"{head} || 'Value too large.'", "INVALID_CAST_ARGUMENT")
            converted = f"CASE WHEN TRY_{converted} IS NULL THEN {too_large} ELSE TRY_{converted} END"
        return f"CASE WHEN regexp_matches({sql}, {string(pattern)}) THEN {converted} ELSE {bad} END"
    if target.base == "boolean":
        return (
            f"CASE WHEN lower({sql}) IN ('t', '1', 'true') THEN true "
            f"WHEN lower({sql}) IN ('f', '0', 'false') THEN false ELSE {bad} END"
        )
    if target.base == "date":
        pattern = "^[\\x00-\\x20]*[0-9]{4}-[0-9]{1,2}-[0-9]{1,2}[\\x00-\\x20]*$"
        return (
            f"CASE WHEN regexp_matches({sql}, {string(pattern)}) AND TRY_CAST(trim({sql}) AS DATE) IS NOT NULL "
            f"THEN CAST(trim({sql}) AS DATE) ELSE {bad} END"
        )
    if target.base == "timestamp":
        return parse_timestamp(g, sql, target.args[0], bad)
    if target.base == "time":
        message = f"'Value cannot be cast to time: ' || {sql}"
        return times.parse(sql, target.args[0], g.fail(message, "INVALID_CAST_ARGUMENT"))
    if target.base == "time_tz":
        message = f"'Value cannot be cast to time with time zone: ' || {sql}"
        offset = zoned_times.offset_of(g.time_zone)  # None: only texts that name their offset (infer_casts)
        session = str(offset) if offset is not None else g.fail(message, "INVALID_CAST_ARGUMENT")
        return zoned_times.parse(sql, target.args[0], session, g.fail(message, "INVALID_CAST_ARGUMENT"))
    return cast(sql, target)


def zoned_precision(sql: str, source: TType, precision: int) -> str:
    """A timestamp(p) or date rounded HALF_UP for CAST to timestamp(precision) with time zone: to
    milliseconds first when the target holds milliseconds at most and the source microseconds
    (operator/scalar/timestamp/TimestampToTimestampWithTimeZoneCast: shortToShort rounds twice)."""
    if source.base != "timestamp" or precision >= source.args[0]:
        return sql
    if precision < 3 < source.args[0] <= 6:
        sql = round_timestamp(sql, 3)
    return round_timestamp(sql, precision, source.args[0])


def parse_timestamp(g: Writer, sql: str, precision: int, bad: str) -> str:
    """CAST(varchar AS timestamp(precision)): the fraction's digits rounded HALF_UP to `precision`
    (io.trino.operator.scalar.timestamp.VarcharToTimestampCast); DuckDB would cut them at six or nine."""
    pattern = "^[0-9]{4}-[0-9]{1,2}-[0-9]{1,2}( [0-9]{1,2}:[0-9]{1,2}(:[0-9]{1,2}([.][0-9]{1,12})?)?)?$"
    text = f"trim({sql})"
    seconds_text = f"regexp_replace({text}, '[.][0-9]*$', '')"
    seconds = (
        f"TRY_CAST({seconds_text} AS TIMESTAMP)"  # TRY_: DuckDB folds a constant CAST early, and `valid` checks it
    )
    unit = 10 ** (12 - precision)  # of the fraction read as picoseconds
    fraction = f"((CAST(rpad(regexp_extract({text}, '[.]([0-9]*)$', 1), 12, '0') AS BIGINT) + {unit // 2}) // {unit})"
    if precision > 9:  # held as a struct (wide_timestamps.py): the microseconds and the picoseconds below
        picos = f"({fraction} * {unit})"
        micros = f"{seconds} + to_microseconds({picos} // {wide.PICOS_PER_MICRO})"
        value = wide.make(micros, f"{picos} % {wide.PICOS_PER_MICRO}", zoned=False)
    elif precision > 6:
        value = f"make_timestamp_ns(epoch_ns({as_nanoseconds(g, seconds)}) + {fraction} * {10 ** (9 - precision)})"
    else:
        value = f"{seconds} + to_microseconds({fraction} * {10 ** (6 - precision)})"
    valid = f"regexp_matches({text}, {string(pattern)}) AND TRY_CAST({seconds_text} AS TIMESTAMP) IS NOT NULL"
    return f"CASE WHEN {valid} THEN {value} ELSE {bad} END"


def varchar_of(g: Writer, sql: str, source: TType) -> str:
    """Trino's text of a value (CAST AS VARCHAR): doubles as 1.5E0, decimals with their full scale,
    timestamps with exactly p fractional digits."""
    if source.base in ("varchar", "char"):
        return sql
    if source.is_approx:
        return approx_text(sql, source)
    if source.is_decimal:
        precision, scale = source.args
        if precision == scale:
            return f"regexp_replace(CAST({sql} AS VARCHAR), '^(-?)[.]', '\\10.')"
        return f"CAST({sql} AS VARCHAR)"
    if wide.is_wide(source) and source.base == "timestamp":
        return f"{timestamp_text(wide.micros(sql), 6)} || {wide.fraction_digits(sql, source.args[0])}"
    if source.base == "timestamp":
        return timestamp_text(sql, source.args[0])
    if source.base == "time":
        return pico_times.text(sql, source.args[0]) if pico_times.is_wide(source) else times.text(sql, source.args[0])
    if source.base == "time_tz":
        return zoned_times.text(sql, source.args[0])
    if wide.is_wide(source):
        zone, precision = tt.zone_of(source), source.args[0]
        wall = timestamp_text(zones.local(wide.micros(sql), zone), 6)
        return f"{wall} || {wide.fraction_digits(sql, precision)} || {string(' ' + zone)}"
    if source.base == "timestamp_tz":
        zone = tt.zone_of(source)
        return timestamp_text(zones.local(sql, zone), source.args[0]) + f" || {string(' ' + zone)}"
    if source.base in ("interval_ds", "interval_ym"):
        return interval_text(sql, source)
    if source.base == "date":
        return date_text(sql)
    return f"CAST({sql} AS VARCHAR)"


def date_text(sql: str) -> str:
    """Trino's text of a date: `uuuu-MM-dd`, a year before year 0 of four digits after its sign (`-0500`;
    DuckDB writes `0501-06-01 (BC)`), one past 9999 unsigned."""
    year = f"year({sql})"
    before_zero = f"printf('%05d', {year}) || strftime({sql}, '-%m-%d')"
    return f"CASE WHEN {year} < 0 THEN {before_zero} ELSE strftime({sql}, '%Y-%m-%d') END"


def interval_text(sql: str, source: TType) -> str:
    """Trino's text of an interval: `-1 02:03:04.500` (day to second, milliseconds) or `-1-2` (year to
    month), the sign before the whole value."""
    if source.base == "interval_ym":
        months = f"(date_part('year', {sql}) * 12 + date_part('month', {sql}))"
        sign = f"CASE WHEN {months} < 0 THEN '-' ELSE '' END"
        return f"{sign} || CAST(abs({months}) // 12 AS VARCHAR) || '-' || CAST(abs({months}) % 12 AS VARCHAR)"
    millis = f"CAST(epoch_ms({sql}) AS BIGINT)"
    sign = f"CASE WHEN {millis} < 0 THEN '-' ELSE '' END"
    parts = [f"lpad(CAST(abs({millis}) // {unit} % {modulo} AS VARCHAR), 2, '0')" for unit, modulo in _CLOCK]
    fraction = f"lpad(CAST(abs({millis}) % 1000 AS VARCHAR), 3, '0')"
    days = f"CAST(abs({millis}) // 86400000 AS VARCHAR)"
    clock = " || ':' || ".join(parts)
    return f"{sign} || {days} || ' ' || {clock} || '.' || {fraction}"


#: (milliseconds per unit, units per next unit) of hours, minutes and seconds.
_CLOCK = ((3_600_000, 24), (60_000, 60), (1000, 60))


def timestamp_text(sql: str, precision: int) -> str:
    """Trino's text of a timestamp(p): exactly p fractional digits, and the year as java.time writes it,
    of four digits at least, signed past 9999 and before year 0 (`+10000-06-01`, `-0500-06-01`)."""
    formats = {0: "-%m-%d %H:%M:%S", 3: "-%m-%d %H:%M:%S.%g", 6: "-%m-%d %H:%M:%S.%f", 9: "-%m-%d %H:%M:%S.%n"}
    year = f"CAST(strftime({sql}, '%Y') AS BIGINT)"  # year() of a TIMESTAMP_NS just before 1970 says 1970
    year_text = (
        f"CASE WHEN {year} > 9999 THEN '+' || CAST({year} AS VARCHAR) "
        f"ELSE printf(CASE WHEN {year} < 0 THEN '%05d' ELSE '%04d' END, {year}) END"
    )
    if precision in formats:
        return f"{year_text} || strftime({sql}, {string(formats[precision])})"
    digits = 6 if precision < 6 else 9
    return f"{year_text} || left(strftime({sql}, {string(formats[digits])}), {16 + precision})"


def real_text(sql: str) -> str:
    """A real as Java's Float.toString digits (`d.ddde±xx`): the shortest that read back as it, at least
    two. DuckDB's own text has every digit of a whole real from 2^24 up (-1234567936.0, where Java's
    is -1.234568E9)."""
    texts = f'list_transform(range(1, 9), lambda "_n": format(\'{{:.{{}}e}}\', CAST({sql} AS DOUBLE), "_n"))'
    return f'list_filter({texts}, lambda "_t": CAST("_t" AS FLOAT) = {sql})[1]'


def fixed_text(text: str) -> str:
    """A number's text (`1.5e-38`) with a negative exponent written out (`0.000...15`): DuckDB's CAST
    of such a text to a decimal fails when its digits reach past the scale, where it rounds written out."""
    t = '"_t"'
    power = f"TRY_CAST(split_part({t}, 'e', 2) AS INTEGER)"
    digits = f"replace(replace(split_part({t}, 'e', 1), '-', ''), '.', '')"
    sign = f"CASE WHEN starts_with({t}, '-') THEN '-' ELSE '' END"
    written = f"CASE WHEN {power} < 0 THEN {sign} || '0.' || repeat('0', -{power} - 1) || {digits} ELSE {t} END"
    return f"list_transform([{text}], lambda {t}: {written})[1]"


#: The smallest normal double and real: below them (subnormal) Java's digits are not the shortest.
MIN_NORMAL = {"double": "2.2250738585072014E-308", "real": "1.17549435E-38"}


def approx_text(sql: str, source: TType, *, json: bool = False) -> str:
    """A double or real as Trino prints it: Java's DecimalFormat("0.0###E0") of the shortest digits that
    round-trip (1.5E0, 1.0E10, -2.5E-4, 0E0, NaN, Infinity). For a real, as the real Trino 476 prints
    it: one digit becomes the two nearest the value (REAL '1.4E-45', not 1.0E-45), and more than 7
    are rounded to 7 (REAL '3.4028235E38' is 3.402823E38). With `json`, a double's digits as Jackson
    writes them (Java 24's Double.toString: one digit becomes the two nearest, 4.9E-324). Otherwise a
    subnormal double is refused at run time: Trino's digits for it are not the shortest
    (CAST(4.9E-324 AS VARCHAR) is 4.9E-324, and 1.0E-323 for twice as much); from 2^53 to 2^63 they
    are the whole number's (_long_digits), and from 2^63 up a double whose shortest digits lie
    halfway between two doubles is refused (_halfway)."""
    value = f"CAST({sql} AS {'FLOAT' if source.base == 'real' else 'DOUBLE'})"
    digits, exponent = _digits(value, source, json=json)
    halfway = _halfway(digits, exponent)
    if source.base == "double" and not json:
        long_digits, long_exponent = _long_digits(value)
        big = f"abs({value}) >= {2**53} AND abs({value}) < {2**63}"
        digits = f"CASE WHEN {big} THEN {long_digits} ELSE {digits} END"
        exponent = f"CASE WHEN {big} THEN {long_exponent} ELSE {exponent} END"
    mantissa = f"left({digits}, 1) || '.' || coalesce(nullif(substr({digits}, 2), ''), '0')"
    subnormal = ""
    if source.base == "double" and not json:
        what = "the text of a subnormal double (VARCHAR): Java's digits differ"
        refuse = f"error({string('NOT_SUPPORTED: unsupported in lakegate: ' + what)})"
        subnormal = f"WHEN abs({value}) < {MIN_NORMAL[source.base]} THEN {refuse} "
        what = "the text of a double of 2^63 or more halfway between two doubles (VARCHAR): Java's digits differ"
        refuse = f"error({string('NOT_SUPPORTED: unsupported in lakegate: ' + what)})"
        subnormal += f"WHEN abs({value}) >= {2**63} AND {halfway} THEN {refuse} "
    return (
        f"CASE WHEN isnan({value}) THEN 'NaN' "
        f"WHEN isinf({value}) THEN CASE WHEN {value} > 0 THEN 'Infinity' ELSE '-Infinity' END "
        f"WHEN {value} = 0 THEN CASE WHEN starts_with(CAST({value} AS VARCHAR), '-') THEN '-0E0' ELSE '0E0' END "
        f"{subnormal}"
        f"ELSE CASE WHEN {value} < 0 THEN '-' ELSE '' END || {mantissa} || 'E' || CAST({exponent} AS VARCHAR) END"
    )


#: 5^0 .. 5^23: a whole number of 10^e with e > 23 has an odd part past 54 bits.
_FIVES = "[" + ", ".join(f"{5**e}::HUGEINT" for e in range(24)) + "]"


def _halfway(digits: str, exponent: str) -> str:
    """Whether the shortest decimal (digits x 10^(exponent - len + 1), a whole number) lies halfway between
    two doubles (its odd part has 54 bits), where it rounds to the double only by ties-to-even. Trino's
    digits for such a double from 2^63 up are longer and follow no rule lakegate reproduces (1e23 is
    9.999999999999999E22, 2e23 1.9999999999999998E23); for every other double they are the shortest
    (checked on 855 values from 2^63 to 1e31 against the real Trino 476)."""
    power = f"({exponent} - length({digits}) + 1)"
    whole = f"CAST({digits} AS HUGEINT) * {_FIVES}[{power} + 1]"
    odd = f"({whole} // ({whole} & -({whole})))"
    return f"({power} BETWEEN 0 AND 23 AND {odd} >= {2**53} AND {odd} < {2**54})"


def _long_digits(value: str) -> tuple[str, str]:
    """The digits and exponent Trino's CAST to VARCHAR gives a double of 2^53 <= |value| < 2^63 (a
    whole number): all its decimal digits, the last one or two rounded off HALF_UP from 2^58 and
    2^61 up (Java's older digit generation, which DecimalFormat keeps: 2.79926185055634656E17,
    8.6882974016250143E18, not the shortest 2.7992618505563466E17); checked on 1,530 values against
    the real Trino 476."""
    whole = f"CAST(abs({value}) AS HUGEINT)"
    dropped = f"(CASE WHEN abs({value}) >= {2**61} THEN 2 WHEN abs({value}) >= {2**58} THEN 1 ELSE 0 END)"
    unit = f"CAST(pow(10, {dropped}) AS HUGEINT)"
    round_up = f"CASE WHEN ({whole} % {unit}) * 2 >= {unit} AND {unit} > 1 THEN 1 ELSE 0 END"
    kept = f"CAST({whole} // {unit} + {round_up} AS VARCHAR)"
    return f"rtrim({kept}, '0')", f"(length({kept}) - 1 + {dropped})"


def java_digits(value: str) -> tuple[str, str]:
    """The digits (no leading or trailing zeros) and decimal exponent of Java 24's Double.toString of
    a positive finite DOUBLE `value`: the shortest that round-trip, one digit becoming the two
    nearest the value (4.9E-324, not 5E-324)."""
    return _digits(value, tt.DOUBLE, json=True)


def _digits(value: str, source: TType, *, json: bool) -> tuple[str, str]:
    """approx_text's digits and exponent of abs(value) (see there)."""
    exact = f"CAST(abs({value}) AS DOUBLE)"
    text = f"CAST(abs({value}) AS VARCHAR)"
    shortest = f"regexp_replace(replace(split_part({text}, 'e', 1), '.', ''), '^0+|0+$', '', 'g')"

    def nearest(significant: int) -> tuple[str, str]:  # the digits and exponent rounded to `significant`
        rounded = f"format('{{:.{significant - 1}e}}', {exact})"
        digits = f"regexp_replace(replace(split_part({rounded}, 'e', 1), '.', ''), '0+$', '')"
        return digits, f"CAST(split_part({rounded}, 'e', 2) AS INTEGER)"

    digits, exponent = shortest, _shortest_exponent(text)
    if source.base == "real" or json:
        (two, two_exponent), (seven, seven_exponent) = nearest(2), nearest(7)
        one, long = f"length({shortest}) = 1", f"length({shortest}) > 7" if source.base == "real" else "false"
        digits = f"CASE WHEN {one} THEN {two} WHEN {long} THEN {seven} ELSE {digits} END"
        exponent = f"CASE WHEN {one} THEN {two_exponent} WHEN {long} THEN {seven_exponent} ELSE {exponent} END"
    return digits, exponent


def _shortest_exponent(text: str) -> str:
    """The decimal exponent of DuckDB's shortest text of a positive number (`1e+23`, `0.00012`, `123.5`):
    where its first digit stands (the 17-digit rounding of 1e23, 9.99...E22, has another)."""
    mantissa = f"split_part({text}, 'e', 1)"
    power = f"coalesce(TRY_CAST(nullif(split_part({text}, 'e', 2), '') AS INTEGER), 0)"
    whole, fraction = f"ltrim(split_part({mantissa}, '.', 1), '0')", f"split_part({mantissa}, '.', 2)"
    leading = f"(length({fraction}) - length(ltrim({fraction}, '0')))"
    return f"({power} + CASE WHEN length({whole}) > 0 THEN length({whole}) - 1 ELSE -{leading} - 1 END)"


@transform(ShownWide)
def shown_wide(g: Writer, node: ShownWide) -> str:
    """The value with its wall time (wide_timestamps.shown): the struct orders as the value where ORDER
    BY names the result column."""
    t = ttype(node)
    return wide.shown(g.coerce(node.this, t), tt.zone_of(t) if t.base == "timestamp_tz" else None)


@transform(FloorMicros)
def floored_micros(g: Writer, node: FloorMicros) -> str:
    if wide.is_wide(ttype(node.this)):
        return wide.micros(g.sql(node.this))
    return floor_micros(g.sql(node.this))
