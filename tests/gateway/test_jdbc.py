"""The official Trino JDBC driver (io.trino:trino-jdbc:476) against a real `lakegate serve`, and the
same calls against the real Trino 476: DatabaseMetaData as DBeaver and DataGrip browse a catalog
(tests/gateway/jdbc/JdbcProbe.java, compiled with javac at test time) and PreparedStatements.

Trino is the judge of every shape: for each call the result columns (label, type name,
java.sql.Types) must be the ones Trino answers, and where the rows can be the same they must be:
the columns of a lake table are compared with those of a Trino memory table created with the very
same column types, and every type lakegate lists in getTypeInfo must be listed alike by Trino.
"""

from __future__ import annotations

import json
import os
import subprocess
from collections.abc import Callable
from pathlib import Path

import duckdb
import pytest
import trino

from lakegate.lake import paths
from lakegate.lake.catalog import Catalog

PROBE = Path(__file__).parent / "jdbc" / "JdbcProbe.java"
#: A query whose answer needs no table, run as a PreparedStatement on both servers.
LITERAL_QUERY = ["SELECT ? + 1 AS answer, ?, CAST(? AS double) / 4", "41", "héllo", "3"]
#: Calls whose rows name no catalog or schema of either server: the rows must be equal.
SAME_ROWS = (
    "getTableTypes()",
    "getProcedures(catalog, schema, %)",
    "getUDTs(catalog, schema, %, null)",
    "getProcedureColumns(catalog, schema, %, %)",
    "getSuperTypes(catalog, schema, %)",
    "getSuperTables(catalog, schema, %)",
    "getAttributes(catalog, schema, %, %)",
    "getPseudoColumns(catalog, schema, table, %)",
    "getPrimaryKeys(catalog, schema, table)",
    "getImportedKeys(catalog, schema, table)",
    "getIndexInfo(catalog, schema, table)",
    f"PreparedStatement {LITERAL_QUERY[0]}",
)


@pytest.fixture(scope="module")
def jdbc_probe(jdk, trino_jar, tmp_path_factory) -> Callable[..., dict[str, dict]]:
    """`probe(url, catalog, schema, table, *queries)`: JdbcProbe's answers, call -> result."""
    driver = trino_jar("trino-jdbc")
    classes = tmp_path_factory.mktemp("jdbc-probe")
    subprocess.run(
        [str(jdk / "bin" / "javac"), "-cp", str(driver), "-d", str(classes), str(PROBE)],
        check=True,
        capture_output=True,
        timeout=120,
    )

    def probe(url: str, catalog: str, schema: str, table: str, *queries: list[str]) -> dict[str, dict]:
        args = [url, "tester", catalog, schema, table]
        for query in queries:
            args += ["--", *query]
        done = subprocess.run(
            [str(jdk / "bin" / "java"), "-cp", f"{driver}{os.pathsep}{classes}", "JdbcProbe", *args],
            capture_output=True,
            text=True,
            timeout=180,
        )
        assert done.returncode == 0, done.stderr[-3000:]
        return {line["call"]: line["result"] for line in map(json.loads, done.stdout.splitlines())}

    return probe


@pytest.fixture(scope="module")
def trino_twins(lake_server, all_types, trino_url):
    """A schema of the real Trino's memory catalog with tables `metadata` and `sample` whose columns
    have the names and types lakegate describes for `main.metadata` and the all-types `sample`."""
    schema = f"clients_jdbc_{os.getpid()}"
    judge = trino.dbapi.connect(host="127.0.0.1", port=int(trino_url.rsplit(":", 1)[1]), user="tester").cursor()
    lake = trino.dbapi.connect(host=lake_server.host, port=lake_server.port, user="tester", catalog="lake").cursor()

    def run(cursor, sql: str) -> list:
        cursor.execute(sql)
        return cursor.fetchall()

    run(judge, f"CREATE SCHEMA memory.{schema}")
    tables = {"metadata": "main.metadata", "sample": f'"{all_types[0]}".sample'}
    for name, source in tables.items():
        columns = ", ".join(f'"{column}" {trino_type}' for column, trino_type, *_ in run(lake, f"DESCRIBE {source}"))
        run(judge, f"CREATE TABLE memory.{schema}.{name} ({columns})")
    yield schema
    for name in tables:
        run(judge, f"DROP TABLE memory.{schema}.{name}")
    run(judge, f"DROP SCHEMA memory.{schema}")


def _same_shapes(lakegate: dict[str, dict], judge: dict[str, dict]) -> None:
    assert lakegate.keys() == judge.keys()
    for call, answer in judge.items():
        if "columns" in answer:
            assert lakegate[call].get("columns") == answer["columns"], (call, lakegate[call])
        else:
            assert lakegate[call] == answer, call


@pytest.mark.parametrize("branch_table", [("main", "metadata"), ("all-types", "sample")])
def test_database_metadata_answers_as_trino(
    branch_table, lake_server, server_lake, all_types, trino_url, trino_twins, jdbc_probe
):
    branch, table = branch_table
    branch = all_types[0] if branch == "all-types" else branch
    lakegate = jdbc_probe(f"jdbc:trino://127.0.0.1:{lake_server.port}", "lake", branch, table, LITERAL_QUERY)
    judge = jdbc_probe(f"jdbc:trino://{trino_url.split('://')[1]}", "memory", trino_twins, table, LITERAL_QUERY)

    assert lakegate["product"] == judge["product"] == {"name": "Trino", "version": "476"}
    _same_shapes(lakegate, judge)
    for call in SAME_ROWS:
        assert lakegate[call] == judge[call], call
    rows = {call: answer.get("rows") for call, answer in lakegate.items()}
    assert rows[f"PreparedStatement {LITERAL_QUERY[0]}"] == [[42, "héllo", 0.75]]

    # catalogs and schemas: the served catalog's branches, and the system catalog
    assert rows["getCatalogs()"] == [["lake"], ["system"]]
    catalog = Catalog(server_lake)
    lake_schemas = sorted([*catalog.branches(), "information_schema"])
    assert rows["getSchemas(catalog, null)"] == [[s, "lake"] for s in lake_schemas]
    assert rows["getSchemas(catalog, %)"] == rows["getSchemas(catalog, null)"]
    assert rows["getSchemas(catalog, schema)"] == [[branch, "lake"]]
    assert [r for r in rows["getSchemas()"] if r[1] == "lake"] == rows["getSchemas(catalog, null)"]
    assert {r[0] for r in rows["getSchemas()"] if r[1] == "system"} == {r[0] for r in judge["getSchemas()"]["rows"]} & {
        "information_schema",
        "jdbc",
        "metadata",
        "runtime",
    }

    # tables: every table of the branch, as Trino lists a table
    schema = catalog.schema(branch)
    names = sorted(schema)
    for call in (
        "getTables(catalog, schema, null, null)",
        "getTables(catalog, schema, %, null)",
        "getTables(catalog, schema, %, TABLE VIEW)",
    ):
        assert [r[2] for r in rows[call]] == names, call
        assert all(r[:2] == ["lake", branch] for r in rows[call])
    (listed,) = rows["getTables(catalog, schema, table, null)"]
    assert listed[2:] == judge["getTables(catalog, schema, table, null)"]["rows"][0][2:]

    # columns: each attribute as Trino derives it from the same column type
    columns = rows["getColumns(catalog, schema, table, null)"]
    assert [(r[3], r[5]) for r in columns] == list(schema[table].items())
    assert [r[:2] for r in columns] == [["lake", branch]] * len(columns)
    assert [r[2:] for r in columns] == [r[2:] for r in judge["getColumns(catalog, schema, table, null)"]["rows"]]
    assert rows["getColumns(catalog, schema, escaped table, %)"] == columns
    whole_schema = rows["getColumns(catalog, schema, %, %)"]
    assert [r for r in whole_schema if r[2] == table] == columns
    assert sorted({r[2] for r in whole_schema}) == names

    # types: each one lakegate lists is listed alike by Trino, and every column's type is listed
    judge_types = {tuple(r) for r in judge["getTypeInfo()"]["rows"]}
    assert [r for r in rows["getTypeInfo()"] if tuple(r) not in judge_types] == []
    listed_types = {r[0] for r in rows["getTypeInfo()"]}
    assert {r[5].split("(")[0] for r in columns} <= listed_types


def test_prepared_statement_over_the_lake(lake_server, server_lake, jdbc_probe):
    batch = "b1"
    expected = duckdb.sql(
        f"SELECT count(*) FROM read_parquet('{paths.table_glob(server_lake, 'main', 'metadata')}', "
        f"hive_partitioning = true) WHERE batch_id = '{batch}'"
    ).fetchall()[0][0]
    answers = jdbc_probe(
        f"jdbc:trino://127.0.0.1:{lake_server.port}/lake/main",
        "lake",
        "main",
        "metadata",
        ["SELECT count(*), min(batch_id) FROM metadata WHERE batch_id = ? AND test_suite_revision >= ?", batch, "0"],
        ["SELECT job_id FROM lake.main.metadata WHERE batch_id = ? ORDER BY job_id LIMIT 1", "no such batch"],
    )
    counted = answers[next(call for call in answers if "count(*)" in call)]
    assert counted["columns"] == [["_col0", "bigint", -5], ["_col1", "varchar", 12]]
    assert counted["rows"] == [[expected, batch]]
    empty = answers[next(call for call in answers if "LIMIT 1" in call)]
    assert empty == {"columns": [["job_id", "varchar", 12]], "rows": []}


def test_system_jdbc_tables_are_trinos(lake_server, trino_url):
    """Every table of system.jdbc that the driver reads, with Trino's columns and types."""
    sql = (
        "SELECT table_name, column_name, data_type FROM system.information_schema.columns "
        "WHERE table_schema = 'jdbc' ORDER BY table_name, ordinal_position"
    )
    answers = []
    for url in (lake_server.url, trino_url):
        host, port = url.split("://")[1].split(":")
        cursor = trino.dbapi.connect(host=host, port=int(port), user="tester").cursor()
        cursor.execute(sql)
        answers.append(cursor.fetchall())
    assert answers[0] == answers[1]
    assert {row[0] for row in answers[0]} >= {"catalogs", "schemas", "tables", "columns", "types", "procedures"}
