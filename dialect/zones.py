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

UTC = "UTC"

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
    if name in _regions():
        return name
    text, negate = name, False
    for prefix in _OFFSET_PREFIXES:
        if name.startswith(prefix) and name[len(prefix) : len(prefix) + 1] in ("+", "-"):
            text, negate = name[len(prefix) :], prefix == "Etc/GMT"
            break
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


def _icu(zone: str) -> str:
    """The zone as a DuckDB (ICU) string literal: ICU reads offsets as `GMT+05:45`."""
    return f"'GMT{zone}'" if is_offset(zone) else f"'{zone}'"


def local(sql: str, zone: str) -> str:
    """DuckDB SQL of the wall-clock TIMESTAMP in `zone` of the instant `sql` (a TIMESTAMPTZ)."""
    return f"timezone({_icu(zone)}, {sql})"


def instant(sql: str, zone: str) -> str:
    """DuckDB SQL of the instant (TIMESTAMPTZ) of the wall-clock TIMESTAMP `sql` in `zone`, as
    java.time.ZonedDateTime.of reads it: a time in a gap moves forward by the gap, a time in an overlap
    takes the earlier instant (ICU takes the later: the earlier is tried first, 1 hour back)."""
    if zone == UTC or is_offset(zone):
        return f"timezone({_icu(zone)}, {sql})"
    later = f"timezone({_icu(zone)}, {sql})"
    earlier = f"({later} - INTERVAL 1 HOUR)"
    return f"CASE WHEN {local(earlier, zone)} = {sql} THEN {earlier} ELSE {later} END"
