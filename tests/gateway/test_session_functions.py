"""`current_catalog`, `current_schema`, `current_user`, `current_path`, `current_timezone()` and
`current_groups()` over a real `lakegate serve`, answered as the real Trino 476 answers them in each
session situation: no catalog or schema set, a catalog set, both set (also names that do not exist,
and names in upper case, which Trino lower-cases), and a session zone."""

from __future__ import annotations

import pytest
import trino

from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine.trino_backend import TrinoBackend

SESSION_SQL = "SELECT current_catalog, current_schema, current_user, current_path, current_timezone(), current_groups()"


def answer(url: str, sql: str, **session) -> tuple[list, list]:
    """(rows, [(column, type)]) of `sql`, or raises the client's error."""
    host, port = url.split("://")[1].split(":")
    cursor = trino.dbapi.connect(host=host, port=int(port), user=session.pop("user", "Tester"), **session).cursor()
    cursor.execute(sql)
    rows = cursor.fetchall()
    return rows, [(d[0], d[1]) for d in cursor.description]


#: Session situations: (lakegate's session, the real Trino's session); catalog and schema names differ.
SITUATIONS = [
    ({}, {}),
    ({"catalog": "lake"}, {"catalog": "memory"}),
    ({"catalog": "lake", "schema": "main"}, {"catalog": "memory", "schema": "default"}),
    ({"catalog": "LAKE", "schema": "Main"}, {"catalog": "MEMORY", "schema": "Default"}),
    ({"catalog": "nosuch", "schema": "nosuch"}, {"catalog": "nosuch", "schema": "nosuch"}),
    ({"catalog": "system", "schema": "jdbc"}, {"catalog": "system", "schema": "jdbc"}),
    ({"timezone": "America/New_York", "user": "mixed.Case"}, {"timezone": "America/New_York", "user": "mixed.Case"}),
]


@pytest.mark.parametrize("lakegate_session, trino_session", SITUATIONS)
def test_session_functions_answer_as_trino(lakegate_session, trino_session, lake_server, trino_url):
    rows, columns = answer(lake_server.url, SESSION_SQL, **lakegate_session)
    judge_rows, judge_columns = answer(trino_url, SESSION_SQL, **trino_session)
    assert (
        columns
        == judge_columns
        == [
            ("_col0", "varchar"),
            ("_col1", "varchar"),
            ("_col2", "varchar"),
            ("_col3", "varchar"),
            ("_col4", "varchar"),
            ("_col5", "array(varchar)"),
        ]
    )
    (row,), (judge,) = rows, judge_rows
    assert row[2:] == judge[2:]
    # catalog and schema: the session's names, lower-cased, as Trino answers its own
    for value, judge_value, name, judge_name in zip(row[:2], judge[:2], ("catalog", "schema"), ("catalog", "schema")):
        assert (value is None) == (judge_value is None) == (lakegate_session.get(name) is None)
        if value is not None:
            assert value == lakegate_session[name].lower()
            assert judge_value == trino_session[judge_name].lower()


@pytest.mark.parametrize(
    "sql",
    [
        "SELECT current_user AS u, length(current_user) AS n, current_user = 'Tester' AS same",
        "SELECT x FROM (VALUES 1, 2) AS t(x) WHERE current_schema IS NULL ORDER BY x",
        'SELECT current_schema AS s FROM (VALUES 1) AS t("current_schema")',
        'SELECT "current_schema" FROM (VALUES 7) AS t("current_schema")',
        "SELECT typeof(current_catalog), typeof(current_groups()), cardinality(current_groups())",
    ],
)
def test_session_functions_in_expressions(sql, lake_server, trino_url):
    assert answer(lake_server.url, sql) == answer(trino_url, sql)


@pytest.mark.parametrize("sql", ["SELECT current_user()", "SELECT current_catalog()", "SELECT 1 + current_schema()"])
def test_parentheses_are_a_syntax_error(sql, lake_server, trino_url):
    errors = []
    for url in (lake_server.url, trino_url):
        with pytest.raises(trino.exceptions.TrinoUserError) as raised:
            answer(url, sql)
        errors.append((raised.value.error_name, raised.value.message.split(": ")[0]))
    assert errors[0] == errors[1]
    assert errors[0][0] == "SYNTAX_ERROR"


def test_lake_queries_read_the_session(lake_server):
    rows, _ = answer(
        lake_server.url,
        "SELECT current_user, current_schema, count(*) FROM metadata GROUP BY 1, 2",
        catalog="lake",
        schema="main",
        user="alice",
    )
    ((user, schema, count),) = rows
    assert (user, schema) == ("alice", "main") and count > 0


def test_refused_with_the_trino_backend(lake_server):
    """A forwarding backend would get the cluster's own catalog and schema names: refused by name."""
    backend = TrinoBackend(lake_server.url, user="tester", catalog="lake", schema_map={"*": "{branch}"})
    try:
        with pytest.raises(DialectError) as refused:
            backend.execute("SELECT 1, current_schema", branch="main")
        assert (refused.value.error_name, refused.value.message) == (
            "NOT_SUPPORTED",
            "unsupported in lakegate: current_schema with the Trino backend",
        )
        forwarded = backend.execute("SELECT 'current_user' AS text", branch="main")
        assert [row for batch in forwarded.batches for row in batch.to_pylist()] == [{"text": "current_user"}]
    finally:
        backend.close()
