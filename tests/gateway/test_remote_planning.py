"""A statement text over `planner.REMOTE_PARSE_CHARS` is checked and parsed in a query worker
process (`IsolatedBackend.query_names`), not in the process that serves every client: the engine
over worker processes answers it exactly as the in-process engine does (rows, and every error with
its name, message, line and column), and this process never parses it."""

from __future__ import annotations

import pytest

from lakegate.dialect import statements
from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine import planner
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.limits import Limits


@pytest.fixture(scope="module")
def engines(server_lake):
    """(in-process engine, engine over worker processes) on the server tests' lake."""
    local = Engine.open(server_lake)
    isolated = Engine.open(server_lake, limits=Limits(max_concurrent_queries=2, query_timeout=60), isolated=True)
    yield local, isolated
    isolated.close()
    local.close()


def padded(sql: str, where: str = "") -> str:
    """`sql` with a WHERE clause of job ids long enough to be planned remotely, then `where`."""
    ids = ", ".join(f"'id-{i:05d}-{'x' * 100}'" for i in range(planner.REMOTE_PARSE_CHARS // 100))
    return f"{sql}\nWHERE job_id NOT IN ({ids})\n{where}"


def outcome(engine: Engine, sql: str) -> tuple:
    session = engine.session(branch="main")
    try:
        result = engine.execute(sql, session)
        return ("rows", result.columns, sorted(result.rows()))
    except DialectError as error:
        return ("error", error.error_name, error.message, error.line, error.column)


def parses() -> tuple[int, int]:
    return statements.parsed.cache_info().misses, planner._names_of.cache_info().misses


@pytest.mark.parametrize(
    "sql",
    [
        # qualified names and version(): the worker drops the qualifiers the server resolved
        padded("SELECT job_id, version() AS v, lake.main.metadata.batch_id FROM lake.main.metadata", "ORDER BY 1"),
        padded("EXPLAIN SELECT count(*) FROM main.metadata"),
        padded("SELECT count(*) FROM metadata", "AND"),  # a syntax error at the end: line 3
        padded("SELECT count(*) FROM metadata", "GROUP BY nope"),  # the analyzer's error
        padded("SELECT count(*) FROM lake.main.no_such_table"),  # resolved in the server: its position
        padded('SELECT count(*) FROM lake.main.metadata x JOIN lake."feature/all-types".sample y ON true'),
        padded("SELECT 1 FROM metadata", "; SELECT 2"),  # the text check: two statements
        padded("SELECT count(*) FROM metadata", "AND job_id IN (" + ", ".join(["'a'"] * 20_000) + ")"),  # tokens
        padded("INSERT INTO metadata SELECT * FROM metadata"),  # a write: refused before parsing
    ],
    ids=["qualified", "explain", "syntax", "analysis", "unknown-table", "two-branches", "two-statements",
         "too-many-tokens", "write"],
)  # fmt: skip
def test_a_large_statement_is_answered_as_in_process_without_parsing_it_here(engines, sql):
    local, isolated = engines
    assert len(sql) > planner.REMOTE_PARSE_CHARS
    expected = outcome(local, sql)
    before = parses()
    assert outcome(isolated, sql) == expected
    assert parses() == before, "the serving process parsed the large statement"


def test_a_small_statement_is_still_planned_here(engines):
    """The worker's round trip is only worth it for large texts: a small one is parsed in this process."""
    _, isolated = engines
    before = parses()
    assert outcome(isolated, "SELECT count(*) FROM lake.main.metadata WHERE job_id <> 'small-statement'")[0] == "rows"
    assert parses()[0] > before[0]
