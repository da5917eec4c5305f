"""The query worker pool (gateway/engine/worker_pool.py) over the server tests' lake, with real
worker processes and real queries: what a worker keeps after its query (DuckDB's allocator holds on
to freed memory) is counted against the memory limit instead of ending the worker, and an idle
worker is retired only when that count, with the running queries' growth, passes the limit."""

from __future__ import annotations

import time

import pytest

from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.query_worker import send
from lakegate.gateway.engine.worker_pool import WorkerPool, WorkerProcess

#: Distinct rows of numbers and their text: DuckDB keeps about 100 MB after it (a million rows).
HEAVY = (
    "SELECT count(*) FROM (SELECT DISTINCT a * 10000 + b AS k, CAST(a * 10000 + b AS VARCHAR) AS s "
    "FROM UNNEST(sequence(1, 100)) AS t(a) CROSS JOIN UNNEST(sequence(1, 10000)) AS u(b))"
)
#: The same over 300,000 rows: a fresh worker grows about 25 MB.
LIGHT = HEAVY.replace("sequence(1, 100)", "sequence(1, 30)")
#: What the pool retired before: a worker that kept more than this after its query.
OLD_RETIRE_BYTES = 64 << 20


@pytest.fixture
def pool(server_lake):
    pool = WorkerPool(server_lake, memory_limit="1GB", threads=1, limits=Limits(), size=2, warm=0, keep=2)
    assert pool.wait_ready(60)
    yield pool
    pool.close()


def run(worker: WorkerProcess, sql: str) -> tuple:
    """The worker's answer to one query (a count: its only batch comes with the answer)."""
    send(worker.connection, ("execute", sql, "main", None, (), "UTC", None, ()))
    return worker.connection.recv()


def test_a_worker_that_keeps_memory_after_its_query_answers_the_next_one(pool):
    worker = pool.take(time.monotonic() + 60)
    assert run(worker, HEAVY)[:2] == ("started", [("_col0", "bigint")])
    pool.give_back(worker, healthy=True)
    assert worker.kept > OLD_RETIRE_BYTES and worker in pool._idle
    again = pool.take(time.monotonic() + 60)
    assert again is worker and run(again, HEAVY)[0] == "started"
    pool.give_back(again, healthy=True)
    assert again.process.is_alive()


def test_an_idle_workers_kept_memory_is_retired_before_a_query_fails(pool):
    first, second = pool.take(time.monotonic() + 60), pool.take(time.monotonic() + 60)
    assert run(first, HEAVY)[0] == "started"
    pool.give_back(first, healthy=True)
    assert first in pool._idle
    pool.limit_bytes = first.kept + (8 << 20)  # a limit the idle worker's kept memory nearly fills
    answer = run(second, LIGHT)  # grows the second worker past the room left
    assert answer[0] == "started", answer
    pool.give_back(second, healthy=True)
    first.process.join(10)
    assert first.process.exitcode is not None and first not in pool._idle
    assert second in pool._idle and second.process.is_alive()
    assert sum(worker.kept for worker in pool._idle) <= pool.limit_bytes
