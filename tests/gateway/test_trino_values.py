"""Trino protocol encoding: type signatures and values, checked against the real trino client's own
decoding (trino.mapper.RowMapperFactory) and on real DuckDB Arrow batches."""

from __future__ import annotations

import datetime as dt
import json
import math
import uuid
from decimal import Decimal
from zoneinfo import ZoneInfo

import duckdb
import pyarrow as pa
import pytest
from trino.mapper import RowMapperFactory

from lakegate.dialect.trino_types import parse_type
from lakegate.gateway.engine.trino_values import arrow_type, encode_rows, encoder, protocol_type, type_signature
from lakegate.lake.schema import ARROW_TYPES

VARCHAR = {"rawType": "varchar", "arguments": [{"kind": "LONG", "value": 2147483647}]}


def decoded(columns, rows):
    """What the trino Python client makes of encoded rows (after a JSON round trip)."""
    described = [{"name": name, "type": t, "typeSignature": type_signature(t)} for name, t in columns]
    wire = json.loads(json.dumps(rows, allow_nan=False))
    return RowMapperFactory().create(columns=described, legacy_primitive_types=False).map(wire)


@pytest.mark.parametrize(
    "trino_type, signature",
    [
        ("bigint", {"rawType": "bigint", "arguments": []}),
        ("integer", {"rawType": "integer", "arguments": []}),
        ("double", {"rawType": "double", "arguments": []}),
        ("boolean", {"rawType": "boolean", "arguments": []}),
        ("varchar", VARCHAR),
        ("varchar(10)", {"rawType": "varchar", "arguments": [{"kind": "LONG", "value": 10}]}),
        ("char(3)", {"rawType": "char", "arguments": [{"kind": "LONG", "value": 3}]}),
        (
            "decimal(10,2)",
            {"rawType": "decimal", "arguments": [{"kind": "LONG", "value": 10}, {"kind": "LONG", "value": 2}]},
        ),
        ("timestamp(3)", {"rawType": "timestamp", "arguments": [{"kind": "LONG", "value": 3}]}),
        (
            "timestamp(6) with time zone",
            {"rawType": "timestamp with time zone", "arguments": [{"kind": "LONG", "value": 6}]},
        ),
        ("time(3)", {"rawType": "time", "arguments": [{"kind": "LONG", "value": 3}]}),
        ("date", {"rawType": "date", "arguments": []}),
        ("varbinary", {"rawType": "varbinary", "arguments": []}),
        ("uuid", {"rawType": "uuid", "arguments": []}),
        ("interval day to second", {"rawType": "interval day to second", "arguments": []}),
        ("array(varchar)", {"rawType": "array", "arguments": [{"kind": "TYPE", "value": VARCHAR}]}),
        (
            "map(varchar, bigint)",
            {
                "rawType": "map",
                "arguments": [
                    {"kind": "TYPE", "value": VARCHAR},
                    {"kind": "TYPE", "value": {"rawType": "bigint", "arguments": []}},
                ],
            },
        ),
        (
            "row(a bigint, b varchar)",
            {
                "rawType": "row",
                "arguments": [
                    {
                        "kind": "NAMED_TYPE",
                        "value": {"fieldName": {"name": "a"}, "typeSignature": {"rawType": "bigint", "arguments": []}},
                    },
                    {"kind": "NAMED_TYPE", "value": {"fieldName": {"name": "b"}, "typeSignature": VARCHAR}},
                ],
            },
        ),
        (
            "row(integer, double)",
            {
                "rawType": "row",
                "arguments": [
                    {"kind": "NAMED_TYPE", "value": {"typeSignature": {"rawType": "integer", "arguments": []}}},
                    {"kind": "NAMED_TYPE", "value": {"typeSignature": {"rawType": "double", "arguments": []}}},
                ],
            },
        ),
    ],
)
def test_type_signatures(trino_type, signature):
    assert type_signature(trino_type) == signature


def test_unknown_type_names_are_refused():
    with pytest.raises(ValueError):
        type_signature("VARCHAR[]")


@pytest.mark.parametrize(
    "trino_type, value, wire",
    [
        ("bigint", 9223372036854775807, 9223372036854775807),
        ("double", 1.5, 1.5),
        ("double", math.inf, "Infinity"),
        ("double", -math.inf, "-Infinity"),
        ("real", math.nan, "NaN"),
        ("decimal(10,2)", Decimal("1.5"), "1.50"),
        ("decimal(38,10)", Decimal("0E-10"), "0.0000000000"),
        ("decimal(5,0)", Decimal("-12"), "-12"),
        ("varchar", "héllo", "héllo"),
        ("boolean", False, False),
        ("varbinary", b"\x00\xffab", "AP9hYg=="),
        ("date", dt.date(2024, 2, 29), "2024-02-29"),
        ("timestamp(3)", dt.datetime(2024, 1, 2, 3, 4, 5, 123000), "2024-01-02 03:04:05.123"),
        ("timestamp(0)", dt.datetime(2024, 1, 2, 3, 4, 5), "2024-01-02 03:04:05"),
        ("timestamp(6)", dt.datetime(2024, 1, 2, 3, 4, 5, 7), "2024-01-02 03:04:05.000007"),
        ("timestamp(9)", dt.datetime(2024, 1, 2, 3, 4, 5, 7), "2024-01-02 03:04:05.000007000"),
        (
            "timestamp(3) with time zone",
            dt.datetime(2024, 1, 2, 3, 4, 5, 123000, tzinfo=dt.UTC),
            "2024-01-02 03:04:05.123 UTC",
        ),
        (
            "timestamp(3) with time zone",
            dt.datetime(2024, 7, 2, 3, 4, 5, tzinfo=ZoneInfo("Europe/Paris")),
            "2024-07-02 03:04:05.000 Europe/Paris",
        ),
        (
            "timestamp(0) with time zone",
            dt.datetime(2024, 7, 2, 3, 4, 5, tzinfo=dt.timezone(dt.timedelta(hours=5, minutes=30))),
            "2024-07-02 03:04:05 +05:30",
        ),
        ("time(3)", dt.time(1, 2, 3, 500000), "01:02:03.500"),
        ("uuid", uuid.UUID("12345678-1234-5678-1234-567812345678"), "12345678-1234-5678-1234-567812345678"),
        (
            "interval day to second",
            dt.timedelta(days=1, hours=2, minutes=3, seconds=4, milliseconds=5),
            "1 02:03:04.005",
        ),
        ("interval day to second", -dt.timedelta(seconds=1.5), "-0 00:00:01.500"),
        ("array(double)", [1.0, math.nan, None], [1.0, "NaN", None]),
        ("array(decimal(4,1))", [Decimal("1.5"), None], ["1.5", None]),
        ("map(varchar, double)", {"a": math.inf}, {"a": "Infinity"}),
        ("map(bigint, varchar)", [(1, "x"), (2, None)], {"1": "x", "2": None}),
        ("map(boolean, bigint)", {True: 1}, {"true": 1}),
        # keys are Java's toString of the key's object value (server/protocol/JsonEncodingUtils.MapEncoder)
        ("map(array(integer), integer)", [([1], 2)], {"[1]": 2}),
        ("map(array(array(varchar)), integer)", [([["a", None], []], 2)], {"[[a, null], []]": 2}),
        ("map(row(x integer, y boolean), integer)", [({"x": 1, "y": True}, 2)], {"[1, true]": 2}),
        (
            "map(double, integer)",
            [(1e7, 1), (0.001, 2), (-2.5e-4, 3), (1.5, 4)],
            {"1.0E7": 1, "0.001": 2, "-2.5E-4": 3, "1.5": 4},
        ),
        ("row(a bigint, b decimal(3,1))", {"a": 1, "b": Decimal("2.5")}, [1, "2.5"]),
        ("array(row(name varchar, value double))", [{"name": "n", "value": math.nan}], [["n", "NaN"]]),
    ],
)
def test_value_encoding(trino_type, value, wire):
    encode = encoder(trino_type)
    assert encode(value) == wire
    assert encode(None) is None


@pytest.mark.parametrize(
    "trino_type, value",
    [
        ("double", 2.5),
        ("double", math.inf),
        ("decimal(10,2)", Decimal("-7.25")),
        ("varbinary", b"\x01\x02"),
        ("date", dt.date(1999, 12, 31)),
        ("timestamp(3)", dt.datetime(2024, 1, 2, 3, 4, 5, 123000)),
        ("timestamp(6)", dt.datetime(2024, 1, 2, 3, 4, 5, 123456)),
        ("timestamp(3) with time zone", dt.datetime(2024, 1, 2, 3, 4, 5, 123000, tzinfo=ZoneInfo("UTC"))),
        ("uuid", uuid.uuid4()),
        ("array(bigint)", [1, None, 3]),
        ("map(varchar, bigint)", {"a": 1}),
        ("interval day to second", dt.timedelta(days=3, seconds=7, microseconds=250000)),
        ("time(6)", dt.time(23, 59, 59, 999999)),
    ],
)
def test_the_trino_client_decodes_what_is_encoded(trino_type, value):
    assert decoded([("c", trino_type)], [[encoder(trino_type)(value)]]) == [[value]]


def test_encode_rows_of_a_duckdb_batch_match_the_trino_client():
    con = duckdb.connect()
    con.execute("SET TimeZone = 'UTC'")
    batch = (
        con.sql("""
        SELECT * FROM (VALUES
          (1::BIGINT, 1.5::DOUBLE, 1.50::DECIMAL(10,2), 'a', TRUE, DATE '2024-01-02',
           CAST(TIMESTAMP '2024-01-02 03:04:05.123' AS TIMESTAMP_MS), TIMESTAMP '2024-01-02 03:04:05.123456',
           TIMESTAMPTZ '2024-01-02 03:04:05.5+00', ['x', NULL], {'k': 2.5::DOUBLE}, 'ab'::BLOB, 0::DECIMAL(20,10),
           TIMESTAMP_NS '2024-01-02 03:04:05.123456789'),
          (NULL, 'NaN'::DOUBLE, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL),
          (-2, '-Infinity'::DOUBLE, -0.05, 'ü', FALSE, DATE '1970-01-01',
           CAST(TIMESTAMP '1970-01-01 00:00:00' AS TIMESTAMP_MS), TIMESTAMP '1970-01-01 00:00:00',
           TIMESTAMPTZ '1970-01-01 00:00:00+00', [], {'k': NULL}, ''::BLOB, 0.0000000001, NULL)
        ) AS v(i, d, dec, s, b, day, ts3, ts6, tz, arr, st, bin, small, ts9)""")
        .to_arrow_table()
        .to_batches()[0]
    )
    columns = [
        ("i", "bigint"),
        ("d", "double"),
        ("dec", "decimal(10,2)"),
        ("s", "varchar"),
        ("b", "boolean"),
        ("day", "date"),
        ("ts3", "timestamp(3)"),
        ("ts6", "timestamp(6)"),
        ("tz", "timestamp(3) with time zone"),
        ("arr", "array(varchar)"),
        ("st", "row(k double)"),
        ("bin", "varbinary"),
        ("small", "decimal(20,10)"),
        ("ts9", "timestamp(9)"),
    ]
    rows = encode_rows(columns, batch)
    assert rows[0] == [
        1,
        1.5,
        "1.50",
        "a",
        True,
        "2024-01-02",
        "2024-01-02 03:04:05.123",
        "2024-01-02 03:04:05.123456",
        "2024-01-02 03:04:05.500 UTC",
        ["x", None],
        [2.5],
        "YWI=",
        "0.0000000000",
        "2024-01-02 03:04:05.123456789",
    ]
    assert rows[1] == [None, "NaN"] + [None] * 12
    assert rows[2][:9] == [
        -2,
        "-Infinity",
        "-0.05",
        "ü",
        False,
        "1970-01-01",
        "1970-01-01 00:00:00.000",
        "1970-01-01 00:00:00.000000",
        "1970-01-01 00:00:00.000 UTC",
    ]
    assert rows[2][12] == "0.0000000001"
    client = decoded(columns[:-1], [row[:-1] for row in rows])
    assert client[0][:9] == [
        1,
        1.5,
        Decimal("1.50"),
        "a",
        True,
        dt.date(2024, 1, 2),
        dt.datetime(2024, 1, 2, 3, 4, 5, 123000),
        dt.datetime(2024, 1, 2, 3, 4, 5, 123456),
        dt.datetime(2024, 1, 2, 3, 4, 5, 500000, tzinfo=ZoneInfo("UTC")),
    ]
    assert math.isnan(client[1][1]) and client[2][1] == -math.inf
    assert json.dumps(rows, allow_nan=False)


def test_temporal_columns_get_exactly_p_fraction_digits():
    con = duckdb.connect()
    con.execute("SET TimeZone = 'UTC'")
    batch = (
        con.sql("""SELECT TIMESTAMP '2024-01-02 03:04:05.12' AS t, TIMESTAMPTZ '2024-01-02 03:04:05.25+00' AS z,
                              TIME '01:02:03.5' AS c, CAST(TIMESTAMP '2024-01-02 03:04:05' AS TIMESTAMP_S) AS s,
                              TIMESTAMP_NS '2024-01-02 03:04:05.123456789' AS n""")
        .to_arrow_table()
        .to_batches()[0]
    )
    for types, expected in [
        (
            ("timestamp(1)", "timestamp(1) with time zone", "time(1)", "timestamp(3)", "timestamp(6)"),
            [
                "2024-01-02 03:04:05.1",
                "2024-01-02 03:04:05.2 UTC",
                "01:02:03.5",
                "2024-01-02 03:04:05.000",
                "2024-01-02 03:04:05.123456",
            ],
        ),
        (
            ("timestamp(0)", "timestamp(6) with time zone", "time(3)", "timestamp(0)", "timestamp(9)"),
            [
                "2024-01-02 03:04:05",
                "2024-01-02 03:04:05.250000 UTC",
                "01:02:03.500",
                "2024-01-02 03:04:05",
                "2024-01-02 03:04:05.123456789",
            ],
        ),
    ]:
        assert encode_rows(list(zip("tzcsn", types)), batch) == [expected]


def test_encode_rows_checks_the_column_count():
    batch = pa.record_batch([pa.array([1])], names=["a"])
    assert encode_rows([("a", "bigint")], batch) == [[1]]
    with pytest.raises(ValueError):
        encode_rows([("a", "bigint"), ("b", "bigint")], batch)


@pytest.mark.parametrize("trino_type", list(ARROW_TYPES))
def test_the_engine_carries_each_lake_type_as_the_lake_stores_it(trino_type):
    assert arrow_type(parse_type(trino_type)) == ARROW_TYPES[trino_type]


def test_protocol_type_writes_interval_types_as_trino_does():
    # the real Trino 476's `type` of SELECT INTERVAL '1' DAY, ARRAY[INTERVAL '1' DAY],
    # MAP(ARRAY['a'], ARRAY[INTERVAL '1' MONTH]), CAST(ROW(INTERVAL '1' DAY) AS row(x interval day to second))
    assert protocol_type("interval day to second") == "INTERVAL DAY TO SECOND"
    assert protocol_type("array(interval day to second)") == "array(INTERVAL DAY TO SECOND)"
    assert protocol_type("map(varchar(1), interval year to month)") == "map(varchar(1), INTERVAL YEAR TO MONTH)"
    assert protocol_type("row(x interval day to second)") == "row(x INTERVAL DAY TO SECOND)"
    assert protocol_type("timestamp(3) with time zone") == "timestamp(3) with time zone"


def test_years_past_9999_are_written_with_a_sign_as_trino_does():
    """The real Trino 476 answers date_add('year', 10000, ...) with `+12025-07-01 ...` and
    date_add('year', -12000, ...) with `-9975-07-01 ...` (ISO 8601's expanded years)."""
    con = duckdb.connect()
    con.execute("SET TimeZone = 'UTC'")
    batch = (
        con.sql("""
        SELECT CAST(DATE '2025-07-01' + INTERVAL 10000 YEAR AS DATE),
               CAST(TIMESTAMP '2025-07-01 12:00:00.123' + INTERVAL 10000 YEAR AS TIMESTAMP_MS),
               TIMESTAMPTZ '2025-07-01 12:00:00.123+00' + INTERVAL 10000 YEAR,
               CAST(TIMESTAMP '2025-07-01 12:00:00.123' - INTERVAL 12000 YEAR AS TIMESTAMP_MS),
               DATE '9999-12-31',
               make_timestamp(-1099511627776000000),
               make_timestamp(1099511627776000000)::TIMESTAMPTZ,
               CAST(DATE '0001-01-01' - INTERVAL 10000 YEAR AS DATE)
    """)
        .to_arrow_table()
        .to_batches()[0]
    )
    columns = [
        ("a", "date"),
        ("b", "timestamp(3)"),
        ("c", "timestamp(3) with time zone"),
        ("d", "timestamp(3)"),
        ("e", "date"),
        ("f", "timestamp(6)"),
        ("g", "timestamp(3) with time zone"),
        ("h", "date"),
    ]
    assert encode_rows(columns, batch) == [
        [
            "+12025-07-01",
            "+12025-07-01 12:00:00.123",
            "+12025-07-01 12:00:00.123 UTC",
            "-9975-07-01 12:00:00.123",
            "9999-12-31",
            "-32873-11-12 23:23:44.000000",  # from_unixtime(-1099511627776) and (1099511627776), in Trino
            "+36812-02-20 00:36:16.000 UTC",
            "-9999-01-01",
        ]
    ]


def test_time_with_time_zone_is_written_as_trino_writes_it():
    """Values translated and computed by DuckDB ({utc_ps, offset_min} structs, dialect/zoned_times.py),
    encoded as the real Trino 476 answers this query (offsets at -14:00 and +14:00, the last picosecond of a
    day, a negative offset under an hour, NULL)."""
    from lakegate.dialect.translate import translate

    query = translate(
        "SELECT x FROM (VALUES TIME '23:59:59.999999999999 +14:00', TIME '00:00:00 -14:00', "
        "TIME '01:02:03.5 -00:35', NULL) t(x)",
        {},
    )
    assert query.columns == (("x", "time(12) with time zone"),)
    batch = duckdb.connect().sql(query.duckdb_sql).to_arrow_table().combine_chunks().to_batches()[0]
    assert arrow_type(parse_type("time(12) with time zone")) == batch.schema.field(0).type
    assert encode_rows(query.columns, batch) == [
        ["23:59:59.999999999999+14:00"],
        ["00:00:00.000000000000-14:00"],
        ["01:02:03.500000000000-00:35"],
        [None],
    ]


def test_ipaddress_is_written_as_trino_writes_it():
    """IPADDRESS values computed by DuckDB (16-byte BLOBs, dialect/ipaddresses.py), encoded as the real Trino
    476 answers this query: IPv4-mapped addresses dotted, the longest run of zero groups (the first of two equal
    ones) as ::, an IPv4-compatible address in hex, NULL."""
    from lakegate.dialect.translate import translate

    query = translate(
        "SELECT x FROM (VALUES IPADDRESS '::ffff:1.2.3.4', IPADDRESS '0:0:1:0:0:0:1:0', IPADDRESS '1:0:0:1:0:0:1:1', "
        "IPADDRESS '::1.2.3.4', IPADDRESS '::', IPADDRESS '1:2:3:4:5:6:7:8', NULL) t(x)",
        {},
    )
    assert query.columns == (("x", "ipaddress"),)
    batch = duckdb.connect().sql(query.duckdb_sql).to_arrow_table().combine_chunks().to_batches()[0]
    assert arrow_type(parse_type("ipaddress")) == batch.schema.field(0).type
    assert encode_rows(query.columns, batch) == [
        ["1.2.3.4"],
        ["0:0:1::1:0"],
        ["1::1:0:0:1:1"],
        ["::102:304"],
        ["::"],
        ["1:2:3:4:5:6:7:8"],
        [None],
    ]
