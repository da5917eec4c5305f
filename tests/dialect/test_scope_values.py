"""One translation of a query serves every job: `translate_in_scope` gives exactly what `translate` gives
for the job's own scope (text, Trino SQL, columns), with job ids that try to break out of their
literal, and falls back to the scope's own translation whenever the stand-ins could be confused
with the query's text. Run on DuckDB over the real Parquet fixture tables (tests/dialect/conftest.py)."""

from __future__ import annotations

import pytest

from lakegate.dialect import translate as translation_module
from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope
from lakegate.dialect.scope_values import translate_in_scope
from lakegate.dialect.translate import translate

QUERIES = [
    "SELECT count(*), max(x) FROM odom",
    "SELECT m.experience_name, count(*) FROM odom o JOIN metadata m ON o.job_id = m.job_id GROUP BY 1",
    "WITH odom AS (SELECT 1 AS x) SELECT * FROM odom",
    "SELECT x FROM odom WHERE x > ? ORDER BY x",
    "SELECT 'lakegatestandinjobqx', count(*) FROM odom",  # a stand-in in the query: its own translation
]
HOSTILE = ["j1", "j1' OR '1' = '1", "a\\'b", "a\nb", "é\u2028z", "lakegatestandinjobzw", "", "''"]


@pytest.mark.parametrize("sql", QUERIES)
@pytest.mark.parametrize("job", HOSTILE)
def test_the_bound_translation_is_the_scopes_own(fixture_lake, sql, job):
    params = (2.0,) if "?" in sql else ()
    for scope in (Scope("b1", job), Scope(job), Scope(job, "j1")):
        assert translate_in_scope(sql, fixture_lake.schema, scope=scope, params=params) == translate(
            sql, fixture_lake.schema, scope=scope, params=params
        )


def test_a_hostile_job_id_stays_inside_its_literal(fixture_lake):
    translation = translate_in_scope(
        "SELECT count(*) FROM odom", fixture_lake.schema, scope=Scope("b1", "j1' OR '1' = '1")
    )
    with fixture_lake.transaction() as con:
        assert con.execute(translation.duckdb_sql).fetchall() == [(0,)]
    translation = translate_in_scope("SELECT count(*) FROM odom", fixture_lake.schema, scope=Scope("b1", "j1"))
    with fixture_lake.transaction() as con:
        assert con.execute(translation.duckdb_sql).fetchall() == [(4,)]


def test_every_job_shares_one_cached_translation(fixture_lake):
    translation_module.clear_cache()
    for job in ("j1", "j2", "j3", "j4"):
        translate_in_scope("SELECT max(x) FROM odom", fixture_lake.schema, scope=Scope("b1", job))
    assert len(translation_module._cache) == 2  # the two stand-in translations, whatever the number of jobs


def test_errors_are_the_scopes_own(fixture_lake):
    with pytest.raises(DialectError) as own:
        translate("SELECT nope FROM odom", fixture_lake.schema, scope=Scope("b1", "j1"))
    with pytest.raises(DialectError) as bound:
        translate_in_scope("SELECT nope FROM odom", fixture_lake.schema, scope=Scope("b1", "j1"))
    assert (bound.value.message, bound.value.line, bound.value.column) == (
        own.value.message,
        own.value.line,
        own.value.column,
    )
