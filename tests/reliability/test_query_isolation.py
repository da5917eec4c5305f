"""Queries run in worker processes (gateway/engine/isolated_backend.py), against one real `lakegate
serve --memory-limit 512MB --query-timeout 3` each (10 s for the memory bombs): a query that builds
lists or strings without bound fails with Trino's EXCEEDED_*_MEMORY_LIMIT (or its time limit) while
the memory the server's processes hold together stays under the limit plus the documented margin; a
query that never returns to DuckDB (a Python function over 2,048 one-megabyte values in one call)
frees its slot at its time limit; a bomb over a system table runs in a worker as well (the
server's own process stays small); 20 nested lambdas are bounded the same way; and `SELECT 1` answers
at once after each. The same holds for `lakegate query`. Pages of wide rows are bounded by bytes.
Bounded: each statement ends within its time limit plus a second.
"""

from __future__ import annotations

import json
import signal
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor

import pytest
import requests

from tests.gateway.conftest import CLI
from tests.reliability.conftest import (
    HEADERS,
    MEMORY_LIMIT_MB,
    QUERY_TIMEOUT,
    RSS_MARGIN_MB,
    MemoryWatch,
    outcome,
    peak_of,
    select_one_seconds,
    start_server,
)

MEMORY = {"EXCEEDED_LOCAL_MEMORY_LIMIT", "EXCEEDED_GLOBAL_MEMORY_LIMIT"}
#: Seconds within which `SELECT 1` answers after a killed query: a warm worker is ready, or its
#: replacement starts (about 0.3 s on an idle machine; several times that on a shared, loaded one).
AT_ONCE = 2
BOUNDED = MEMORY | {"EXCEEDED_TIME_LIMIT"}
#: 10^8 list elements (about 800 MB): only a memory limit stops it within the time limit.
LIST_BOMB = "SELECT cardinality(flatten(transform(sequence(1, 10000), x -> sequence(1, 10000))))"
#: Strings built from the lake's own rows (metadata has a few jobs, odom_linear_velocity many samples).
STRING_BOMBS = [
    "SELECT length(array_join(array_agg(rpad(job_id, 1000000, 'x')), ',')) "
    "FROM metadata CROSS JOIN UNNEST(sequence(1, 2000)) AS t(i)",
    "SELECT sum(length(replace(rpad(job_id, 1000000, 'x'), 'x', rpad('y', 2000, 'y')))) FROM metadata",
    "SELECT sum(length(regexp_replace(rpad(job_id, 1000000, 'x'), 'x', '" + "y" * 2000 + "'))) FROM metadata",
    "SELECT length(reduce(array_agg(rpad(job_id, 100000, 'x')), '', (s, x) -> s || x || s, s -> s)) "
    "FROM odom_linear_velocity",
    "SELECT length(concat(array_join(array_agg(rpad(job_id, 1000000, 'x')), ''), "
    "array_join(array_agg(rpad(job_id, 1000000, 'y')), ''))) FROM odom_linear_velocity "
    "CROSS JOIN UNNEST(sequence(1, 200)) AS t(i)",
]
#: The list bomb over a system table: it runs in a query worker too, not in the server's own process.
SYSTEM_TABLE_BOMB = f"{LIST_BOMB} FROM information_schema.schemata"
#: MB the server's own process may reach at its peak (its workers aside): about 200 MB idle, and a
#: bomb run in it would add 800 MB or more.
SERVER_OWN_MB = 400
#: One call of a Python function (SpookyHash) per row over a whole DuckDB chunk: minutes in one call.
UNINTERRUPTIBLE = (
    "SELECT max(to_hex(spooky_hash_v2_64(to_utf8(rpad(CAST(x AS varchar), 1000000, 'x'))))) "
    "FROM UNNEST(sequence(1, 2048)) AS t(x)"
)
#: 10^10 elements: past `lakegate query`'s default memory limit (2GB) long before its time limit.
HUGE_LIST_BOMB = (
    "SELECT cardinality(flatten(transform(sequence(1, 100), "
    "y -> flatten(transform(sequence(1, 10000), x -> sequence(1, 10000))))))"
)
NESTED_LAMBDAS = "SELECT " + "transform(ARRAY[1], x -> " * 20 + "x" + ")" * 20


@pytest.fixture
def small_server(tmp_path):
    """A server that runs at most two queries at once."""
    yield from start_server(tmp_path, "--max-concurrent-queries", "2")


@pytest.fixture
def memory_server(tmp_path):
    """A server with time enough for a runaway allocation to reach the memory limit on a busy machine."""
    yield from start_server(tmp_path, "--query-timeout", "10")


def test_memory_bombs_fail_and_the_server_stays_under_its_limit(memory_server):
    process, url, lake = memory_server
    assert outcome(url, b"SELECT 1", lake) == "FINISHED"
    with MemoryWatch(process.pid) as memory:
        assert outcome(url, LIST_BOMB.encode(), lake) in MEMORY
        assert select_one_seconds(url, lake) < AT_ONCE
        for bomb in [*STRING_BOMBS, SYSTEM_TABLE_BOMB]:
            assert outcome(url, bomb.encode(), lake) in BOUNDED, bomb
            assert select_one_seconds(url, lake) < AT_ONCE
        with ThreadPoolExecutor(3) as pool:  # two at once, and an EXPLAIN ANALYZE of one
            names = list(
                pool.map(
                    lambda sql: outcome(url, sql.encode(), lake),
                    [LIST_BOMB, STRING_BOMBS[0], f"EXPLAIN ANALYZE {STRING_BOMBS[0]}"],
                )
            )
        assert set(names) <= BOUNDED, names
        assert select_one_seconds(url, lake) < AT_ONCE
    own = peak_of(process.pid)
    print(f"peak memory of the server's processes: {memory.peak:.0f} MB; of its own: {own:.0f} MB")  # docs
    assert memory.peak < MEMORY_LIMIT_MB + RSS_MARGIN_MB
    assert own < SERVER_OWN_MB  # every query ran in a worker
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=5) == 0


def test_a_query_that_never_returns_to_duckdb_frees_its_slot(small_server):
    process, url, lake = small_server
    started = time.monotonic()
    with ThreadPoolExecutor(4) as pool:  # four clients, each its own user
        names = list(pool.map(lambda n: outcome(url, UNINTERRUPTIBLE.encode(), lake, f"client{n}"), range(4)))
    assert names == ["EXCEEDED_TIME_LIMIT"] * 4
    # two slots, four queries of the time limit each, a second of grace per query: no slot outlives its query
    assert time.monotonic() - started < 2 * (QUERY_TIMEOUT + 2)
    with ThreadPoolExecutor(4) as pool:
        assert max(pool.map(lambda n: select_one_seconds(url, lake, f"client{n}"), range(4))) < AT_ONCE


def test_nested_lambdas_are_bounded(small_server):
    process, url, lake = small_server
    with MemoryWatch(process.pid) as memory, ThreadPoolExecutor(4) as pool:
        names = list(pool.map(lambda n: outcome(url, NESTED_LAMBDAS.encode(), lake, f"client{n}"), range(4)))
    assert set(names) <= BOUNDED | {"FINISHED"}, names
    assert select_one_seconds(url, lake) < AT_ONCE
    print(f"peak memory of the server's processes: {memory.peak:.0f} MB")  # shown with -s: docs/sql-endpoint.md
    assert memory.peak < MEMORY_LIMIT_MB + RSS_MARGIN_MB


def test_lakegate_query_holds_the_same_limits(tmp_path):
    from tests.gateway.conftest import build_server_lake

    lake = build_server_lake(tmp_path)
    done = subprocess.run(
        [*CLI, "query", "--lake", str(lake), HUGE_LIST_BOMB], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 1 and done.stdout == ""
    assert len(done.stderr.splitlines()) == 1 and "Query exceeded" in done.stderr, done.stderr


@pytest.fixture
def patient_server(tmp_path):
    """A server whose time limit leaves a client time to read 30 MB of pages."""
    yield from start_server(tmp_path, "--query-timeout", "60")


def test_wide_rows_come_in_pages_of_about_a_megabyte(patient_server):
    """Pages are bounded by bytes, as Trino's target result size bounds them, not only by rows."""
    process, url, lake = patient_server
    sql = b"SELECT x, rpad(CAST(x AS varchar), 1000000, 'x') AS wide FROM UNNEST(sequence(1, 30)) AS t(x)"
    response = requests.post(f"{url}/v1/statement", data=sql, headers=HEADERS, timeout=60).json()
    sizes, rows = [], 0
    while "nextUri" in response:
        body = requests.get(response["nextUri"], timeout=60).content
        response = json.loads(body)
        if "data" in response:
            sizes.append(len(body))
            rows += len(response["data"])
    assert response["stats"]["state"] == "FINISHED" and rows == 30, response.get("error")
    assert max(sizes) < 2_200_000, sizes  # one or two rows of 1 MB a page, never all 30 in one
