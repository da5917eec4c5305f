"""The differential fuzzer: random Trino queries over a small lake, answered by lakegate and by the
real Trino reading the same Parquet files; every difference is a mismatch (`python3 dev.py fuzz`).

    python3 dev.py fuzz --queries N --seed S [--trino URL] [--out FILE] [--lake DIR] [--jobs K] [--seconds T]
    python3 dev.py fuzz --queries N --seed S --from I --to J --slice FILE [--out FILE]   (one slice)
    python3 dev.py fuzz --summary FILE...                                                (the slices' sum)

Prints `tried T, equal E, lakegate refused R, both errored B, mismatched M`:
equal: the same result types and rows; lakegate refused: lakegate said NOT_SUPPORTED (naming the
construct) or ran out of time where Trino answered; both errored: both raised an error (any); mismatched: anything
else (different values, types or row counts, lakegate answering where Trino raises, or lakegate
failing with another error where Trino answers). Each mismatch is a JSON line in --out with the
query and both answers. Exit status 1 when there was a mismatch.

A long run spans sessions in slices: query i of seed S depends only on (S, i), so `--from I --to J`
judges queries I..J-1 of the run alone and `--slice FILE` writes that slice's counts (JSON, once the
slice is complete; an interrupted slice writes nothing and is run again). `--summary FILE...` adds
the slices up into the run's one summary line, after checking that they are of one seed and one
generator (a fingerprint of the generator's code, the functions it calls and the lake's tables) and
do not overlap; it names the queries no slice covers yet.
"""

from __future__ import annotations

import argparse
import hashlib
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
from trino_fuzz import queries as fuzz_queries
from trino_fuzz.answer_match import differ
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


def fingerprint(shapes: list, tables: dict) -> str:
    """What decides the queries of a seed: the generator's code, the function shapes it calls and the
    lake's tables (slices of one run must share it)."""
    text = Path(fuzz_queries.__file__).read_text() + repr(shapes) + repr(sorted(tables.items()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def fuzz(
    queries: int,
    seed: int,
    trino_url: str,
    lake_dir: Path,
    out: Path | None,
    jobs: int = 4,
    progress: bool = False,
    seconds: float | None = None,
    start: int = 0,
    slice_file: Path | None = None,
) -> tuple[Counter, list[Verdict]]:
    """Generate and judge queries `start`..`queries`-1 of `seed` (fewer when `seconds` run out: a
    bounded run is a prefix of the unbounded one); the counts and the mismatches. With `slice_file`,
    a completed run writes its counts there (JSON, see `add_slices`)."""
    lake = fuzz_lake.build(lake_dir)
    schema_prefix = f"{SCHEMA_PREFIX}{os.getpid()}_"  # runs at once (CI, a long run) keep apart
    trino = Trino(trino_url, f"{schema_prefix}main")
    drop_orphans(trino, SCHEMA_PREFIX)
    register(trino, lake, schema_prefix)
    mine = Lakegate(lake)
    handle = out.open("w") if out is not None else None  # each mismatch is written as it is found
    counts: Counter = Counter()
    mismatches: list[Verdict] = []
    spent: Counter = Counter()  # seconds summed over the queries, per side
    began = time.monotonic()

    def settle(query: Query, theirs, ours) -> None:
        verdict = judge(query, ours.result(), theirs.result())
        counts[verdict.kind] += 1
        for name, outcome in (("lakegate", verdict.lakegate), ("trino", verdict.trino)):
            spent[f"{name}_seconds"] += outcome.seconds
        spent["trino_cpu_seconds"] += verdict.trino.cpu_seconds
        if verdict.kind == "mismatched":
            mismatches.append(verdict)
            if handle is not None:
                handle.write(json.dumps(record(verdict), ensure_ascii=False) + "\n")
                handle.flush()
        if progress and sum(counts.values()) % PROGRESS == 0:
            print(f"... {summary(counts)}", file=sys.stderr, flush=True)

    try:
        tables = {name: list(columns.items()) for name, columns in mine.engine.backend.schema("main").items()}
        shapes = discover()
        generator = Generator(seed, shapes, tables)
        deadline = time.monotonic() + seconds if seconds else None
        in_flight: deque = deque()
        stop = queries
        with ThreadPoolExecutor(jobs) as pool, ThreadPoolExecutor(LAKEGATE_THREADS) as own:
            for index in range(start, queries):
                if deadline is not None and time.monotonic() > deadline:
                    stop = index
                    break
                query = generator.query(index)
                in_flight.append((query, pool.submit(trino.run, query.sql), own.submit(mine.run, query.sql)))
                while len(in_flight) > WINDOW or (in_flight and in_flight[0][1].done() and in_flight[0][2].done()):
                    settle(*in_flight.popleft())
            while in_flight:
                settle(*in_flight.popleft())
        if progress:
            print(timing(counts, spent, time.monotonic() - began), file=sys.stderr, flush=True)
        if slice_file is not None:
            record_slice(slice_file, seed, start, stop, fingerprint(shapes, tables), counts)
    finally:
        mine.close()
        unregister(trino, f"{schema_prefix}main")
        if handle is not None:
            handle.close()
    return counts, mismatches


def timing(counts: Counter, spent: Counter, wall: float) -> str:
    """Where the queries' time went: the rate, and each side's seconds per query."""
    tried = max(sum(counts.values()), 1)
    return (
        f"{60 * tried / max(wall, 1e-9):.0f} queries/min ({wall:.0f} s wall); per query: lakegate "
        f"{1000 * spent['lakegate_seconds'] / tried:.0f} ms wall, Trino {1000 * spent['trino_seconds'] / tried:.0f} "
        f"ms wall ({1000 * spent['trino_cpu_seconds'] / tried:.0f} ms CPU in its query stats)"
    )


KINDS = ("equal", "refused", "both_errored", "mismatched")


def record_slice(path: Path, seed: int, start: int, stop: int, generator: str, counts: Counter) -> None:
    """Write a completed slice's counts (whole or not at all: through a temporary file)."""
    entry = {"seed": seed, "from": start, "to": stop, "generator": generator, **{k: counts[k] for k in KINDS}}
    temporary = path.with_name(path.name + ".partial")
    temporary.write_text(json.dumps(entry) + "\n")
    temporary.replace(path)


def add_slices(paths: list[Path]) -> tuple[Counter, str]:
    """The counts of slice files added up, and what they cover ("queries 0..1000 of seed 5, generator
    <fingerprint>", with any gaps); ValueError when they are of different runs or overlap."""
    entries = sorted((json.loads(path.read_text()) | {"file": str(path)} for path in paths), key=lambda e: e["from"])
    if not entries:
        raise ValueError("no slice files given")
    runs = {(e["seed"], e["generator"]) for e in entries}
    if len(runs) > 1:
        raise ValueError(f"slices of different runs (seed, generator): {sorted(runs)}")
    counts: Counter = Counter()
    covered, gaps = entries[0]["from"], [f"{0}..{entries[0]['from']}"] if entries[0]["from"] else []
    for previous, entry in zip([None, *entries], entries):
        if previous is not None and entry["from"] < previous["to"]:
            raise ValueError(
                f"{entry['file']} (from {entry['from']}) overlaps {previous['file']} (to {previous['to']})"
            )
        if entry["from"] > covered:
            gaps.append(f"{covered}..{entry['from']}")
        if sum(entry[k] for k in KINDS) != entry["to"] - entry["from"]:
            raise ValueError(f"{entry['file']}: its counts do not add up to its {entry['to'] - entry['from']} queries")
        counts.update({k: entry[k] for k in KINDS})
        covered = entry["to"]
    seed, generator = runs.pop()
    missing = f"; not run yet: queries {', '.join(gaps)}" if gaps else ""
    return counts, f"queries 0..{covered} of seed {seed}, generator {generator}{missing}"


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
    parser.add_argument(
        "--from", dest="start", type=int, default=0, metavar="I", help="the slice's first query (default 0)"
    )
    parser.add_argument("--to", type=int, metavar="J", help="the slice ends before query J (default N)")
    parser.add_argument(
        "--slice", type=Path, metavar="FILE", help="write the completed slice's counts here (for --summary)"
    )
    parser.add_argument(
        "--summary",
        type=Path,
        nargs="+",
        metavar="FILE",
        help="print the summary line of the slices' files added up (runs no query)",
    )
    args = parser.parse_args(argv)
    if args.summary:
        try:
            counts, coverage = add_slices(args.summary)
        except (ValueError, KeyError, OSError) as error:
            parser.error(f"--summary: {error}")
        print(summary(counts))
        print(coverage)
        return 1 if counts["mismatched"] else 0
    stop = args.queries if args.to is None else args.to
    if not 0 <= args.start <= stop <= args.queries:
        parser.error(f"--from {args.start} --to {stop}: need 0 <= I <= J <= N ({args.queries})")
    counts, mismatches = fuzz(
        stop,
        args.seed,
        args.trino,
        args.lake,
        args.out,
        args.jobs,
        progress=True,
        seconds=args.seconds,
        start=args.start,
        slice_file=args.slice,
    )
    print(summary(counts))
    if mismatches:
        print(f"mismatches written to {args.out}")
    return 1 if mismatches else 0


if __name__ == "__main__":
    sys.exit(main())
