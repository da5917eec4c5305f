"""How `lakegate serve` runs queries under its limits, against real `lakegate serve` processes: the
time limit stops Python planning and DuckDB work (EXPLAIN ANALYZE included) and frees the worker,
the dashboard's queries go through the same limits, a client that stops polling abandons its query,
and SIGTERM stops the server within 5 s whatever its queries do.

Trino semantics followed (trinodb/trino): `docs/src/main/sphinx/admin/properties-query-management.rst`
(`query.max-execution-time` fails a query with EXCEEDED_TIME_LIMIT; `query.client.timeout`: a query
whose client stops fetching results is cancelled, ABANDONED_QUERY, by `QueryTracker`), and
`docs/src/main/sphinx/sql/explain-analyze.rst` (EXPLAIN ANALYZE executes the query).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import requests
import trino

from tests.gateway.conftest import ENDLESS, Server, serve

HEADERS = {"X-Trino-User": "tester", "X-Trino-Catalog": "lake", "X-Trino-Schema": "main"}
#: SQL that sqlglot takes minutes to parse today (exponential in the nesting depth).
#: A query whose planning runs away: the server spends 60 s of pure-Python work planning it when
#: started with LAKEGATE_TEST_SLOW_PLANNING set to its marker (parsing itself is bounded now).
SLOW_MARKER = "runaway-planning"
NESTED = f"SELECT '{SLOW_MARKER}'"


def run(server: Server, sql: str, within: float = 30, user: str = "tester") -> dict:
    """The last document of one query of `user`, following nextUri; fails if it does not end `within` seconds."""
    deadline = time.monotonic() + within
    headers = {**HEADERS, "X-Trino-User": user}
    document = requests.post(f"{server.url}/v1/statement", data=sql.encode(), headers=headers, timeout=within).json()
    while "nextUri" in document:
        assert time.monotonic() < deadline, f"{sql[:40]!r} did not end within {within}s"
        document = requests.get(document["nextUri"], timeout=within).json()
    return document


def cpu_seconds(pid: int) -> float:
    """User and system CPU time the process used so far (/proc/PID/stat)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def cpu_over_a_second(pid: int) -> float:
    before = cpu_seconds(pid)
    time.sleep(1)
    return cpu_seconds(pid) - before


def stop_within(server: Server, seconds: float = 5) -> int:
    """SIGTERM; the exit code, which must come within `seconds` (the process is killed otherwise)."""
    server.process.send_signal(signal.SIGTERM)
    try:
        return server.process.wait(timeout=seconds)
    except subprocess.TimeoutExpired:
        server.process.kill()
        server.process.wait()
        pytest.fail(f"lakegate serve did not stop within {seconds}s of SIGTERM")


@pytest.fixture
def start(server_lake, tmp_path, monkeypatch):
    """Start `lakegate serve ARGS` on a copy of the test lake (the dashboard may write to it); every
    server still running is killed after the test."""
    lake = tmp_path / "lake"
    shutil.copytree(server_lake, lake)
    monkeypatch.setenv("LAKEGATE_TEST_SLOW_PLANNING", SLOW_MARKER)
    servers: list[Server] = []

    def started(*args: str) -> Server:
        server = serve(lake, tmp_path / f"stderr-{len(servers)}.log", *args)
        servers.append(server)
        return server

    yield started
    for server in servers:
        if server.process.poll() is None:
            server.process.kill()
            server.process.wait()


def test_queries_past_their_time_limit_while_planning_free_their_workers(start):
    server = start("--query-timeout", "1", "--max-concurrent-queries", "2")
    assert run(server, "SELECT 1")["data"] == [[1]]  # warm: what follows measures the server, not its start
    with ThreadPoolExecutor(4) as pool:  # four clients, each its own user: two run at once
        documents = list(pool.map(lambda n: run(server, NESTED, user=f"client{n}"), range(4)))
    assert [d["error"]["errorName"] for d in documents] == ["EXCEEDED_TIME_LIMIT"] * 4
    started = time.monotonic()
    assert run(server, "SELECT 1", within=5)["data"] == [[1]]
    assert time.monotonic() - started < 1
    assert cpu_over_a_second(server.process.pid) < 0.3  # the parsing was abandoned, not left running
    assert stop_within(server) == 0


def test_sigterm_stops_the_server_while_workers_plan(start):
    server = start("--max-concurrent-queries", "2")
    posted = [  # four clients, each its own user: two run at once
        requests.post(
            f"{server.url}/v1/statement", data=NESTED, headers={**HEADERS, "X-Trino-User": f"client{n}"}, timeout=30
        ).json()
        for n in range(4)
    ]
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and requests.get(posted[1]["infoUri"], timeout=30).json()["state"] != "RUNNING":
        time.sleep(0.05)
    assert stop_within(server) == 0
    assert "Traceback" not in server.log.read_text()


def test_explain_analyze_stops_at_the_time_limit(start):
    server = start("--query-timeout", "2")
    started = time.monotonic()
    error = run(server, f"EXPLAIN ANALYZE {ENDLESS}")["error"]
    assert (error["errorName"], error["message"]) == (
        "EXCEEDED_TIME_LIMIT",
        "Query exceeded the maximum execution time limit of 2.00s",
    )
    assert time.monotonic() - started < 10
    assert cpu_over_a_second(server.process.pid) < 0.3  # DuckDB was interrupted
    assert stop_within(server) == 0


def test_explain_analyze_stops_when_canceled(start):
    server = start()
    first = requests.post(
        f"{server.url}/v1/statement", data=f"EXPLAIN ANALYZE {ENDLESS}", headers=HEADERS, timeout=30
    ).json()
    document = requests.get(first["nextUri"], timeout=30).json()
    assert document["stats"]["state"] == "RUNNING"
    assert requests.delete(document["nextUri"], timeout=30).status_code == 204
    assert requests.get(first["infoUri"], timeout=30).json()["error"]["errorName"] == "USER_CANCELED"
    time.sleep(0.5)
    assert cpu_over_a_second(server.process.pid) < 0.3
    assert stop_within(server) == 0


def test_dashboard_queries_and_metrics_run_under_the_servers_limits(start):
    server = start("--query-timeout", "3")
    api = f"{server.url}/dashboard/api"
    session = requests.post(f"{api}/sessions", json={"branch": "main", "batch": "b1"}, timeout=60).json()
    assert "id" in session, session
    started = time.monotonic()
    answer = requests.post(
        f"{api}/sessions/{session['id']}/query", json={"sql": ENDLESS, "scope": "batch"}, timeout=60
    ).json()
    assert answer["error"]["name"] == "EXCEEDED_TIME_LIMIT" and "3.00s" in answer["error"]["message"]
    assert time.monotonic() - started < 10
    assert cpu_over_a_second(server.process.pid) < 0.3
    state = requests.post(
        f"{api}/sessions/{session['id']}/metrics",
        timeout=60,
        json={"name": "Endless", "type": "batch", "template": "scalar", "description": "", "query_string": ENDLESS},
    ).json()
    endless = next(m for m in state["metrics"] if m["name"] == "Endless")["result"]
    assert endless["status"] == "ERROR" and "time limit" in endless["error"]["message"]
    assert cpu_over_a_second(server.process.pid) < 0.3
    running = ThreadPoolExecutor(1)  # a dashboard query still running when SIGTERM comes
    running.submit(
        requests.post, f"{api}/sessions/{session['id']}/query", json={"sql": ENDLESS, "scope": "batch"}, timeout=60
    )
    time.sleep(0.5)
    assert stop_within(server) == 0
    running.shutdown(wait=True)
    assert "Traceback" not in server.log.read_text()


def test_a_client_that_stops_polling_abandons_its_query(start):
    server = start(
        "--client-timeout", "4", "--max-concurrent-queries", "1"
    )  # 4 s: a loaded machine still polls in time
    connection = trino.dbapi.connect(host=server.host, port=server.port, user="tester", catalog="lake", schema="main")
    cursor = connection.cursor()
    cursor.execute("SELECT x, y FROM UNNEST(sequence(1, 2000)) AS a(x) CROSS JOIN UNNEST(sequence(1, 1000)) AS b(y)")
    assert len(cursor.fetchmany(5000)) == 5000  # two pages at least, then the client goes quiet
    query_id = cursor.query_id
    started = time.monotonic()  # the only worker is held by the abandoned query until it fails
    rows = trino.dbapi.connect(
        host=server.host, port=server.port, user="tester", catalog="system", schema="runtime"
    ).cursor()
    rows.execute(f"SELECT state, error_code FROM queries WHERE query_id = '{query_id}'")
    assert rows.fetchall() == [["FAILED", "ABANDONED_QUERY"]]
    assert time.monotonic() - started < 12  # the client timeout, plus a loaded machine's slack
    assert stop_within(server) == 0


def test_a_new_empty_lake_serves_at_once_and_quietly(tmp_path):
    """A lake with no branch yet: the query workers have nothing to warm (they used to fail warming
    branch 'main', printing tracebacks and being replaced until the start-up gave up waiting)."""
    lake = tmp_path / "lake"
    lake.mkdir()
    server = serve(lake, tmp_path / "stderr.log", timeout=30)
    try:
        assert run(server, "SELECT 1")["data"] == [[1]]
        assert "Schema 'main' does not exist" in run(server, "SELECT * FROM topic")["error"]["message"]
    finally:
        assert server.stop() == 0
    assert "Traceback" not in server.log.read_text()
