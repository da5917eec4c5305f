"""The session time zone end to end: a real `lakegate serve` on 127.0.0.1 and the real `trino` client
connected with timezone='America/New_York' and with an offset zone, SET TIME ZONE, and `lakegate query
--time-zone` as a subprocess. Expected values are computed with Python's zoneinfo from the tz database,
independently of DuckDB's ICU, which lakegate uses."""

from __future__ import annotations

import datetime as dt
import json
import subprocess
import sys
from zoneinfo import ZoneInfo

import pytest
import trino

#: Every zone-dependent function and cast lakegate supports, each with the text Trino shows for it
#: (computed below from zoneinfo for the session zone).
ZONED_SQL = """
SELECT current_timezone(),
       CAST(from_unixtime(1000000000) AS varchar),
       hour(from_unixtime(1000000000)), minute(from_unixtime(1000000000)), day(from_unixtime(1000000000)),
       EXTRACT(HOUR FROM from_unixtime(1000000000)),
       date_format(from_unixtime(1000000000), '%Y-%m-%d %H:%i'),
       CAST(from_unixtime(1000000000) AS timestamp(3)),
       CAST(from_unixtime(1000000000) AS date),
       to_unixtime(TIMESTAMP '2001-09-09 00:00:00'),
       CAST(CAST(TIMESTAMP '2001-09-09 00:00:00' AS timestamp with time zone) AS varchar),
       CAST(date_trunc('day', from_unixtime(1000000000)) AS varchar),
       CAST(date_add('day', 1, from_unixtime(1000000000)) AS varchar),
       date_diff('hour', TIMESTAMP '2001-09-09 00:00:00', from_unixtime(1000000000)),
       timezone_hour(from_unixtime(1000000000)), timezone_minute(from_unixtime(1000000000)),
       CAST(at_timezone(TIMESTAMP '2001-09-09 00:00:00', 'UTC') AS varchar),
       CAST(with_timezone(TIMESTAMP '2001-09-09 00:00:00', 'UTC') AS varchar),
       DATE '2001-09-09' = TIMESTAMP '2001-09-09 00:00:00 UTC',
       CAST(current_timestamp AS date) = current_date,
       localtimestamp - CAST(current_timestamp AS timestamp(3)) = INTERVAL '0' SECOND,
       CAST(now() AS varchar) LIKE '% ' || current_timezone(),
       to_iso8601(from_unixtime(1000000000)),
       date(from_unixtime(1000000000)), last_day_of_month(from_unixtime(1000000000)),
       timezone_hour(TIMESTAMP '2001-09-09 00:00:00'),
       CAST(date_trunc('hour', from_unixtime(1000000000)) AS varchar),
       from_unixtime(1000000000) = TIMESTAMP '2001-09-09 01:46:40 UTC'
"""


def _offset(value: dt.datetime) -> tuple[int, int]:
    minutes = int(value.utcoffset().total_seconds()) // 60
    sign = -1 if minutes < 0 else 1
    return sign * (abs(minutes) // 60), sign * (abs(minutes) % 60)


def expected(zone: str, tz: dt.tzinfo) -> list:
    """What Trino answers ZONED_SQL with in the session zone `zone` (tz: its tzinfo)."""
    instant = dt.datetime.fromtimestamp(1_000_000_000, tz)
    midnight = dt.datetime(2001, 9, 9, tzinfo=tz)  # TIMESTAMP '2001-09-09 00:00:00' read in the zone
    day = instant.replace(hour=0, minute=0, second=0)
    hours, minutes = _offset(instant)
    utc_midnight = dt.datetime(2001, 9, 9, tzinfo=dt.UTC)
    return [
        zone,
        instant.strftime("%Y-%m-%d %H:%M:%S.000 ") + zone,
        instant.hour,
        instant.minute,
        instant.day,
        instant.hour,
        instant.strftime("%Y-%m-%d %H:%M"),
        instant.replace(tzinfo=None),
        instant.date(),
        midnight.timestamp(),
        "2001-09-09 00:00:00.000 " + zone,
        day.strftime("%Y-%m-%d %H:%M:%S.000 ") + zone,
        (instant + dt.timedelta(days=1)).strftime("%Y-%m-%d %H:%M:%S.000 ") + zone,
        int((instant - midnight).total_seconds() / 3600),  # whole hours, toward zero
        hours,
        minutes,
        midnight.astimezone(dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),  # timestamp(0): no fraction
        "2001-09-09 00:00:00 UTC",
        dt.datetime(2001, 9, 9, tzinfo=tz) == utc_midnight,
        True,
        True,
        True,
        instant.isoformat(timespec="milliseconds"),
        instant.date(),
        (instant.replace(day=28) + dt.timedelta(days=4)).replace(day=1).date() - dt.timedelta(days=1),
        _offset(midnight)[0],
        instant.replace(minute=0, second=0).strftime("%Y-%m-%d %H:%M:%S.000 ") + zone,
        True,
    ]


ZONES = [
    ("America/New_York", ZoneInfo("America/New_York")),
    ("+05:45", dt.timezone(dt.timedelta(hours=5, minutes=45))),
    ("Asia/Kathmandu", ZoneInfo("Asia/Kathmandu")),
]


def fetch(server, sql: str, zone: str) -> list[list]:
    """Rows of `sql` in the session zone `zone`: the client's timezone= for a region; the Python client
    takes only region names there, so an offset is set with SET TIME ZONE."""
    offset = zone[0] in "+-"
    with trino.dbapi.connect(
        host=server.host,
        port=server.port,
        user="tester",
        catalog="lake",
        schema="main",
        timezone="UTC" if offset else zone,
    ) as connection:
        cursor = connection.cursor()
        if offset:
            cursor.execute(f"SET TIME ZONE '{zone}'")
            cursor.fetchall()
        cursor.execute(sql)
        return cursor.fetchall()


@pytest.mark.parametrize("zone, tz", ZONES, ids=[zone for zone, _ in ZONES])
def test_trino_client_session_zone(lake_server, zone, tz):
    """The client's timezone= (X-Trino-Time-Zone), or SET TIME ZONE, is the session zone of every
    zone-dependent function (an unknown zone in X-Trino-Time-Zone: test_server_protocol)."""
    assert fetch(lake_server, ZONED_SQL, zone) == [expected(zone, tz)]


def test_zoned_values_arrive_in_their_zone(lake_server):
    """A timestamp with time zone result carries its own zone to the client, whatever the session zone."""
    (row,) = fetch(
        lake_server,
        "SELECT TIMESTAMP '2001-08-22 03:04:05.321 America/New_York', from_unixtime(0), "
        "TIMESTAMP '2001-08-22 03:04:05.321 -08:30' AT TIME ZONE '+07:09'",
        "Asia/Kathmandu",
    )
    assert row[0] == dt.datetime(2001, 8, 22, 3, 4, 5, 321000, tzinfo=ZoneInfo("America/New_York"))
    assert row[1] == dt.datetime(1970, 1, 1, tzinfo=dt.UTC) and row[1].utcoffset() == dt.timedelta(hours=5, minutes=30)
    assert row[2].utcoffset() == dt.timedelta(hours=7, minutes=9) and (row[2].hour, row[2].minute) == (18, 43)


def test_set_time_zone(lake_server):
    """SET TIME ZONE sets the session property time_zone_id, which the client sends back; LOCAL clears it."""
    with trino.dbapi.connect(
        host=lake_server.host, port=lake_server.port, user="tester", catalog="lake", timezone="UTC"
    ) as connection:
        cursor = connection.cursor()
        cursor.execute("SET TIME ZONE 'America/Los_Angeles'")
        cursor.fetchall()
        cursor.execute("SELECT current_timezone(), hour(from_unixtime(0))")
        assert cursor.fetchall() == [["America/Los_Angeles", 16]]
        cursor.execute("SET TIME ZONE LOCAL")
        cursor.fetchall()
        cursor.execute("SELECT current_timezone()")
        assert cursor.fetchall() == [["UTC"]]
        with pytest.raises(trino.exceptions.TrinoUserError, match="Time zone not supported: Mars/Olympus"):
            cursor.execute("SET TIME ZONE 'Mars/Olympus'")
            cursor.fetchall()


def lakegate_query(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "lakegate.gateway.cli", "query", *args], capture_output=True, text=True, timeout=120
    )


def test_query_command_time_zone():
    done = lakegate_query(
        "--format", "json", "--time-zone", "America/New_York", "SELECT current_timezone(), from_unixtime(0)"
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["rows"] == [["America/New_York", "1969-12-31 19:00:00.000 America/New_York"]]
    done = lakegate_query("--time-zone", "Mars/Olympus", "SELECT 1")
    assert done.returncode == 1 and done.stderr == "lakegate: Time zone not supported: Mars/Olympus\n"


def test_picosecond_times_and_the_session_date_through_the_protocol(lake_server):
    """time(12) arrives as Trino's text, every digit kept (dialect/pico_times.py); a time cast to a
    timestamp lands on the session's date in the session zone, the next day when it rounds up to 24:00."""
    with trino.dbapi.connect(
        host=lake_server.host,
        port=lake_server.port,
        user="tester",
        catalog="lake",
        timezone="Pacific/Kiritimati",
        legacy_primitive_types=True,
    ) as connection:
        cursor = connection.cursor()
        cursor.execute(
            "SELECT TIME '12:34:56.123456789012', CAST(TIME '23:59:59.9999999' AS timestamp(6)), "
            "CAST(TIME '01:02:03.1234567+05:45' AS timestamp(9)), CAST(current_date AS varchar)"
        )
        ((time, rounded, zoned, today),) = cursor.fetchall()
        assert [column.type_code for column in cursor.description[:3]] == ["time(12)", "timestamp(6)", "timestamp(9)"]
    day = dt.date.fromisoformat(today)
    assert time == "12:34:56.123456789012"
    assert rounded == f"{day + dt.timedelta(days=1)} 00:00:00.000000"
    assert zoned == f"{day} 01:02:03.123456700"
