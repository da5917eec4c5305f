"""dialect/zones.py: zone names read as Trino's TimeZoneKey reads them, and the wall time <-> instant
SQL checked in real DuckDB against Python's zoneinfo (an independent reading of the tz database) around
every daylight-saving transition, where java.time (Trino) and ICU (DuckDB) differ."""

from __future__ import annotations

import datetime as dt
from zoneinfo import ZoneInfo

import duckdb
import pytest

from lakegate.dialect import zones


@pytest.mark.parametrize(
    "name, zone",
    [
        ("America/New_York", "America/New_York"),
        ("UTC", "UTC"),
        ("Etc/UTC", "UTC"),
        ("Z", "UTC"),
        ("GMT0", "UTC"),
        ("+00:00", "UTC"),
        ("UTC+0", "UTC"),
        ("+05:45", "+05:45"),
        ("-08:30", "-08:30"),
        ("+7", "+07:00"),
        ("+0709", "+07:09"),
        ("UTC+7", "+07:00"),
        ("GMT-08:30", "-08:30"),
        ("Etc/GMT+5", "-05:00"),  # the tz database names it too, but the real Trino 476 shows the offset
        ("Etc/GMT+05:00", "-05:00"),  # a legacy offset: Etc/GMT's sign is inverted (TimeZoneKey.normalizeZoneId)
    ],
)
def test_canonical_names(name, zone):
    assert zones.canonical(name) == zone


@pytest.mark.parametrize("name", ["Mars/Olympus", "america/new_york", "+15:00", "+05:60", "GMT7", ""])
def test_unknown_zones(name):
    with pytest.raises(ValueError, match="Time zone not supported"):
        zones.canonical(name)


def _wall_times_around_transitions(zone: str, year: int):
    """Every 15 minutes from 4 hours before to 4 hours after each offset change of `zone` in `year`."""
    tz = ZoneInfo(zone)
    moment, previous = dt.datetime(year, 1, 1), tz.utcoffset(dt.datetime(year, 1, 1))
    while moment.year == year:
        offset = tz.utcoffset(moment)
        if offset != previous:
            yield from (moment + dt.timedelta(minutes=m) for m in range(-240, 241, 15))
        previous = offset
        moment += dt.timedelta(hours=1)


@pytest.mark.parametrize(
    "zone", ["America/New_York", "Europe/Berlin", "Australia/Lord_Howe", "Antarctica/Troll", "Europe/London"]
)
def test_instant_reads_wall_times_as_java_time(zone):
    """Gaps move forward by the gap, overlaps take the earlier instant (java.time.ZonedDateTime.of; zoneinfo
    with fold=0 gives the same instants); Lord Howe's DST is 30 minutes, Troll's 2 hours, London's 1944
    double summer time 2 hours."""
    connection = duckdb.connect()
    connection.execute("SET TimeZone = 'UTC'")
    walls = [w for year in (1944, 2013, 2020) for w in _wall_times_around_transitions(zone, year)]
    assert walls
    sql = " UNION ALL ".join(
        f"SELECT {i} AS i, epoch({zones.instant(f'TIMESTAMP {chr(39)}{w:%Y-%m-%d %H:%M}{chr(39)}', zone)}) AS e"
        for i, w in enumerate(walls)
    )
    got = dict(connection.execute(sql).fetchall())
    want = {i: w.replace(tzinfo=ZoneInfo(zone), fold=0).timestamp() for i, w in enumerate(walls)}
    assert got == want
