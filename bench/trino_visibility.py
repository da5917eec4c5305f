"""What Trino's Hive connector sees while lakegate publishes: Trino queried in a loop during real writes.

    python3 dev.py bench trino_visibility [--smoke] [--jobs N] [--repeats K] [--trino-url URL]

Needs a running Trino 476 (`python3 dev.py trino start`). Builds a lake of one batch of N generated
jobs (fixtures/generate.py, the example config; rebuilt each run in bench/.work/trino_visibility/),
registers it with `lakegate trino-ddl --apply`, and while one reader thread sends
`SELECT job_id, count(*) FROM odom_linear_velocity WHERE batch_id = 'b1' GROUP BY job_id` to Trino
back to back, runs K times each of these writers as the CLI runs them (in a subprocess):

* `lakegate ingest` of one job again (same data) into the batch before it is compacted;
* `lakegate lake compact` of the batch (each job's files merged into one file per table);
* `lakegate ingest` of one job again into the compacted batch (the batch's shared files rewritten
  without the job, the job's own file added).

Every job keeps its row count through every write, so each answer is classified against it:
exact (every job once), duplicated (some job's rows counted twice: old and new files both listed),
missing (a job with fewer rows: its file listed before it was published, or deleted while the
query ran), or failed (Trino's error, e.g. a file deleted under a running query). Prints, per
writer, the answers that started while it ran, by class, and the longest stretch of inexact
answers; writes section "Trino during a publish" of bench/RESULTS.md (not with --smoke).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path
from urllib.parse import urlsplit

import trino

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import trino_server  # noqa: E402
from results import write_section  # noqa: E402

from lakegate.fixtures.generate import CONFIG_PATH, generate_batch  # noqa: E402
from lakegate.gateway.engine.trino_registration import read_registration  # noqa: E402
from lakegate.lake.config import load_config  # noqa: E402
from lakegate.lake.ingest import ingest_job  # noqa: E402
from lakegate.lake.metadata import load_metadata_file  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "bench" / ".work" / "trino_visibility"
CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
TOPIC = "odom_linear_velocity"
QUERY = f"SELECT job_id, count(*) FROM {TOPIC} WHERE batch_id = 'b1' GROUP BY job_id"


def lakegate(*args: object) -> str:
    done = subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=900)
    if done.returncode != 0:
        raise SystemExit(f"lakegate {' '.join(map(str, args[:2]))} failed: {done.stderr.strip()}")
    return done.stdout


class Reader(threading.Thread):
    """Sends QUERY to Trino back to back; keeps (start, end, answer or error name) of each."""

    def __init__(self, url: str, schema: str):
        super().__init__(daemon=True)
        parts = urlsplit(url)
        self.connection = trino.dbapi.connect(
            host=parts.hostname, port=parts.port, user="bench", catalog="hive", schema=schema, source="visibility"
        )
        self.answers: list[tuple[float, float, dict | str]] = []
        self.stop = threading.Event()

    def run(self) -> None:
        while not self.stop.is_set():
            start = time.monotonic()
            try:
                cursor = self.connection.cursor()
                cursor.execute(QUERY)
                answer: dict | str = {job: n for job, n in cursor.fetchall()}
            except trino.exceptions.TrinoQueryError as error:
                answer = error.error_name or "error"
            self.answers.append((start, time.monotonic(), answer))


def classify(answer: dict | str, expected: dict[str, int]) -> str:
    if isinstance(answer, str):
        return f"failed ({answer})"
    if answer == expected:
        return "exact"
    if any(answer.get(job, 0) < n for job, n in expected.items()):
        return "missing"
    return "duplicated"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--smoke", action="store_true", help="3 jobs, one repeat, printed only")
    parser.add_argument("--jobs", type=int, default=20, help="jobs in the batch (default 20)")
    parser.add_argument("--repeats", type=int, default=5, help="runs of each writer (default 5)")
    parser.add_argument("--trino-url", help="the Trino 476 (default: the one dev.py trino started)")
    args = parser.parse_args()
    url = args.trino_url or (trino_server.running() or {}).get("url")
    if not url:
        raise SystemExit("needs a running Trino 476: python3 dev.py trino start")
    jobs, repeats = (3, 1) if args.smoke else (args.jobs, args.repeats)
    started = time.perf_counter()
    shutil.rmtree(WORK, ignore_errors=True)
    lake = WORK / "lake"
    generated = generate_batch(WORK / "inputs", jobs=jobs, samples_per_goal=50)
    config = load_config(CONFIG_PATH)
    for job in generated:
        metadata = load_metadata_file(job.metadata_path)
        ingest_job(lake, "main", "b1", job.job_id, [job.emissions_path], config=config, metadata=metadata)
    prefix = f"bench_{uuid.uuid4().hex[:6]}_"
    lakegate("trino-ddl", "--lake", lake, "--apply", "--trino-url", url, "--schema-prefix", prefix)
    reader = Reader(url, read_registration(lake, url).schemas["main"])
    again = generated[len(generated) // 2]
    ingest = [
        "ingest", "--lake", lake, "--branch", "main", "--batch", "b1", "--job", again.job_id,
        "--metrics-config-path", CONFIG_PATH, "--metadata", again.metadata_path, "--no-progress", again.emissions_path,
    ]  # fmt: skip
    writers = [
        ("re-ingest of one job, batch not compacted", ingest),
        ("`lake compact` of the batch", ["lake", "compact", "--lake", lake, "--branch", "main", "--batch", "b1"]),
        ("re-ingest of one job into the compacted batch", ingest),
    ]
    try:
        reader.start()
        deadline = time.monotonic() + 120
        while len(reader.answers) < 3 and time.monotonic() < deadline:
            time.sleep(0.5)
        baseline = [a for _, _, a in reader.answers if isinstance(a, dict)]
        if not baseline:
            raise SystemExit(f"Trino answered no query before the writes: {reader.answers}")
        expected = baseline[-1]
        if sum(expected.values()) == 0 or len(expected) != jobs:
            raise SystemExit(f"Trino does not see the {jobs} jobs before the writes: {expected}")
        spans: dict[str, list[tuple[float, float]]] = {name: [] for name, _ in writers}
        for _ in range(repeats):
            for name, command in writers:
                if name.startswith("`lake compact`"):  # compact only an uncompacted batch: ingest each job again
                    for job in generated:
                        metadata = load_metadata_file(job.metadata_path)
                        ingest_job(
                            lake, "main", "b1", job.job_id, [job.emissions_path], config=config, metadata=metadata
                        )
                    time.sleep(0.5)
                begin = time.monotonic()
                lakegate(*command)
                spans[name].append((begin, time.monotonic()))
                time.sleep(1.0)
    finally:
        reader.stop.set()
        reader.join(120)
        lakegate("trino-ddl", "--lake", lake, "--drop", "--trino-url", url)
    lines = [
        f"- Trino 476 at {url}, hive catalog over the lake (`lakegate trino-ddl --apply`); one batch of {jobs} jobs "
        f"of the example config; the reader: `{QUERY}` back to back",
        f"- each writer run {repeats} time(s) through the CLI; an answer counts for a writer when it started while the "
        "writer's process ran (its start-up and Python imports included)",
        f"- load average at the end: {', '.join(f'{x:.1f}' for x in os.getloadavg())} on {os.cpu_count()} cores",
        "",
        "| writer | writer time (median) | answers meanwhile | exact | duplicated | missing | failed | "
        "longest inexact stretch |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, windows in spans.items():
        counts: dict[str, int] = {}
        longest = 0.0
        for begin, end in windows:
            inexact_since = None
            for start, finish, answer in reader.answers:
                if not begin <= start <= end:
                    continue
                kind = classify(answer, expected)
                counts[kind] = counts.get(kind, 0) + 1
                if kind == "exact":
                    inexact_since = None
                else:
                    inexact_since = inexact_since if inexact_since is not None else start
                    longest = max(longest, finish - inexact_since)
        failed = sum(n for kind, n in counts.items() if kind.startswith("failed"))
        failures = ", ".join(sorted(kind[8:-1] for kind in counts if kind.startswith("failed")))
        failed_text = f"{failed} ({failures})" if failures else str(failed)
        durations = sorted(end - begin for begin, end in windows)
        lines.append(
            f"| {name} | {durations[len(durations) // 2]:.2f} s | {sum(counts.values())} | {counts.get('exact', 0)} | "
            f"{counts.get('duplicated', 0)} | {counts.get('missing', 0)} | {failed_text} | {longest * 1000:.0f} ms |"
        )
    total = [a for _, _, a in reader.answers]
    lines += ["", f"({len(total)} answers in all; benchmark took {time.perf_counter() - started:.0f} s)"]
    if args.smoke:
        print("\n".join(lines))
        return 0
    write_section(
        "Trino during a publish",
        f"python3 dev.py bench trino_visibility --jobs {jobs} --repeats {repeats}",
        lines,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
