"""The Python functions the engine registers on its DuckDB connections (gateway/engine/udfs.py):
they answer through a real `lakegate serve` over real Parquet files and the official trino
client, under the engine's lock-down, and a failing one is a Trino-named error."""

from __future__ import annotations

import hashlib

import duckdb
import pytest
import trino
from duckdb.sqltypes import BLOB

from lakegate.dialect.errors import runtime_error
from lakegate.gateway.engine import udfs


def _query(server, sql: str) -> list:
    with trino.dbapi.connect(host="127.0.0.1", port=server.port, user="me", catalog="lake", schema="main") as conn:
        cursor = conn.cursor()
        cursor.execute(sql)
        return cursor.fetchall()


def test_hashes_of_a_parquet_column_through_the_server(lake_server):
    rows = _query(lake_server, "SELECT job_id, sha512(to_utf8(job_id)), xxhash64(X'') FROM metadata ORDER BY 1")
    assert len(rows) == 3
    for job_id, digest, empty in rows:
        assert digest == hashlib.sha512(job_id.encode()).digest()
        assert empty == bytes.fromhex("EF46DB3751D8E999")  # TestVarbinaryFunctions.testXxhash64


def test_hashes_in_a_system_table_query(lake_server):
    rows = _query(lake_server, "SELECT to_hex(murmur3(to_utf8(catalog_name))) FROM system.metadata.catalogs")
    assert len(rows) == 2 and all(len(value) == 32 for (value,) in rows)


def test_a_failing_function_is_a_trino_named_error():
    connection = duckdb.connect()
    connection.create_function("fails", udfs.trino_named("murmur3", lambda data: data[9]), [BLOB], BLOB)
    with pytest.raises(duckdb.Error) as raised:
        connection.execute("SELECT fails(X'01')").fetchall()
    connection.close()
    error = runtime_error(str(raised.value))
    assert (error.error_name, error.message) == ("GENERIC_INTERNAL_ERROR", "murmur3 failed: index out of range")
