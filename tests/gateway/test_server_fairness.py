"""Fair to every client, on a real `lakegate serve` with 2 query slots: a free slot goes to the user
with the fewest running queries (one user's flood cannot keep another's SELECT 1 behind it), queued
queries of a client that stopped polling are dropped without running, the queue holds a bounded
amount of statement text, and a client that stops reading a large result frees its slot once its
heartbeat lapses."""

from __future__ import annotations

import threading
import time

import pytest
import requests

BIG = "SELECT a.x, b.y, 'padding padding padding padding' AS p FROM UNNEST(sequence(1, 10000)) AS a(x) " \
    "CROSS JOIN UNNEST(sequence(1, 1000)) AS b(y)"  # fmt: skip


@pytest.fixture(scope="module")
def two_slots(start_server):
    return start_server("--max-concurrent-queries", "2", "--query-timeout", "4", "--heartbeat-timeout", "2")


def post(server, sql: str, user: str) -> dict:
    return requests.post(f"{server.url}/v1/statement", data=sql, headers={"X-Trino-User": user}, timeout=30).json()


def info(server, query_id: str) -> dict:
    return requests.get(f"{server.url}/v1/query/{query_id}", timeout=30).json()


def wait_for(condition, timeout: float = 30) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.1)


def test_one_users_flood_does_not_keep_another_users_query_waiting(two_slots, endless):
    stop = threading.Event()
    flood = [post(two_slots, endless, "alice") for _ in range(8)]  # 2 run (until the time limit), 6 wait

    def keep_polling(document: dict) -> None:  # alice is still there: her queued queries must not be dropped
        while "nextUri" in document and not stop.is_set():
            document = requests.get(document["nextUri"], timeout=30).json()

    pollers = [threading.Thread(target=keep_polling, args=(d,)) for d in flood]
    for poller in pollers:
        poller.start()
    try:
        document = post(two_slots, "SELECT 1", "bob")
        while "nextUri" in document:
            document = requests.get(document["nextUri"], timeout=30).json()
        assert document["data"] == [[1]]
        states = [info(two_slots, d["id"])["state"] for d in flood]
        # bob's query ran in the first slot freed (an alice query past its 4 s limit), ahead of alice's queue
        assert states.count("QUEUED") >= 3, states
    finally:
        stop.set()
        for d in flood:
            requests.delete(f"{two_slots.url}/v1/query/{d['id']}", timeout=30)
        for poller in pollers:
            poller.join(timeout=30)


@pytest.fixture(scope="module")
def patient_slots(start_server):
    """Two slots whose queries may run a minute (an endless query holds its slot for the whole test),
    and bodies of at most 100 KB (the queue holds 32 of them)."""
    return start_server("--max-concurrent-queries", "2", "--query-timeout", "60", "--max-body", "100000")


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


def test_the_queue_holds_a_bounded_amount_of_statement_text(patient_slots, endless):
    """Queued statements of the largest size a body may have (polled, so none is dropped): the 33rd
    finds the queue's 32 bodies' worth of text taken and fails with QUERY_QUEUE_FULL at once; the queue
    takes more once they left."""
    from lakegate.gateway.server.query_lifecycle import QUEUED_BODIES

    running = [post(patient_slots, endless, "frank") for _ in range(2)]  # both slots busy: the rest queue
    large = "SELECT 1 -- " + "x" * 98_988  # 99,000 characters (--max-body 100,000)
    stop = threading.Event()
    queued: list[dict] = []

    def keep_polling(document: dict) -> None:
        while "nextUri" in document and not stop.is_set():
            document = requests.get(document["nextUri"], timeout=30).json()

    pollers = []
    try:
        for _ in range(QUEUED_BODIES):
            queued.append(post(patient_slots, large, "frank"))
            pollers.append(threading.Thread(target=keep_polling, args=(queued[-1],)))
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
