"""Start-up benchmark: how long `lakegate --help` and every command's own `--help` (nested ones such as
`lakegate metrics run --help` included) take, against a bare Python interpreter started the same way.

    python3 dev.py bench cli_startup [--runs R]

Each run is a fresh process of the installed `lakegate` script (`.venv/bin/lakegate`, or the one
beside this interpreter); runs alternate between the measured commands and `python -c pass`, the
baseline. Median wall-clock seconds of R runs each (goal: `lakegate --help` and every command's
`--help` under 0.3 s, as fast as a user feels as instant). Writes section "CLI start-up" of
bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, write_section  # noqa: E402

from lakegate.gateway.cli.main import build_parser  # noqa: E402

LAKEGATE = Path(sys.executable).parent / "lakegate"
GOAL = 0.3
BASELINE = "`python -c pass` (baseline)"
TOP = "`lakegate --help`"


def command_lines(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Every command line with a parser of its own (`metrics`, `metrics run`, ...), in the help's order."""
    found: list[tuple[str, ...]] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found += [(*prefix, name), *command_lines(sub, (*prefix, name))]
    return found


def commands() -> dict[str, list[str]]:
    """Name in the table -> command line: the baseline, `lakegate --help`, then each command's --help."""
    measured = {BASELINE: [sys.executable, "-c", "pass"], TOP: [str(LAKEGATE), "--help"]}
    for line in command_lines(build_parser("*")):
        measured[f"`lakegate {' '.join(line)} --help`"] = [str(LAKEGATE), *line, "--help"]
    return measured


def run_seconds(command: list[str]) -> tuple[float, float]:
    """Wall-clock and CPU (user + system) seconds of one run of `command`; the CPU time is what other
    work on the machine does not inflate."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, stdout=subprocess.DEVNULL, check=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=15, help="runs of each command (default 15)")
    args = parse_args(parser, runs=2)
    measured = commands()
    figures: dict[str, list[float]] = {name: [] for name in measured}
    cpu: dict[str, list[float]] = {name: [] for name in measured}
    for _ in range(args.runs):
        for name, command in measured.items():
            wall, used = run_seconds(command)
            figures[name].append(wall)
            cpu[name].append(used)
    medians = {name: statistics.median(runs) for name, runs in figures.items()}
    cpu_medians = {name: statistics.median(runs) for name, runs in cpu.items()}
    baseline, help_median = medians[BASELINE], medians[TOP]
    slowest = max((name for name in medians if name not in (BASELINE, TOP)), key=medians.__getitem__)
    lines = [
        f"- median of {args.runs} alternating runs, each a fresh process, wall-clock; load average at the end: "
        + ", ".join(f"{load:.2f}" for load in os.getloadavg()),
        "",
        "| command | median | ratio to the baseline | ratio to `lakegate --help` | median CPU (user+sys) | runs |",
        "|---|---:|---:|---:|---:|---|",
        *(
            f"| {name} | {medians[name]:.3f} s | {medians[name] / baseline:.1f}x | "
            f"{medians[name] / help_median:.1f}x | {cpu_medians[name]:.3f} s | "
            + ", ".join(f"{r:.3f}" for r in runs)
            + " |"
            for name, runs in figures.items()
        ),
        "",
        f"- goal: `lakegate --help` under {GOAL} s: **{'met' if help_median < GOAL else 'not met'}** "
        f"({help_median:.3f} s)",
        f"- goal: every command's --help under {GOAL} s too: **{'met' if medians[slowest] < GOAL else 'not met'}** "
        f"(slowest {slowest}, {medians[slowest]:.3f} s, {medians[slowest] / help_median:.1f}x `lakegate --help`)",
        f"- CPU time (not inflated by other work on the machine): `lakegate --help` {cpu_medians[TOP]:.3f} s, the "
        f"slowest command's --help {max(cpu_medians[n] for n in cpu_medians if n not in (BASELINE, TOP)):.3f} s, "
        f"`python -c pass` {cpu_medians[BASELINE]:.3f} s",
    ]
    write_section("CLI start-up", "python3 dev.py bench cli_startup", lines)


if __name__ == "__main__":
    main()
