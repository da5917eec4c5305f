"""Per-query cost of `lakegate serve`: the server's CPU for one `SELECT 1`, this tree against a
baseline revision, measured in the same run.

    python3 dev.py bench per_query [--baseline REV] [--rounds R] [--queries N]

Uses the translate benchmark's lake (bench/.work/translate), and the baseline's files as
`git archive REV` gives them (bench/.work/per_query/REV, imported through PYTHONPATH in place of
this tree). Starts `lakegate serve` on 127.0.0.1 from each in turn, `--rounds` times alternating
(baseline first), and runs `SELECT 1` through the trino client: after 50 warm-up queries, 3 blocks
of N, each giving the CPU (user + system) of the server's processes per query (its own process and
its query workers, also its own process alone) and the wall time per query.

Writes section "Per-query cost" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, write_section  # noqa: E402
from server import Server, client_rows  # noqa: E402
from starvation import own_cpu  # noqa: E402
from translate import build_lake  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "per_query"


def baseline_path(revision: str) -> Path:
    """A directory whose `lakegate` is the files of `revision` (built once per commit)."""
    commit = subprocess.check_output(["git", "rev-parse", "--short", revision], cwd=ROOT, text=True).strip()
    path = WORK / commit
    if not (path / "READY").exists():
        shutil.rmtree(path, ignore_errors=True)
        (path / "lakegate").mkdir(parents=True)
        archive = subprocess.run(["git", "archive", commit], cwd=ROOT, capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(path / "lakegate")], input=archive, check=True)
        (path / "READY").write_text(commit)
    return path


def measure(
    lake: Path, queries: int, pythonpath: Path | None, extra: list[str], warm_up: int = 50
) -> list[tuple[float, float, float]]:
    """(server CPU ms, own-process CPU ms, wall ms) per `SELECT 1`, for 3 blocks of `queries` after
    `warm_up` queries."""
    if pythonpath is None:
        os.environ.pop("PYTHONPATH", None)
    else:
        os.environ["PYTHONPATH"] = str(pythonpath)
    try:
        server = Server(lake, extra)
    finally:
        os.environ.pop("PYTHONPATH", None)
    blocks = []
    try:
        connection = server.connect()
        for _ in range(warm_up):
            client_rows(connection, "SELECT 1")
        for _ in range(3):
            total, own, start = server.cpu(), own_cpu(server), time.perf_counter()
            for _ in range(queries):
                client_rows(connection, "SELECT 1")
            blocks.append(
                (
                    (server.cpu() - total) / queries * 1e3,
                    (own_cpu(server) - own) / queries * 1e3,
                    (time.perf_counter() - start) / queries * 1e3,
                )
            )
    finally:
        server.stop()
    return blocks


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--baseline", default="HEAD", help="the git revision to compare with (default HEAD)")
    parser.add_argument("--rounds", type=int, default=3, help="baseline / this tree server pairs (default 3)")
    parser.add_argument("--queries", type=int, default=300, help="SELECT 1 per measured block (default 300)")
    parser.add_argument("--slots", type=int, help="the servers' --max-concurrent-queries (default: theirs)")
    args = parse_args(parser, argv, rounds=1, queries=5, slots=1)
    extra = [] if args.slots is None else ["--max-concurrent-queries", str(args.slots)]
    started, load_start = time.perf_counter(), os.getloadavg()[0]
    lake = build_lake(200_000)
    base = baseline_path(args.baseline)
    runs: dict[str, list[tuple[float, float, float]]] = {"baseline": [], "this tree": []}
    for _ in range(args.rounds):
        runs["baseline"] += measure(lake, args.queries, base, extra, min(50, args.queries))
        runs["this tree"] += measure(lake, args.queries, None, extra, min(50, args.queries))

    def median(name: str, i: int) -> float:
        return statistics.median(block[i] for block in runs[name])

    rows = [
        f"| {name} | {median(name, 0):.2f} ms | {median(name, 1):.2f} ms | {median(name, 2):.2f} ms | "
        f"{median(name, 0) / median('baseline', 0):.2f}x |"
        for name in runs
    ]
    write_section(
        "Per-query cost",
        f"python3 dev.py bench per_query --baseline {args.baseline}",
        [
            f"`SELECT 1` through the trino client on `lakegate serve {' '.join(extra)}` (127.0.0.1, the lake of "
            f"bench/.work/translate), the baseline ({(base / 'READY').read_text()}) and this tree alternating, "
            f"{args.rounds} servers each; per server 50 warm-up queries, then 3 blocks of {args.queries}. Medians "
            f"of the blocks. Load average (1 min) at the start {load_start:.1f}, at the end "
            f"{os.getloadavg()[0]:.1f}, on {os.cpu_count()} cores: a loaded machine inflates CPU time too.",
            "",
            "| server | CPU per query (server and its query workers) | its own process | wall per query | CPU "
            "vs baseline |",
            "|---|---:|---:|---:|---:|",
            *rows,
            "",
            "- CPU per query of each block (ms): "
            + "; ".join(f"{name} {', '.join(f'{b[0]:.2f}' for b in blocks)}" for name, blocks in runs.items()),
            f"(benchmark took {time.perf_counter() - started:.0f} s)",
        ],
    )


if __name__ == "__main__":
    main()
