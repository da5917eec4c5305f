"""Against the peer: `lakegate serve` and buenavista 0.5.0 (a DuckDB server speaking Trino's
protocol) over the same Parquet lake, through the same official trino client.

    python3 dev.py bench peer [--rows 10000000] [--select1 300] [--aggregates 5] [--rounds 3]

buenavista is installed by this bench into its own venv (results.VENVS/buenavista-0.5.0, kept per
machine: pip, from PyPI, `buenavista==0.5.0 "duckdb>=1,<2" pyarrow uvicorn`) and served as its
`examples/duckdb_http.py` shows (`http.main.quacko` with that example's Trino-to-DuckDB rewriter), on
an in-memory DuckDB (2 threads, as lakegate's) whose catalog `lake` holds the lake's own views
(`Catalog.view_sql`) over the same Parquet files. One patch, to the bench's copy only: buenavista's
`http/schemas.py` declares `QueryResult`'s optional fields without defaults, which pydantic 2
treats as required, so every answer fails validation; the bench gives them `= None`.

Both servers run side by side on 127.0.0.1; each round measures every workload on one server
then the other (which goes first alternates by round): `SELECT 1` (after 20 warm-up queries),
a GROUP BY aggregate over the topic (bench/server.py's AGGREGATE), and the fetch of one job's
rows x 3 columns (rows/10: 1,000,000 by default). For each, the wall time and the CPU (user +
system) of the server's processes per query; medians over the rounds' queries. Results are
checked equal in shape (row count, columns) between the servers.

Writes section "Against buenavista" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import trino

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import VENVS, parse_args, venv_lock, wait_serving, write_section  # noqa: E402
from server import AGGREGATE, FETCH, THREADS, Server, client_rows, free_port  # noqa: E402
from translate import build_lake  # noqa: E402

from lakegate.lake.catalog import Catalog  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "peer"
VERSION = "0.5.0"
PACKAGES = [f"buenavista=={VERSION}", "duckdb>=1,<2", "pyarrow", "uvicorn"]

#: buenavista's Trino-protocol server as its examples/duckdb_http.py runs it, over the lake's views.
SERVE = r"""
import json, sys
import duckdb, uvicorn
from fastapi import FastAPI
from buenavista.examples.duckdb_http import rewriter
from buenavista.backends.duckdb import DuckDBConnection
from buenavista.http import main

views, port, threads = json.load(open(sys.argv[1])), int(sys.argv[2]), int(sys.argv[3])
db = duckdb.connect(config={"threads": threads})
db.execute("ATTACH ':memory:' AS lake")
db.execute("USE lake")
for name, select in views.items():
    db.execute(f'CREATE VIEW "{name}" AS {select}')
app = FastAPI()
main.quacko(app, DuckDBConnection(db), rewriter)
uvicorn.run(app, host="127.0.0.1", port=port, log_level="warning")
"""

#: Optional fields of buenavista's QueryResult that pydantic 2 reads as required without a default.
OPTIONAL_FIELDS = ("partial_cancel_uri", "columns", "data", "update_type", "update_count")


def install_buenavista() -> Path:
    """The Python of the bench's buenavista venv, installed and patched once per machine."""
    with venv_lock(VENVS / f"buenavista-{VERSION}") as venv:
        python, ready = venv / "bin" / "python", venv / "READY"
        if not ready.exists():
            _install(venv, python, ready)
    return python


def _install(venv: Path, python: Path, ready: Path) -> None:
    """Create `venv` afresh, install PACKAGES into it, patch buenavista, then write `ready` (pip freeze)."""
    subprocess.run([sys.executable, "-m", "venv", "--clear", str(venv)], check=True)
    subprocess.run([str(python), "-m", "pip", "install", "-q", *PACKAGES], check=True)
    site = subprocess.check_output(
        [str(python), "-c", "import buenavista, os; print(os.path.dirname(buenavista.__file__))"], text=True
    ).strip()
    schemas = Path(site) / "http" / "schemas.py"
    text = schemas.read_text()
    for field in OPTIONAL_FIELDS:
        start = text.index(f"    {field}: Optional[")
        end = text.index("\n", start)
        if not text[start:end].endswith("= None"):
            text = text[:end] + " = None" + text[end:]
    schemas.write_text(text)
    ready.write_text(subprocess.check_output([str(python), "-m", "pip", "freeze"], text=True))


class Buenavista(Server):
    """buenavista's Trino-protocol server in a subprocess on 127.0.0.1 (same cpu/pids/connect/stop)."""

    def __init__(self, python: Path, lake: Path):  # noqa: D107 - replaces Server's command only
        self.port = free_port()
        views = WORK / "views.json"
        views.write_text(json.dumps(Catalog(lake).view_sql("main")))
        script = WORK / "serve_buenavista.py"
        script.write_text(SERVE)
        self.log = open(WORK / "buenavista.log", "w")
        command = [str(python), str(script), str(views), str(self.port), str(THREADS)]
        self.process = subprocess.Popen(command, stdout=self.log, stderr=subprocess.STDOUT)
        wait_serving(self.process, self.port, self.stop, "buenavista", self.log.name)


def run_block(server: Server, connection: trino.dbapi.Connection, sql: str, count: int) -> tuple[list, float, set]:
    """`count` runs of `sql`: the wall seconds of each, the server's CPU seconds per run over the block
    (the kernel counts CPU in clock ticks, too coarse for one query) and the row counts seen."""
    walls, shapes, cpu = [], set(), server.cpu()
    for _ in range(count):
        start = time.perf_counter()
        shapes.add(len(client_rows(connection, sql)))
        walls.append(time.perf_counter() - start)
    return walls, (server.cpu() - cpu) / count, shapes


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", type=int, default=10_000_000, help="rows of the bench lake (default 10,000,000)")
    parser.add_argument("--select1", type=int, default=300, help="SELECT 1 per server per round (default 300)")
    parser.add_argument("--aggregates", type=int, default=5, help="aggregates per server per round (default 5)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds over both servers (default 3)")
    args = parse_args(parser, argv, rows=20_000, select1=20, aggregates=2, rounds=1)
    started, load_start = time.perf_counter(), os.getloadavg()[0]
    WORK.mkdir(parents=True, exist_ok=True)
    lake = build_lake(args.rows)
    python = install_buenavista()
    fetch = FETCH + f" LIMIT {args.rows // 10}"
    workloads = [("SELECT 1", "SELECT 1", args.select1), ("aggregate", AGGREGATE, args.aggregates), ("fetch", fetch, 1)]
    servers: dict[str, Server] = {}
    walls: dict[tuple[str, str], list[float]] = {}
    cpus: dict[tuple[str, str], list[float]] = {}
    shapes: dict[tuple[str, str], set[int]] = {}
    try:
        servers["lakegate"] = Server(lake, [])
        servers["buenavista"] = Buenavista(python, lake)
        connections = {
            name: trino.dbapi.connect(
                host="127.0.0.1", port=server.port, user="bench", catalog="lake", schema="main", request_timeout=600
            )
            for name, server in servers.items()
        }
        for name in servers:
            run_block(servers[name], connections[name], "SELECT 1", 20)
            run_block(servers[name], connections[name], AGGREGATE, 1)
        for round_ in range(args.rounds):
            order = list(servers) if round_ % 2 == 0 else list(reversed(servers))
            for workload, sql, count in workloads:
                for name in order:
                    block_walls, cpu, seen = run_block(servers[name], connections[name], sql, count)
                    walls.setdefault((name, workload), []).extend(block_walls)
                    cpus.setdefault((name, workload), []).append(cpu)
                    shapes.setdefault((name, workload), set()).update(seen)
    finally:
        for server in servers.values():
            server.stop()
    for workload, _, _ in workloads:
        seen = {name: shapes[(name, workload)] for name in servers}
        if len({frozenset(s) for s in seen.values()}) != 1:
            raise SystemExit(f"{workload}: the servers disagree on the row count: {seen}")

    fetched = args.rows // 10
    rows = []
    for workload, _, _ in workloads:
        wall = {name: statistics.median(walls[(name, workload)]) for name in servers}
        cpu = {name: statistics.median(cpus[(name, workload)]) for name in servers}
        if workload == "fetch":
            cells = [f"{fetched / wall[n]:,.0f} rows/s ({wall[n]:.2f} s), CPU {cpu[n]:.2f} s" for n in servers]
        else:
            cells = [f"{wall[n] * 1e3:.2f} ms, CPU {cpu[n] * 1e3:.2f} ms" for n in servers]
        count = len(walls[("lakegate", workload)])
        ratio = wall["buenavista"] / wall["lakegate"]
        rows.append(
            f"| {workload} (n={count}) | {' | '.join(cells)} | {ratio:.2f}x | "
            f"{'lakegate' if ratio > 1 else 'buenavista'} |"
        )
    versions = (python.parent.parent / "READY").read_text().split()
    peer_versions = ", ".join(
        v for v in versions if v.split("==")[0].lower() in {"buenavista", "duckdb", "fastapi", "pydantic", "uvicorn"}
    )
    write_section(
        "Against buenavista",
        "python3 dev.py bench peer",
        [
            f"The bench lake of {args.rows:,} rows (bench/.work/translate), `lakegate serve` (defaults) and "
            f"buenavista {VERSION} (examples/duckdb_http.py's server, DuckDB {THREADS} threads; its venv: "
            f"{peer_versions}) side by side on 127.0.0.1, through the official trino client (one connection "
            "each, request timeout 600 s: buenavista sends a whole result in one reply); "
            f"{args.rounds} rounds, the servers alternating within each. Load average (1 min) at the "
            f"start {load_start:.1f}, at the end {os.getloadavg()[0]:.1f}, on {os.cpu_count()} cores. Medians; "
            "CPU is the server's processes (user + system) per query over each block, median of the blocks; "
            "the ratio is buenavista's wall time over lakegate's (above 1: lakegate ahead).",
            "",
            "| workload | lakegate | buenavista | ratio | ahead |",
            "|---|---:|---:|---:|---|",
            *rows,
            "",
            f"- workloads: `SELECT 1`; aggregate `{AGGREGATE}`; fetch `{fetch}` ({fetched:,} rows x 3 columns).",
            "- buenavista answers every statement in the POST's reply (no paging, the whole result in one JSON "
            "document), names `SELECT 1`'s column `1` (Trino: `_col0`) and reports DOUBLE columns as `real`.",
            f"(benchmark took {time.perf_counter() - started:.0f} s)",
        ],
    )


if __name__ == "__main__":
    main()
