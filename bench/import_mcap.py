"""Benchmark: `lakegate import mcap` messages per second on a 1M-message MCAP file.

The file (ROS 2 odometry messages with a `ros2msg` schema: a stamp, a frame name and a nested
twist, written with mcap-ros2-support into bench/.work/, made once and kept) is imported to an
emissions file by the real CLI in a fresh process, three fields per row, timestamps from the
message stamp. A rate is messages per second of the command's process CPU time (process start,
decoding, the Emitter's checks and writing; least disturbed by other load on a shared machine),
and per wall-clock second; the median of RUNS runs.

    python3 dev.py bench import_mcap [--runs 3] [--messages 1000000]

(Not bench/mcap.py: a script of that name would shadow the `mcap` package it imports.)
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

from mcap_ros2.writer import Writer
from results import parse_args, write_section  # bench/ is on sys.path when this file runs as a script

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "mcap"
CONFIG = "version: 1\ntopics:\n  odom_linear_velocity:\n    schema: {x: float, y: float, z: float}\n"
MAPPING = (
    "/odom:\n  topic: odom_linear_velocity\n"
    "  fields: {x: twist.linear.x, y: twist.linear.y, z: twist.linear.z}\n  timestamp: stamp\n"
)
MSGDEF = """\
builtin_interfaces/Time stamp
string frame
bench_msgs/Twist twist
================================================================================
MSG: bench_msgs/Twist
bench_msgs/Vector3 linear
bench_msgs/Vector3 angular
================================================================================
MSG: bench_msgs/Vector3
float64 x
float64 y
float64 z
"""


def make_log(path: Path, count: int) -> None:
    """`count` odometry messages at 100 Hz."""
    with open(path, "wb") as stream:
        writer = Writer(stream)
        schema = writer.register_msgdef("bench_msgs/Odom", MSGDEF)
        for i in range(count):
            ns = 1_700_000_000_000_000_000 + i * 10_000_000
            message = {
                "stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9},
                "frame": "base_link",
                "twist": {
                    "linear": {"x": i * 0.001, "y": -i * 0.002, "z": 0.5},
                    "angular": {"x": 0.0, "y": 0.0, "z": i * 1e-4},
                },
            }
            writer.write_message("/odom", schema, message, log_time=ns)
        writer.finish()


def import_once(log: Path) -> tuple[float, float]:
    """CPU and wall-clock seconds of one `lakegate import mcap` to an emissions file."""
    output = WORK / "emissions.resim.jsonl"
    command = [sys.executable, "-m", "lakegate.gateway.cli", "import", "mcap", str(log), "--no-progress"]
    command += ["--mapping", str(WORK / "map.yaml"), "--metrics-config-path", str(WORK / "config.resim.yaml")]
    before, start = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    subprocess.run([*command, "--output", str(output)], check=True, stdout=subprocess.DEVNULL)
    wall, after = time.perf_counter() - start, resource.getrusage(resource.RUSAGE_CHILDREN)
    output.unlink()
    return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--messages", type=int, default=1_000_000)
    args = parse_args(parser, runs=1, messages=2_000)
    WORK.mkdir(parents=True, exist_ok=True)
    (WORK / "config.resim.yaml").write_text(CONFIG)
    (WORK / "map.yaml").write_text(MAPPING)
    log = WORK / f"odom-{args.messages}.mcap"
    if not log.exists():
        print(f"writing {log} ...", file=sys.stderr, flush=True)
        make_log(log, args.messages)
    runs = [import_once(log) for _ in range(args.runs)]
    cpu, wall = (statistics.median(run[i] for run in runs) for i in (0, 1))
    write_section(
        "MCAP import",
        f"python3 dev.py bench import_mcap --runs {args.runs} --messages {args.messages}",
        [
            f"- input: {args.messages:,} ROS 2 odometry messages (stamp, frame, nested twist), "
            f"{log.stat().st_size / 2**20:.0f} MiB MCAP (zstd chunks), made by mcap-ros2-support",
            "- measured: `lakegate import mcap ... --output FILE` in a fresh process, the whole command (decoding, "
            f"the Emitter's checks, writing); median of {args.runs} runs. Rates per second of process CPU time "
            "are the figures judged (least disturbed by other load on this shared machine). "
            f"Load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}",
            "- where the time goes (cProfile of a 20,000-message import, measured once): decoding the ROS 2 "
            "messages in mcap-ros2-support (pure Python) about 55%, reading the MCAP chunks about 15%, the field "
            "paths and timestamps about 15%, the Emitter's checks and writing about 7%",
            "",
            "| measure | figure | runs (s) |",
            "|---|---|---|",
            f"| messages per CPU second | {args.messages / cpu:,.0f} /s | {', '.join(f'{r[0]:.1f}' for r in runs)} |",
            f"| messages per wall-clock second | {args.messages / wall:,.0f} /s | "
            f"{', '.join(f'{r[1]:.1f}' for r in runs)} |",
        ],
    )


if __name__ == "__main__":
    main()
