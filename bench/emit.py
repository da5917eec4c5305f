"""Benchmark: the Emitter's validated emit() and emit_series() rates against the two reference Emitters.

The references are `resim.metrics.python.emissions.Emitter` of PyPI `resim-open-core` 1.6.0 and
`signalflag.sdk.metrics.emissions.Emitter` of PyPI `signalflag` 1.8.0, each installed into its own
venv (created on first run, kept per machine: results.VENVS). Each measurement runs in a fresh subprocess, ours
and the references' alternating, all validating against fixtures/config.resim.yaml and writing to
a file under bench/.work/; a rate is the median of RUNS runs and includes close().

    python3 dev.py bench emit [--runs 5] [--emits 200000] [--points 200000]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import time
import venv
from pathlib import Path

from results import VENVS, parse_args, venv_lock, write_section  # bench/ is on sys.path when this file runs as a script

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work"
CONFIG = ROOT / "fixtures" / "config.resim.yaml"
TOPIC = "odom_linear_velocity"
GOAL = 5.0  # validated emit() at least 5x each reference's rate
SERIES_GOAL = 10.0  # emit_series() points at least 10x each reference's rate
#: Measured by hand (cProfile), not by this script: written under the table as it is.
PROFILE_NOTE = (
    "- where the time goes in `emit_series()` of 200,000 3-float points (cProfile and per-phase timings, "
    "measured once, not by this script): before the column path, the record-by-record loop (per-value "
    "type checks, one `orjson.dumps` per value, one %-format per line) took about 75% and queueing, "
    "joining and writing the lines about 25%; now, checking the columns (exact-type counts, min/max of "
    "the timestamps, NumPy finiteness and magnitude tests) about 25%, one `orjson.dumps` per block of "
    "4,096 lines about 30%, one `bytes.translate` per block about 20%, laying out the blocks' flat lists "
    "about 6%, the write about 15%. Validated `emit()` of the 3-float topic (CPU ns per emit, all "
    "threads, medians of 7 in one process): ~1,200 with chunks of 8,192 handed to the flusher thread: the"
    " bench's own loop (the dict, the call) ~185; the emitting thread ~550 (checks ~220, of which the "
    "three floats' type, finiteness and magnitude ~130; the calls `emit` -> the topic's row function "
    "~100; queueing the row); the flusher thread ~465 (`orjson.dumps` of the rows ~175, `bytes.translate`"
    " ~140, popping and grouping ~35, freeing the rows and the write the rest). In fresh processes, as "
    "this script runs, the hand-over cost ~250 more (a chunk of 8,192 rows and its text outgrow the CPU's"
    " cache: 4,096 was nearly as slow, 2,048 and 1,024 alike fast): chunks of 1,024 written by the "
    "emitting thread itself take 1,470 -> 1,170 (5 alternating fresh runs each)."
    " Not taken: checks inlined into one generated `emit` per Emitter (~50 less, but a reference cycle), "
    "separators as `str` (~13 less), other block layouts (slower)"
)
#: Each reference: its venv, the distribution pinned into it, and the module holding its Emitter.
REFERENCES = {
    "resim": (VENVS / "resim-open-core-1.6.0", "resim-open-core==1.6.0", "resim.metrics.python.emissions"),
    "signalflag": (VENVS / "signalflag-1.8.0", "signalflag==1.8.0", "signalflag.sdk.metrics.emissions"),
}
IMPLS = ("ours", *REFERENCES)


def python_of(impl: str) -> str:
    return sys.executable if impl == "ours" else str(REFERENCES[impl][0] / "bin" / "python")


def ensure_reference(impl: str) -> str:
    """Create the reference's venv and install its pinned distribution if needed; its version."""
    venv_dir, requirement, module = REFERENCES[impl]
    dist = requirement.split("==")[0]
    python = python_of(impl)
    probe = [python, "-c", f"from importlib.metadata import version; import {module}; print(version({dist!r}))"]
    with venv_lock(venv_dir):
        if Path(python).exists():
            found = subprocess.run(probe, capture_output=True, text=True)
            if found.returncode == 0 and found.stdout.strip() == requirement.split("==")[1]:
                return found.stdout.strip()
        print(f"installing {requirement} into {venv_dir} ...", file=sys.stderr, flush=True)
        venv.EnvBuilder(with_pip=True, clear=True).create(venv_dir)
        subprocess.run([python, "-m", "pip", "install", "-q", "--disable-pip-version-check", requirement], check=True)
        return subprocess.run(probe, capture_output=True, text=True, check=True).stdout.strip()


def worker(impl: str, mode: str, count: int, out: Path) -> None:
    """Run in a subprocess: time `count` emits (or series points) and print the rate as JSON."""
    if impl == "ours":
        from lakegate.lake.emitter import Emitter
    elif impl == "resim":
        from resim.metrics.python.emissions import Emitter
    else:
        from signalflag.sdk.metrics.emissions import Emitter
    rng = random.Random(1)
    xs, ys, zs = ([rng.uniform(-2, 2) for _ in range(count)] for _ in range(3))
    out.unlink(missing_ok=True)
    emitter = Emitter(config_path=str(CONFIG), output_path=str(out))
    start, cpu_start = time.perf_counter(), time.process_time()
    if mode == "emit":
        emit = emitter.emit
        for i in range(count):
            emit(TOPIC, {"x": xs[i], "y": ys[i], "z": zs[i]}, timestamp=i)
    else:
        emitter.emit_series(TOPIC, {"x": xs, "y": ys, "z": zs}, timestamps=list(range(count)))
    emitter.close()
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    print(json.dumps({"wall": count / wall, "cpu": count / cpu}))


def measure(impl: str, mode: str, count: int) -> dict[str, float]:
    """One run in a fresh process: rates per second of wall-clock and of process CPU time."""
    python = python_of(impl)
    out = WORK / f"emit-{impl}-{mode}.jsonl"
    result = subprocess.run(
        [python, __file__, "--worker", impl, mode, str(count), str(out)], capture_output=True, text=True, check=True
    )
    with out.open() as lines:
        written = sum(1 for _ in lines)
    if written != count:
        raise SystemExit(f"{impl} {mode}: wrote {written} lines, expected {count}")
    return json.loads(result.stdout)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=5, help="runs per measurement; the median is reported (default 5)")
    parser.add_argument("--emits", type=int, default=200_000, help="emit() calls per run (default 200000)")
    parser.add_argument("--points", type=int, default=200_000, help="points per emit_series() run (default 200000)")
    parser.add_argument("--worker", nargs=4, metavar=("IMPL", "MODE", "COUNT", "OUT"), help=argparse.SUPPRESS)
    args = parse_args(parser, runs=1, emits=2_000, points=2_000)
    if args.worker:
        impl, mode, count, out = args.worker
        worker(impl, mode, int(count), Path(out))
        return 0

    WORK.mkdir(parents=True, exist_ok=True)
    versions = {impl: ensure_reference(impl) for impl in REFERENCES}
    load_start = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    runs: dict[tuple[str, str], list[dict[str, float]]] = {}
    for mode, count in (("emit", args.emits), ("series", args.points)):
        for run in range(args.runs):
            for impl in IMPLS:  # alternate, so that load changes hit all alike
                runs.setdefault((impl, mode), []).append(measure(impl, mode, count))
            print(
                f"{mode} run {run + 1}/{args.runs}: "
                + ", ".join(f"{impl} {runs[impl, mode][-1]['cpu']:,.0f}/s" for impl in IMPLS)
                + " (CPU time)",
                file=sys.stderr,
                flush=True,
            )
    identical = {
        (impl, mode): (WORK / f"emit-{impl}-{mode}.jsonl").read_bytes()
        == (WORK / f"emit-ours-{mode}.jsonl").read_bytes()
        for impl in REFERENCES
        for mode in ("emit", "series")
    }
    for scratch in WORK.glob("emit-*.jsonl"):
        scratch.unlink()

    def rate(impl: str, mode: str, clock: str) -> float:
        return statistics.median(r[clock] for r in runs[impl, mode])

    def row(mode: str, what: str, clock: str) -> str:
        ours = rate("ours", mode, clock)
        refs = [rate(impl, mode, clock) for impl in REFERENCES]
        figures = " / ".join(", ".join(f"{r[clock] / 1000:.0f}k" for r in runs[impl, mode]) for impl in IMPLS)
        per = {"cpu": "per CPU second", "wall": "per wall-clock second"}[clock]
        return (
            f"| {what}, {per} | {ours:,.0f} /s | "
            + " | ".join(f"{ref:,.0f} /s | {ours / ref:.2f}x" for ref in refs)
            + f" | {figures} |"
        )

    emit_what = f"validated `emit()`, 3-float topic ({args.emits:,} emits)"
    series_what = f"`emit_series()` points ({args.points:,} points in one call)"
    ratio = {
        (impl, mode): rate("ours", mode, "cpu") / rate(impl, mode, "cpu")
        for impl in REFERENCES
        for mode in ("emit", "series")
    }
    met = all(ratio[impl, "emit"] >= GOAL for impl in REFERENCES)
    series_met = all(ratio[impl, "series"] >= SERIES_GOAL for impl in REFERENCES)
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    names = {"resim": f"resim-open-core {versions['resim']}", "signalflag": f"signalflag {versions['signalflag']}"}
    write_section(
        "Emitter",
        "python3 dev.py bench emit",
        [
            "- baselines: the reference `Emitter`s of "
            + " and ".join(names.values())
            + " (each in its own venv), validating against the same config, measured in the same run; runs "
            "alternate lakegate / resim / signalflag, each in a fresh process",
            f"- median of {args.runs} runs, including `close()`; random full-precision floats. Rates per second of "
            "process CPU time (all threads) are the figures judged, as they are least disturbed by other load on "
            f"this shared machine; wall-clock rates are shown too. Load average (1, 5, 15 min) at the start: "
            f"{load_start}; at the end: {load}",
            "",
            "| measure | lakegate | resim | ratio | signalflag | ratio | runs (lakegate / resim / signalflag) |",
            "|---|---|---|---|---|---|---|",
            row("emit", emit_what, "cpu"),
            row("emit", emit_what, "wall"),
            row("series", series_what, "cpu"),
            row("series", series_what, "wall"),
            "",
            f"- goal: validated `emit()` >= {GOAL:.0f}x each reference per CPU second: "
            f"**{'met' if met else 'NOT met'}** ("
            + ", ".join(f"{ratio[impl, 'emit']:.2f}x {names[impl]}" for impl in REFERENCES)
            + f"); `emit_series()` points >= {SERIES_GOAL:.0f}x each reference per CPU second: "
            f"**{'met' if series_met else 'NOT met'}** ("
            + ", ".join(f"{ratio[impl, 'series']:.2f}x {names[impl]}" for impl in REFERENCES)
            + ")",
            "- the emissions files of the last runs are byte-identical to each reference's: "
            + "; ".join(
                f"{names[impl]}: `emit()` {'yes' if identical[impl, 'emit'] else 'NO'}, "
                f"`emit_series()` {'yes' if identical[impl, 'series'] else 'NO'}"
                for impl in REFERENCES
            ),
            PROFILE_NOTE,
        ],
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
