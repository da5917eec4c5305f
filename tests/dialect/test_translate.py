"""The translator's entry point: the Translation it returns (DuckDB SQL, Trino SQL, Trino columns),
the cache, rejections with Trino's error names and positions in the original text, the rows of the
issue's table, and the product guide's example queries run for real on DuckDB over Parquet."""

from __future__ import annotations

from decimal import Decimal

import duckdb
import pytest

from lakegate.dialect import translate as translate_module
from lakegate.dialect.errors import DialectError, runtime_error
from lakegate.dialect.translate import Translation, translate

#: Topic tables of the product guide's examples, as the lake would describe them.
GUIDE_SCHEMA = {
    "odom_linear_velocity": {"timestamp": "bigint", "x": "double", "y": "double", "z": "double", "job_id": "varchar"},
    "time_to_goal": {"timestamp": "bigint", "time_s": "double", "job_id": "varchar"},
    "covariance_accuracy": {"timestamp": "bigint", "within_1_sigma": "bigint", "job_id": "varchar"},
    "pose_difference": {"timestamp": "bigint", "position_diff_m": "double", "job_id": "varchar"},
    "goal_status": {"timestamp": "bigint", "state": "varchar", "job_id": "varchar"},
    "metadata": {
        "job_id": "varchar",
        "experience_name": "varchar",
        "experience_tag_names": "array(varchar)",
        "job_conflated_status": "varchar",
    },
}


@pytest.fixture(scope="module")
def guide(tmp_path_factory):
    """A DuckDB connection with the guide's tables as views over real Parquet files."""
    root = tmp_path_factory.mktemp("guide")
    con = duckdb.connect()
    con.execute("SET TimeZone = 'UTC'")
    data = {
        "odom_linear_velocity": "SELECT * FROM (VALUES (0::BIGINT, 3.0::DOUBLE, 4.0::DOUBLE, 0.0::DOUBLE, 'j1'), "
        "(2000000000, 6.0, 8.0, 0.0, 'j1')) v(timestamp, x, y, z, job_id)",
        "time_to_goal": "SELECT * FROM (VALUES (1::BIGINT, 10.5::DOUBLE, 'j1'), (2, 20.25, 'j1')) "
        "v(timestamp, time_s, job_id)",
        "covariance_accuracy": "SELECT * FROM (VALUES (1::BIGINT, 1::BIGINT, 'j1'), (2, 1, 'j1'), (3, 0, 'j1')) "
        "v(timestamp, within_1_sigma, job_id)",
        "pose_difference": "SELECT * FROM (VALUES (1::BIGINT, 0.5::DOUBLE, 'j1'), (2, 1.25, 'j2'), (3, 0.75, 'j3')) "
        "v(timestamp, position_diff_m, job_id)",
        "goal_status": "SELECT * FROM (VALUES (1::BIGINT, 'DRIVING', 'j1')) v(timestamp, state, job_id)",
        "metadata": "SELECT * FROM (VALUES ('j1', 'Parking', ['my_prefix_a', 'my_tag'], 'PASSED'), "
        "('j2', 'Highway', ['my_tag', 'my_prefix_a'], 'PASSED'), ('j3', 'Parking', ['my_prefix_b'], 'BLOCKER')) "
        "v(job_id, experience_name, experience_tag_names, job_conflated_status)",
    }
    for table, select in data.items():
        path = root / f"{table}.parquet"
        con.execute(f"COPY ({select}) TO '{path}' (FORMAT parquet)")
        con.execute(f"CREATE VIEW \"{table}\" AS SELECT * FROM read_parquet('{path}')")
    yield con
    con.close()


def run(con, sql: str, params=()):
    translation = translate(sql, GUIDE_SCHEMA, params=params)
    return translation.columns, con.execute(translation.duckdb_sql).fetchall()


# --- the Translation -------------------------------------------------------------------------------
def test_translation_carries_duckdb_sql_trino_sql_and_trino_columns():
    translation = translate('SELECT 1, 1.5 AS "x", \'abc\' AS s, x AS "X" FROM odom_linear_velocity;', GUIDE_SCHEMA)
    assert isinstance(translation, Translation)
    assert translation.columns == (("_col0", "integer"), ("x", "decimal(2,1)"), ("s", "varchar(3)"), ("X", "double"))
    assert translation.trino_sql.startswith("SELECT 1, 1.5 AS")
    duckdb.connect().execute(f"CREATE TABLE odom_linear_velocity (x DOUBLE); {translation.duckdb_sql}")


def test_select_star_expands_in_schema_order():
    columns = translate("SELECT * FROM time_to_goal", GUIDE_SCHEMA).columns
    assert columns == (("timestamp", "bigint"), ("time_s", "double"), ("job_id", "varchar"))


def test_cached_translation_is_reused_and_keyed_by_schema_and_params():
    sql = "SELECT count(*) FROM time_to_goal HAVING count(*) < ?"
    first = translate(sql, GUIDE_SCHEMA, params=(3,), schema_version="v1")
    assert translate(sql, GUIDE_SCHEMA, params=(3,), schema_version="v1") is first
    assert translate(sql, GUIDE_SCHEMA, params=(4,), schema_version="v1") is not first
    changed = {**GUIDE_SCHEMA, "time_to_goal": {"time_s": "bigint"}}
    assert translate(sql, changed, params=(3,)) is not translate(sql, GUIDE_SCHEMA, params=(3,))
    translate_module.clear_cache()
    assert translate(sql, GUIDE_SCHEMA, params=(3,), schema_version="v1") is not first


# --- rejections with positions ----------------------------------------------------------------------
@pytest.mark.parametrize(
    "sql, name, line, column, words",
    [
        ("SELECT x,\n         shuffle(x) FROM odom_linear_velocity", "NOT_SUPPORTED", 2, 10, "function 'shuffle'"),
        ("SELECT frobnicate(x) FROM odom_linear_velocity", "FUNCTION_NOT_FOUND", 1, 8, "'frobnicate'"),
        ("SELECT x FROM nowhere", "TABLE_NOT_FOUND", 1, 15, "'nowhere'"),
        ('SELECT x,\n  "Missing Col" FROM odom_linear_velocity', "COLUMN_NOT_FOUND", 2, 3, "'Missing Col'"),
        ("SELECT job_id FROM time_to_goal t JOIN metadata m ON t.job_id = m.job_id", "AMBIGUOUS_NAME", 1, 8, "job_id"),
        ("SELECT 'a' = 1", "TYPE_MISMATCH", 1, 8, "varchar(1) = integer"),
        ("SELECT x FROM odom_linear_velocity WHERE", "SYNTAX_ERROR", 1, 41, "mismatched input '<EOF>'"),
        ("SELECT 1; SELECT 2", ("SYNTAX_ERROR", "PERMISSION_DENIED"), 1, 11, "statement"),
        ("SELECT 1::integer", "SYNTAX_ERROR", 1, 9, "'::'"),
        ("SELECT regexp_like(job_id, '(?=a)') FROM time_to_goal", "NOT_SUPPORTED", 1, 8, "lookaround"),
        ("SELECT job_id, count(*) FROM time_to_goal", "EXPRESSION_NOT_AGGREGATE", 1, 8, "job_id"),
        ("SELECT time_s FROM time_to_goal HAVING count(*) < ?", "INVALID_PARAMETER_USAGE", None, None, "parameters"),
    ],
)
def test_rejections_name_the_construct_and_its_position(sql, name, line, column, words):
    with pytest.raises(DialectError) as caught:
        translate(sql, GUIDE_SCHEMA)
    error = caught.value
    assert error.error_name in ((name,) if isinstance(name, str) else name)
    if line is not None:
        assert (error.line, error.column) == (line, column), str(error)
    assert words in str(error)


def test_position_of_a_function_in_a_multiline_query_with_unicode():
    sql = "SELECT 'σ',\n  \"größe\" AS ü,\n\tshuffle(x)\nFROM odom_linear_velocity"
    with pytest.raises(DialectError) as caught:
        translate(sql, {"odom_linear_velocity": {"x": "double", "größe": "double"}})
    assert (caught.value.line, caught.value.column) == (3, 2)
    assert str(caught.value).endswith("(line 3, column 2)")


def test_runtime_errors_map_to_trino_names():
    assert runtime_error("Invalid Input Error: DIVISION_BY_ZERO: Division by zero").error_name == "DIVISION_BY_ZERO"
    assert runtime_error("Invalid Input Error: DIVISION_BY_ZERO: Division by zero").message == "Division by zero"
    assert (
        runtime_error("Conversion Error: Could not convert string 'x' to INT32").error_name == "INVALID_CAST_ARGUMENT"
    )
    assert runtime_error("Out of Range Error: Overflow in addition of INT32").error_name == "NUMERIC_VALUE_OUT_OF_RANGE"
    decimal = runtime_error("Out of Range Error: Overflow in subtract of DECIMAL(38) (-99 - 1);")
    assert (decimal.error_name, decimal.message) == ("NUMERIC_VALUE_OUT_OF_RANGE", "Decimal overflow")
    assert "Overflow in addition of INT32" in runtime_error("Overflow in addition of INT32 (1 + 2)!").message


# --- the issue's table -------------------------------------------------------------------------------
def test_issue_table_rows_answer_as_trino(guide):
    con = duckdb.connect()
    con.execute("CREATE TABLE t AS SELECT 5::BIGINT AS a, 2::BIGINT AS b")
    schema = {"t": {"a": "bigint", "b": "bigint"}}

    def one(sql):
        translation = translate(sql, schema)
        cursor = con.execute(translation.duckdb_sql)
        return translation.columns[0][1], cursor.fetchall()[0][0], str(cursor.description[0][1])

    assert one("SELECT a / b FROM t") == ("bigint", 2, "BIGINT")
    assert one("SELECT 5 / 2") == ("integer", 2, "INTEGER")
    assert one("SELECT sum(a) FROM t") == ("bigint", 5, "BIGINT")
    assert one("SELECT format('%.2f', 3.14159)") == ("varchar", "3.14", "VARCHAR")
    assert one("SELECT try(1/0)") == ("integer", None, "INTEGER")
    assert one("SELECT reduce(ARRAY[1, 2], 0, (s, x) -> s + x, s -> s * 10)") == ("integer", 30, "INTEGER")
    assert one("SELECT typeof(1E9)") == ("varchar", "double", "VARCHAR")
    with pytest.raises(duckdb.Error) as caught:
        con.execute(translate("SELECT ARRAY[1,2][5]", schema).duckdb_sql).fetchall()
    assert runtime_error(str(caught.value)).error_name == "INVALID_FUNCTION_ARGUMENT"


# --- the product guide's examples, unchanged ------------------------------------------------------------
def test_guide_speed_line(guide):
    columns, rows = run(
        guide,
        "SELECT 'Speed', timestamp / 1E9 AS \"Time (s)\", SQRT(POWER(x, 2) + POWER(y, 2)) "
        'AS "Speed (m/s)" FROM odom_linear_velocity;',
    )
    assert columns == (("_col0", "varchar(5)"), ("Time (s)", "double"), ("Speed (m/s)", "double"))
    assert sorted(rows) == [("Speed", 0.0, 5.0), ("Speed", 2.0, 10.0)]


def test_guide_scalar_with_subquery(guide):
    columns, rows = run(
        guide,
        "SELECT CASE WHEN (SELECT COUNT(*) FROM time_to_goal) != 3 THEN 75.0 ELSE sum(time_s) END FROM time_to_goal;",
    )
    assert columns == (("_col0", "double"),) and rows == [(75.0,)]


@pytest.mark.parametrize("threshold, returned", [(3, 1), (2, 0)])
def test_guide_status_query_with_parameter(guide, threshold, returned):
    columns, rows = run(guide, "SELECT '1' FROM time_to_goal HAVING COUNT(*) < ?", params=(threshold,))
    assert columns == (("_col0", "varchar(1)"),) and len(rows) == returned


def test_guide_batch_bar_with_join(guide):
    columns, rows = run(
        guide,
        "SELECT 'Maximum', m.experience_name as \"Experience Name\", MAX(position_diff_m) as "
        '"Maximum Localization Error (m)" FROM pose_difference pd JOIN metadata m on '
        "pd.job_id = m.job_id GROUP BY m.experience_name ORDER BY m.experience_name;",
    )
    assert [c[0] for c in columns] == ["_col0", "Experience Name", "Maximum Localization Error (m)"]
    assert rows == [("Maximum", "Highway", 1.25), ("Maximum", "Parking", 0.75)]


def test_guide_table_keeps_the_inner_order(guide):
    columns, rows = run(
        guide,
        """SELECT "Metric", "Value" FROM (
  SELECT 1 as sort_order, 'Total Samples' as "Metric", CAST(COUNT(*) AS VARCHAR) as "Value" FROM covariance_accuracy
  UNION ALL
  SELECT 2 as sort_order, 'Within 1σ (target: ~68%)' as "Metric",
    CONCAT(CAST(ROUND(100.0 * AVG(CASE WHEN within_1_sigma = 1 THEN 1.0 ELSE 0.0 END), 1) AS VARCHAR), '%') as "Value"
    FROM covariance_accuracy
  ORDER BY sort_order);""",
    )
    assert columns == (("Metric", "varchar(24)"), ("Value", "varchar"))
    assert rows == [("Total Samples", "3"), ("Within 1σ (target: ~68%)", "70.00%")]


def test_guide_state_timeline_and_min_avg_max(guide):
    columns, rows = run(guide, "SELECT 'Navigation' as \"System\", timestamp, state FROM goal_status;")
    assert columns == (("System", "varchar(10)"), ("timestamp", "bigint"), ("state", "varchar"))
    assert rows == [("Navigation", 1, "DRIVING")]
    columns, rows = run(
        guide,
        "SELECT m.experience_name, MIN(position_diff_m), AVG(position_diff_m), "
        "MAX(position_diff_m) FROM pose_difference d JOIN metadata m on d.job_id = m.job_id "
        "GROUP BY m.experience_name",
    )
    assert [t for _, t in columns] == ["varchar", "double", "double", "double"]
    assert sorted(rows) == [("Highway", 1.25, 1.25, 1.25), ("Parking", 0.5, 0.625, 0.75)]


def test_guide_classified_tags_with_filter_and_count_if(guide):
    columns, rows = run(
        guide,
        "WITH classified AS (SELECT filter(experience_tag_names, x -> starts_with(x, "
        "'my_prefix_'))[1] AS group_name, job_conflated_status FROM metadata WHERE "
        "contains(experience_tag_names, 'my_tag')) SELECT group_name, count_if("
        "job_conflated_status = 'PASSED') AS passed FROM classified WHERE group_name IS NOT "
        "NULL GROUP BY group_name",
    )
    assert columns == (("group_name", "varchar"), ("passed", "bigint"))
    assert rows == [("my_prefix_a", 2)]


def test_guide_classified_tags_fails_like_trino_on_an_empty_filter(guide):
    translation = translate(
        "SELECT filter(experience_tag_names, x -> starts_with(x, 'none_'))[1] FROM metadata", GUIDE_SCHEMA
    )
    with pytest.raises(duckdb.Error) as caught:
        guide.execute(translation.duckdb_sql).fetchall()
    assert "Array subscript must be less than or equal to array length: 1 > 0" in str(caught.value)


def test_guide_metadata_star(guide):
    columns, rows = run(guide, "SELECT * FROM metadata")
    assert [n for n, _ in columns] == list(GUIDE_SCHEMA["metadata"])
    assert len(rows) == 3 and rows[0][2] == ["my_prefix_a", "my_tag"]


def test_decimal_values_come_back_exact(guide):
    columns, rows = run(guide, "SELECT round(avg(CAST(time_s AS decimal(10,2))), 1) FROM time_to_goal")
    assert columns == (("_col0", "decimal(11,2)"),) and rows == [(Decimal("15.40"),)]


def test_comment_after_trailing_semicolon_is_not_a_second_statement():
    assert translate("SELECT 1; -- done", {}).columns == (("_col0", "integer"),)
    with pytest.raises(DialectError):
        translate("SELECT 1; SELECT 2", {})
