"""Real clients against a real `lakegate serve` on 127.0.0.1: the official `trino` DBAPI client,
SQLAlchemy's `trino://` dialect, pandas.read_sql, and aiotrino (a second, asyncio/aiohttp client).
Expected values come from the emitted rows or from DuckDB reading the lake's Parquet files directly."""

from __future__ import annotations

import asyncio
import datetime as dt
import threading
import time

import aiotrino
import duckdb
import pandas as pd
import pytest
import requests
import sqlalchemy
import trino
from sqlalchemy import MetaData, Table, create_engine, inspect, select, text
from sqlalchemy.sql import sqltypes
from trino.sqlalchemy import datatype
from trino.transaction import IsolationLevel

from lakegate.lake import paths


def connect(server, schema: str = "main", **kwargs) -> trino.dbapi.Connection:
    return trino.dbapi.connect(
        host=server.host, port=server.port, user="tester", catalog="lake", schema=schema, **kwargs
    )


def fetch(server, sql: str, params=None, **kwargs) -> list[list]:
    with connect(server, **kwargs) as connection:
        cursor = connection.cursor()
        cursor.execute(sql, params) if params is not None else cursor.execute(sql)
        return cursor.fetchall()


def parquet(lake, sql: str) -> list[tuple]:
    """`sql` run by DuckDB over the lake's Parquet files of branch main (`{table}` placeholders)."""
    tables = {
        name: f"read_parquet('{paths.table_glob(lake, 'main', name)}', hive_partitioning = true, "
        "hive_types = {'batch_id': VARCHAR})"
        for name in ("metadata", "odom_linear_velocity")
    }
    return duckdb.sql(sql.format(**tables)).fetchall()


# --- trino.dbapi ------------------------------------------------------------------------------------


def test_every_lake_column_type_round_trips(lake_server, all_types):
    branch, emitted = all_types
    with connect(lake_server, schema=branch) as connection:
        cursor = connection.cursor()
        cursor.execute(
            "SELECT flag, n, x, s, st, img, tags, metrics, timestamp, batch_id FROM sample ORDER BY timestamp"
        )
        rows = cursor.fetchall()
        description = [(d[0], d[1]) for d in cursor.description]
    assert description == [
        ("flag", "boolean"),
        ("n", "bigint"),
        ("x", "double"),
        ("s", "varchar"),
        ("st", "varchar"),
        ("img", "varchar"),
        ("tags", "array(varchar)"),
        (
            "metrics",
            "array(row(name varchar, description varchar, status varchar, type varchar, value varchar, extra varchar))",
        ),
        ("timestamp", "bigint"),
        ("batch_id", "varchar"),
    ]
    for row, source, timestamp in zip(rows, emitted, range(len(emitted))):
        flag, n, x, s, st, img, tags, metrics, ts, batch = row
        assert (flag, n, x, s, st, img, tags, ts, batch) == (
            source["flag"],
            source["n"],
            source["x"],
            source["s"],
            source["st"],
            source["img"],
            source["tags"],
            timestamp,
            "b1",
        )
        assert type(flag) is bool and type(n) is int and type(x) is float and type(tags) is list
        assert [tuple(m) for m in metrics] == [
            (m["name"], m.get("description"), m.get("status"), m["type"], m["value"], None) for m in source["metrics"]
        ]
    first_metric = rows[0][7][0]
    assert (first_metric.name, first_metric.value, first_metric.description) == ("m", "1.5", None)


def test_timestamps_and_arrays_of_the_metadata_table(lake_server, server_lake):
    rows = fetch(
        lake_server,
        "SELECT job_id, build_creation_timestamp, time, experience_tag_names, job_metrics_status "
        "FROM metadata ORDER BY job_id",
    )
    expected = parquet(
        server_lake,
        "SELECT job_id, build_creation_timestamp, time, experience_tag_names, "
        "job_metrics_status FROM {metadata} ORDER BY job_id",
    )
    assert [tuple(r) for r in rows] == expected and len(rows) == 3
    assert all(type(r[1]) is dt.datetime and r[1].tzinfo is None and type(r[3]) is list for r in rows)
    with connect(lake_server) as connection:
        cursor = connection.cursor()
        cursor.execute("SELECT build_creation_timestamp FROM metadata LIMIT 1")
        cursor.fetchall()
        name, type_code, _, _, precision, _, _ = cursor.description[0]
    assert (name, type_code, precision) == ("build_creation_timestamp", "timestamp(3)", 3)


def test_nanosecond_timestamps_reach_the_client_with_every_digit(lake_server):
    sql = (
        "SELECT TIMESTAMP '2020-05-10 12:34:56.123456789' AS t9, "
        "CAST(TIMESTAMP '1969-12-31 23:59:59.99999995' AS TIMESTAMP(7)) AS t7, "
        "TIMESTAMP '2020-05-10 23:59:59.999999999' + INTERVAL '1' HOUR AS later, "
        "TIMESTAMP '2020-05-10 12:34:56.000000002' > TIMESTAMP '2020-05-10 12:34:56.000000001' AS after"
    )
    with connect(lake_server, legacy_primitive_types=True) as connection:
        cursor = connection.cursor()
        cursor.execute(sql)
        rows = cursor.fetchall()
        types = [column[1] for column in cursor.description]
    assert rows == [
        ["2020-05-10 12:34:56.123456789", "1970-01-01 00:00:00.0000000", "2020-05-11 00:59:59.999999999", True]
    ]
    assert types == ["timestamp(9)", "timestamp(7)", "timestamp(9)", "boolean"]


def test_parameters(lake_server, all_types, server_lake):
    branch, _ = all_types
    assert fetch(
        lake_server,
        "SELECT count(*) FROM sample WHERE flag = ? AND n > ? AND x < ? AND s = ?",
        (True, -5, 2.0, "héllo, wörld"),
        schema=branch,
    ) == [[1]]
    moment = parquet(server_lake, "SELECT min(build_creation_timestamp) FROM {metadata}")[0][0]
    assert fetch(
        lake_server,
        "SELECT count(*) FROM metadata WHERE build_creation_timestamp <= ? AND batch_id IN (?, ?)",
        (moment, "b1", "b2"),
    ) == [[3]]
    legacy = fetch(
        lake_server,
        "SELECT count(*) FROM sample WHERE contains(tags, ?)",
        ("a",),
        schema=branch,
        legacy_prepared_statements=True,
    )  # PREPARE / EXECUTE ... USING / DEALLOCATE
    assert legacy == [[1]]


def test_errors_are_programming_errors_with_their_position(lake_server):
    with pytest.raises(trino.dbapi.ProgrammingError) as caught:
        fetch(lake_server, "SELECT job_id,\n       nope\nFROM metadata")
    error = caught.value
    assert (error.error_name, error.error_location) == ("COLUMN_NOT_FOUND", (2, 8))
    assert "nope" in error.message and error.query_id
    with pytest.raises(trino.dbapi.ProgrammingError) as caught:
        fetch(lake_server, "SELECT count(*) FROM metadata WHERE nope = ?", (1,))
    assert caught.value.error_location == (1, 37)
    with pytest.raises(trino.dbapi.ProgrammingError) as caught:
        fetch(lake_server, "DROP TABLE metadata")
    assert caught.value.error_name == "PERMISSION_DENIED"


def test_session_properties_use_and_describe(lake_server):
    narrowed = fetch(
        lake_server, "SELECT count(*), count(DISTINCT batch_id) FROM metadata", session_properties={"batch_id": "b2"}
    )
    assert narrowed == [[1, 1]]
    with connect(lake_server) as connection:
        cursor = connection.cursor()
        cursor.execute('USE "feature/all-types"')
        cursor.fetchall()
        cursor.execute("SELECT count(*) FROM sample")  # the client now sends the new schema
        assert cursor.fetchall() == [[2]]
        described = cursor.describe("SELECT flag AS f, n, x + 1 FROM sample")
        assert [(d.name, d.type, d.type_size, d.aliased) for d in described] == [
            ("f", "boolean", 1, True),
            ("n", "bigint", 8, False),
            ("_col2", "double", 8, False),
        ]
        cursor.execute("SET SESSION job_id = 'j1'")
        cursor.fetchall()
        cursor.execute("SELECT count(*) FROM sample")
        assert cursor.fetchall() == [[2]]
        cursor.execute("SET SESSION job_id = 'elsewhere'")
        cursor.fetchall()
        cursor.execute("SELECT count(*) FROM sample")
        assert cursor.fetchall() == [[0]]


def test_transactions(lake_server):
    with connect(lake_server, isolation_level=IsolationLevel.READ_COMMITTED) as connection:
        cursor = connection.cursor()
        cursor.execute("SELECT count(*) FROM metadata")
        assert cursor.fetchall() == [[3]]
        connection.commit()


def test_cancel_stops_a_long_query_and_the_server_stays_healthy(start_server, endless):
    server = start_server("--max-concurrent-queries", "1")  # the only worker must come free
    connection = connect(server)
    cursor = connection.cursor()
    outcome: list[BaseException | list] = []

    def run() -> None:
        try:
            cursor.execute(endless)
            outcome.append(cursor.fetchall())
        except BaseException as error:  # noqa: BLE001 - the outcome is asserted below
            outcome.append(error)

    worker = threading.Thread(target=run)
    worker.start()
    deadline = time.monotonic() + 60
    state = None
    while state != "RUNNING" and time.monotonic() < deadline:
        time.sleep(0.1)
        if cursor.query_id:
            state = requests.get(f"{server.url}/v1/query/{cursor.query_id}", timeout=30).json()["state"]
    assert state == "RUNNING"
    time.sleep(0.5)  # DuckDB is deep in the cross join
    cursor.cancel()
    worker.join(60)
    assert not worker.is_alive()
    assert isinstance(outcome[0], trino.exceptions.TrinoUserError)
    info = requests.get(f"{server.url}/v1/query/{cursor.query_id}", timeout=30).json()
    assert info["state"] == "FAILED" and info["error"]["errorName"] == "USER_CANCELED"
    # the single worker is free again: DuckDB stopped (the cross join would run for hours)
    assert fetch(server, "SELECT count(*) FROM metadata", request_timeout=60) == [[3]]
    connection.close()


# --- SQLAlchemy and pandas --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def engine(lake_server):
    engine = create_engine(f"trino://tester@{lake_server.host}:{lake_server.port}/lake/main")
    yield engine
    engine.dispose()


def test_sqlalchemy_inspects_schemas_tables_and_columns(engine, all_types):
    branch, _ = all_types
    inspector = inspect(engine)
    assert set(inspector.get_schema_names()) == {"main", branch, "information_schema"}
    assert sorted(inspector.get_table_names(schema=branch)) == [
        *("container_performance", "events", "metadata", "sample", "test_length_seconds")
    ]
    assert {"metadata", "events", "odom_linear_velocity"} <= set(inspector.get_table_names())
    assert inspector.has_table("sample", schema=branch) and not inspector.has_table("nope", schema=branch)
    columns = {c["name"]: c["type"] for c in inspector.get_columns("sample", schema=branch)}
    assert isinstance(columns["flag"], sqltypes.BOOLEAN)
    assert isinstance(columns["n"], sqltypes.BIGINT)
    assert isinstance(columns["x"], datatype.DOUBLE)
    assert isinstance(columns["s"], sqltypes.VARCHAR)
    assert isinstance(columns["tags"], sqltypes.ARRAY) and isinstance(columns["tags"].item_type, sqltypes.VARCHAR)
    assert isinstance(columns["metrics"], sqltypes.ARRAY) and isinstance(columns["metrics"].item_type, datatype.ROW)
    assert [name for name, _ in columns["metrics"].item_type.attr_types] == [
        "name",
        "description",
        "status",
        "type",
        "value",
        "extra",
    ]
    timestamp = {c["name"]: c["type"] for c in inspector.get_columns("metadata")}["build_creation_timestamp"]
    assert isinstance(timestamp, datatype.TIMESTAMP) and timestamp.precision == 3
    assert inspector.get_table_comment("metadata") == {"text": None}
    assert inspector.get_view_names() == [] and inspector.get_indexes("metadata") == []


def test_sqlalchemy_text_binds_and_reflected_tables(engine, server_lake, all_types):
    branch, _ = all_types
    with engine.connect() as connection:
        count = connection.execute(
            text("SELECT count(*) FROM odom_linear_velocity WHERE batch_id = :batch AND x > :x"),
            {"batch": "b1", "x": 0.5},
        ).scalar()
        assert (
            count
            == parquet(server_lake, "SELECT count(*) FROM {odom_linear_velocity} WHERE batch_id = 'b1' AND x > 0.5")[0][
                0
            ]
        )
        assert connection.execute(text("SELECT version()")).scalar() == engine.dialect.server_version_info[0]
        sample = Table("sample", MetaData(), autoload_with=connection, schema=branch)
        rows = connection.execute(select(sample.c.n, sample.c.tags).where(sample.c.flag == True)).all()  # noqa: E712
        assert [tuple(r) for r in rows] == [(2**62, ["a", "b"])]
        with pytest.raises(sqlalchemy.exc.ProgrammingError):
            connection.execute(text("SELECT nope FROM metadata"))


def test_pandas_reads_a_topic_joined_with_metadata(engine, server_lake):
    sql = (
        "SELECT m.experience_name, count(*) AS samples, avg(o.x) AS mean_x "
        "FROM odom_linear_velocity o JOIN metadata m ON o.job_id = m.job_id AND o.batch_id = m.batch_id "
        "GROUP BY m.experience_name ORDER BY m.experience_name"
    )
    frame = pd.read_sql(sql, engine)
    assert list(frame.columns) == ["experience_name", "samples", "mean_x"]
    assert str(frame["samples"].dtype) == "int64" and str(frame["mean_x"].dtype) == "float64"
    expected = parquet(
        server_lake,
        sql.replace("odom_linear_velocity o", "{odom_linear_velocity} o").replace("metadata m", "{metadata} m"),
    )
    assert len(expected) == 3
    for (name, samples, mean_x), row in zip(expected, frame.itertuples(index=False)):
        assert (row.experience_name, row.samples) == (name, samples)
        assert row.mean_x == pytest.approx(mean_x, rel=1e-12)


# --- aiotrino ---------------------------------------------------------------------------------------


def test_aiotrino_runs_a_query_and_reports_an_error(lake_server, server_lake):
    async def scenario() -> tuple[list, list, BaseException]:
        connection = aiotrino.dbapi.connect(
            host=lake_server.host, port=lake_server.port, user="tester", catalog="lake", schema="main"
        )
        try:
            cursor = await connection.cursor()
            await cursor.execute(
                "SELECT job_id, build_creation_timestamp, experience_tag_names FROM metadata ORDER BY job_id"
            )
            rows = await cursor.fetchall()
            description = [(d.name, d.type_code) for d in await cursor.get_description()]
            try:
                await cursor.execute("SELECT job_id FROM metadata WHERE nope")
                await cursor.fetchall()
            except aiotrino.exceptions.TrinoUserError as error:
                return rows, description, error
            raise AssertionError("no error")
        finally:
            await connection.close()

    rows, description, error = asyncio.run(scenario())
    expected = parquet(
        server_lake, "SELECT job_id, build_creation_timestamp, experience_tag_names FROM {metadata} ORDER BY job_id"
    )
    assert [tuple(r) for r in rows] == expected
    assert description == [
        ("job_id", "varchar"),
        ("build_creation_timestamp", "timestamp(3)"),
        ("experience_tag_names", "array(varchar)"),
    ]
    assert (error.error_name, error.error_location) == ("COLUMN_NOT_FOUND", (1, 35))
