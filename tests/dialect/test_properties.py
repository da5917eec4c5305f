"""Properties of the dialect, checked on generated inputs (hypothesis):

- every parameter value, written as a literal by the trino client or by lakegate, reads back from
  `EXECUTE ... USING` as the same value (`dialect.params`);
- the read-only guard: whatever statement text is sent, translation either refuses it with a
  DialectError or gives DuckDB exactly one SELECT statement (checked by DuckDB's own statement parser).
"""

from __future__ import annotations

import datetime as dt
import math
from decimal import Decimal
from typing import Any

import duckdb
from hypothesis import given, settings
from hypothesis import strategies as st
from trino.dbapi import Cursor

from lakegate.dialect.errors import DialectError
from lakegate.dialect.params import TypedLiteral, literal, parse_using
from lakegate.dialect.translate import translate

PROPERTY = settings(max_examples=200, deadline=None)


def client_literal(value: Any) -> str:
    """The literal text the trino Python client sends for `value` (its own formatter)."""
    return Cursor.__new__(Cursor)._format_prepared_param(value)


scalars = (
    st.none()
    | st.booleans()
    | st.integers(-(2**63), 2**63 - 1)
    | st.floats()
    | st.integers(0, 8).flatmap(lambda places: st.decimals(-(10**20), 10**20, places=places))
    | st.text(st.characters(blacklist_categories=["Cs"]), max_size=8)
    | st.binary(max_size=8)
    | st.dates(min_value=dt.date(1000, 1, 1))  # the client writes earlier years with fewer digits: see below
    | st.uuids()
)
values = st.recursive(
    scalars,
    lambda inner: (
        st.lists(inner, max_size=3)
        | st.tuples(inner, inner)
        | st.dictionaries(st.text(max_size=3) | st.integers(-9, 9), inner, max_size=3)
    ),
    max_leaves=6,
)


def same(a: Any, b: Any) -> bool:
    """Equal values of equal types: floats by their bits (NaN is NaN, -0.0 is not 0.0), decimals by their digits."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a) == math.copysign(1, b))
    if isinstance(a, Decimal):
        return format(a, "f") == format(b, "f")
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return same(list(a), list(b)) and same(list(a.values()), list(b.values()))
    return a == b


@PROPERTY
@given(value=values)
def test_every_value_the_trino_client_sends_reads_back_from_execute_using(value):
    [read] = parse_using(f"EXECUTE st USING {client_literal(value)}")
    assert same(read, value), (client_literal(value), read)


@PROPERTY
@given(value=values)
def test_every_literal_lakegate_writes_reads_back_as_the_same_literal(value):
    """`literal` writes each value as a typed Trino literal; reading it back gives the same literal
    (a value Python cannot hold exactly, as a TIMESTAMP, comes back as its type and text)."""
    try:
        text = literal(value).sql(dialect="trino")
    except DialectError as error:  # only decimals beyond Trino's 38 digits
        assert error.error_name == "INVALID_LITERAL", error
        return
    [read] = parse_using(f"EXECUTE st USING {text}")
    assert literal(read).sql(dialect="trino") == text


def test_a_date_the_client_writes_with_fewer_year_digits_stays_typed_text():
    """The client writes date(999, 1, 1) as DATE '999-01-01' (strftime); it is kept as that literal, so
    the query answers it as the same literal written inline would."""
    text = client_literal(dt.date(999, 1, 1))
    assert text == "DATE '999-01-01'"
    assert parse_using(f"EXECUTE st USING {text}, DATE '2024-02-30'") == [
        TypedLiteral("date", "999-01-01"),
        TypedLiteral("date", "2024-02-30"),
    ]


SCHEMA = {"t": {"a": "bigint", "s": "varchar"}}
#: statements of every kind DuckDB or Trino knows, reads and writes, some with a query inside
STATEMENTS = [
    "SELECT a FROM t",
    "WITH w AS (SELECT a FROM t) SELECT * FROM w",
    "VALUES (1, 'x')",
    "TABLE t",
    "SELECT 1 UNION ALL SELECT 2",
    "INSERT INTO t SELECT * FROM t",
    "INSERT INTO t VALUES (1, 'x')",
    "WITH w AS (SELECT 1) INSERT INTO t SELECT * FROM w",
    "UPDATE t SET a = 1",
    "DELETE FROM t",
    "MERGE INTO t USING t AS u ON t.a = u.a WHEN MATCHED THEN DELETE",
    "TRUNCATE t",
    "CREATE TABLE u AS SELECT * FROM t",
    "CREATE OR REPLACE VIEW v AS SELECT 1",
    "CREATE MACRO m(x) AS x",
    "DROP TABLE t",
    "ALTER TABLE t ADD COLUMN c int",
    "COPY t TO 'out.csv'",
    "COPY (SELECT 1) TO 'out.parquet' (FORMAT parquet)",
    "EXPORT DATABASE 'dir'",
    "IMPORT DATABASE 'dir'",
    "ATTACH 'other.db' AS other",
    "DETACH other",
    "INSTALL httpfs",
    "LOAD httpfs",
    "PRAGMA version",
    "SET memory_limit = '1GB'",
    "SET SESSION query_max_run_time = '1h'",
    "RESET memory_limit",
    "CALL pragma_version()",
    "CHECKPOINT",
    "VACUUM",
    "BEGIN TRANSACTION",
    "START TRANSACTION",
    "COMMIT",
    "USE other",
    "PREPARE p FROM SELECT 1",
    "EXECUTE p",
    "DESCRIBE t",
    "SHOW TABLES",
    "SUMMARIZE t",
    "PIVOT t ON a",
    "FROM t",
    "EXPLAIN SELECT 1",
    "EXPLAIN ANALYZE DELETE FROM t",
    "SELECT * FROM read_csv('x.csv')",
    "SELECT * FROM query('DROP TABLE t')",
    "SELECT (SELECT count(*) FROM t)",
]


@st.composite
def statement_texts(draw: st.DrawFn) -> str:
    """One or two statements, dressed as a client might send them: comments, brackets, case, semicolons."""
    parts = []
    for statement in draw(st.lists(st.sampled_from(STATEMENTS), min_size=1, max_size=2)):
        if draw(st.booleans()):
            statement = "".join(c.swapcase() if draw(st.booleans()) else c for c in statement)
        if statement.upper().startswith(("SELECT", "WITH", "VALUES", "TABLE")) and draw(st.booleans()):
            statement = f"({statement})"
        prefix = draw(st.sampled_from(["", " ", "\n", "/* c */ ", "-- c\n", "/* a; DROP TABLE t */"]))
        parts.append(prefix + statement)
    return ";".join(parts) + draw(st.sampled_from(["", ";", " ; ", ";\n-- end"]))


@settings(max_examples=300, deadline=None)
@given(sql=statement_texts())
def test_only_a_single_select_ever_reaches_duckdb(sql):
    try:
        duckdb_sql = translate(sql, SCHEMA).duckdb_sql
    except DialectError:
        return
    statements = duckdb.extract_statements(duckdb_sql)
    assert [s.type for s in statements] == [duckdb.StatementType.SELECT], (sql, duckdb_sql)
