"""Fairness benchmark: `SELECT 1` of one user while another user floods `lakegate serve`.

    python3 dev.py bench fairness [--runs N] [--flood F]

Starts `lakegate serve` on 127.0.0.1 (an empty lake: the queries need no table) with 4 query slots
and a 2 s time limit. User B runs `SELECT 1` N times through the trino client, first on the idle
server (the baseline, in the same run), then while user A keeps F clients busy, each running a query
that lasts until the time limit and asking again at once (so A always has queries running and
queued, and keeps polling them: none is dropped as abandoned). A free slot goes to the user with the
fewest running queries, so B waits for at most one of A's queries to end, never for A's queue.

Writes section "Fairness" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import requests
import trino

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, write_section  # noqa: E402

ENDLESS = (
    "SELECT count(*) FROM UNNEST(sequence(1, 10000)) AS a(x) CROSS JOIN UNNEST(sequence(1, 10000)) AS b(y) "
    "CROSS JOIN UNNEST(sequence(1, 10000)) AS c(z) WHERE a.x + b.y + c.z = 7"
)
SLOTS, TIME_LIMIT = 4, 2


def serve(lake: Path) -> tuple[subprocess.Popen, str]:
    command = [sys.executable, "-m", "lakegate.gateway.cli", "serve", "--lake", str(lake), "--port", "0"]
    command += ["--max-concurrent-queries", str(SLOTS), "--query-timeout", str(TIME_LIMIT)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    line = process.stdout.readline()
    return process, line.split(" at ", 1)[1].split()[0]


def select_1_ms(url: str, runs: int) -> list[float]:
    host, port = url.split("//", 1)[1].split(":")
    times = []
    with trino.dbapi.connect(host=host, port=int(port), user="bob") as connection:
        cursor = connection.cursor()
        for _ in range(runs):
            start = time.perf_counter()
            cursor.execute("SELECT 1")
            cursor.fetchall()
            times.append((time.perf_counter() - start) * 1000)
    return times


def flood(url: str, stop: threading.Event, counts: dict) -> None:
    """One of user A's clients: an endless query after another, each polled until it fails."""
    with requests.Session() as session:
        while not stop.is_set():
            document = session.post(f"{url}/v1/statement", data=ENDLESS, headers={"X-Trino-User": "alice"}).json()
            while "nextUri" in document and not stop.is_set():
                document = session.get(document["nextUri"]).json()
            counts["alice"] += 1
            if "nextUri" in document:
                session.delete(document["nextUri"])


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=40, help="SELECT 1 queries of user B per phase")
    parser.add_argument("--flood", type=int, default=16, help="user A's concurrent clients")
    args = parse_args(parser, argv, runs=5, flood=6)
    load_start = os.getloadavg()[0]
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as lake:
        process, url = serve(Path(lake))
        try:
            select_1_ms(url, 5)  # warm-up
            idle = select_1_ms(url, args.runs)
            stop, counts = threading.Event(), {"alice": 0}
            clients = [threading.Thread(target=flood, args=(url, stop, counts)) for _ in range(args.flood)]
            for client in clients:
                client.start()
            time.sleep(TIME_LIMIT + 1)  # alice's queries hold every slot, the rest of hers wait
            flooded = select_1_ms(url, args.runs)
            stop.set()
            for client in clients:
                client.join(timeout=60)
        finally:
            process.terminate()
            process.wait(30)
    load_end = os.getloadavg()[0]

    def summary(times: list[float]) -> str:
        return f"median {statistics.median(times):.1f} ms, max {max(times):.0f} ms"

    ratio = statistics.median(flooded) / statistics.median(idle)
    write_section(
        "Fairness",
        "python3 dev.py bench fairness",
        [
            f"Server: `lakegate serve --max-concurrent-queries {SLOTS} --query-timeout {TIME_LIMIT}` on 127.0.0.1, "
            f"empty lake. User A: {args.flood} clients, each running a query that lasts until the time limit and "
            f"starting the next at once (polling each: none is dropped). User B: `SELECT 1` through the trino "
            f"client, {args.runs} times per phase. Load average (1 min) at the start {load_start:.1f}, at the end "
            f"{load_end:.1f}, on {os.cpu_count()} cores.",
            "",
            "| user B's `SELECT 1` | latency |",
            "|---|---|",
            f"| idle server (baseline, same run) | {summary(idle)} |",
            f"| while user A floods | {summary(flooded)} ({ratio:.1f}x the idle median) |",
            "",
            f"- user A's queries ended during the run: {counts['alice']}; B never waits behind A's queue, only for "
            f"a slot to free (at most one of A's queries reaching its {TIME_LIMIT} s limit)",
            f"(benchmark took {time.perf_counter() - started:.0f} s)",
        ],
    )


if __name__ == "__main__":
    main()
