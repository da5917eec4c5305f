"""The one reader of statements: each text is read once into a `Statement` whose kind is one of
`statements.KINDS` (each with its one owner), with the query an EXPLAIN explains and a tree parsed
once per text; refusals of the text stay the guard's, with their positions."""

from __future__ import annotations

import pytest

from lakegate.dialect import guard, statements
from lakegate.dialect.errors import DialectError
from lakegate.dialect.statements import read


@pytest.mark.parametrize(
    "sql, kind, name",
    [
        ("SELECT 1", "query", "SELECT"),
        ("  -- comment\n((VALUES 1))", "query", "VALUES"),
        ("EXPLAIN ANALYZE SELECT 1", "explain", "EXPLAIN"),
        ("EXPLAIN INSERT INTO t VALUES 1", "other", "EXPLAIN INSERT"),
        ("SHOW TABLES", "show", "SHOW TABLES"),
        ("DESC odom", "describe", "DESC"),
        ("DESCRIBE OUTPUT st", "describe_prepared", "DESCRIBE OUTPUT"),
        ("DESCRIBE input", "describe", "DESCRIBE INPUT"),  # a table named input
        ("DESCRIBE INPUT st extra", "describe", "DESCRIBE INPUT"),
        ("EXECUTE st USING 1", "execute", "EXECUTE"),
        ("EXECUTE IMMEDIATE 'SELECT 1'", "execute", "EXECUTE"),
        ("use main", "session", "USE"),
        ("SET TIME ZONE 'UTC'", "session", "SET TIME ZONE"),
        ("SET SESSION batch_id = 'b'", "session", "SET SESSION"),
        ("DEALLOCATE PREPARE st", "session", "DEALLOCATE PREPARE"),
        ("START TRANSACTION", "session", "START TRANSACTION"),
        ("SET PATH lake", "other", "SET PATH"),
        ("DEALLOCATE st", "other", "DEALLOCATE"),
        ("CALL system.runtime.kill_query('q')", "call", "CALL"),
        ("INSERT INTO odom VALUES (1)", "other", "INSERT"),
        ("frobnicate", "other", "FROBNICATE"),
        ("", "other", ""),
    ],
)
def test_each_statement_has_one_kind(sql, kind, name):
    statement = read(sql)
    assert (statement.kind, statement.name) == (kind, name)
    assert statement.kind in statements.KINDS


def test_one_table_decides_every_kind():
    """Every kind the table of statement kinds gives has its owner in `KINDS`; the reader adds only the
    prepared statement's DESCRIBE (told from a table named input or output by its tokens)."""
    given = {kind for kind, _ in guard.STATEMENTS.values()}
    assert given <= statements.KINDS.keys()
    assert statements.KINDS.keys() - given == {"describe_prepared"}


def test_explain_reads_the_query_it_explains():
    sql = "EXPLAIN ANALYZE (TYPE DISTRIBUTED)\n  SELECT x FROM odom"
    statement = read(sql)
    assert (statement.body, statement.analyze) == ("SELECT x FROM odom", True)
    assert sql[statement.offset :] == statement.body
    assert statement.tree.sql() == "SELECT x FROM odom"


def test_the_tree_is_parsed_once_per_text():
    assert read("SELECT 1 AS a").tree is read("SELECT 1 AS a").tree


def test_parse_errors_of_an_explained_query_point_into_the_whole_text():
    with pytest.raises(DialectError) as caught:
        _ = read("EXPLAIN\nSELECT 1 +").tree
    assert (caught.value.error_name, caught.value.line) == ("SYNTAX_ERROR", 2)


def test_a_rewritten_statement_keeps_its_text_and_carries_its_edits():
    statement = read("SELECT x FROM main.odom")
    tree = statement.tree.copy()
    rewritten = statement.rewritten(tree, ((14, 19, "     "),))
    assert rewritten.text == statement.text and rewritten.tree is tree
    assert rewritten.edited_text() == "SELECT x FROM      odom"
    assert statement.edited_text() == statement.text
