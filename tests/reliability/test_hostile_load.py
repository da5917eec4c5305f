"""Hostile load against one real `lakegate serve` with small limits: the two
out-of-memory queries, 8 nested-ARRAY queries that take the parser minutes, an EXPLAIN ANALYZE of a
cross-join bomb, two 50 MB bodies and 8 statements of almost 1 MB (the most a body may hold), all at
once; after that `SELECT 1` answers in under a second,
the memory the server's processes (the server and its query workers) held together stayed under its
memory limit plus the documented margin (docs/sql-endpoint.md), and SIGTERM stops it within 5 s.

The server runs under a hard address-space cap (RLIMIT_AS), so that a limit that fails can never
take the test machine's memory. Bounded: 21 requests, each ending within the query time limit.

Trino semantics (trinodb/trino): `repeat(element, count)` refuses a count above 10,000
(`core/trino-main/src/main/java/io/trino/operator/scalar/RepeatFunction.java`); a query longer than
`query.max-length` fails with QUERY_TEXT_TOO_LARGE and one past `query.max-execution-time` with
EXCEEDED_TIME_LIMIT (`docs/src/main/sphinx/admin/properties-query-management.rst`).
"""

from __future__ import annotations

import signal
import time
from concurrent.futures import ThreadPoolExecutor

import requests

from tests.gateway.conftest import ENDLESS
from tests.reliability.conftest import HEADERS, MEMORY_LIMIT_MB, RSS_MARGIN_MB, MemoryWatch, outcome

#: Nested ARRAY[ that once took sqlglot exponential time: answered at depth 22 now, refused past 32
#: (Trino's "statement is too large" SYNTAX_ERROR).
NESTED = "SELECT " + "ARRAY[" * 22 + "1" + "]" * 22
TOO_DEEP = "SELECT " + "ARRAY[" * 40 + "1" + "]" * 40
BODY = b"SELECT 1 -- " + b"x" * 50_000_000
#: A statement of 976 KB the server accepts and answers: a count with an IN list of 8,000 job ids.
LARGE = ("SELECT count(*) FROM odom_linear_velocity WHERE job_id IN (" + ", ".join(
    f"'{i:0118d}'" for i in range(8000)) + ")").encode()  # fmt: skip
#: (request body, the Trino error names that refuse it clearly)
HOSTILE = [
    *[(NESTED.encode(), {"FINISHED", "EXCEEDED_TIME_LIMIT"})] * 4,
    *[(TOO_DEEP.encode(), {"SYNTAX_ERROR"})] * 4,
    (f"EXPLAIN ANALYZE {ENDLESS}".encode(), {"EXCEEDED_TIME_LIMIT"}),
    (b"SELECT cardinality(repeat(1, 1000000000))", {"INVALID_FUNCTION_ARGUMENT", "EXCEEDED_GLOBAL_MEMORY_LIMIT"}),
    (b"SELECT repeat('x', 1000000000)", {"INVALID_FUNCTION_ARGUMENT", "EXCEEDED_GLOBAL_MEMORY_LIMIT"}),
    (BODY, {"QUERY_TEXT_TOO_LARGE"}),
    (BODY.replace(b"-- ", b", '", 1) + b"'", {"QUERY_TEXT_TOO_LARGE"}),
    *[(LARGE, {"FINISHED", "EXCEEDED_TIME_LIMIT"})] * 8,
]


def test_hostile_load_leaves_the_server_healthy(server):
    process, url, lake = server
    assert outcome(url, b"SELECT 1", lake) == "FINISHED"  # warm: what follows measures the load, not the start
    with MemoryWatch(process.pid) as memory, ThreadPoolExecutor(len(HOSTILE)) as pool:
        # each hostile client its own user: together they may take every slot
        names = list(pool.map(lambda n: outcome(url, HOSTILE[n][0], lake, f"client{n}"), range(len(HOSTILE))))
    assert [name in expected for name, (_, expected) in zip(names, HOSTILE)] == [True] * len(HOSTILE), str(
        list(zip(names, [body[:40] for body, _ in HOSTILE]))
    )

    started = time.monotonic()
    document = requests.post(f"{url}/v1/statement", data=b"SELECT 1", headers=HEADERS, timeout=5).json()
    while "nextUri" in document:
        document = requests.get(document["nextUri"], timeout=5).json()
    assert document.get("data") == [[1]]
    assert time.monotonic() - started < 1
    print(f"peak memory of the server's processes: {memory.peak:.0f} MB")  # shown with -s: docs/sql-endpoint.md
    assert memory.peak < MEMORY_LIMIT_MB + RSS_MARGIN_MB

    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=5) == 0
