"""The read-only guard: only queries pass; writes, DuckDB statements, file and internals functions,
several statements, oversized or deeply nested texts, bad encodings are refused with a clear error
and its position. Runs through the real translate() as well, since sqlglot parses some DuckDB-only
syntax leniently as Trino."""

from __future__ import annotations

import pytest
import sqlglot

from lakegate.dialect import guard
from lakegate.dialect.errors import DialectError
from lakegate.dialect.statements import read
from lakegate.dialect.translate import translate

SCHEMA = {"odom": {"timestamp": "bigint", "x": "double", "batch_id": "varchar", "job_id": "varchar"}}


def refused(sql, **kwargs) -> DialectError:
    with pytest.raises(DialectError) as caught:
        translate(sql, SCHEMA, **kwargs)
    return caught.value


@pytest.mark.parametrize(
    "sql, kind",
    [
        ("SELECT 1", "query"),
        ("  -- comment\n/* block */ ((SELECT 1))", "query"),
        ("WITH a AS (SELECT 1) SELECT * FROM a", "query"),
        ("VALUES (1, 2)", "query"),
        ("TABLE odom", "query"),
        ("SHOW TABLES", "show"),
        ("show columns from odom", "show"),
        ("DESCRIBE odom", "describe"),
        ("DESC odom", "describe"),
        ("EXPLAIN SELECT 1", "explain"),
        ("EXPLAIN ANALYZE VERBOSE (TYPE DISTRIBUTED, FORMAT TEXT) SELECT 1", "explain"),
        ("EXPLAIN (SELECT 1)", "explain"),
        ("EXPLAIN INSERT INTO t VALUES 1", "other"),
        ("SET SESSION query_max_run_time = '1h'", "session"),
        ("RESET SESSION query_max_run_time", "session"),
        ("SET TIME ZONE 'UTC'", "session"),
        ("USE lakegate.main", "session"),
        ("PREPARE st FROM SELECT ?", "session"),
        ("EXECUTE st USING 1", "execute"),
        ("EXECUTE IMMEDIATE 'SELECT 1'", "execute"),
        ("DEALLOCATE PREPARE st", "session"),
        ("START TRANSACTION", "session"),
        ("COMMIT", "session"),
        ("ROLLBACK", "session"),
        ("CALL system.runtime.kill_query('q1')", "call"),
        ("INSERT INTO odom VALUES (1)", "other"),
        ("SET threads = 64", "other"),
        ("PRAGMA version", "other"),
        ("frobnicate everything", "other"),
    ],
)
def test_statement_kind(sql, kind):
    assert read(sql).kind == kind


def test_explained_query():
    assert guard.explained_query("EXPLAIN ANALYZE (TYPE DISTRIBUTED) SELECT x FROM odom") == (
        "SELECT x FROM odom",
        True,
    )
    assert guard.explained_query("explain\n  SELECT 1") == ("SELECT 1", False)


@pytest.mark.parametrize(
    "sql, name",
    [
        ("INSERT INTO odom SELECT * FROM odom", "INSERT"),
        ("UPDATE odom SET x = 1", "UPDATE"),
        ("DELETE FROM odom", "DELETE"),
        ("MERGE INTO odom USING odom s ON true WHEN MATCHED THEN DELETE", "MERGE"),
        ("CREATE TABLE t AS SELECT 1", "CREATE TABLE"),
        ("CREATE OR REPLACE VIEW v AS SELECT 1", "CREATE OR"),
        ("DROP TABLE odom", "DROP TABLE"),
        ("ALTER TABLE odom ADD COLUMN y DOUBLE", "ALTER TABLE"),
        ("COPY odom TO '/tmp/out.csv'", "COPY"),
        ("ATTACH '/tmp/other.duckdb' AS other", "ATTACH"),
        ("DETACH other", "DETACH"),
        ("INSTALL httpfs", "INSTALL"),
        ("LOAD httpfs", "LOAD"),
        ("SET threads = 64", "SET"),
        ("RESET threads", "RESET"),
        ("SET VARIABLE x = 1", "SET VARIABLE"),
        ("PRAGMA enable_profiling", "PRAGMA"),
        ("CALL system.runtime.kill_query('q1')", "CALL"),
        ("EXPORT DATABASE '/tmp/dump'", "EXPORT DATABASE"),
        ("IMPORT DATABASE '/tmp/dump'", "IMPORT DATABASE"),
        ("CHECKPOINT", "CHECKPOINT"),
        ("EXPLAIN DROP TABLE odom", "EXPLAIN DROP TABLE"),
        ("  /* hidden */ (COPY odom TO 'x')", "COPY"),
    ],
)
def test_writes_and_duckdb_statements_are_denied_by_name(sql, name):
    error = refused(sql)
    assert error.error_name == "PERMISSION_DENIED"
    assert f"{name} statements are not allowed" in error.message
    first_word = name.split()[1] if name.startswith("EXPLAIN") else name.split()[0]  # EXPLAIN: the explained statement
    assert (error.line, error.column) == (1, sql.upper().index(first_word) + 1)


def test_a_write_behind_a_with_is_denied_by_its_name():
    error = refused("WITH a AS (SELECT 1 AS x) INSERT INTO odom SELECT * FROM a")
    assert error.error_name == "PERMISSION_DENIED" and error.message.startswith("Access Denied: INSERT statements")


@pytest.mark.parametrize(
    "sql",
    [
        "SET SESSION query_max_run_time = '1h'",
        "RESET SESSION x",
        "USE lakegate.main",
        "PREPARE st FROM SELECT 1",
        "EXECUTE st",
        "EXECUTE IMMEDIATE 'SELECT 1'",
        "DEALLOCATE PREPARE st",
        "START TRANSACTION",
        "COMMIT",
        "ROLLBACK",
        "SET TIME ZONE 'UTC'",
    ],
)
def test_session_statements_are_left_to_the_server(sql):
    error = refused(sql)
    assert error.error_name == "NOT_SUPPORTED"
    assert "handled by the server" in error.message


@pytest.mark.parametrize(
    "sql, function, column",
    [
        ("SELECT * FROM read_csv('/etc/passwd')", "read_csv", 15),
        ("SELECT * FROM read_csv_auto('/etc/passwd')", "read_csv_auto", 15),
        ("SELECT * FROM read_json('x.json')", "read_json", 15),
        ("SELECT * FROM read_text('/etc/passwd')", "read_text", 15),
        ("SELECT * FROM read_blob('/etc/passwd')", "read_blob", 15),
        ("SELECT * FROM read_parquet('/tmp/x.parquet')", "read_parquet", 15),
        ("SELECT * FROM parquet_scan('/tmp/x.parquet')", "parquet_scan", 15),
        ("SELECT * FROM sniff_csv('/etc/passwd')", "sniff_csv", 15),
        ("SELECT * FROM duckdb_settings()", "duckdb_settings", 15),
        ("SELECT * FROM pragma_version()", "pragma_version", 15),
        ("SELECT * FROM query('SELECT 1')", "query", 15),
        ("SELECT * FROM sqlite_scan('x.db', 't')", "sqlite_scan", 15),
        ("SELECT * FROM iceberg_scan('s3://b/t')", "iceberg_scan", 15),
        ("SELECT * FROM odom, range(10)", "range", 21),
        ("SELECT * FROM odom CROSS JOIN LATERAL generate_series(1, 3)", "generate_series", 39),
    ],
)
def test_table_functions_other_than_unnest_are_denied(sql, function, column):
    error = refused(sql)
    assert error.error_name == "PERMISSION_DENIED"
    assert f"'{function}'" in error.message
    assert (error.line, error.column) == (1, column)


@pytest.mark.parametrize(
    "sql, function",
    [
        ("SELECT getenv('HOME')", "getenv"),
        ("SELECT current_setting('threads')", "current_setting"),
        ("SELECT x FROM odom WHERE x > (SELECT count(*) FROM (SELECT read_text('/etc/passwd')))", "read_text"),
        ("SELECT json_execute_serialized_sql('{}')", "json_execute_serialized_sql"),
        ("SELECT glob('*')", "glob"),
    ],
)
def test_file_and_internals_functions_are_denied_anywhere(sql, function):
    error = refused(sql)
    assert error.error_name == "PERMISSION_DENIED"
    assert f"function '{function}'" in error.message


def test_trino_table_function_syntax_is_denied():
    error = refused("SELECT * FROM TABLE(system.query(query => 'SELECT 1'))")
    assert error.error_name == "PERMISSION_DENIED" and "TABLE(...)" in error.message


def test_unnest_passes():
    guard.check(sqlglot.parse_one("SELECT n, i FROM UNNEST(ARRAY[7, 8]) WITH ORDINALITY AS t(n, i)", read="trino"))
    assert translate("SELECT n FROM UNNEST(ARRAY[7, 8]) AS t(n)", SCHEMA).columns == (("n", "integer"),)


def test_duckdb_syntax_that_sqlglot_reads_leniently_is_refused():
    # sqlglot parses a quoted file name after FROM as a table; DuckDB would read the file
    error = refused("SELECT * FROM 'data/file.csv'")
    assert error.error_name == "PERMISSION_DENIED" and "reading files" in error.message
    assert refused("SELECT * FROM 'file.csv'").error_name == "TABLE_NOT_FOUND"
    assert refused('SELECT * FROM "/etc/passwd"').error_name == "PERMISSION_DENIED"
    # DuckDB's FROM-first query is not Trino
    error = refused("FROM odom")
    assert error.error_name == "SYNTAX_ERROR" and (error.line, error.column) == (1, 1)
    assert refused("SELECT * INTO t2 FROM odom").error_name == "PERMISSION_DENIED"


def test_multiple_statements_are_denied_with_the_position_of_the_second():
    error = refused("SELECT 1;\n  DROP TABLE odom")
    assert error.error_name == "PERMISSION_DENIED" and "multiple statements" in error.message
    assert (error.line, error.column) == (2, 3)
    assert refused("SELECT 1; SELECT 2").error_name == "PERMISSION_DENIED"
    # a trailing semicolon and semicolons inside literals are one statement
    assert translate("SELECT 1;", SCHEMA).columns == (("_col0", "integer"),)
    assert translate("SELECT ';' AS s ;", SCHEMA).columns == (("s", "varchar(1)"),)
    guard.check_text("SELECT ';' AS s; -- a comment after the semicolon")


def test_deeply_nested_parentheses_are_refused_without_recursion_error():
    megabyte = "SELECT " + "(" * 499_990 + "1" + ")" * 499_990
    error = refused(megabyte)
    assert error.error_name == "SYNTAX_ERROR" and "statement is too large" in error.message
    assert (error.line, error.column) == (1, 8 + guard.MAX_NESTING)
    assert refused("SELECT " + "(" * 1_000_000).error_name == "QUERY_TEXT_TOO_LARGE"
    # brackets inside strings and comments do not count
    text = "SELECT '" + "(" * 100 + "' AS s -- " + "[" * 100
    assert translate(text, SCHEMA).columns == (("s", "varchar(100)"),)


def test_other_deep_nesting_is_a_clear_error_not_a_crash():
    error = refused("SELECT " + "NOT " * 5000 + "true")
    assert "nested too deeply" in error.message


def test_text_checks():
    error = refused(b"SELECT '\xff\xfe'")
    assert error.error_name == "SYNTAX_ERROR" and "not valid UTF-8" in error.message
    assert (error.line, error.column) == (1, 9)
    error = refused("SELECT 1,\n 'a\x00b'")
    assert "NUL" in error.message and (error.line, error.column) == (2, 4)
    assert refused("SELECT '\udc80'").error_name == "SYNTAX_ERROR"
    assert refused("SELECT 1 -- " + "x" * guard.MAX_TEXT_BYTES).error_name == "QUERY_TEXT_TOO_LARGE"
    assert guard.check_text(b"SELECT 'caf\xc3\xa9'") == "SELECT 'café'"


def test_check_on_parsed_trees():
    for sql in (
        "SELECT x FROM odom",
        "SELECT 1 UNION ALL SELECT 2",
        "VALUES 1",
        "(SELECT 1)",
        "SHOW TABLES",
        "DESCRIBE odom",
    ):
        guard.check(sqlglot.parse_one(sql, read="trino"))
    for sql in ("INSERT INTO t VALUES (1)", "SET x = 1", "CREATE TABLE t (a INT)", "USE a.b"):
        with pytest.raises(DialectError):
            guard.check(sqlglot.parse_one(sql, read="trino"))
