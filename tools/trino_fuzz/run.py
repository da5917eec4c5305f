"""The differential fuzzer: random Trino queries over a small lake, answered by lakegate and by the
real Trino reading the same Parquet files; every difference is a mismatch (`python3 dev.py fuzz`).

    python3 dev.py fuzz --queries N --seed S [--trino URL] [--out FILE] [--lake DIR] [--jobs K] [--seconds T]

Prints `tried T, equal E, lakegate refused R, both errored B, mismatched M`:
equal: the same result types and rows; lakegate refused: lakegate said NOT_SUPPORTED (naming the
construct) or ran out of time where Trino answered; both errored: both raised an error (any); mismatched: anything
else (different values, types or row counts, lakegate answering where Trino raises, or lakegate
failing with another error where Trino answers). Each mismatch is a JSON line in --out with the
query and both answers. Exit status 1 when there was a mismatch.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections import Counter, deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from trino_fuzz import lake as fuzz_lake
from trino_fuzz.compare import differ
from trino_fuzz.functions import discover
from trino_fuzz.queries import Generator, Query
from trino_fuzz.sides import Lakegate, Outcome, Trino, drop_orphans, register, unregister

DEFAULT_TRINO = "http://127.0.0.1:18080"
SCHEMA_PREFIX = "fuzzer_"
#: lakegate's refusals: the construct is named and not answered (never a silent difference); a
#: query that ran out of time is counted here too (a resource limit, which depends on the machine).
REFUSALS = frozenset({"NOT_SUPPORTED", "EXCEEDED_TIME_LIMIT"})
#: Queries lakegate's Engine runs at once (as the server does).
LAKEGATE_THREADS = 2
#: Queries in flight at once (sent to both sides, not judged yet): each side works through them at
#: its own pace, so neither waits for the other's slowest query of a batch.
WINDOW = 64
#: Progress is printed every this many queries.
PROGRESS = 500


@dataclass
class Verdict:
    query: Query
    kind: str  # equal | refused | both_errored | mismatched
    lakegate: Outcome
    trino: Outcome
    why: str = ""


def judge(query: Query, mine: Outcome, theirs: Outcome) -> Verdict:
    if mine.error and theirs.error:
        return Verdict(query, "both_errored", mine, theirs)
    if mine.error in REFUSALS:
        return Verdict(query, "refused", mine, theirs)
    if mine.error:
        return Verdict(query, "mismatched", mine, theirs, f"lakegate raised {mine.error} where Trino answers")
    if theirs.error:
        return Verdict(query, "mismatched", mine, theirs, f"lakegate answers where Trino raises {theirs.error}")
    why = differ(mine, theirs, query.ordered)
    return Verdict(query, "mismatched" if why else "equal", mine, theirs, why or "")


def record(verdict: Verdict) -> dict:
    """A mismatch as written to --out: the query and both answers."""
    return {
        "query": verdict.query.sql,
        "ordered": verdict.query.ordered,
        "why": verdict.why,
        "lakegate": verdict.lakegate.as_dict(),
        "trino": verdict.trino.as_dict(),
    }


def summary(counts: Counter) -> str:
    tried = sum(counts.values())
    return (
        f"tried {tried}, equal {counts['equal']}, lakegate refused {counts['refused']}, "
        f"both errored {counts['both_errored']}, mismatched {counts['mismatched']}"
    )


def fuzz(
    queries: int,
    seed: int,
    trino_url: str,
    lake_dir: Path,
    out: Path | None,
    jobs: int = 4,
    progress: bool = False,
    seconds: float | None = None,
) -> tuple[Counter, list[Verdict]]:
    """Generate and judge `queries` queries (fewer when `seconds` run out: the generator's order is
    the same, so a bounded run is a prefix of the unbounded one); the counts and the mismatches."""
    lake = fuzz_lake.build(lake_dir)
    schema_prefix = f"{SCHEMA_PREFIX}{os.getpid()}_"  # runs at once (CI, a long run) keep apart
    trino = Trino(trino_url, f"{schema_prefix}main")
    drop_orphans(trino, SCHEMA_PREFIX)
    register(trino, lake, schema_prefix)
    mine = Lakegate(lake)
    handle = out.open("w") if out is not None else None  # each mismatch is written as it is found
    counts: Counter = Counter()
    mismatches: list[Verdict] = []

    def settle(query: Query, theirs, ours) -> None:
        verdict = judge(query, ours.result(), theirs.result())
        counts[verdict.kind] += 1
        if verdict.kind == "mismatched":
            mismatches.append(verdict)
            if handle is not None:
                handle.write(json.dumps(record(verdict), ensure_ascii=False) + "\n")
                handle.flush()
        if progress and sum(counts.values()) % PROGRESS == 0:
            print(f"... {summary(counts)}", file=sys.stderr, flush=True)

    try:
        tables = {name: list(columns.items()) for name, columns in mine.engine.backend.schema("main").items()}
        generator = Generator(seed, discover(), tables)
        deadline = time.monotonic() + seconds if seconds else None
        in_flight: deque = deque()
        with ThreadPoolExecutor(jobs) as pool, ThreadPoolExecutor(LAKEGATE_THREADS) as own:
            for _ in range(queries):
                if deadline is not None and time.monotonic() > deadline:
                    break
                query = generator.query()
                in_flight.append((query, pool.submit(trino.run, query.sql), own.submit(mine.run, query.sql)))
                while len(in_flight) > WINDOW or (in_flight and in_flight[0][1].done() and in_flight[0][2].done()):
                    settle(*in_flight.popleft())
            while in_flight:
                settle(*in_flight.popleft())
    finally:
        mine.close()
        unregister(trino, f"{schema_prefix}main")
        if handle is not None:
            handle.close()
    return counts, mismatches


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="dev.py fuzz", description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--queries", type=int, default=1000, metavar="N", help="how many queries (default 1000)")
    parser.add_argument("--seed", type=int, default=1, metavar="S", help="the random seed (default 1)")
    parser.add_argument(
        "--trino", default=DEFAULT_TRINO, metavar="URL", help=f"the real Trino (default {DEFAULT_TRINO})"
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("fuzz-mismatches.jsonl"),
        metavar="FILE",
        help="where each mismatch goes, one JSON line each (default fuzz-mismatches.jsonl)",
    )
    parser.add_argument(
        "--lake",
        type=Path,
        default=Path(tempfile.gettempdir()) / "lakegate-fuzz" / "lake",
        metavar="DIR",
        help="where the fuzz lake is built (reused when up to date)",
    )
    parser.add_argument("--jobs", type=int, default=4, metavar="K", help="queries Trino runs at once (default 4)")
    parser.add_argument(
        "--seconds", type=float, metavar="T", help="stop generating after about T seconds (the summary counts what ran)"
    )
    args = parser.parse_args(argv)
    counts, mismatches = fuzz(
        args.queries,
        args.seed,
        args.trino,
        args.lake,
        args.out,
        args.jobs,
        progress=True,
        seconds=args.seconds,
    )
    print(summary(counts))
    if mismatches:
        print(f"mismatches written to {args.out}")
    return 1 if mismatches else 0


if __name__ == "__main__":
    sys.exit(main())
