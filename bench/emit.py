"""Benchmark: the Emitter's validated emit() and emit_series() rates against the reference Emitter.

The reference is `resim.metrics.python.emissions.Emitter` from PyPI `resim-open-core`, installed
into bench/.work/ref-venv (created on first run). Each measurement runs in a fresh subprocess,
ours and the reference's alternating, both validating against fixtures/config.resim.yaml and
writing to a file under bench/.work/; a rate is the median of RUNS runs and includes close().

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

from results import parse_args, write_section  # bench/ is on sys.path when this file runs as a script

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work"
REF_VENV = WORK / "ref-venv"
REF_PYTHON = REF_VENV / "bin" / "python"
CONFIG = ROOT / "fixtures" / "config.resim.yaml"
TOPIC = "odom_linear_velocity"
GOAL = 3.0  # validated emit() at least 3x the reference's rate


def ensure_reference() -> str:
    """Create the reference venv and install resim-open-core into it if needed; its version."""
    probe = [
        str(REF_PYTHON),
        "-c",
        "from importlib.metadata import version; import resim.metrics.python.emissions; "
        "print(version('resim-open-core'))",
    ]
    if REF_PYTHON.exists():
        found = subprocess.run(probe, capture_output=True, text=True)
        if found.returncode == 0:
            return found.stdout.strip()
    print(f"installing resim-open-core into {REF_VENV} ...", file=sys.stderr, flush=True)
    venv.EnvBuilder(with_pip=True, clear=True).create(REF_VENV)
    subprocess.run(
        [str(REF_PYTHON), "-m", "pip", "install", "-q", "--disable-pip-version-check", "resim-open-core"], check=True
    )
    return subprocess.run(probe, capture_output=True, text=True, check=True).stdout.strip()


def worker(impl: str, mode: str, count: int, out: Path) -> None:
    """Run in a subprocess: time `count` emits (or series points) and print the rate as JSON."""
    if impl == "ours":
        from lakegate.lake.emitter import Emitter
    else:
        from resim.metrics.python.emissions import Emitter
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
    python = sys.executable if impl == "ours" else str(REF_PYTHON)
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
    ref_version = ensure_reference()
    runs: dict[tuple[str, str], list[dict[str, float]]] = {}
    for mode, count in (("emit", args.emits), ("series", args.points)):
        for run in range(args.runs):
            for impl in ("ours", "reference"):  # alternate, so that load changes hit both alike
                runs.setdefault((impl, mode), []).append(measure(impl, mode, count))
            print(
                f"{mode} run {run + 1}/{args.runs}: ours {runs['ours', mode][-1]['cpu']:,.0f}/s, "
                f"reference {runs['reference', mode][-1]['cpu']:,.0f}/s (CPU time)",
                file=sys.stderr,
                flush=True,
            )
    identical = (WORK / "emit-ours-emit.jsonl").read_bytes() == (WORK / "emit-reference-emit.jsonl").read_bytes()
    for scratch in WORK.glob("emit-*.jsonl"):
        scratch.unlink()

    def rate(impl: str, mode: str, clock: str) -> float:
        return statistics.median(r[clock] for r in runs[impl, mode])

    def row(mode: str, what: str, clock: str) -> str:
        ours, ref = rate("ours", mode, clock), rate("reference", mode, clock)
        figures = " / ".join(
            ", ".join(f"{r[clock] / 1000:.0f}k" for r in runs[impl, mode]) for impl in ("ours", "reference")
        )
        per = {"cpu": "per CPU second", "wall": "per wall-clock second"}[clock]
        return f"| {what}, {per} | {ours:,.0f} /s | {ref:,.0f} /s | {ours / ref:.2f}x | {figures} |"

    emit_what = f"validated `emit()`, 3-float topic ({args.emits:,} emits)"
    series_what = f"`emit_series()` points ({args.points:,} points in one call)"
    ratio = {clock: rate("ours", "emit", clock) / rate("reference", "emit", clock) for clock in ("cpu", "wall")}
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    write_section(
        "Emitter",
        "python3 dev.py bench emit",
        [
            f"- baseline: reference `Emitter` of resim-open-core {ref_version} (its own venv), validating against "
            "the same config, measured in the same run; runs alternate lakegate / reference, each in a fresh process",
            f"- median of {args.runs} runs, including `close()`; random full-precision floats. Rates per second of "
            "process CPU time (all threads) are the figures judged, as they are least disturbed by other load on "
            f"this shared machine; wall-clock rates are shown too. Load average at the end: {load}",
            "",
            "| measure | lakegate | reference | ratio | runs (lakegate / reference) |",
            "|---|---|---|---|---|",
            row("emit", emit_what, "cpu"),
            row("emit", emit_what, "wall"),
            row("series", series_what, "cpu"),
            row("series", series_what, "wall"),
            "",
            f"- goal: validated `emit()` >= {GOAL:.0f}x the reference: "
            f"**{'met' if ratio['cpu'] >= GOAL else 'NOT met'}** "
            f"({ratio['cpu']:.2f}x per CPU second, {ratio['wall']:.2f}x per wall-clock second)",
            f"- the two emissions files of the last `emit()` runs are byte-identical: {'yes' if identical else 'no'}",
        ],
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
