"""One statement path: a query's text is checked (encoding, size, nesting), classified (its kind from
the table of statement kinds) and parsed once on its way through the server, `lakegate query` /
`metrics run` (`Engine.execute`, in process or over query worker processes, as the commands run it) and
forwarding (`forwarded_sql`), however many steps hand it on.

The counts come from wrapping the three readers of a text (guard's lexeme scan, the statement-word
table, sqlglot's parser) and counting the calls that see this test's own text (a unique marker)."""

from __future__ import annotations

import itertools
import pickle
from collections import Counter
from types import SimpleNamespace

import pytest
import requests

from lakegate.dialect import guard, statements, translate
from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine import isolated_backend, query_worker
from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.trino_backend import forwarded_sql
from lakegate.gateway.server.app import create_app

from .conftest import served_in_thread

HEADERS = {"X-Trino-User": "tester", "X-Trino-Catalog": "lake", "X-Trino-Schema": "main"}
_serial = itertools.count()


@pytest.fixture(scope="module")
def engine(server_lake):
    engine = Engine(DuckDBBackend(server_lake, memory_limit="512MB", threads=1), owns_backend=True)
    yield engine
    engine.close()


@pytest.fixture(scope="module")
def isolated(server_lake):
    """An engine over query worker processes, as `lakegate query` and `lakegate serve` run one."""
    engine = Engine.open(server_lake, limits=Limits(max_concurrent_queries=1, query_timeout=60), isolated=True)
    yield engine
    engine.close()


@pytest.fixture(scope="module")
def server(engine):
    with served_in_thread(create_app(engine)) as url:
        yield SimpleNamespace(url=url)


@pytest.fixture
def counted(monkeypatch):
    """A fresh query text (a marker no other text has) and the count of each reading of it."""
    marker = f"statement_path_{next(_serial)}_{id(monkeypatch)}"
    counts: Counter = Counter()

    def counting(name, function, seen):
        def wrapper(*args, **kwargs):
            if seen(*args, **kwargs):
                counts[name] += 1
            return function(*args, **kwargs)

        return wrapper

    def has_marker(sql, *_, **__):
        return isinstance(sql, str) and marker in sql

    def whole_statement(sql, offset=0):
        return offset == 0 and has_marker(sql)

    def parser_input(parser, tokens, sql=None, *_, **__):
        return has_marker(sql)

    monkeypatch.setattr(guard, "_check_size", counting("checked", guard._check_size, has_marker))
    monkeypatch.setattr(guard, "statement_kind", counting("classified", guard.statement_kind, whole_statement))
    parse = translate.LakegateTrino.Parser.parse
    monkeypatch.setattr(
        translate.LakegateTrino.Parser,
        "parse",
        lambda self, tokens, sql=None, *a, **k: counting("parsed", parse, parser_input)(self, tokens, sql, *a, **k),
    )
    return SimpleNamespace(sql=f"SELECT 1 AS {marker}", counts=counts)


def _run(server, sql: str) -> list:
    document = requests.post(f"{server.url}/v1/statement", data=sql.encode(), headers=HEADERS, timeout=30).json()
    rows = list(document.get("data", []))
    while "nextUri" in document:
        document = requests.get(document["nextUri"], timeout=30).json()
        rows += document.get("data", [])
    assert "error" not in document, document["error"]
    return rows


def test_a_server_query_is_checked_classified_and_parsed_once(server, counted):
    assert _run(server, counted.sql) == [[1]]
    assert counted.counts == {"checked": 1, "classified": 1, "parsed": 1}


def test_an_explained_server_query_is_checked_classified_and_parsed_once(server, counted):
    assert _run(server, f"EXPLAIN {counted.sql}")
    assert counted.counts == {"checked": 1, "classified": 1, "parsed": 1}


def test_an_engine_query_is_read_once(engine, counted):
    """The path of `lakegate query` and of `metrics run` (both `Engine.execute`)."""
    result = engine.execute(counted.sql, engine.session())
    assert result.rows() == [(1,)]
    assert counted.counts == {"checked": 1, "classified": 1, "parsed": 1}


def test_a_forwarded_query_is_read_once(counted):
    assert forwarded_sql(counted.sql).sql.startswith("SELECT 1")
    assert counted.counts == {"checked": 1, "classified": 1, "parsed": 1}


def test_a_query_that_only_has_text_is_read_once_by_translate(counted):
    assert translate.translate(counted.sql, {}).columns[0][1] == "integer"
    assert counted.counts == {"checked": 1, "classified": 1, "parsed": 1}


def test_a_refused_write_is_refused_from_the_one_reading(server, counted):
    document = requests.post(
        f"{server.url}/v1/statement", data=f"INSERT INTO t {counted.sql}".encode(), headers=HEADERS, timeout=30
    ).json()
    while "nextUri" in document:
        document = requests.get(document["nextUri"], timeout=30).json()
    assert document["error"]["errorName"] == "PERMISSION_DENIED"
    assert "INSERT" in document["error"]["message"]
    assert counted.counts == {"checked": 1, "classified": 1}


@pytest.mark.parametrize("qualified", [False, True], ids=["as-sent", "rewritten"])
def test_a_query_run_by_a_worker_process_is_checked_and_classified_once(
    isolated, counted, monkeypatch, server_lake, qualified
):
    """This process reads the text once; the worker it is sent to (`lakegate query`, `lakegate serve`)
    checks and classifies nothing, and parses the text at most once (a statement the planner rewrote
    arrives with its tree; one sent as it came is parsed there, once per text: unpickling a tree costs
    about what parsing it does, and a worker's parse of a repeated text is cached). Shown by replaying
    the request it was sent, pickled as on the pipe, twice through a worker's own code in this process."""
    sql = f"SELECT count(*) AS {counted.sql.split()[-1]} FROM " + ("lake.main.metadata" if qualified else "metadata")
    sent: list[tuple] = []
    real_send = isolated_backend.send

    def recording(connection, message):
        sent.append(message)
        real_send(connection, message)

    monkeypatch.setattr(isolated_backend, "send", recording)
    rows = isolated.execute(sql, isolated.session(branch="main")).rows()
    assert rows and rows[0][0] > 0
    assert counted.counts == {"checked": 1, "classified": 1, "parsed": 1}
    (request,) = [message for message in sent if message[0] == "execute"]
    statements.parsed.cache_clear()  # a worker process has caches of its own: empty, as this text never reached it
    translate.clear_cache()
    worker = query_worker.Worker(server_lake, "256MB", 1, Limits())
    try:
        for replay in ("first", "again"):
            counted.counts.clear()
            answer = worker.answer(pickle.loads(pickle.dumps(request)))
            worker.drop()
            assert answer[0] == "started", answer
            assert counted.counts == ({"parsed": 1} if replay == "first" and not qualified else {}), replay
    finally:
        worker.backend.close()


@pytest.mark.parametrize(
    "sql",
    [
        "frobnicate everything",  # no statement starts so: SYNTAX_ERROR at the word, decided when read
        "(  frob)",
        "WITH a AS (SELECT 1 AS x) INSERT INTO no_such_table SELECT * FROM a",  # a write behind a query's words
        "SET ROLE admin",
    ],
)
def test_a_statement_is_refused_alike_by_translate_and_the_engine(engine, sql):
    """One reading, one answer: `translate(sql)` (what `metrics validate` runs) and the engine (the
    server, `lakegate query`) refuse a statement that is not a query with the same error."""

    def refusal(run) -> tuple:
        with pytest.raises(DialectError) as caught:
            run()
        error = caught.value
        return error.error_name, error.message, error.line, error.column

    by_engine = refusal(lambda: engine.execute(sql, engine.session(branch="main")))
    assert by_engine == refusal(lambda: translate.translate(sql, {}))
    assert by_engine[0] in ("SYNTAX_ERROR", "PERMISSION_DENIED", "NOT_SUPPORTED")
