"""Timestamps with time zone past microseconds through a real `lakegate serve` and the official trino
client: from_unixtime_nanos over a real Parquet column of nanosecond integers (robot data stores its
timestamps as bigint nanoseconds) arrives as Trino's text with nine fraction digits, in the session
zone; literals of up to twelve digits as Trino writes them."""

from __future__ import annotations

import datetime as dt
from zoneinfo import ZoneInfo

import trino


def _rows(server, sql: str, zone: str) -> tuple[list, list[str]]:
    with trino.dbapi.connect(
        host="127.0.0.1",
        port=server.port,
        user="me",
        catalog="lake",
        schema="main",
        timezone=zone,
        legacy_primitive_types=True,  # the protocol's text, as Trino sends it
    ) as conn:
        cursor = conn.cursor()
        cursor.execute(sql)
        return cursor.fetchall(), [column[1] for column in cursor.description]


def _trino_text(nanos: int, zone: str) -> str:
    seconds, fraction = divmod(nanos, 10**9)
    stamp = dt.datetime.fromtimestamp(seconds, ZoneInfo(zone))
    return f"{stamp:%Y-%m-%d %H:%M:%S}.{fraction:09d} {zone}"


def test_nanosecond_column_through_the_server(lake_server):
    for zone in ("UTC", "America/New_York"):
        rows, types = _rows(
            lake_server,
            'SELECT "timestamp" + 123, from_unixtime_nanos("timestamp" + 123) FROM odom_linear_velocity ORDER BY 1',
            zone,
        )
        assert types == ["bigint", "timestamp(9) with time zone"]
        assert len(rows) > 3
        assert [text for _, text in rows] == [_trino_text(nanos, zone) for nanos, _ in rows]


def test_comparisons_and_min_max_through_the_server(lake_server):
    rows, _ = _rows(
        lake_server,
        'SELECT min("timestamp"), min(from_unixtime_nanos("timestamp")), count(*) FILTER (WHERE '
        'from_unixtime_nanos("timestamp") > from_unixtime_nanos(1)) FROM odom_linear_velocity',
        "UTC",
    )
    [(first, first_text, later)] = rows
    assert first_text == _trino_text(first, "UTC") and later > 0


def test_picosecond_timestamps_with_time_zone_through_the_server(lake_server):
    rows, types = _rows(
        lake_server,
        "SELECT TIMESTAMP '2020-05-01 12:34:56.123456789012 Asia/Kathmandu' AT TIME ZONE 'America/New_York', "
        "CAST(TIMESTAMP '1500-05-01 12:34:56.99999999 +05:45' AS timestamp(7) with time zone) "
        "FROM odom_linear_velocity ORDER BY 1 LIMIT 1",
        "UTC",
    )
    assert types == ["timestamp(12) with time zone", "timestamp(7) with time zone"]
    assert rows == [["2020-05-01 02:49:56.123456789012 America/New_York", "1500-05-01 12:34:57.0000000 +05:45"]]
