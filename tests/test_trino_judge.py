"""The judge itself: the real Trino 476 runs, binds only 127.0.0.1, and reads Parquet files anywhere
on the machine through its hive catalog (the catalog the lake is registered in)."""

from __future__ import annotations

import uuid
from urllib.parse import urlsplit

import pyarrow as pa
import pyarrow.parquet as pq
import trino


def _cursor(url: str) -> trino.dbapi.Cursor:
    parts = urlsplit(url)
    return trino.dbapi.connect(host=parts.hostname, port=parts.port, user="lakegate-tests").cursor()


def test_trino_476_answers_with_its_own_types(trino_url):
    cur = _cursor(trino_url)
    cur.execute("SELECT node_version FROM system.runtime.nodes")
    assert cur.fetchall() == [["476"]]
    # Java's half-up rounding of 317.5 (DuckDB 2.0.1 gives 3.17): the judge settles such questions.
    cur.execute("SELECT round(DOUBLE '3.175', 2), typeof(round(DOUBLE '3.175', 2))")
    assert cur.fetchall() == [[3.18, "double"]]


def _listening(port: int) -> set[str]:
    """The local addresses (hex, as /proc/net shows them) of the sockets listening on `port`."""
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in open(table).read().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            address, hex_port = local.rsplit(":", 1)
            if state == "0A" and int(hex_port, 16) == port:
                found.add(address)
    return found


def test_trino_binds_loopback_only(trino_url):
    loopback = {"0100007F", "0000000000000000FFFF00000100007F"}  # 127.0.0.1, as IPv4 and IPv4-mapped IPv6
    listening = _listening(urlsplit(trino_url).port)
    assert listening and listening <= loopback, listening


def test_hive_catalog_reads_parquet_in_any_folder(trino_url, tmp_path):
    table_dir = tmp_path / "speeds"
    table_dir.mkdir()
    pq.write_table(pa.table({"t": [1, 2, 3], "v": [0.5, float("nan"), None]}), table_dir / "part.parquet")
    schema = f"judge_{uuid.uuid4().hex[:8]}"
    cur = _cursor(trino_url)
    cur.execute(f"CREATE SCHEMA hive.{schema}")
    cur.fetchall()
    try:
        cur.execute(
            f"CREATE TABLE hive.{schema}.speeds (t bigint, v double) "
            f"WITH (external_location = 'local://{table_dir}', format = 'PARQUET')"
        )
        cur.fetchall()
        cur.execute(f"SELECT count(*), count(v), sum(t), bool_or(is_nan(v)) FROM hive.{schema}.speeds")
        assert cur.fetchall() == [[3, 2, 6, True]]
    finally:
        cur.execute(f"DROP TABLE IF EXISTS hive.{schema}.speeds")
        cur.fetchall()
        cur.execute(f"DROP SCHEMA hive.{schema}")
        cur.fetchall()
