"""`?` parameters: bound as typed Trino literals in text order, never pasted; a wrong count is a clear
error; status-check thresholds bind with the right types; EXECUTE ... USING lists as the real trino
client writes them are read back."""

from __future__ import annotations

import datetime as dt
import math
import uuid
from decimal import Decimal
from zoneinfo import ZoneInfo

import numpy as np
import pytest
import sqlglot
from trino.dbapi import Cursor

from lakegate.dialect.errors import DialectError
from lakegate.dialect.params import Execute, TypedLiteral, bind, literal, parse_execute, parse_using
from lakegate.dialect.scope import Scope
from lakegate.dialect.translate import translate


def client_literal(value) -> str:
    """The literal text the trino Python client sends for `value` (its own formatter)."""
    return Cursor.__new__(Cursor)._format_prepared_param(value)


def run(fixture_lake, sql, params, scope=None):
    translation = translate(sql, fixture_lake.schema, params=params, scope=scope)
    with fixture_lake.transaction() as con:
        return translation, con.execute(translation.duckdb_sql).fetchall()


@pytest.mark.parametrize(
    "value, trino_type",
    [
        (3, "integer"),
        (-7, "integer"),
        (2**31, "bigint"),
        (-(2**63), "bigint"),
        (1.5, "double"),
        (-0.25, "double"),
        (1e300, "double"),
        (Decimal("1.25"), "decimal(3,2)"),
        (Decimal("-001.50"), "decimal(3,2)"),
        (Decimal("7"), "decimal(1,0)"),
        ("it's", "varchar(4)"),
        ("", "varchar(0)"),
        (True, "boolean"),
        (None, "unknown"),
        (dt.date(2024, 2, 29), "date"),
        (dt.datetime(2024, 1, 2, 3, 4, 5, 123456), "timestamp(6)"),
        ([1, 2, 3], "array(integer)"),
        (["a", None], "array(varchar(1))"),
        (TypedLiteral("timestamp(3)", "2024-01-02 03:04:05.123"), "timestamp(3)"),
    ],
)
def test_each_value_binds_as_a_typed_literal(fixture_lake, value, trino_type):
    translation, rows = run(fixture_lake, "SELECT ?, typeof(?)", [value, value])
    assert translation.columns[0][1] == trino_type
    expected = dt.datetime(2024, 1, 2, 3, 4, 5, 123000) if isinstance(value, TypedLiteral) else value
    assert rows == [(expected, trino_type)]


def test_non_finite_doubles(fixture_lake):
    _, rows = run(fixture_lake, "SELECT ?, ?, ?", [math.inf, -math.inf, math.nan])
    assert rows[0][0] == math.inf and rows[0][1] == -math.inf and math.isnan(rows[0][2])


def test_strings_are_never_pasted(fixture_lake):
    hostile = "x'; DROP TABLE odom; --"
    translation, rows = run(fixture_lake, "SELECT ? AS s, count(*) FROM odom WHERE job_id = ?", [hostile, hostile])
    assert rows == [(hostile, 0)]
    assert "'x''; DROP TABLE odom; --'" in translation.trino_sql


def test_placeholders_bind_in_text_order(fixture_lake):
    # sqlglot keeps a SELECT's WITH and LIMIT after its other clauses; binding follows the text
    sql = (
        "WITH c AS (SELECT ? AS a) SELECT ? AS b, count(*) FROM odom "
        "WHERE job_id = (SELECT a FROM c) AND x > ? GROUP BY 1 HAVING count(*) > ? ORDER BY 1 LIMIT ?"
    )
    translation, rows = run(fixture_lake, sql, ["j1", "second", 1.0, 0, 5])
    assert rows == [("second", 3)]
    assert translation.trino_sql.index("'j1'") < translation.trino_sql.index("'second'")


def test_wrong_count_names_expected_and_given(fixture_lake):
    for params in ([], [1, 2]):
        with pytest.raises(DialectError) as caught:
            translate("SELECT ? FROM odom", fixture_lake.schema, params=params)
        assert caught.value.error_name == "INVALID_PARAMETER_USAGE"
        assert caught.value.message == f"Incorrect number of parameters: expected 1 but found {len(params)}"
    with pytest.raises(DialectError):
        translate("SELECT 1", fixture_lake.schema, params=[1])


def test_numpy_numbers_bind_like_python_numbers(fixture_lake):
    _, rows = run(
        fixture_lake, "SELECT ?, typeof(?), ?, typeof(?)", [np.int64(5), np.int64(5), np.float64(2.5), np.float64(2.5)]
    )
    assert rows == [(5, "integer", 2.5, "double")]


def test_unbindable_values_are_clear_errors():
    with pytest.raises(DialectError) as caught:
        literal(2**64)
    assert caught.value.error_name == "INVALID_LITERAL"
    with pytest.raises(DialectError) as caught:
        literal(object())
    assert "Python type object" in caught.value.message
    with pytest.raises(DialectError):
        literal(Decimal("NaN"))


@pytest.mark.parametrize("threshold, returns_a_row", [(3, False), (3.5, True), (4, True), (2.5, False)])
def test_status_check_thresholds_bind_right(fixture_lake, threshold, returns_a_row):
    # events has 3 rows: the status query returns a row (blocks / warns) when COUNT(*) < threshold
    translation, rows = run(fixture_lake, "SELECT '1' FROM events HAVING COUNT(*) < ?", [threshold])
    assert rows == ([("1",)] if returns_a_row else [])
    assert translation.columns == (("_col0", "varchar(1)"),)


def test_status_threshold_with_a_scope(fixture_lake):
    # job j1 of odom has max(x) = 6.0
    sql = "SELECT 1 FROM odom HAVING MAX(x) > ?"
    assert run(fixture_lake, sql, [5.0], Scope(job_id="j1"))[1] == [(1,)]
    assert run(fixture_lake, sql, [6], Scope(job_id="j1"))[1] == []
    assert run(fixture_lake, sql, [Decimal("5.99")], Scope(job_id="j1"))[1] == [(1,)]


def test_bind_replaces_in_place_and_keeps_literal_nodes():
    tree = sqlglot.parse_one("SELECT ?, ?", read="trino")
    bound = bind(tree, [1, "a"])
    assert bound.sql(dialect="trino") == "SELECT 1, 'a'"
    assert not list(bound.find_all(sqlglot.exp.Placeholder))


@pytest.mark.parametrize(
    "value",
    [
        None,
        True,
        False,
        0,
        42,
        -7,
        2**40,
        -(2**63),
        1.5,
        -2.5e-7,
        math.inf,
        -math.inf,
        Decimal("1.25"),
        Decimal("-0.001"),
        "it's",
        "",
        b"\x01\x02\xff",
        dt.date(2024, 1, 2),
        uuid.UUID("12345678-1234-5678-1234-567812345678"),
        [1, 2, None],
        ["a", "b"],
        (1, "x"),
        {"k": 1.5},
    ],
)
def test_using_lists_written_by_the_trino_client_read_back(value):
    assert parse_using(f"EXECUTE st USING {client_literal(value)}") == [value]


def test_using_lists_of_typed_literals():
    ts = dt.datetime(2024, 1, 2, 3, 4, 5, 123456)
    values = parse_using(
        f"EXECUTE st USING {client_literal(ts)}, {client_literal(math.nan)}, "
        f"TIMESTAMP '2024-01-02 03:04:05.123', TIME '01:02:03', 1.50, 1E3"
    )
    assert values[0] == TypedLiteral("timestamp(6)", "2024-01-02 03:04:05.123456")
    assert math.isnan(values[1])
    assert values[2:] == [
        TypedLiteral("timestamp(3)", "2024-01-02 03:04:05.123"),
        TypedLiteral("time(0)", "01:02:03"),
        Decimal("1.50"),
        1000.0,
    ]
    zoned = parse_using(f"EXECUTE st USING {client_literal(dt.datetime(2024, 1, 2, tzinfo=ZoneInfo('Europe/Paris')))}")
    assert zoned == [TypedLiteral("timestamp(6) with time zone", "2024-01-02 00:00:00.000000 Europe/Paris")]


def test_parse_execute():
    sql = "SELECT 'it''s', ? FROM odom WHERE x > ?"
    text = "EXECUTE IMMEDIATE '" + sql.replace("'", "''") + "' USING 'a', 2;"
    assert parse_execute(text) == Execute(name=None, statement=sql, params=["a", 2])
    assert parse_execute("execute st_0a1b USING DOUBLE '1.5'") == Execute(name="st_0a1b", statement=None, params=[1.5])
    assert parse_execute("EXECUTE st") == Execute(name="st", statement=None, params=[])
    for bad in (
        "EXECUTE st USING x + 1",
        "EXECUTE st USING (SELECT 1)",
        "EXECUTE st WITH 1",
        "SELECT 1",
        "EXECUTE IMMEDIATE st",
        "EXECUTE st USING",
    ):
        with pytest.raises(DialectError):
            parse_execute(bad)


def test_a_bound_query_runs_like_the_same_query_with_literals(fixture_lake):
    _, bound = run(
        fixture_lake, "SELECT count(*), sum(x) FROM odom WHERE x > ? AND job_id IN (?, ?)", [1.0, "j1", "j2"]
    )
    _, literal_rows = run(
        fixture_lake, "SELECT count(*), sum(x) FROM odom WHERE x > 1.0E0 AND job_id IN ('j1', 'j2')", []
    )
    assert bound == literal_rows == [(6, 19.5)]
