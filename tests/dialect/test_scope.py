"""Scopes: every lake table a query reads is restricted to one job or batch, in every part of the
query, except names a visible CTE shadows. Checked on the rewritten Trino SQL and by running the
translation on DuckDB over the real Parquet fixture tables (odom and metadata hold jobs j1 and j2
of batch b1 and job j3 of batch b2; odom has 4 rows of j1 with x = 3, 6, 0, 1.5, 4 of j2, 1 of j3)."""

from __future__ import annotations

import pytest
import sqlglot
from sqlglot import exp

from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope, restrict
from lakegate.dialect.translate import translate

JOB = Scope(batch_id="b1", job_id="j1")
BATCH = Scope(batch_id="b1")
TABLES = {"odom", "metadata", "t", "events"}


def rewritten(sql: str, scope: Scope = JOB) -> str:
    return restrict(sqlglot.parse_one(sql, read="trino"), scope, TABLES).sql(dialect="trino")


def run(fixture_lake, sql: str, scope: Scope | None = JOB) -> list[tuple]:
    translation = translate(sql, fixture_lake.schema, scope=scope)
    with fixture_lake.transaction() as con:
        return con.execute(translation.duckdb_sql).fetchall()


def test_a_reference_becomes_a_filtered_derived_table_with_its_alias():
    assert (
        rewritten("SELECT o.x FROM odom o")
        == "SELECT o.x FROM (SELECT * FROM odom WHERE batch_id = 'b1' AND job_id = 'j1') AS o"
    )
    assert (
        rewritten("SELECT odom.x FROM odom", BATCH)
        == "SELECT odom.x FROM (SELECT * FROM odom WHERE batch_id = 'b1') AS odom"
    )
    assert (
        rewritten("SELECT count(*) FROM lakegate.main.odom")
        == "SELECT COUNT(*) FROM (SELECT * FROM lakegate.main.odom WHERE batch_id = 'b1' AND job_id = 'j1') AS odom"
    )
    assert rewritten("SELECT 1 FROM not_a_lake_table") == "SELECT 1 FROM not_a_lake_table"


def test_an_empty_scope_changes_nothing(fixture_lake):
    tree = sqlglot.parse_one("SELECT x FROM odom", read="trino")
    assert restrict(tree, Scope(), TABLES) is tree and tree.sql(dialect="trino") == "SELECT x FROM odom"
    assert run(fixture_lake, "SELECT count(*) FROM odom", Scope()) == [(9,)]


@pytest.mark.parametrize(
    "sql, job_rows, batch_rows",
    [
        ("SELECT DISTINCT job_id FROM odom ORDER BY 1", [("j1",)], [("j1",), ("j2",)]),
        ("SELECT count(*), max(x) FROM odom", [(4, 6.0)], [(8, 6.0)]),
        ("SELECT odom.x FROM odom WHERE odom.x > 2 ORDER BY 1", [(3.0,), (6.0,)], [(3.0,), (3.0,), (4.0,), (6.0,)]),
        (
            "SELECT m.experience_name, count(*) FROM odom o JOIN metadata m ON o.job_id = m.job_id "
            "GROUP BY 1 ORDER BY 1",
            [("Parking lot", 4)],
            [("Highway merge", 4), ("Parking lot", 4)],
        ),
        ("SELECT count(*) FROM metadata", [(1,)], [(2,)]),
        ("SELECT (SELECT count(*) FROM odom), (SELECT count(*) FROM metadata)", [(4, 1)], [(8, 2)]),
        (
            "SELECT experience_name FROM metadata WHERE job_id IN (SELECT job_id FROM odom) ORDER BY 1",
            [("Parking lot",)],
            [("Highway merge",), ("Parking lot",)],
        ),
        (
            "SELECT count(*) FROM metadata m WHERE EXISTS (SELECT 1 FROM odom o WHERE o.job_id = m.job_id)",
            [(1,)],
            [(2,)],
        ),
        (
            "SELECT m.job_id, l.n FROM metadata m CROSS JOIN LATERAL "
            "(SELECT count(*) AS n FROM odom o WHERE o.job_id = m.job_id) l ORDER BY 1",
            [("j1", 4)],
            [("j1", 4), ("j2", 4)],
        ),
        ("SELECT job_id FROM odom UNION SELECT job_id FROM metadata ORDER BY 1", [("j1",)], [("j1",), ("j2",)]),
        ("SELECT count(*) FROM (SELECT x FROM odom UNION ALL SELECT x FROM odom)", [(8,)], [(16,)]),
        ("SELECT count(*) FROM (SELECT job_id FROM odom EXCEPT SELECT 'j2')", [(1,)], [(1,)]),
        (
            "WITH a AS (SELECT * FROM odom), b AS (SELECT * FROM a JOIN metadata USING (job_id)) "
            "SELECT count(*) FROM b",
            [(4,)],
            [(8,)],
        ),
        ("SELECT count(*) FROM (SELECT * FROM (SELECT * FROM odom) AS inner_most) AS outer_most", [(4,)], [(8,)]),
        ("SELECT count(*) FROM ODOM", [(4,)], [(8,)]),
        ("SELECT count(a) FROM odom AS o(ts, a, b, c, d, e)", [(4,)], [(8,)]),
    ],
)
def test_a_scoped_query_never_sees_other_jobs_rows(fixture_lake, sql, job_rows, batch_rows):
    assert run(fixture_lake, sql, JOB) == job_rows
    assert run(fixture_lake, sql, BATCH) == batch_rows


def test_a_cte_shadows_a_table_in_the_rest_of_its_with(fixture_lake):
    # the CTE is not a lake table: left alone
    assert (
        rewritten("WITH odom AS (SELECT 42 AS x) SELECT x FROM odom")
        == "WITH odom AS (SELECT 42 AS x) SELECT x FROM odom"
    )
    assert run(fixture_lake, "WITH odom AS (SELECT 42 AS x) SELECT x FROM odom") == [(42,)]
    # ... but its own body reads the real table (Trino's WITH is not recursive)
    assert run(fixture_lake, "WITH odom AS (SELECT count(*) AS n FROM odom) SELECT n FROM odom") == [(4,)]
    # earlier CTEs see the table, later ones and the body see the CTE
    sql = (
        "WITH a AS (SELECT count(*) AS n FROM odom), odom AS (SELECT 7 AS n) "
        "SELECT (SELECT n FROM a), (SELECT n FROM odom)"
    )
    assert run(fixture_lake, sql) == [(4, 7)]
    # the CTE is visible in nested subqueries of its query, not outside its WITH
    assert run(fixture_lake, "WITH odom AS (SELECT 5 AS x) SELECT (SELECT max(x) FROM odom)") == [(5,)]
    sql = "SELECT (SELECT count(*) FROM odom), (SELECT n FROM (WITH odom AS (SELECT 1 AS n) SELECT n FROM odom))"
    assert run(fixture_lake, sql) == [(4, 1)]
    # a CTE over a set operation, and names compared case-insensitively
    sql = "WITH Odom AS (SELECT 1 AS x UNION ALL SELECT 2) SELECT count(*) FROM (SELECT x FROM ODOM UNION ALL SELECT 3)"
    assert run(fixture_lake, sql) == [(3,)]


def test_a_recursive_cte_shadows_in_its_own_body():
    sql = "WITH RECURSIVE odom(n) AS (SELECT 1 UNION ALL SELECT n + 1 FROM odom WHERE n < 3) SELECT n FROM odom"
    assert rewritten(sql) == sqlglot.parse_one(sql, read="trino").sql(dialect="trino")


def test_a_qualified_name_is_never_a_cte():
    sql = "WITH odom AS (SELECT 1 AS x) SELECT count(*) FROM main.odom"
    assert "FROM (SELECT * FROM main.odom WHERE batch_id = 'b1' AND job_id = 'j1') AS odom" in rewritten(sql)


def test_values_are_string_literal_nodes_never_pasted(fixture_lake):
    hostile = Scope(job_id="j1' OR '1' = '1")
    assert (
        rewritten("SELECT x FROM odom", hostile)
        == "SELECT x FROM (SELECT * FROM odom WHERE job_id = 'j1'' OR ''1'' = ''1') AS odom"
    )
    assert run(fixture_lake, "SELECT count(*) FROM odom", hostile) == [(0,)]


def test_deep_queries_do_not_exhaust_the_stack():
    tree = sqlglot.parse_one("SELECT x FROM odom", read="trino")
    node = tree.expressions[0]
    for _ in range(5000):
        node = exp.Paren(this=node)
    tree.set("expressions", [node])
    restricted = restrict(tree, JOB, TABLES)
    assert isinstance(restricted.args["from_"].this, exp.Subquery)


def test_translation_carries_the_scoped_trino_sql(fixture_lake):
    translation = translate("SELECT count(*) FROM odom", fixture_lake.schema, scope=JOB)
    assert "WHERE batch_id = 'b1' AND job_id = 'j1'" in translation.trino_sql


@pytest.mark.parametrize(
    "sql, rows",
    [
        # a CTE read in a derived table, a joined subquery and a nested CTE's body
        ("WITH i AS (SELECT 1 AS a) SELECT a FROM (SELECT a FROM i)", [(1,)]),
        ("WITH i AS (SELECT 1 AS a) SELECT a FROM (SELECT a FROM (SELECT a FROM i) d1) d2", [(1,)]),
        (
            "WITH n AS (SELECT count(*) AS c FROM odom) SELECT m.job_id, s.c FROM metadata m "
            "JOIN (SELECT c FROM n) s ON true",
            [("j1", 4)],
        ),
        (
            "WITH n AS (SELECT max(x) AS c FROM odom) "
            "SELECT c FROM (WITH k AS (SELECT c * 2 AS c FROM n) SELECT c FROM k)",
            [(12.0,)],
        ),
        ("WITH n AS (SELECT 2 AS c) SELECT * FROM (VALUES 1) v(a) CROSS JOIN (SELECT c FROM n)", [(1, 2)]),
        # a CTE named like a topic shadows it inside a derived table too, and the topic stays scoped in the CTE body
        ("WITH odom AS (SELECT count(*) AS x FROM odom) SELECT x FROM (SELECT x FROM odom)", [(4,)]),
        ("WITH odom AS (SELECT 42 AS x) SELECT o.x FROM metadata m JOIN (SELECT x FROM odom) o ON true", [(42,)]),
    ],
)
def test_a_cte_is_visible_at_every_depth_of_its_query(fixture_lake, sql, rows):
    assert run(fixture_lake, sql) == rows


def test_a_derived_table_does_not_see_its_siblings():
    with pytest.raises(DialectError, match="Table 'i' does not exist"):
        translate(
            "SELECT 1 FROM (WITH i AS (SELECT 1 AS a) SELECT a FROM i) x, (SELECT a FROM i) y",
            {"odom": {"x": "double"}},
        )


@pytest.mark.parametrize(
    "batches, sql, rows",
    [
        # every job of the batches listed (odom: j1, j2 of b1 with 4 rows each, j3 of b2 with 1)
        (("b1", "b2"), "SELECT job_id, count(*) FROM odom GROUP BY 1 ORDER BY 1", [("j1", 4), ("j2", 4), ("j3", 1)]),
        (("b2",), "SELECT DISTINCT batch_id, job_id FROM odom", [("b2", "j3")]),
        (("b1",), "SELECT count(*) FROM metadata", [(2,)]),
        ((), "SELECT count(*) FROM odom", [(0,)]),  # no batches: no rows
        (
            ("b1", "b2"),
            "SELECT m.batch_id, count(*) FROM odom o "
            "JOIN metadata m ON o.batch_id = m.batch_id AND o.job_id = m.job_id GROUP BY 1 ORDER BY 1",
            [("b1", 8), ("b2", 1)],
        ),
        (("b2", "nope"), "WITH odom AS (SELECT 42 AS x) SELECT x FROM odom", [(42,)]),  # a CTE still shadows
    ],
)
def test_a_list_of_batches_shows_every_job_of_them_and_nothing_else(fixture_lake, batches, sql, rows):
    assert run(fixture_lake, sql, Scope(batches=batches)) == rows


def test_a_list_of_batches_is_one_in_list_of_literals():
    assert (
        rewritten("SELECT count(*) FROM odom o", Scope(batches=("b1", "it's")))
        == "SELECT COUNT(*) FROM (SELECT * FROM odom WHERE batch_id IN ('b1', 'it''s')) AS o"
    )
    assert (
        rewritten("SELECT x FROM odom", Scope(batches=())) == "SELECT x FROM (SELECT * FROM odom WHERE FALSE) AS odom"
    )
    with pytest.raises(ValueError, match="not both"):
        Scope(batch_id="b1", batches=("b1",))
