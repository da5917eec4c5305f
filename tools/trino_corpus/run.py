"""The differential run over Trino 476's own function tests (`python3 dev.py corpus`): every SQL that
the QueryAssertions calls of trinodb/trino's compiled tests run (tools/trino_corpus/probes.py),
answered by lakegate (embedded) and by the real Trino, each judged as the conformance differential
judges (tools/trino_differential.py: equal, refused, both errored, trino raises, different).

    python3 dev.py corpus [--smoke | --sample N] [--group functions,types,queries] [--trino URL] [--out FILE]
    python3 dev.py corpus --refusals K     only translate: the K largest families of refusals (no Trino)

Queries of functions drawn at random or from the clock (random, uuid, now, ...) are left out. Prints
one summary line per group and in all; writes every verdict that is not `equal` to --out
(default: report.txt in the corpus cache, outside the repository). Exit status 1 when a `different`
or `trino raises` verdict is not on the allow-list (tools/trino_corpus/known.py).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import trino_differential as differential
from trino_answers import TrinoAnswers

from trino_corpus import known
from trino_corpus.lakegate_side import answers as lakegate_answers
from trino_corpus.probes import CACHE, Probe, doc_examples, load

DEFAULT_TRINO = "http://127.0.0.1:18080"
#: The smoke size: the fixed sample the CI test runs.
SMOKE = 300
#: lakegate's refusals by name: Trino is expected to answer these, so they are asked in batches.
REFUSALS = ("NOT_SUPPORTED", "FUNCTION_NOT_FOUND")
KINDS = ("equal", "refused", "both errored", "trino raises", "different")


#: Functions whose answer is drawn at random or from the clock: their queries are not compared.
NONDETERMINISTIC = re.compile(r"\b(random|rand|uuid|shuffle|now|current_timestamp|localtimestamp)\b", re.IGNORECASE)


def deterministic(probes: Sequence[Probe]) -> list[Probe]:
    """The probes whose answer does not depend on chance or the clock."""
    return [p for p in probes if not NONDETERMINISTIC.search(p.sql)]


def sample(probes: Sequence[Probe], size: int) -> list[Probe]:
    """A fixed, evenly spread sample of `size` probes (every k-th, in the corpus's order)."""
    if size >= len(probes):
        return list(probes)
    step = len(probes) / size
    return [probes[int(i * step)] for i in range(size)]


def judge(probes: Sequence[Probe], trino_url: str) -> list[differential.Verdict]:
    """Each probe answered by lakegate and by Trino, and judged."""
    started = time.monotonic()
    ours = lakegate_answers([p.sql for p in probes])
    print(f"lakegate answered {len(probes)} queries in {time.monotonic() - started:.0f} s", file=sys.stderr)
    trino = TrinoAnswers(trino_url, catalog="memory", schema="default", threads=3)
    theirs = [None] * len(probes)
    for alone in (False, True):  # what lakegate fails (but refusals) is asked alone: a failure spoils a batch
        chosen = [i for i, answer in enumerate(ours) if (answer.error not in (None, *REFUSALS)) == alone]
        for index, answer in zip(chosen, trino.ask_all(((probes[i].sql, "UTC") for i in chosen), batch=not alone)):
            theirs[index] = answer
    return [differential.judge_answers(p.where, p.sql, o, t) for p, o, t in zip(probes, ours, theirs)]


def summary(name: str, verdicts: Sequence[differential.Verdict]) -> str:
    """`name: N queries, E equal (x %), ...`."""
    tally = Counter(v.kind for v in verdicts)
    total = len(verdicts) or 1
    parts = ", ".join(f"{tally[kind]} {kind} ({100 * tally[kind] / total:.1f} %)" for kind in KINDS)
    return f"{name}: {len(verdicts)} queries, {parts}"


def unexpected(verdicts: Sequence[differential.Verdict]) -> list[differential.Verdict]:
    """The failures (`different`, `trino raises`) that the allow-list does not name."""
    return [v for v in verdicts if v.kind in differential.FAILURES and v.sql not in known.KNOWN]


def report(path: Path, lines: Sequence[str], verdicts: Sequence[differential.Verdict]) -> None:
    """Write the summary lines, then every verdict that is not `equal`, by kind, to `path`."""
    refusals = Counter((v.lakegate.split(":")[0]) for v in verdicts if v.kind == "refused")
    text = [*lines, "", "refused, by lakegate's error: " + ", ".join(f"{n} {e}" for e, n in refusals.most_common())]
    for kind in ("different", "trino raises", "refused", "both errored"):
        listed = [v for v in verdicts if v.kind == kind]
        text += ["", f"## {kind} ({len(listed)})", ""]
        text += [str(v) + (f"\n  known: {known.KNOWN[v.sql]}" if v.sql in known.KNOWN else "") for v in listed]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(text) + "\n", encoding="utf-8")


def refusal_families(probes: Sequence[Probe]) -> Counter:
    """How many probes lakegate's translator refuses (NOT_SUPPORTED, FUNCTION_NOT_FOUND), by message with
    its digits replaced by N: the refusal families, without running anything."""
    from lakegate.dialect.errors import DialectError
    from lakegate.dialect.translate import translate

    families: Counter = Counter()
    for probe in probes:
        try:
            translate(probe.sql, {})
        except DialectError as error:
            if error.error_name in REFUSALS:
                families[re.sub(r"\d+", "N", f"{error.error_name}: {error.message}")[:160]] += 1
        except Exception:  # noqa: BLE001 - statements the translator does not take (SHOW, EXPLAIN, ...)
            families["not a query the translator takes"] += 1
    return families


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--smoke", action="store_true", help=f"the fixed sample of {SMOKE} queries the CI test runs")
    size.add_argument("--sample", type=int, help="an evenly spread sample of N queries")
    parser.add_argument(
        "--group",
        default="functions,types,queries",
        help="groups, comma-separated: functions, types, queries (Trino's tests), docs (its documentation's examples)",
    )
    parser.add_argument("--trino", default=DEFAULT_TRINO, help=f"the real Trino's URL (default {DEFAULT_TRINO})")
    parser.add_argument("--out", type=Path, default=CACHE / "report.txt", help="the report file")
    parser.add_argument(
        "--refusals",
        type=int,
        metavar="K",
        help="only translate (no Trino): print the K largest families of lakegate's refusals, with counts",
    )
    parser.add_argument("--refresh", action="store_true", help="extract the corpus again from the tests jar")
    args = parser.parse_args(argv)
    groups = args.group.split(",")
    probes = [p for p in load(args.refresh) if p.group in groups] + (doc_examples() if "docs" in groups else [])
    probes = deterministic(probes)
    if args.smoke or args.sample:
        probes = sample(probes, SMOKE if args.smoke else args.sample)
    if args.refusals:
        families = refusal_families(probes)
        print(f"{len(probes)} queries, {sum(families.values())} refused by the translator:")
        for message, count in families.most_common(args.refusals):
            print(f"{count:6d}  {message}")
        return 0
    started = time.monotonic()
    verdicts = judge(probes, args.trino)
    lines = [summary(group, [v for p, v in zip(probes, verdicts) if p.group == group]) for group in groups]
    lines.append(summary("all", verdicts))
    lines.append(f"({time.monotonic() - started:.0f} s; Trino at {args.trino}; report {args.out})")
    report(args.out, lines, verdicts)
    print("\n".join(lines))
    failing = unexpected(verdicts)
    for verdict in failing[:20]:
        print(verdict)
    return 1 if failing else 0


if __name__ == "__main__":
    sys.exit(main())
