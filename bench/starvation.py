"""Starvation benchmark: `SELECT 1` of one user while other clients post statements of 1 MB.

    python3 dev.py bench starvation [--seconds S] [--rounds R] [--clients C] [--bytes B]

Uses the translate benchmark's lake (bench/.work/translate: the example config, 10 jobs, the topic
`odom_linear_velocity`), starts `lakegate serve` on 127.0.0.1 (default limits: 8 query slots), and
measures user B's `SELECT 1` through the trino client: first on the idle server (the baseline, in
the same run), then while C clients of user A each post a statement of about B bytes (a count over
the topic with an IN list of B bytes, which the server accepts and answers) and, once it is
answered, post the next. The two phases alternate `--rounds` times, so that a change in the
machine's load touches both. Planning such a statement (parsing, translating) is pure-Python work:
where it runs under the server's GIL, every other query waits for it.

Writes section "Starvation" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import itertools
import os
import statistics
import sys
import threading
import time
from pathlib import Path

import requests

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, write_section  # noqa: E402
from server import Server  # noqa: E402
from translate import TOPIC, build_lake  # noqa: E402

#: Characters of each job id of the large statements' IN list (2 tokens each, with its comma).
VALUE_BYTES = 120
_tags = itertools.count()
HEADERS = {"X-Trino-User": "alice", "X-Trino-Catalog": "lake", "X-Trino-Schema": "main"}


def large_statement(size: int, tag: int = 0) -> str:
    """A count over the topic with an IN list of job ids, about `size` bytes of SQL in fewer tokens
    than the server's limit (dialect.guard.MAX_TOKENS): ids of VALUE_BYTES characters. Each `tag`
    gives another text, so that no cache of the server answers a statement it has seen."""
    head = f"SELECT count(*) AS n FROM {TOPIC} WHERE job_id IN ('j0', 'tag-{tag}'"
    count = max(1, (size - len(head)) // (VALUE_BYTES + 4))
    pad = "x" * (VALUE_BYTES - 11)
    return head + "".join(f", 'job-{i:06d}-{pad}'" for i in range(count)) + ")"


def select_1_ms(server: Server, seconds: float) -> list[float]:
    """Milliseconds of each `SELECT 1` through the trino client (one connection), one after the
    other for `seconds` seconds."""
    connection = server.connect()
    cursor = connection.cursor()
    times, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        start = time.perf_counter()
        cursor.execute("SELECT 1")
        cursor.fetchall()
        times.append((time.perf_counter() - start) * 1000)
    connection.close()
    return times


def flood(url: str, size: int, stop: threading.Event, outcomes: list) -> None:
    """One of user A's clients: a large statement after another (each a new text), each polled until
    it is answered; its outcome (seconds, or the error) is appended to `outcomes`."""
    with requests.Session() as session:
        while not stop.is_set():
            sql = large_statement(size, next(_tags))
            start = time.perf_counter()
            document = session.post(f"{url}/v1/statement", data=sql, headers=HEADERS).json()
            while "nextUri" in document and not stop.is_set():
                document = session.get(document["nextUri"]).json()
            if "nextUri" in document:
                session.delete(document["nextUri"])
            elif "error" in document:
                outcomes.append(document["error"]["message"][:200])
            else:
                outcomes.append(time.perf_counter() - start)


def own_cpu(server: Server) -> float:
    """CPU seconds (user + system) of the server's own process, without its query workers: the
    process whose GIL every query's HTTP handling needs."""
    fields = Path(f"/proc/{server.process.pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", type=int, default=200_000, help="rows of the benchmark topic (default 200,000)")
    parser.add_argument("--seconds", type=float, default=10.0, help="seconds of each phase (default 10)")
    parser.add_argument("--rounds", type=int, default=3, help="idle / flooded phase pairs (default 3)")
    parser.add_argument("--clients", type=int, default=8, help="user A's concurrent clients (default 8)")
    parser.add_argument("--bytes", type=int, default=990_000, help="size of user A's statements (default 990,000)")
    args = parse_args(parser, argv, rows=200_000, seconds=1.0, rounds=1, clients=2, bytes=50_000)
    load_start, started = os.getloadavg()[0], time.perf_counter()
    sample = large_statement(args.bytes)
    server = Server(build_lake(args.rows), [])
    idle, flooded, outcomes, cpu = [], [], [], 0.0
    try:
        url = f"http://127.0.0.1:{server.port}"
        select_1_ms(server, 0.5)  # warm-up
        for _ in range(args.rounds):
            idle += select_1_ms(server, args.seconds)
            stop, before = threading.Event(), own_cpu(server)
            clients = [
                threading.Thread(target=flood, args=(url, args.bytes, stop, outcomes)) for _ in range(args.clients)
            ]
            for client in clients:
                client.start()
            time.sleep(1.0)  # every client has posted its statement
            flooded += select_1_ms(server, args.seconds)
            stop.set()
            for client in clients:
                client.join(timeout=600)
            cpu += own_cpu(server) - before
    finally:
        server.stop()
    answered = [o for o in outcomes if isinstance(o, float)]
    errors = [o for o in outcomes if isinstance(o, str)]
    if errors:
        raise SystemExit(f"user A's statements failed: {errors[0]}")

    def summary(times: list[float]) -> str:
        p90 = sorted(times)[int(len(times) * 0.9)]
        return f"median {statistics.median(times):.1f} ms, p90 {p90:.0f} ms, max {max(times):.0f} ms"

    ratio = statistics.median(flooded) / statistics.median(idle)
    large = f"median {statistics.median(answered):.1f} s" if answered else "none answered during the phases"
    write_section(
        "Starvation",
        "python3 dev.py bench starvation",
        [
            f"Server: `lakegate serve` on 127.0.0.1 (default limits: 8 query slots), the lake of "
            f"bench/.work/translate ({args.rows:,} rows). User A: {args.clients} clients, each posting a statement "
            f"of {len(sample):,} bytes (`SELECT count(*) FROM {TOPIC} WHERE job_id IN (...)`, "
            f"{sample.count(', ')} ids of {VALUE_BYTES} characters, each statement a new text) and the next once "
            f"it is answered. User B: `SELECT 1` through the trino client, one after the other for "
            f"{args.seconds:g} s per phase, {args.rounds} idle / flooded phase pairs alternating ({len(idle)} and "
            f"{len(flooded)} queries). Load average (1 min) at the start {load_start:.1f}, at the end "
            f"{os.getloadavg()[0]:.1f}, on {os.cpu_count()} cores.",
            "",
            "| user B's `SELECT 1` | latency |",
            "|---|---|",
            f"| idle server (baseline, same run) | {summary(idle)} |",
            f"| while user A posts 1 MB statements | {summary(flooded)} ({ratio:.1f}x the idle median) |",
            "",
            f"- user A's statements answered during the run: {len(answered)} ({large} each, post to answer); "
            f"CPU of the server's own process (without its query workers, with user B's queries) while they ran: "
            f"{cpu:.1f} s, {cpu / max(1, len(answered)):.2f} s per statement answered",
            f"(benchmark took {time.perf_counter() - started:.0f} s)",
        ],
    )


if __name__ == "__main__":
    main()
