"""Stop signals to a real `lakegate serve`. With queries stuck in work nothing interrupts at once
(pure-Python planning, injected with SLOW_PLANNING_ENV) and more clients than query slots: every
client gets SERVER_SHUTTING_DOWN (none a reset), and the process exits 0 without a traceback. Right
after it says it serves (before and while uvicorn starts): it stops at once, saying only that."""

from __future__ import annotations

import signal
import subprocess
import threading
import time

import requests

from lakegate.gateway.server.query_lifecycle import SLOW_PLANNING_ENV

from .conftest import Server, serve

MARKER = "stuck_in_planning_marker"


def test_sigterm_with_stuck_work_answers_every_client(server_lake, tmp_path, monkeypatch):
    monkeypatch.setenv(SLOW_PLANNING_ENV, MARKER)
    server = serve(server_lake, tmp_path / "serve.log", "--max-concurrent-queries", "4")
    answers: dict[int, str] = {}
    polling = threading.Barrier(13)

    def client(number: int) -> None:
        with requests.Session() as session:  # one keep-alive connection, as the trino client keeps
            try:
                document = session.post(
                    f"{server.url}/v1/statement",
                    data=f"SELECT {number} AS {MARKER}",
                    headers={"X-Trino-User": f"user{number % 3}"},
                    timeout=30,
                ).json()
                polling.wait(timeout=60)
                while "nextUri" in document:
                    document = session.get(document["nextUri"], timeout=30).json()
                answers[number] = document.get("error", {}).get("errorName", "no error")
            except requests.RequestException as error:
                answers[number] = f"{type(error).__name__}: {error}"

    threads = [threading.Thread(target=client, args=(n,)) for n in range(12)]  # 4 run, 8 wait in the queue
    for thread in threads:
        thread.start()
    polling.wait(timeout=60)
    time.sleep(1.0)  # every client is polling; every running query is stuck planning
    started = time.monotonic()
    server.process.send_signal(signal.SIGTERM)
    code = server.process.wait(timeout=30)
    stopped = time.monotonic() - started
    for thread in threads:
        thread.join(timeout=30)
    log = server.log.read_text()
    assert answers == {n: "SERVER_SHUTTING_DOWN" for n in range(12)}, answers
    assert code == 0 and stopped < 5, (code, stopped, log)
    assert "Traceback" not in log and "Fatal Python error" not in log, log
    assert log.strip().endswith("lakegate: stopped")


#: (signal, seconds after the "serving" line): a signal lost there left a server serving for good.
EARLY_STOPS = [(signal.SIGTERM, seconds) for seconds in (0, 0.005, 0.02, 0.05)] + [
    (signal.SIGINT, 0),
    (signal.SIGINT, 0.01),
]


def test_a_stop_signal_right_after_start_up_stops_the_server(server_lake, tmp_path):
    outcomes: dict[int, tuple] = {}

    def start_and_stop(number: int) -> None:
        sent, seconds = EARLY_STOPS[number]
        log = tmp_path / f"serve{number}.log"
        try:
            server: Server = serve(server_lake, log, "--max-concurrent-queries", "1", timeout=180)
        except RuntimeError as error:
            outcomes[number] = (str(error), "")
            return
        time.sleep(seconds)
        server.process.send_signal(sent)
        try:
            code = server.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            server.process.kill()
            code = "still serving 30 s after the signal"
        outcomes[number] = (code, log.read_text())

    threads = [threading.Thread(target=start_and_stop, args=(n,)) for n in range(len(EARLY_STOPS))]
    for thread in threads:  # started together: each start-up is slower, its window wider
        thread.start()
    for thread in threads:
        thread.join(timeout=300)
    assert outcomes == {n: (0, "lakegate: stopped\n") for n in range(len(EARLY_STOPS))}
