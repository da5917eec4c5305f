"""The dialect's limits through a real `lakegate serve` on 127.0.0.1 and the official `trino`
client: functions sized by an argument are refused before the server allocates (Trino's
INVALID_FUNCTION_ARGUMENT; trinodb/trino core/trino-main/src/main/java/io/trino/operator/scalar/
RepeatFunction.java, SequenceFunction.java, StringFunctions.java), deep nesting is refused at once
(SqlParser.java's "statement is too large"), DuckDB-only syntax is a SYNTAX_ERROR (SqlBase.g4), and the
server keeps answering."""

from __future__ import annotations

from pathlib import Path

import pytest
import trino

#: Growth of the server's peak memory allowed while it refuses the queries below; each needs at
#: least 400 MB if its size check came after the allocation (sizes chosen so that even then the
#: test stays under about 1 GB).
PEAK_GROWTH_MB = 250


def _peak_mb(pid: int) -> float:
    """The process's peak resident memory (VmHWM), in MB."""
    status = Path(f"/proc/{pid}/status").read_text()
    return int(next(line for line in status.splitlines() if line.startswith("VmHWM:")).split()[1]) / 1024


def _error(server, sql: str) -> trino.exceptions.TrinoUserError:
    with trino.dbapi.connect(
        host=server.host, port=server.port, user="tester", catalog="lake", schema="main"
    ) as connection:
        with pytest.raises(trino.exceptions.TrinoUserError) as caught:
            connection.cursor().execute(sql).fetchall()
    return caught.value


def _select_1(server) -> list:
    with trino.dbapi.connect(
        host=server.host, port=server.port, user="tester", catalog="lake", schema="main"
    ) as connection:
        return connection.cursor().execute("SELECT 1").fetchall()


@pytest.fixture(scope="module")
def small_server(start_server):
    """A server of its own (so its peak memory is this module's), with a small memory limit."""
    return start_server("--memory-limit", "256MB")


@pytest.mark.parametrize(
    "sql, message",
    [
        ("SELECT repeat('x', 50000000)", "count argument of repeat function must be less than or equal to 10000"),
        (
            "SELECT cardinality(repeat(1, 50000000))",
            "count argument of repeat function must be less than or equal to 10000",
        ),
        (
            "SELECT cardinality(sequence(1, 50000000))",
            "result of sequence function must not have more than 10000 entries",
        ),
        ("SELECT length(lpad('x', 400000000, 'y'))", "Target length must be at most 1000000 in lakegate"),
    ],
)
def test_oversized_allocations_are_refused_and_the_server_keeps_answering(small_server, sql, message):
    before = _peak_mb(small_server.process.pid)
    error = _error(small_server, sql)
    assert error.error_name == "INVALID_FUNCTION_ARGUMENT" and message in error.message
    assert _select_1(small_server) == [[1]]
    assert _peak_mb(small_server.process.pid) - before < PEAK_GROWTH_MB


def test_deep_nesting_and_duckdb_syntax_are_syntax_errors(small_server):
    assert _select_1(small_server) == [[1]]
    deep = _error(small_server, "SELECT " + "ARRAY[" * 40 + "1" + "]" * 40)
    assert deep.error_name == "SYNTAX_ERROR" and "statement is too large" in deep.message
    for sql, location in (("SELECT 10 // 3", (1, 12)), ("SELECT 1 LIMIT 10%", (1, 18))):
        error = _error(small_server, sql)
        assert (error.error_name, error.error_location) == ("SYNTAX_ERROR", location)
        assert "mismatched input" in error.message and "<class" not in error.message
    assert _select_1(small_server) == [[1]]


@pytest.mark.parametrize(
    "sql, parameters",
    [
        ("SELECT * FROM ?", ["metadata"]),  # a table is named, never bound
        ("SELECT count(*) FROM metadata POSITIONAL JOIN events", None),  # DuckDB's join: an alias, then JOIN
        ("SELECT count(*) FROM metadata FOR SYSTEM_TIME AS OF now()", None),
    ],
)
def test_statements_trino_refuses_are_refused_in_its_words(lake_server, trino_url, sql, parameters):
    """lakegate serve and the real Trino 476, both through the trino client: the same error name,
    message and position (with a parameter the client sends EXECUTE IMMEDIATE, whose positions Trino
    counts in the outer text and lakegate in the statement: only the message is compared then)."""

    def refusal(host: str, port: int, catalog: str, schema: str) -> tuple:
        with trino.dbapi.connect(host=host, port=port, user="users", catalog=catalog, schema=schema) as connection:
            cursor = connection.cursor()
            with pytest.raises(trino.exceptions.TrinoQueryError) as caught:
                cursor.execute(sql, parameters)
                cursor.fetchall()
        error = caught.value
        if parameters:
            return error.error_name, error.message.split(": ", 1)[1]
        return error.error_name, error.message, error.error_location

    host, port = trino_url.split("//", 1)[1].split(":")
    trino_answer = refusal(host, int(port), "system", "runtime")
    trino_answer = (
        trino_answer
        if trino_answer[0] != "TABLE_NOT_FOUND"
        else pytest.fail(f"Trino analysed past the syntax: {trino_answer}")
    )
    assert refusal(lake_server.host, lake_server.port, "lake", "main") == trino_answer
