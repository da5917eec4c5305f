"""A query worker (gateway/engine/query_worker.py) over the server tests' lake: when DuckDB fails
inside (an INTERNAL or FATAL error, which invalidates its database), the client reads
GENERIC_INTERNAL_ERROR in lakegate's words, never DuckDB's text, and the worker retires."""

from __future__ import annotations

import duckdb
import pytest

from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.query_worker import INTERNAL_FAILURE, Worker

#: Failures as DuckDB raises them: its own exception classes, and its text kept in a refusal.
FAILURES = [
    duckdb.InternalException("INTERNAL Error: Attempted to access index 3 within vector of size 3"),
    duckdb.FatalException("FATAL Error: Failed: database has been invalidated because of a previous fatal error"),
    DialectError("INTERNAL Error: Calling DatabaseManager::GetDefaultDatabase with no default database set"),
]


@pytest.fixture(scope="module")
def worker(server_lake):
    return Worker(server_lake, "1GB", 1, Limits())


def execute(worker: Worker, sql: str) -> tuple:
    return worker.answer(("execute", sql, "main", None, (), "UTC", None, ()))


def test_a_worker_answers_a_query(worker):
    assert execute(worker, "SELECT count(*) FROM metadata")[0] == "started"


@pytest.mark.parametrize("failure", FAILURES, ids=lambda failure: type(failure).__name__)
def test_an_engine_failure_is_told_in_lakegates_words_and_retires_the_worker(worker, failure, monkeypatch):
    def failing(*args, **kwargs):
        raise failure

    monkeypatch.setattr(worker.backend, "execute", failing)
    worker.broken = False
    answer = execute(worker, "SELECT count(*) FROM metadata")
    assert answer == ("error", INTERNAL_FAILURE, None, None, "GENERIC_INTERNAL_ERROR", True)
    assert worker.broken  # its database is no longer trusted: the process ends after this answer
