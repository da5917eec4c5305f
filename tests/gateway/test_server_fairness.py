"""Fair to every client, on real `lakegate serve` processes with 2 query slots: one user runs at most
`--max-queries-per-user` queries at once (by default all slots but one), so another user's SELECT 1
runs at once while the first user's queries wait QUEUED (the user is X-Trino-User; with --users the
authenticated one, tests/gateway/test_server_security.py); queued queries of a client that stopped
polling are dropped without running, the queue holds a bounded amount of statement text, and a
client that stops reading a large result frees its slot once its heartbeat lapses.

Trino semantics (trino.io/docs/current/admin/resource-groups.html): a query that a resource group
(here a per-user `${USER}` subgroup with a hardConcurrencyLimit) cannot run yet becomes queued, not
failed; the real Trino shows a queued query as `stats.state` QUEUED with `stats.queued` true.
"""

from __future__ import annotations

import threading
import time

import pytest
import requests

BIG = "SELECT a.x, b.y, 'padding padding padding padding' AS p FROM UNNEST(sequence(1, 10000)) AS a(x) " \
    "CROSS JOIN UNNEST(sequence(1, 1000)) AS b(y)"  # fmt: skip


@pytest.fixture(scope="module")
def two_slots(start_server):
    """Two slots, one query per user at once (the default: all slots but one)."""
    return start_server("--max-concurrent-queries", "2", "--query-timeout", "60", "--heartbeat-timeout", "2")


def post(server, sql: str, user: str | None, auth: tuple[str, str] | None = None) -> dict:
    headers = {} if user is None else {"X-Trino-User": user}
    return requests.post(f"{server.url}/v1/statement", data=sql, headers=headers, auth=auth, timeout=30).json()


def info(server, query_id: str, auth: tuple[str, str] | None = None) -> dict:
    return requests.get(f"{server.url}/v1/query/{query_id}", auth=auth, timeout=30).json()


def wait_for(condition, timeout: float = 30) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.1)


def keep_polling(documents: list[dict], auth: tuple[str, str] | None = None) -> tuple[threading.Event, dict]:
    """Poll each query's nextUri in a thread of its own until the event is set (a client still there:
    its queued queries must not be dropped); returns the event and the last document seen of each."""
    stop, seen = threading.Event(), {}

    def poll(document: dict) -> None:
        while "nextUri" in document and not stop.is_set():
            seen[document["id"]] = document = requests.get(document["nextUri"], auth=auth, timeout=30).json()

    for document in documents:
        threading.Thread(target=poll, args=(document,), daemon=True).start()
    return stop, seen


def run(server, sql: str, user: str | None, auth: tuple[str, str] | None = None) -> dict:
    document = post(server, sql, user, auth)
    while "nextUri" in document:
        document = requests.get(document["nextUri"], auth=auth, timeout=30).json()
    return document


def states(server, documents: list[dict], auth: tuple[str, str] | None = None) -> list[str]:
    return sorted(info(server, d["id"], auth)["state"] for d in documents)


def test_a_user_at_the_cap_waits_queued_while_another_users_select_runs_at_once(two_slots, endless):
    flood = [post(two_slots, endless, "alice") for _ in range(4)]  # queries that run until canceled
    stop, seen = keep_polling(flood)
    try:
        # alone on the server, alice still runs one query: the cap holds whoever else is there
        wait_for(lambda: states(two_slots, flood) == ["QUEUED", "QUEUED", "QUEUED", "RUNNING"])
        wait_for(lambda: len(seen) == 4)
        queued = [seen[d["id"]] for d in flood if info(two_slots, d["id"])["state"] == "QUEUED"]
        # what her client sees of a query held back by the cap is what Trino shows of a queued query
        assert {(d["stats"]["state"], d["stats"]["queued"]) for d in queued} == {("QUEUED", True)}
        assert run(two_slots, "SELECT 1", "bob")["data"] == [[1]]
        # bob's query ran in the slot kept free: alice's query still runs, hers still wait
        assert states(two_slots, flood) == ["QUEUED", "QUEUED", "QUEUED", "RUNNING"]
    finally:
        stop.set()
        for d in flood:
            requests.delete(f"{two_slots.url}/v1/query/{d['id']}", timeout=30)


@pytest.fixture(scope="module")
def patient_slots(start_server):
    """Two slots whose queries may run a minute (an endless query holds its slot for the whole test),
    both of which one user may fill, and bodies of at most 100 KB (the queue holds 32 of them)."""
    return start_server(
        "--max-concurrent-queries", "2", "--max-queries-per-user", "2", "--query-timeout", "60", "--max-body", "100000"
    )  # fmt: skip


def test_queued_queries_of_a_vanished_client_are_dropped_without_running(patient_slots, endless):
    two_slots = patient_slots
    vanished = [post(two_slots, endless, "carol") for _ in range(6)]  # never polled again
    queued = [d for d in vanished if info(two_slots, d["id"])["state"] == "QUEUED"]
    assert len(queued) >= 3
    wait_for(lambda: all(info(two_slots, d["id"])["state"] == "FAILED" for d in queued), timeout=15)
    for d in queued:
        error = info(two_slots, d["id"])["error"]
        assert error["errorName"] == "ABANDONED_QUERY" and "stopped polling while queued" in error["message"]
    for d in vanished:
        requests.delete(f"{two_slots.url}/v1/query/{d['id']}", timeout=30)


def test_a_freed_slot_goes_to_the_user_with_the_fewest_running_queries(patient_slots, endless):
    """alice fills both slots (her cap here: a result of 5 MB that waits for her to read it, and an
    endless query) and has two more queued before bob's; when she has read the result, its slot goes
    to bob's query, not to her older queued ones (else bob would wait a minute)."""
    wide = post(patient_slots, "SELECT rpad('x', 1000, 'y') FROM UNNEST(sequence(1, 5000)) AS t(i)", "alice")
    alice = [post(patient_slots, endless, "alice") for _ in range(3)]
    stop, _ = keep_polling(alice)
    try:
        wait_for(lambda: states(patient_slots, [wide, *alice]) == ["QUEUED", "QUEUED", "RUNNING", "RUNNING"])
        bob = post(patient_slots, "SELECT 1", "bob")
        assert info(patient_slots, bob["id"])["state"] == "QUEUED"
        while "nextUri" in wide:  # alice reads her result: its query ends and frees its slot
            wide = requests.get(wide["nextUri"], timeout=30).json()
        assert "error" not in wide, wide
        deadline = time.monotonic() + 20  # far less than the minute alice's query would hold the other slot
        while "nextUri" in bob:
            assert time.monotonic() < deadline, "bob's query waited behind alice's queue"
            bob = requests.get(bob["nextUri"], timeout=30).json()
        assert bob["data"] == [[1]]
    finally:
        stop.set()
        for d in alice:
            requests.delete(f"{patient_slots.url}/v1/query/{d['id']}", timeout=30)


def test_the_queue_holds_a_bounded_amount_of_statement_text(patient_slots, endless):
    """Queued statements of the largest size a body may have (polled, so none is dropped): the 33rd
    finds the queue's 32 bodies' worth of text taken and fails with QUERY_QUEUE_FULL at once; the queue
    takes more once they left."""
    from lakegate.gateway.server.query_lifecycle import QUEUED_BODIES

    running = [post(patient_slots, endless, "frank") for _ in range(2)]  # both slots busy: the rest queue
    large = "SELECT 1 -- " + "x" * 98_988  # 99,000 characters (--max-body 100,000)
    stop = threading.Event()
    queued: list[dict] = []

    def poll(document: dict) -> None:
        while "nextUri" in document and not stop.is_set():
            document = requests.get(document["nextUri"], timeout=30).json()

    pollers = []
    try:
        for _ in range(QUEUED_BODIES):
            queued.append(post(patient_slots, large, "frank"))
            pollers.append(threading.Thread(target=poll, args=(queued[-1],)))
            pollers[-1].start()
        assert all(info(patient_slots, d["id"])["state"] == "QUEUED" for d in queued)
        refused = post(patient_slots, large, "frank")
        assert refused["error"]["errorName"] == "QUERY_QUEUE_FULL", refused
        assert "the statements waiting hold 3,168,000 characters of text" in refused["error"]["message"]
        small = post(patient_slots, "SELECT 2", "frank")  # a small statement still finds room
        assert info(patient_slots, small["id"])["state"] in ("QUEUED", "RUNNING", "FINISHED")
    finally:
        stop.set()
        for d in [*running, *queued]:
            requests.delete(f"{patient_slots.url}/v1/query/{d['id']}", timeout=30)
        for poller in pollers:
            poller.join(timeout=30)
    queued_again = post(patient_slots, large, "frank")  # the canceled statements left the queue
    assert "error" not in queued_again, queued_again
    requests.delete(f"{patient_slots.url}/v1/query/{queued_again['id']}", timeout=30)


def test_a_client_that_stops_reading_frees_its_slot_when_its_heartbeat_lapses(two_slots):
    document = post(two_slots, BIG, "dave")
    while "data" not in document:  # read up to the first page, then go away
        document = requests.get(document["nextUri"], timeout=30).json()
    query_id = document["id"]
    wait_for(lambda: info(two_slots, query_id)["state"] == "FAILED", timeout=20)
    error = info(two_slots, query_id)["error"]
    assert error["errorName"] == "ABANDONED_QUERY" and "stopped reading results for 2s" in error["message"]


def test_large_statement_texts_take_only_a_share_of_the_slots(start_server, monkeypatch):
    """With 4 slots, at most one statement over 64 KiB is in the workers at once (its planning is
    stuck here, SLOW_PLANNING_ENV): the other large ones wait while a small query runs at once."""
    from lakegate.gateway.server.query_lifecycle import SLOW_PLANNING_ENV

    monkeypatch.setenv(SLOW_PLANNING_ENV, "large_text_marker")
    server = start_server("--max-concurrent-queries", "4")
    large = f"SELECT '{'x' * 70_000}' AS large_text_marker"
    stop = threading.Event()
    documents = []

    def client(user: str) -> None:  # posts a large statement and keeps polling it
        document = post(server, large, user)
        documents.append(document)
        while "nextUri" in document and not stop.is_set():
            document = requests.get(document["nextUri"], timeout=30).json()

    clients = [threading.Thread(target=client, args=(f"user{i}",)) for i in range(3)]
    for thread in clients:
        thread.start()
    try:
        wait_for(lambda: len(documents) == 3)
        time.sleep(1.0)
        states = sorted(info(server, d["id"])["state"] for d in documents)
        assert states == ["QUEUED", "QUEUED", "RUNNING"], states
        small = post(server, "SELECT 1", "erin")
        while "nextUri" in small:
            small = requests.get(small["nextUri"], timeout=30).json()
        assert small["data"] == [[1]]
    finally:
        stop.set()
        for d in documents:
            requests.delete(f"{server.url}/v1/query/{d['id']}", timeout=30)
        for thread in clients:
            thread.join(timeout=30)


def test_the_dashboard_leaves_another_users_client_a_slot(start_server, endless):
    """The dashboard's queries hold their user's share of the slots too: two endless ad hoc queries
    of the dashboard (one user) take one of the two slots, and a client's SELECT 1 runs in the other
    while both still wait for their answers."""
    server = start_server("--max-concurrent-queries", "2", "--query-timeout", "30")
    api = f"{server.url}/dashboard/api/sessions"
    session = requests.post(api, json={"branch": "main", "batch": "b1"}, timeout=60).json()
    answered: list[float] = []

    def dashboard_query() -> None:
        requests.post(f"{api}/{session['id']}/query", json={"sql": endless, "scope": "batch"}, timeout=60)
        answered.append(time.monotonic())

    for _ in range(2):
        threading.Thread(target=dashboard_query, daemon=True).start()
    time.sleep(3)  # both sent: one runs, the other waits for the dashboard's share
    done: list[dict] = []
    select = threading.Thread(target=lambda: done.append(run(server, "SELECT 1", "bob")))
    select.start()
    select.join(timeout=25)  # before either endless query reaches its time limit (30 s)
    assert [d.get("data") for d in done] == [[[1]]] and answered == []
