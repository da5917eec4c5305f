"""Scalar functions through the real server and the official trino client: varbinary values
arrive as bytes (the protocol sends them in base64), a bytes parameter binds as a varbinary
literal, and the scalar functions answer as in the conformance cases."""

from __future__ import annotations

import trino


def _query(server, sql: str, params: list | None = None) -> tuple[list, list[str]]:
    with trino.dbapi.connect(host="127.0.0.1", port=server.port, user="me", catalog="lake", schema="main") as conn:
        cursor = conn.cursor()
        cursor.execute(sql, params)
        rows = cursor.fetchall()
        return rows, [column[1] for column in cursor.description]


def test_varbinary_reaches_the_trino_client_as_bytes(lake_server):
    rows, types = _query(
        lake_server,
        "SELECT X'58F7', md5(to_utf8('hashme')), to_hex(sha256(to_utf8(''))), CAST(NULL AS VARBINARY), X''",
    )
    assert rows == [
        [
            bytes.fromhex("58F7"),
            bytes.fromhex("533F6357E0210E67D91F651BC49E1278"),  # TestVarbinaryFunctions.testMd5
            "E3B0C44298FC1C149AFBF4C8996FB92427AE41E4649B934CA495991B7852B855",
            None,
            b"",
        ]
    ]
    assert types == ["varbinary", "varbinary", "varchar", "varbinary", "varbinary"]


def test_a_bytes_parameter_is_a_varbinary(lake_server):
    rows, types = _query(lake_server, "SELECT length(?), to_hex(?)", [b"\x00\xffab", b"\x01"])
    assert rows == [[4, "01"]] and types == ["bigint", "varchar"]


def test_scalar_functions_through_the_server(lake_server):
    rows, _ = _query(
        lake_server,
        "SELECT url_extract_host('https://trino.io/docs/current/index.html'), U&'Hello winter \\2603 !', "
        "bitwise_left_shift(1, 2), human_readable_seconds(96), regexp_position('banana', 'n', 4)",
    )
    assert rows == [["trino.io", "Hello winter ☃ !", 4, "1 minute, 36 seconds", 5]]


def test_ipaddress_reaches_the_trino_client_as_trino_writes_it(lake_server):
    """IPADDRESS values (16 bytes in DuckDB, dialect/ipaddresses.py) are sent as Trino's text of them, which the
    trino client passes on as text; nested ones and map keys too (the real Trino 476's answers)."""
    rows, types = _query(
        lake_server,
        "SELECT IPADDRESS '10.0.0.1', IPADDRESS '2001:0db8:0:0:0:ff00:0042:8329', CAST(IPADDRESS '::1.2.3.4' AS "
        "varchar), ARRAY[IPADDRESS '::ffff:1.2.3.4', NULL], MAP(ARRAY[IPADDRESS '0:0:1:0:0:0:1:0'], ARRAY[1])",
    )
    assert rows == [
        [
            "10.0.0.1",
            "2001:db8::ff00:42:8329",
            "::102:304",
            ["1.2.3.4", None],
            {"0:0:1::1:0": 1},
        ]
    ]
    assert types == ["ipaddress", "ipaddress", "varchar", "array(ipaddress)", "map(ipaddress, integer)"]
