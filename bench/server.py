"""Server benchmark: `lakegate serve` through the official `trino` client, against in-process DuckDB.

    python3 dev.py bench server [--runs R] [--seconds S] [--clients N]

Uses the translate benchmark's lake (built once under bench/.work/translate/: the example config,
10 jobs in 2 batches, a 10,000,000-row topic `odom_linear_velocity` of generated Parquet and one
metadata row per job), starts `lakegate serve` on 127.0.0.1 in a subprocess, and measures through
`trino.dbapi`, and with DuckDB in this process on the same Parquet files (the lake's own views):

* `SELECT 1` latency, median of 200 (after 20 warm-up queries), with the server's and the client's
  CPU per query, and the client's own floor against a stub server that answers at once;
* fetching 1,000,000 rows x 3 columns (one job): rows/s with `fetchall()`, and the server's peak
  memory (VmHWM of its processes, reset through /proc/<pid>/clear_refs before each read), also for
  4,000,000 rows (the same job 4 times, read in chunks) to show it does not grow with the result;
* a GROUP BY aggregate over all 10,000,000 rows: median of 11 alternating runs, ratio to direct
  DuckDB with the server's thread count;
* N concurrent clients (threads, one connection and user each) running a mix of queries for S seconds:
  throughput, p50 / p99 latency, errors.

Writes section "Server" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import math
import os
import socket
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import duckdb
import requests
import trino

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import median_of, parse_args, timed, wait_serving, write_section  # noqa: E402
from translate import JOBS, TOPIC, build_lake  # noqa: E402

from lakegate.lake.catalog import Catalog  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ROWS = 10_000_000
THREADS = 2  # DuckDB threads of the server and of the direct baseline
GOALS = {"select1_ms": 2.0, "rows_per_s": 250_000, "aggregate_ratio": 1.3}
FETCH = f"SELECT timestamp, x, y FROM {TOPIC} WHERE job_id = 'j0'"
#: The same job's rows 4 times: what grows with the result, not with the files DuckDB reads (and caches).
FETCH_4M = " UNION ALL ".join([FETCH] * 4)
AGGREGATE = (
    f"SELECT job_id, count(*) AS n, avg(x) AS ax, min(y) AS my, max(x) AS mx FROM {TOPIC} "
    "GROUP BY job_id ORDER BY job_id"
)
#: The concurrent mix: (name, SQL, parameters or None); each client starts at its own offset.
MIX = [
    ("SELECT 1", "SELECT 1", None),
    ("job aggregate", f"SELECT count(*), avg(x), max(y) FROM {TOPIC} WHERE job_id = 'j3'", None),
    ("1,000-row page", f"SELECT timestamp, x, y FROM {TOPIC} WHERE job_id = 'j5' ORDER BY timestamp LIMIT 1000", None),
    ("parameterized", f"SELECT count(*) FROM {TOPIC} WHERE job_id = ? AND x > ?", ["j7", 1.5]),
    (
        "metadata join",
        f"SELECT m.experience_name, count(*) FROM {TOPIC} d JOIN metadata m ON d.job_id = m.job_id "
        "WHERE d.job_id IN ('j8', 'j9') GROUP BY 1 ORDER BY 1",
        None,
    ),
    ("introspection", "SHOW TABLES", None),
]


#: A stub Trino server that answers at once, to measure what the client itself costs: `SELECT 1` gets
#: its rows in the POST's reply (1 request), any other statement a nextUri to GET them (2 requests).
STUB = r"""
import asyncio, json, sys
port = int(sys.argv[1])
ROWS = json.dumps({"id": "q", "infoUri": "http://127.0.0.1/", "stats": {"state": "FINISHED"}, "data": [[1]],
                   "columns": [{"name": "_col0", "type": "integer",
                                "typeSignature": {"rawType": "integer", "arguments": []}}]}).encode()
QUEUED = json.dumps({"id": "q", "infoUri": "http://127.0.0.1/", "stats": {"state": "QUEUED"},
                     "nextUri": f"http://127.0.0.1:{port}/v1/statement/q/1"}).encode()

def reply(body):
    return b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: %d\r\n\r\n" % len(body) + body

async def handle(reader, writer):
    try:
        while True:
            head = await reader.readuntil(b"\r\n\r\n")
            length = next((int(line.split(b":")[1]) for line in head.split(b"\r\n")
                           if line.lower().startswith(b"content-length:")), 0)
            body = await reader.readexactly(length) if length else b""
            writer.write(reply(QUEUED if head.startswith(b"POST") and body != b"SELECT 1" else ROWS))
            await writer.drain()
    except (asyncio.IncompleteReadError, ConnectionError):
        writer.close()

async def main():
    server = await asyncio.start_server(handle, "127.0.0.1", port)
    print("ready", flush=True)
    await server.serve_forever()

asyncio.run(main())
"""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


class Server:
    """`lakegate serve` in a subprocess on 127.0.0.1."""

    def __init__(self, lake: Path, extra: list[str]):
        self.port = free_port()
        command = [
            sys.executable,
            "-m",
            "lakegate.gateway.cli",
            "serve",
            "--lake",
            str(lake),
            "--host",
            "127.0.0.1",
            "--port",
            str(self.port),
            *extra,
        ]
        self.log = open(ROOT / "bench" / ".work" / "server.log", "w")
        self.process = subprocess.Popen(command, stdout=self.log, stderr=subprocess.STDOUT)
        wait_serving(self.process, self.port, self.stop, "lakegate serve", self.log.name)

    def pids(self) -> list[int]:
        """The server process and its descendants."""
        found, stack = [], [self.process.pid]
        while stack:
            pid = stack.pop()
            found.append(pid)
            for task in Path(f"/proc/{pid}/task").glob("*"):
                try:
                    stack += [int(child) for child in (task / "children").read_text().split()]
                except OSError:
                    pass
        return found

    def memory(self, field: str) -> int:
        """The sum of one /proc memory field over the server's processes, in bytes: "Pss" (the memory
        they take, shared pages counted once; the query workers share the fork server's) or a status
        field, "VmRSS" or "VmHWM" (summed, shared pages counted in each process)."""
        total = 0
        source = "smaps_rollup" if field == "Pss" else "status"
        for pid in self.pids():
            try:
                for line in Path(f"/proc/{pid}/{source}").read_text().splitlines():
                    if line.startswith(field + ":"):
                        total += int(line.split()[1]) * 1024
            except OSError:
                pass
        return total

    def cpu(self) -> float:
        """CPU seconds (user + system) the server's processes used so far, with their reaped children's
        (a query worker that retires moves its CPU time to its parent's, so the sum never falls)."""
        ticks = 0
        for pid in self.pids():
            try:
                fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
                ticks += sum(int(value) for value in fields[11:15])
            except (OSError, IndexError, ValueError):
                pass
        return ticks / os.sysconf("SC_CLK_TCK")

    def reset_peak(self) -> bool:
        """Reset the peak RSS (VmHWM) of the server's processes to their current RSS."""
        try:
            for pid in self.pids():
                Path(f"/proc/{pid}/clear_refs").write_text("5")
            return True
        except OSError:
            return False

    def connect(self, session: requests.Session | None = None, user: str = "bench") -> trino.dbapi.Connection:
        return trino.dbapi.connect(
            host="127.0.0.1", port=self.port, user=user, catalog="lake", schema="main", http_session=session
        )

    def stop(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.log.close()


def direct_duckdb(lake: Path) -> duckdb.DuckDBPyConnection:
    """In-process DuckDB with the lake's own views over the same Parquet files."""
    connection = duckdb.connect(config={"threads": THREADS})
    for name, select in Catalog(lake).view_sql("main").items():
        connection.execute(f'CREATE VIEW "{name}" AS {select}')
    return connection


def client_rows(connection: trino.dbapi.Connection, sql: str, params: list | None = None) -> list:
    cursor = connection.cursor()
    cursor.execute(sql, params)
    return cursor.fetchall()


class Costs:
    """CPU seconds of the server and of this process (the client), and HTTP requests, over a block."""

    def __init__(self, server: Server, session: requests.Session):
        self.server, self.requests = server, 0
        session.hooks["response"].append(self._count)

    def _count(self, response: requests.Response, *args, **kwargs) -> None:
        self.requests += 1

    def measure(self, fn: Callable[[], object]) -> tuple[float, float, int]:
        """Server CPU seconds, client CPU seconds and requests of one call of `fn`."""
        server, client, sent = self.server.cpu(), time.process_time(), self.requests
        fn()
        return self.server.cpu() - server, time.process_time() - client, self.requests - sent


def select_one(server: Server, direct: duckdb.DuckDBPyConnection) -> dict:
    """Median seconds of `SELECT 1` through the client (200 runs) and in-process DuckDB, and what
    one costs: server and client CPU, HTTP requests."""
    session = requests.Session()
    costs = Costs(server, session)
    connection = server.connect(session)
    for _ in range(20):
        client_rows(connection, "SELECT 1")
    ours, runs = median_of(200, lambda: timed(lambda: client_rows(connection, "SELECT 1")))
    server_cpu, client_cpu, sent = costs.measure(lambda: [client_rows(connection, "SELECT 1") for _ in range(200)])
    theirs, _ = median_of(200, lambda: timed(lambda: direct.execute("SELECT 1").fetchall()))
    return {
        "ours": ours,
        "theirs": theirs,
        "p90": percentile(sorted(runs), 90),
        "server_cpu": server_cpu / 200,
        "client_cpu": client_cpu / 200,
        "requests": sent / 200,
    }


def client_floor() -> tuple[float, float]:
    """Median seconds of `SELECT 1` through the client against STUB: rows in the POST's reply, and
    rows after one GET (as Trino answers; lakegate answers fast queries in the POST)."""
    port = free_port()
    stub = subprocess.Popen([sys.executable, "-c", STUB, str(port)], stdout=subprocess.PIPE, text=True)
    try:
        stub.stdout.readline()
        connection = trino.dbapi.connect(host="127.0.0.1", port=port, user="bench")
        medians = []
        for sql in ("SELECT 1", "SELECT 2"):
            for _ in range(20):
                client_rows(connection, sql)
            medians.append(median_of(200, lambda sql=sql: timed(lambda: client_rows(connection, sql)))[0])
        return medians[0], medians[1]
    finally:
        stub.terminate()
        stub.wait()
        stub.stdout.close()


def fetch(server: Server, direct: duckdb.DuckDBPyConnection, runs: int) -> dict:
    """Rows/s of the 1M x 3 fetch (client and direct DuckDB), the server's memory while streaming."""
    session = requests.Session()
    costs = Costs(server, session)
    connection = server.connect(session)
    counted = len(client_rows(connection, FETCH))
    rss_before = server.memory("VmRSS")
    reset = server.reset_peak()
    ours, ours_runs = median_of(runs, lambda: timed(lambda: client_rows(connection, FETCH)))
    peak_1m = server.memory("VmHWM")
    server_cpu, client_cpu, sent = costs.measure(lambda: client_rows(connection, FETCH))
    theirs, _ = median_of(runs, lambda: timed(lambda: direct.execute(FETCH).fetchall()))
    server.reset_peak()
    start = time.perf_counter()
    cursor = connection.cursor()
    cursor.execute(FETCH_4M)
    rows_4m = 0
    while batch := cursor.fetchmany(100_000):
        rows_4m += len(batch)
    seconds_4m = time.perf_counter() - start
    peak_4m = server.memory("VmHWM")
    return {
        "rows": counted,
        "ours": counted / ours,
        "ours_runs": [counted / s for s in ours_runs],
        "theirs": counted / theirs,
        "rss_before": rss_before,
        "peak_1m": peak_1m,
        "peak_4m": peak_4m,
        "rows_4m": rows_4m,
        "rate_4m": rows_4m / seconds_4m,
        "reset": reset,
        "server_cpu": server_cpu,
        "client_cpu": client_cpu,
        "requests": sent,
    }


def aggregate(server: Server, direct: duckdb.DuckDBPyConnection, runs: int) -> dict:
    """Median seconds of the 10M-row GROUP BY through the client and in-process, alternating."""
    connection = server.connect()
    ours_rows = client_rows(connection, AGGREGATE)
    theirs_rows = direct.execute(AGGREGATE).fetchall()
    if len(ours_rows) != len(theirs_rows) or not all(
        math.isclose(a, b, rel_tol=1e-12) if isinstance(a, float) else a == b
        for row, other in zip(ours_rows, theirs_rows)
        for a, b in zip(row, other)
    ):
        raise SystemExit(f"the aggregate differs: server {ours_rows} vs DuckDB {theirs_rows}")
    figures: dict[str, list[float]] = {"ours": [], "theirs": []}
    for run in range(runs):
        pair = [
            ("ours", lambda: client_rows(connection, AGGREGATE)),
            ("theirs", lambda: direct.execute(AGGREGATE).fetchall()),
        ]
        for key, fn in reversed(pair) if run % 2 else pair:
            figures[key].append(timed(fn))
    ours, theirs = statistics.median(figures["ours"]), statistics.median(figures["theirs"])
    return {"ours": ours, "theirs": theirs, "ratio": ours / theirs, "runs": figures}


def concurrency(server: Server, clients: int, seconds: float) -> dict:
    """`clients` threads, one connection and user each, running the mix for `seconds`."""
    latencies: dict[str, list[float]] = {name: [] for name, _, _ in MIX}
    errors: list[str] = []
    lock = threading.Lock()
    stop = time.monotonic() + seconds

    def client(index: int) -> None:
        connection = server.connect(user=f"bench{index}")  # a user of their own: the per-user cap is not measured
        turn = index
        while time.monotonic() < stop:
            name, sql, params = MIX[turn % len(MIX)]
            turn += 1
            start = time.perf_counter()
            try:
                client_rows(connection, sql, params)
            except Exception as error:  # every failure counts, whatever its kind
                with lock:
                    errors.append(f"{name}: {type(error).__name__}: {str(error)[:200]}")
                continue
            with lock:
                latencies[name].append(time.perf_counter() - start)

    threads = [threading.Thread(target=client, args=(i,)) for i in range(clients)]
    started = time.perf_counter()
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    elapsed = time.perf_counter() - started
    every = sorted(x for values in latencies.values() for x in values)
    return {
        "queries": len(every),
        "qps": len(every) / elapsed,
        "p50": percentile(every, 50),
        "p99": percentile(every, 99),
        "errors": errors,
        "elapsed": elapsed,
        "per_query": {
            name: (len(v), percentile(sorted(v), 50), percentile(sorted(v), 99)) for name, v in latencies.items()
        },
    }


def percentile(values: list[float], p: float) -> float:
    if not values:
        return float("nan")
    return values[min(len(values) - 1, round(p / 100 * (len(values) - 1)))]


def verdict(met: bool) -> str:
    return "**met**" if met else "**missed**"


def mb(value: int) -> str:
    return f"{value / 2**20:,.0f} MB"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rows", type=int, default=ROWS, help=f"rows of the benchmark topic (default {ROWS:,})")
    parser.add_argument("--runs", type=int, default=3, help="runs of the fetch and aggregate measures (default 3)")
    parser.add_argument("--seconds", type=float, default=30.0, help="length of the concurrency test (default 30)")
    parser.add_argument("--clients", type=int, default=32, help="concurrent clients (default 32)")
    parser.add_argument(
        "--serve-arg",
        action="append",
        default=[],
        metavar="ARG",
        help="an extra argument for `lakegate serve` (repeat for several)",
    )
    args = parse_args(parser, rows=200_000, runs=1, seconds=2.0, clients=4)
    started, load_start = time.perf_counter(), os.getloadavg()[0]
    lake = build_lake(args.rows)
    direct = direct_duckdb(lake)
    server = Server(lake, args.serve_arg)
    try:
        idle_rss = server.memory("Pss")
        one = select_one(server, direct)
        floor_one, floor_two = client_floor()
        fetched = fetch(server, direct, args.runs)
        summed = aggregate(server, direct, max(args.runs, 11))
        load = concurrency(server, args.clients, args.seconds)
    finally:
        server.stop()
        direct.close()
    bounded = fetched["peak_4m"] < 1.25 * fetched["peak_1m"]  # 4x the rows, less than 1.25x the memory
    lines = [
        f"Lake: `{TOPIC}` with {args.rows:,} rows in {len(JOBS)} jobs of Parquet (bench/.work/translate), one metadata "
        f"row per job. Server: `lakegate serve` on 127.0.0.1{''.join(' ' + a for a in args.serve_arg)}; client: "
        f"`trino.dbapi` in this process; baseline: DuckDB in this process on the same Parquet files through the "
        f"lake's views ({THREADS} threads). Load average (1 min) at the start {load_start:.1f}, at the end "
        f"{os.getloadavg()[0]:.1f}, on {os.cpu_count()} cores: other work on the machine slows both sides.",
        "",
        "| measure | lakegate serve + trino client | direct DuckDB | goal | verdict |",
        "|---|---:|---:|---|---|",
        f"| `SELECT 1` latency, median of 200 | {one['ours'] * 1e3:.2f} ms | {one['theirs'] * 1e3:.3f} ms | < "
        f"{GOALS['select1_ms']:.0f} ms | {verdict(one['ours'] * 1e3 < GOALS['select1_ms'])} |",
        f"| fetch {fetched['rows']:,} rows x 3 columns, median of {args.runs} | {fetched['ours']:,.0f} rows/s | "
        f"{fetched['theirs']:,.0f} rows/s | >= {GOALS['rows_per_s']:,} rows/s | "
        f"{verdict(fetched['ours'] >= GOALS['rows_per_s'])} |",
        f"| GROUP BY over {args.rows:,} rows, median of {len(summed['runs']['ours'])} | "
        f"{summed['ours'] * 1e3:.0f} ms | "
        f"{summed['theirs'] * 1e3:.0f} ms | <= {GOALS['aggregate_ratio']}x | {summed['ratio']:.2f}x "
        f"{verdict(summed['ratio'] <= GOALS['aggregate_ratio'])} |",
        f"| {args.clients} concurrent clients, {load['elapsed']:.0f} s mix | {load['qps']:.1f} queries/s, p50 "
        f"{load['p50'] * 1e3:.0f} ms, p99 {load['p99'] * 1e3:.0f} ms, {len(load['errors'])} errors | | 0 errors | "
        f"{verdict(not load['errors'])} |",
        f"| server memory while streaming | idle {mb(idle_rss)} (PSS); peak {mb(fetched['peak_1m'])} for 1M rows, "
        f"{mb(fetched['peak_4m'])} for {fetched['rows_4m']:,} rows ({fetched['rate_4m']:,.0f} rows/s) | | 4x the rows, "
        f"< 1.25x the peak "
        f"| {verdict(bounded)} |",
        "",
        f"- `SELECT 1`: p90 {one['p90'] * 1e3:.2f} ms; per query {one['requests']:.1f} HTTP requests, server CPU "
        f"{one['server_cpu'] * 1e3:.2f} ms, client CPU {one['client_cpu'] * 1e3:.2f} ms. The same client against "
        f"a stub server that answers at once (another process): {floor_two * 1e3:.2f} ms with POST + GET (2 "
        f"requests, as Trino answers), {floor_one * 1e3:.2f} ms with the rows in the POST's reply (as lakegate "
        f"answers a fast query)",
        f"- fetch of {fetched['rows']:,} rows: server CPU {fetched['server_cpu']:.2f} s (alone it would allow "
        f"{fetched['rows'] / max(fetched['server_cpu'], 1e-9):,.0f} rows/s), client CPU {fetched['client_cpu']:.2f} s "
        f"({fetched['rows'] / max(fetched['client_cpu'], 1e-9):,.0f} rows/s: the trino client's JSON decoding and "
        f"value mapping), {fetched['requests']} HTTP requests",
        f"- fetch runs (rows/s): {', '.join(f'{r:,.0f}' for r in fetched['ours_runs'])}; RSS before the fetches "
        f"{mb(fetched['rss_before'])}" + ("" if fetched["reset"] else " (peak could not be reset: VmHWM since start)"),
        f"- aggregate runs (ms): server {', '.join(f'{s * 1e3:.0f}' for s in summed['runs']['ours'])}; DuckDB "
        f"{', '.join(f'{s * 1e3:.0f}' for s in summed['runs']['theirs'])}",
        "- concurrency mix, per query (count, p50, p99): "
        + "; ".join(
            f"{name} {n} / {p50 * 1e3:.0f} ms / {p99 * 1e3:.0f} ms" for name, (n, p50, p99) in load["per_query"].items()
        ),
    ]
    if load["errors"]:
        lines.append(f"- first errors: {'; '.join(load['errors'][:3])}")
    lines.append(f"\n(benchmark took {time.perf_counter() - started:.0f} s)")
    write_section("Server", "python3 dev.py bench server", lines)


if __name__ == "__main__":
    main()
