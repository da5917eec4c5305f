"""Start-up benchmark: how long `lakegate --help` (and a command's own `--help`) takes, against a bare
Python interpreter started the same way.

    python3 dev.py bench cli_startup [--runs R]

Each run is a fresh process of the installed `lakegate` script (`.venv/bin/lakegate`, or the one
beside this interpreter); runs alternate between the measured commands and `python -c pass`, the
baseline. Median wall-clock seconds of R runs each (goal: `lakegate --help` under 0.3 s). Writes
section "CLI start-up" of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, write_section  # noqa: E402

LAKEGATE = Path(sys.executable).parent / "lakegate"
GOAL = 0.3
COMMANDS = {
    "`python -c pass` (baseline)": [sys.executable, "-c", "pass"],
    "`lakegate --help`": [str(LAKEGATE), "--help"],
    "`lakegate query --help`": [str(LAKEGATE), "query", "--help"],
    "`lakegate metrics --help`": [str(LAKEGATE), "metrics", "--help"],
}


def wall_seconds(command: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(command, stdout=subprocess.DEVNULL, check=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=15, help="runs of each command (default 15)")
    args = parse_args(parser, runs=2)
    figures: dict[str, list[float]] = {name: [] for name in COMMANDS}
    for _ in range(args.runs):
        for name, command in COMMANDS.items():
            figures[name].append(wall_seconds(command))
    medians = {name: statistics.median(runs) for name, runs in figures.items()}
    baseline = medians["`python -c pass` (baseline)"]
    help_median = medians["`lakegate --help`"]
    lines = [
        f"- median of {args.runs} alternating runs, each a fresh process, wall-clock; load average at the end: "
        + ", ".join(f"{load:.2f}" for load in os.getloadavg()),
        "",
        "| command | median | ratio to the baseline | runs |",
        "|---|---:|---:|---|",
        *(
            f"| {name} | {medians[name]:.3f} s | {medians[name] / baseline:.1f}x | "
            + ", ".join(f"{r:.3f}" for r in runs)
            + " |"
            for name, runs in figures.items()
        ),
        "",
        f"- goal: `lakegate --help` under {GOAL} s: **{'met' if help_median < GOAL else 'not met'}** "
        f"({help_median:.3f} s)",
    ]
    write_section("CLI start-up", "python3 dev.py bench cli_startup", lines)


if __name__ == "__main__":
    main()
