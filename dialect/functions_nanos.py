"""from_unixtime_nanos (issue 14 family 5): nanoseconds since the epoch as a timestamp(9) with time
zone in the session zone, held as dialect/zoned_nanos.py describes.

Source: trinodb/trino core/trino-main/src/main/java/io/trino/operator/scalar/DateTimeFunctions.java
(fromUnixtimeNanosLong; FromUnixtimeNanosDecimal rounds a decimal HALF_UP to whole nanoseconds) and
operator/scalar/timestamptz/ToUnixTime.java; cases in tests/dialect/cases/cov_nanos.yaml.
"""

from __future__ import annotations

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import zoned_nanos
from lakegate.dialect.analyze import Call
from lakegate.dialect.registry import overload, register

#: The largest magnitude of nanoseconds DuckDB's TIMESTAMP_NS holds (the bigints past it are its infinities).
_LAST_NANOS = 2**63 - 2


def _from_unixtime_nanos(call: Call) -> tt.TType:
    types = call.types
    if len(types) != 1 or types[0] is None or not (types[0].is_integral or types[0].is_decimal or types[0].is_unknown):
        call.mismatch()
    return tt.timestamp(9, True, call.analyzer.time_zone)


def _render_from_unixtime_nanos(g, node, args) -> str:
    """make_timestamp_ns of the whole nanoseconds (DuckDB's CAST of a decimal to BIGINT rounds half away
    from zero, as Trino's MathFunctions.Round.roundShort)."""
    nanos = f"CAST({g.sql(args[0])} AS BIGINT)"
    message = (
        tf.string("unsupported in lakegate: from_unixtime_nanos of ")
        + f" || {nanos} || "
        + tf.string(" (DuckDB's TIMESTAMP_NS keeps its extreme values for its infinities)")
    )
    return (
        f"CASE WHEN {nanos} NOT BETWEEN {-_LAST_NANOS} AND {_LAST_NANOS} THEN {g.fail(message, 'NOT_SUPPORTED')} "
        f"ELSE make_timestamp_ns({nanos}) END"
    )


register(
    "from_unixtime_nanos",
    "datetime",
    "from_unixtime_nanos(unixtime) -> timestamp(9) with time zone",
    _from_unixtime_nanos,
    _render_from_unixtime_nanos,
    notes="In the session time zone. Such values can be shown, compared with each other, ordered, grouped, "
    "aggregated with min / max / count / arbitrary, moved with AT TIME ZONE and cast to timestamp(p), date and "
    "varchar; other uses are refused.",
)


def _to_unixtime_nanos(call: Call) -> tt.TType | None:
    return tt.DOUBLE if len(call.types) == 1 and zoned_nanos.is_zoned_nanos(call.types[0]) else None


def _render_to_unixtime_nanos(g, node, args) -> str:
    """ToUnixTime of a LongTimestampWithTimeZone: epochMillis / 1000.0 + picosOfMilli / 1e12, in doubles
    (the milliseconds floored, the picoseconds of the millisecond never negative)."""
    nanos = f"epoch_ns({g.sql(args[0])})"
    millis = tf.floor_div(nanos, 1_000_000)
    return f"(CAST({millis} AS DOUBLE) / 1000.0 + CAST(({nanos} - {millis} * 1000000) * 1000 AS DOUBLE) / 1e12)"


overload(
    "to_unixtime",
    _to_unixtime_nanos,
    _render_to_unixtime_nanos,
    "to_unixtime(timestamp(9) with time zone) -> double",
)
