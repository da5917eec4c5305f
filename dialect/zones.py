"""Trino's time zones: zone names read as Trino reads them, and the DuckDB SQL (ICU) that moves between
an instant and its wall-clock time in a zone.

How lakegate holds `timestamp(p) with time zone`: DuckDB holds the instant (TIMESTAMPTZ, its session
zone always UTC), and the zone is static per expression, kept in the expression's Trino type
(`TType("timestamp_tz", (p, zone))`, see trino_types.zone_of). Every zone-dependent operation
(fields, date_trunc, calendar arithmetic, casts to timestamp, date or varchar, rendering) is written
with that zone explicitly, so it computes what Trino computes on a value carrying that zone. An
expression whose values would not all carry one zone has the zone None and is refused where the zone
matters (analyze.zone_or_refuse).
"""

from __future__ import annotations

import re
import zoneinfo
from functools import lru_cache

from lakegate.dialect.errors import DialectError

UTC = "UTC"

#: The zone rules, as docs/functions.md lists them (tools/functions_doc.py).
RULES = (
    "The session zone is X-Trino-Time-Zone (the client's `timezone=`), overridden by `SET TIME ZONE`; "
    "`lakegate query --time-zone`; UTC without either. Zone names are Trino's: IANA regions, UTC and its "
    "aliases, offsets `+hh:mm` (`+7`, `UTC+7`, `Etc/GMT-7` read as `+07:00`); others fail with "
    "NOT_SUPPORTED `Time zone not supported`.",
    "In the session zone: `current_timezone()`, `from_unixtime(x)`, `current_timestamp` / `now()`, "
    "`localtimestamp`, `current_date`, CAST of a timestamp or date to timestamp with time zone, "
    "`to_unixtime(timestamp)`, `at_timezone(timestamp, z)`, `timestamp AT TIME ZONE z`, and a date or "
    "timestamp compared with a timestamp with time zone.",
    "A timestamp with time zone keeps the zone of its value: a literal's (`TIMESTAMP '... America/New_York'`, "
    "`'... -08:30'`), the session zone, `AT TIME ZONE 'z'`, `at_timezone`, `with_timezone`, "
    "`from_unixtime(x, 'z')`. It is shown in that zone, and fields (`hour`, `day`, `EXTRACT`), "
    "`date_trunc`, `date_format`, `timezone_hour` / `timezone_minute`, casts to timestamp, date and varchar, "
    "calendar units (day and longer) of `date_add` compute on its wall time in that zone, and of "
    "`date_diff` in the first value's zone when both have at most millisecond precision (in UTC above, as "
    "Trino's DateDiff); hours and shorter units, `+ INTERVAL` (months too: in UTC, as Trino's "
    "TimestampWithTimeZoneOperators) and comparisons use the instant.",
    "How: DuckDB holds the instant (TIMESTAMPTZ, its own session zone always UTC); the zone is static per "
    "expression, carried in the expression's Trino type, and every zone-dependent operation is written with "
    "it (DuckDB's ICU `timezone(zone, x)`; offsets as `GMT+05:45`); result columns are given that zone.",
    "A wall time in a daylight-saving gap moves forward by the gap; one in an overlap is the earlier "
    "instant (java.time.ZonedDateTime.of, as Trino).",
    "Refused (NOT_SUPPORTED) where the zone matters: values of several zones in one expression (CASE, "
    "COALESCE, UNION, VALUES mixing zones, dates or timestamps), a zone that is not a literal, and arrays, "
    "maps or rows of zoned values in a zone other than UTC as results.",
)

#: Names Trino reads as UTC (io.trino.spi.type.TimeZoneKey.UTC_EQUIVALENTS).
_UTC_EQUIVALENTS = frozenset(
    "GMT GMT0 GMT+0 GMT-0 Etc/GMT Etc/GMT0 Etc/GMT+0 Etc/GMT-0 UT UT+0 UT-0 Etc/UT Etc/UT+0 Etc/UT-0 "
    "UTC UTC+0 UTC-0 Etc/UTC Etc/UTC+0 Etc/UTC-0 +0000 +00:00 -0000 -00:00 Z Zulu UCT Greenwich Universal "
    "Etc/Universal Etc/UCT".split()
)
#: Prefixes of legacy offset names, `GMT-7`, `Etc/GMT+5` (TimeZoneKey.UTC_OFFSET_PREFIXES, longest first).
_OFFSET_PREFIXES = ("Etc/GMT", "Etc/UTC", "Etc/UT", "GMT", "UTC", "UT")
#: An offset as java.time.ZoneOffset.of reads it: +h, +hh, +hh:mm, +hhmm.
_OFFSET = re.compile(r"([+-])([0-9]{1,2})(?::?([0-9]{2}))?")
#: Trino's offset zones span -14:00 .. +14:00 (TimeZoneKey.OFFSET_TIME_ZONE_MIN/MAX).
_MAX_OFFSET_MINUTES = 14 * 60


@lru_cache(maxsize=1)
def _regions() -> frozenset[str]:
    """The IANA region names (the tz database's, as Java's and ICU's zone lists hold them)."""
    return frozenset(zoneinfo.available_timezones()) - {"Factory", "localtime", "posixrules"}


def _offset_zone(sign: str, hours: int, minutes: int) -> str | None:
    total = hours * 60 + minutes
    if minutes > 59 or total > _MAX_OFFSET_MINUTES:
        return None
    if total == 0:
        return UTC
    return f"{sign}{hours:02d}:{minutes:02d}"


@lru_cache(maxsize=256)
def canonical(name: str) -> str:
    """Trino's id of the zone `name` (io.trino.spi.type.TimeZoneKey.getTimeZoneKey): a region name as
    given, `UTC` for each of its equivalents, an offset as `+hh:mm` (`+7`, `+0700`, `UTC+7` and
    `Etc/GMT-7` are all `+07:00`, `GMT+00:00` is UTC). ValueError `Time zone not supported: name` otherwise."""
    if name in _UTC_EQUIVALENTS:
        return UTC
    text, negate = name, False
    for prefix in _OFFSET_PREFIXES:  # before the regions: the tz database also names Etc/GMT-7
        if name.startswith(prefix) and name[len(prefix) : len(prefix) + 1] in ("+", "-"):
            text, negate = name[len(prefix) :], prefix == "Etc/GMT"
            break
    else:
        if name in _regions():
            return name
    match = _OFFSET.fullmatch(text)
    zone = None
    if match is not None:
        sign = match.group(1) if not negate else {"+": "-", "-": "+"}[match.group(1)]
        zone = _offset_zone(sign, int(match.group(2)), int(match.group(3) or 0))
    if zone is None:
        raise ValueError(f"Time zone not supported: {name}")
    return zone


def is_offset(zone: str) -> bool:
    """Whether the (canonical) zone is a fixed offset such as `+05:45`."""
    return zone[:1] in ("+", "-")


def _icu(zone: str | None) -> str:
    """The zone as a DuckDB (ICU) string literal: ICU reads offsets as `GMT+05:45`; refused for None
    (values that may carry different zones, whose local times lakegate cannot compute)."""
    if zone is None:
        raise DialectError(
            "unsupported in lakegate: the local date or time of timestamp with time zone values that may carry "
            "different zones (a CASE, COALESCE, UNION, VALUES, greatest or least mixing zones)",
            error_name="NOT_SUPPORTED",
        )
    return f"'GMT{zone}'" if is_offset(zone) else f"'{zone}'"


def local(sql: str, zone: str) -> str:
    """DuckDB SQL of the wall-clock TIMESTAMP in `zone` of the instant `sql` (a TIMESTAMPTZ)."""
    return f"timezone({_icu(zone)}, {sql})"


def instant(sql: str, zone: str) -> str:
    """DuckDB SQL of the instant (TIMESTAMPTZ) of the wall-clock TIMESTAMP `sql` in `zone`, as
    java.time.ZonedDateTime.of reads it: a time in a gap moves forward by the gap (as ICU does), a time in
    an overlap is the earlier instant (ICU gives the later): the wall time read with the offset the zone
    had 3 hours before ICU's instant, when that reading gives the same wall time back."""
    later = f"timezone({_icu(zone)}, {sql})"
    if zone == UTC or is_offset(zone):
        return later
    before = f"({later} - INTERVAL 3 HOUR)"
    earlier = f"timezone('UTC', {sql} - ({local(before, zone)} - {local(before, UTC)}))"
    return f"CASE WHEN {local(earlier, zone)} = {sql} THEN {earlier} ELSE {later} END"
