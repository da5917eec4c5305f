"""Fairness benchmark: `SELECT 1` of one user while another user floods `lakegate serve`.

    python3 dev.py bench fairness [--runs N] [--flood F]

Starts `lakegate serve` on 127.0.0.1 (an empty lake: the queries need no table) with 4 query slots
and a 2 s time limit, twice: with `--max-queries-per-user 4` (one user may fill every slot) and with
the default cap (all slots but one: 3). On each, user B runs `SELECT 1` N times through the trino
client, first on the idle server (the baseline, in the same run), then while user A keeps F clients
busy, each running a query that lasts until the time limit and asking again at once (so A always
has queries running and queued, and keeps polling them: none is dropped as abandoned). With every
slot open to A, B waits for one of A's queries to end; under the cap a slot is always free for B.

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


def serve(lake: Path, *options: str) -> tuple[subprocess.Popen, str]:
    command = [sys.executable, "-m", "lakegate.gateway.cli", "serve", "--lake", str(lake), "--port", "0"]
    command += ["--max-concurrent-queries", str(SLOTS), "--query-timeout", str(TIME_LIMIT), *options]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    line = process.stdout.readline()
    return process, line.split(" at ", 1)[1].split()[0]


def select_1_ms(url: str, runs: int) -> tuple[list[float], list[str]]:
    """User B's `SELECT 1`, `runs` times: the latencies of those answered, and the errors of the rest."""
    host, port = url.split("//", 1)[1].split(":")
    times, errors = [], []
    with trino.dbapi.connect(host=host, port=int(port), user="bob") as connection:
        cursor = connection.cursor()
        for _ in range(runs):
            start = time.perf_counter()
            try:
                cursor.execute("SELECT 1")
                cursor.fetchall()
            except trino.exceptions.TrinoQueryError as error:
                errors.append(error.error_name)
                continue
            times.append((time.perf_counter() - start) * 1000)
    return times, errors


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


def flooded(lake: Path, runs: int, clients: int, *options: str) -> tuple[list[float], list[str], int]:
    """B's `SELECT 1` on a server started with `options` while A's `clients` flood it; and how many
    of A's queries ended meanwhile."""
    process, url = serve(lake, *options)
    try:
        select_1_ms(url, 5)  # warm-up
        stop, counts = threading.Event(), {"alice": 0}
        threads = [threading.Thread(target=flood, args=(url, stop, counts)) for _ in range(clients)]
        for thread in threads:
            thread.start()
        time.sleep(TIME_LIMIT + 1)  # alice's queries hold what slots she may take, the rest of hers wait
        times, errors = select_1_ms(url, runs)
        stop.set()
        for thread in threads:
            thread.join(timeout=60)
    finally:
        process.terminate()
        process.wait(30)
    return times, errors, counts["alice"]


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
            idle, _ = select_1_ms(url, args.runs)
        finally:
            process.terminate()
            process.wait(30)
        uncapped = flooded(Path(lake), args.runs, args.flood, "--max-queries-per-user", str(SLOTS))
        capped = flooded(Path(lake), args.runs, args.flood)
    load_end = os.getloadavg()[0]

    def row(label: str, times: list[float], errors: list[str]) -> str:
        if not times:
            return f"| {label} | none answered; errors: {', '.join(sorted(set(errors)))} |"
        failed = f"; {len(errors)} failed ({', '.join(sorted(set(errors)))})" if errors else ""
        ratio = statistics.median(times) / statistics.median(idle)
        return (
            f"| {label} | median {statistics.median(times):.1f} ms, max {max(times):.0f} ms "
            f"({ratio:.1f}x the idle median){failed} |"
        )

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
            row("idle server (baseline, same run)", idle, []),
            row(f"while A floods, `--max-queries-per-user {SLOTS}` (A may fill every slot)", *uncapped[:2]),
            row(f"while A floods, default cap ({SLOTS - 1}: a slot is always free for B)", *capped[:2]),
            "",
            f"- user A's queries ended during the flooded phases: {uncapped[2]} and {capped[2]}; with every slot "
            f"open to A, B waits for one of A's queries to reach its {TIME_LIMIT} s limit; under the cap B's query "
            "runs at once beside A's",
            f"(benchmark took {time.perf_counter() - started:.0f} s)",
        ],
    )


if __name__ == "__main__":
    main()
