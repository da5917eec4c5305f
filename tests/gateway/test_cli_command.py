"""Every `lakegate` command given careless input, as a real subprocess: a clear message, never a traceback.

Careless input: missing files, folders instead of files, empty files, binary garbage, `--lake`
naming a file, a report to a folder or to a full device, a read-only or full lake, and
argument values out of range. (Unreadable files are not tried: the tests may run as root.)
"""

from __future__ import annotations

import os
import random
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from lakegate.lake.catalog import Catalog

FIXTURE_CONFIG = Path(__file__).resolve().parents[2] / "fixtures" / "config.resim.yaml"
CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
GOOD_LINE = '{"$metadata": {"topic": "robot_speed", "timestamp": 1}, "$data": {"speed": 1.0}}\n'
RUN = ["metrics", "run", "--lake", "lake", "--branch", "main", "--batch", "b", "--all-metrics"]


def lakegate(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*CLI, *args], capture_output=True, text=True, cwd=cwd, timeout=120, env={**os.environ, "COLUMNS": "200"}
    )


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    """A folder of careless inputs beside good ones, and a lake with one job (batch b) and its config."""
    root = tmp_path_factory.mktemp("careless")
    (root / "README.md").write_text("# not a lake\n")
    (root / "adir").mkdir()
    (root / "empty").write_bytes(b"")
    (root / "garbage").write_bytes(random.Random(9).randbytes(4096))
    (root / "good.jsonl").write_text(GOOD_LINE)
    shutil.copy(FIXTURE_CONFIG, root / "config.yaml")
    done = lakegate(
        "ingest",
        "--lake",
        "lake",
        "--branch",
        "main",
        "--batch",
        "b",
        "--job",
        "j",
        "--metrics-config-path",
        "config.yaml",
        "good.jsonl",
        cwd=root,
    )
    assert done.returncode == 0, done.stderr
    return root


INGEST = ["ingest", "--lake", "lake", "--branch", "main", "--batch", "b2", "--job", "j"]
DEBUG = ["metrics", "debug", "--all-metrics", "--no-browser"]

#: (command line, exit code, a text the output must hold)
CASES = [
    (["config", "check", "missing"], 1, "missing: cannot read the file: [Errno 2] No such file or directory"),
    (["config", "check", "adir"], 1, "adir: cannot read the file: [Errno 21] Is a directory"),
    (["config", "check", "garbage"], 1, "garbage: cannot read the file: 'utf-8' codec can't decode"),
    (["config", "schema", "-o", "adir"], 1, "lakegate: cannot write adir: Is a directory"),
    ([*INGEST, "--metrics-config-path", "config.yaml", "missing"], 1, "emissions file 'missing' does not exist"),
    (
        [*INGEST, "--metrics-config-path", "config.yaml", "adir"],
        1,
        "emissions file 'adir' does not exist or is not a file",
    ),
    ([*INGEST, "--metrics-config-path", "config.yaml", "garbage"], 1, "invalid UTF-8 at byte"),
    ([*INGEST, "--metrics-config-path", "adir", "good.jsonl"], 1, "config file 'adir' does not exist"),
    ([*INGEST, "--metrics-config-path", "garbage", "good.jsonl"], 1, "garbage: cannot read the file"),
    (
        [*INGEST, "--metrics-config-path", "config.yaml", "--metadata", "adir", "good.jsonl"],
        1,
        "metadata file 'adir' does not exist",
    ),
    ([*INGEST, "--metrics-config-path", "config.yaml", "--metadata", "garbage", "good.jsonl"], 1, "bad metadata"),
    (
        [*INGEST, "--metrics-config-path", "config.yaml", "--job-status", "WHATEVER", "good.jsonl"],
        2,
        "argument --job-status: invalid choice: 'WHATEVER' (choose from 'SUCCEEDED', 'FAILED')",
    ),
    (
        [
            "ingest",
            "--lake",
            "README.md",
            "--branch",
            "main",
            "--batch",
            "b",
            "--job",
            "j",
            "--metrics-config-path",
            "config.yaml",
            "good.jsonl",
        ],
        1,
        "--lake 'README.md' is not a directory",
    ),
    (["lake", "ls", "--lake", "README.md"], 1, "no lake at 'README.md'"),
    (["query", "--lake", "README.md", "SELECT 1"], 1, "no lake at README.md (not a directory)"),
    (
        ["metrics", "sync", "--lake", "README.md", "--branch", "main", "--metrics-config-path", "config.yaml"],
        1,
        "--lake 'README.md' is not a directory",
    ),
    (
        ["metrics", "run", "--lake", "README.md", "--branch", "main", "--batch", "b", "--all-metrics"],
        1,
        "no lake at 'README.md'",
    ),
    ([*RUN, "--threads", "0"], 2, "argument --threads: expected a positive number, got '0'"),
    ([*RUN, "--report", "adir"], 1, "--report 'adir' is a directory; name the HTML file to write"),
    pytest.param(
        [*RUN, "--report", "/dev/full"],
        1,
        "cannot write the report '/dev/full': No space left on device (the results are stored in the lake)",
        marks=pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full"),
    ),
    (
        [*DEBUG, "--emissions-file", "adir", "--metrics-config-path", "config.yaml"],
        1,
        "emissions file 'adir' does not exist or is not a file",
    ),
    (
        [*DEBUG, "--emissions-file", "good.jsonl", "--metrics-config-path", "config.yaml", "--lake", "README.md"],
        1,
        "Not a directory",
    ),
    (["demo", "--lake", "README.md"], 1, "--lake 'README.md' is not a directory"),
    (["trino-ddl", "--lake", "README.md", "--location", "s3://x/lake"], 1, "no lake at README.md (not a directory)"),
    (["trino-ddl", "--lake", "lake", "--location", "s3://x/lake", "--output", "adir"], 1, "Is a directory: 'adir'"),
    (["serve", "--lake", "README.md"], 1, "no lake at README.md (not a directory)"),
    (["serve", "--lake", "lake", "--users", "adir"], 1, "users file 'adir' cannot be read"),
    (["serve", "--lake", "lake", "--users", "garbage"], 1, "users file 'garbage' cannot be read"),
]


@pytest.mark.parametrize(
    "args, code, text", CASES, ids=lambda value: " ".join(value) if isinstance(value, list) else None
)
def test_careless_input_gets_a_clear_message(workspace: Path, args: list[str], code: int, text: str):
    result = lakegate(*args, cwd=workspace)
    assert "Traceback" not in result.stderr + result.stdout
    assert result.returncode == code, result.stderr
    assert text in result.stdout + result.stderr
    if code == 2:  # argparse: the usage, then one error line
        assert result.stderr.splitlines()[-1].startswith("lakegate ")
    elif args[:2] != ["config", "check"]:  # config check lists its problems on standard output
        assert result.stderr.startswith("lakegate: ")


def snapshot(lake: Path) -> list:
    con = Catalog(lake).connect("main")
    return [con.execute(f"SELECT * FROM {table} ORDER BY ALL").fetchall() for table in ("metadata", "metric_results")]


@pytest.fixture
def mounted(tmp_path: Path):
    """mount(*options, source=...) mounts on a fresh folder (needs root; skipped where not permitted)."""
    points: list[Path] = []

    def mount(*options: str, source: str = "tmpfs") -> Path:
        point = tmp_path / f"mount{len(points)}"
        point.mkdir()
        done = subprocess.run(["mount", *options, source, str(point)], capture_output=True, text=True, timeout=10)
        if done.returncode != 0:
            pytest.skip(f"mount is not permitted here: {done.stderr.strip()}")
        points.append(point)
        return point

    yield mount
    for point in reversed(points):
        subprocess.run(["umount", "-l", str(point)], timeout=10, check=True)


def test_metrics_run_on_a_read_only_lake(workspace: Path, tmp_path: Path, mounted):
    lake = tmp_path / "lake"
    shutil.copytree(workspace / "lake", lake)
    assert lakegate(*RUN[:3], str(lake), *RUN[4:], cwd=workspace).returncode in (0, 2, 3)  # results to keep
    before = snapshot(lake)
    read_only = mounted("--bind", source=str(lake))
    subprocess.run(["mount", "-o", "remount,ro,bind", str(read_only)], check=True, timeout=10)
    result = lakegate(*RUN[:3], str(read_only), *RUN[4:], cwd=workspace)
    assert (result.returncode, result.stderr.count("\n")) == (1, 1), result.stderr
    assert result.stderr.startswith("lakegate: cannot store the results in the lake: Read-only file system")
    assert snapshot(lake) == before


def test_metrics_run_on_a_full_disk(workspace: Path, mounted):
    disk = mounted("-t", "tmpfs", "-o", "size=4m")
    lake = disk / "lake"
    shutil.copytree(workspace / "lake", lake)
    assert lakegate(*RUN[:3], str(lake), *RUN[4:], cwd=workspace).returncode in (0, 2, 3)
    before = snapshot(lake)
    free = shutil.disk_usage(disk).free
    with (disk / "filler").open("wb") as filler:  # leave a few KiB: less than the results need
        filler.write(b"\0" * (free - 8192))
    result = lakegate(*RUN[:3], str(lake), *RUN[4:], cwd=workspace)
    assert (result.returncode, result.stderr.count("\n")) == (1, 1), result.stderr
    assert result.stderr.startswith("lakegate: cannot store the results in the lake:")
    assert "No space left on device" in result.stderr
    (disk / "filler").unlink()
    assert snapshot(lake) == before


def test_commands_on_a_full_disk_say_so_in_one_line(nav_jobs, mounted, tmp_path: Path):
    """ingest and metrics run with a few KiB left, at several fill levels (so that the disk fills
    while a Parquet file is written, while the record commits, ...): one `lakegate:` line, never a
    traceback (not even pyarrow's "Exception ignored" from a writer's __del__)."""
    disk = mounted("-t", "tmpfs", "-o", "size=6m")
    job = nav_jobs.jobs[1]
    for free_kib in (8, 96):  # a staged Parquet file, then the record commit, find the disk full
        shutil.rmtree(disk / "lake", ignore_errors=True)
        (disk / "filler").unlink(missing_ok=True)
        common = ["--lake", "lake", "--branch", "main", "--batch", "b", "--metrics-config-path", str(nav_jobs.config)]
        first = lakegate("ingest", str(job.emissions_path), *common, "--job", "j0", cwd=disk)
        assert first.returncode == 0, first.stderr
        free = shutil.disk_usage(disk).free
        with (disk / "filler").open("wb") as filler:
            filler.write(b"\0" * max(0, free - free_kib * 1024))
        for command in (
            ["ingest", str(job.emissions_path), *common, "--job", "j1"],
            ["metrics", "run", *common, "--metrics-set", "Nav Metrics"],
        ):
            result = lakegate(*command, cwd=disk)
            assert "Traceback" not in result.stderr and "Exception ignored" not in result.stderr, result.stderr
            if result.returncode not in (0, 2, 3):
                assert result.returncode == 1 and result.stderr.count("\n") == 1, (free_kib, command, result.stderr)
                assert result.stderr.startswith("lakegate: ") and "No space left on device" in result.stderr
