"""`lakegate ingest` and `lakegate lake ls`, run as real subprocesses."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from lakegate.lake.catalog import Catalog

FIXTURE_CONFIG = Path(__file__).resolve().parents[2] / "fixtures" / "config.resim.yaml"
CLI = [sys.executable, "-m", "lakegate.gateway.cli"]


def lakegate(*args, cwd=None, check=True):
    result = subprocess.run(
        [*CLI, *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        env={**os.environ, "COLUMNS": "200"},
        timeout=120,
    )
    if check:
        assert result.returncode == 0, result.stderr
    return result


def line(topic, timestamp, data, event=False):
    meta = {"topic": topic, "timestamp": timestamp, **({"event": True} if event else {})}
    return json.dumps({"$metadata": meta, "$data": data}) + "\n"


@pytest.fixture
def emissions(tmp_path):
    path = tmp_path / "emissions.resim.jsonl"
    path.write_text(
        "".join(line("robot_speed", i, {"speed": 0.5 * i}) for i in range(10))
        + line(
            "goal_reached",
            11,
            {"name": "g", "description": "d", "status": "PASSED", "tags": ["nav"], "metrics": []},
            True,
        )
    )
    return path


def test_ingest_with_flags_and_metadata_file_then_ls(tmp_path, emissions):
    lake = tmp_path / "lake"
    metadata = tmp_path / "job.yaml"
    metadata.write_text("experience_name: from file\nbuild_version: '0.9'\ntest_suite_name: nightly\n")
    result = lakegate(
        "ingest",
        "--lake",
        lake,
        "--branch",
        "feature/x",
        "--batch",
        "b1",
        "--job",
        "j1",
        "--metrics-config-path",
        FIXTURE_CONFIG,
        "--metadata",
        metadata,
        "--experience-name",
        "sunny",
        "--tag",
        "my_tag",
        "--tag",
        "my_prefix_a",
        "--no-progress",
        emissions,
    )
    out = result.stdout
    assert (
        "ingested job 'j1' of batch 'b1' on branch 'feature/x': 11 rows in 2 topic(s), 1 event(s), from 11 lines" in out
    )
    assert "robot_speed" in out and "no rows for: odom_linear_velocity" in out
    assert result.stderr == ""  # no progress bar when not a terminal
    con = Catalog(lake).connect("feature/x")
    assert con.execute(
        "SELECT experience_name, build_version, test_suite_name, experience_tag_names FROM metadata"
    ).fetchall() == [("sunny", "0.9", "nightly", ["my_tag", "my_prefix_a"])]
    assert con.execute("SELECT COUNT(*), MAX(speed), ANY_VALUE(experience_name) FROM robot_speed").fetchall() == [
        (10, 4.5, "sunny")
    ]

    listing = lakegate("lake", "ls", "--lake", lake).stdout
    assert listing.strip() == "feature/x  (1 batch, 1 job)"
    detail = lakegate("lake", "ls", "--lake", lake, "--branch", "feature/x").stdout
    assert "b1: 1 job(s): j1" in detail
    assert any(line.split()[:3] == ["robot_speed", "topic", "10"] for line in detail.splitlines() if line.strip())
    assert any(
        line.split()[:3] == ["odom_linear_velocity", "topic", "0"] for line in detail.splitlines() if line.strip()
    )
    assert any(line.split()[:3] == ["metadata", "metadata", "1"] for line in detail.splitlines() if line.strip())


def test_default_config_is_the_branchs_current_one_then_the_cwd_file(tmp_path, emissions):
    lake = tmp_path / "lake"
    empty_dir = tmp_path / "elsewhere"
    empty_dir.mkdir()
    failed = lakegate(
        "ingest",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        "b",
        "--job",
        "j",
        emissions,
        cwd=empty_dir,
        check=False,
    )
    assert failed.returncode == 1 and "no config" in failed.stderr and "Traceback" not in failed.stderr
    project = tmp_path / "project"
    (project / ".resim" / "metrics").mkdir(parents=True)
    (project / ".resim" / "metrics" / "config.resim.yaml").write_text(FIXTURE_CONFIG.read_text())
    lakegate("ingest", "--lake", lake, "--branch", "main", "--batch", "b", "--job", "j1", emissions, cwd=project)
    # now the branch has a config in the lake: it is used from anywhere
    lakegate("ingest", "--lake", lake, "--branch", "main", "--batch", "b", "--job", "j2", emissions, cwd=empty_dir)
    assert Catalog(lake).connect("main").execute("SELECT COUNT(*) FROM robot_speed").fetchall() == [(20,)]


def test_bad_lines_are_grouped_by_cause_say_what_skipping_drops_and_exit_1(tmp_path):
    lake = tmp_path / "lake"
    bad = tmp_path / "bad.jsonl"
    event = {"name": "g", "description": "d", "status": 5, "tags": [], "metrics": []}
    bad.write_text(
        "".join(line("robot_speed", i, {"speed": "fast"}) for i in range(25))
        + line("robot_speed", 99, {"speed": 1.0})
        + "".join(line("goal_reached", i, event, True) for i in range(3))
        + line("robot_speeds", 1, {"speed": 1.0})
    )
    result = lakegate(
        "ingest",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        "b",
        "--job",
        "j",
        "--metrics-config-path",
        FIXTURE_CONFIG,
        bad,
        check=False,
    )
    assert result.returncode == 1 and result.stdout == ""
    assert result.stderr.splitlines() == [
        "lakegate: 29 bad lines in the emissions of job 'j'; nothing was written (--skip-bad-lines would keep the "
        "good rows and drop 25 rows of topic 'robot_speed', 3 events of event topic 'goal_reached' (with their "
        "metrics), 1 line naming no declared topic)",
        f"  {bad}:1: topic 'robot_speed', field 'speed': expected float, got str 'fast' (and 24 more lines like it)",
        f"  {bad}:27: topic 'goal_reached', field 'status': expected status (a string), got int 5 "
        "(and 2 more lines like it)",
        f"  {bad}:30: unknown topic 'robot_speeds' (did you mean 'robot_speed'?)",
    ]
    skipped = lakegate(
        "ingest",
        "--lake",
        lake,
        "--branch",
        "main",
        "--batch",
        "b",
        "--job",
        "j",
        "--metrics-config-path",
        FIXTURE_CONFIG,
        "--skip-bad-lines",
        bad,
    )
    assert (
        "skipped 29 bad line(s), dropping 25 rows of topic 'robot_speed', 3 events of event topic "
        "'goal_reached' (with their metrics), 1 line naming no declared topic; they are in " in skipped.stdout
    )
    assert "_quarantine" in skipped.stdout and "(and 24 more lines like it)" in skipped.stdout


@pytest.mark.parametrize(
    "args, message",
    [
        (["--batch", "a/b"], "lakegate: batch id 'a/b' contains '/'"),
        (["--metadata", "{tmp}/job.yaml"], "job.yaml:1:1: unknown metadata column 'experiance_name'"),
        (["--metrics-config-path", "{tmp}/broken.yaml"], "broken.yaml:1:1"),
        (["--metrics-config-path", "{tmp}/missing.yaml"], "lakegate: config file"),
    ],
)
def test_user_errors_are_one_line_without_traceback(tmp_path, emissions, args, message):
    (tmp_path / "job.yaml").write_text("experiance_name: x\n")
    (tmp_path / "broken.yaml").write_text("versoin: 1\n")
    base = {"--batch": "b", "--metrics-config-path": str(FIXTURE_CONFIG)}
    base.update(dict(zip(args[::2], args[1::2])))
    argv = ["ingest", "--lake", tmp_path / "lake", "--branch", "main", "--job", "j", emissions]
    for flag, value in base.items():
        argv += [flag, value.replace("{tmp}", str(tmp_path))]
    result = lakegate(*argv, check=False)
    assert result.returncode == 1
    assert message.replace("{tmp}", str(tmp_path)) in result.stderr
    assert "Traceback" not in result.stderr


def test_progress_bar_when_asked(tmp_path, emissions):
    result = lakegate(
        "ingest",
        "--lake",
        tmp_path / "lake",
        "--branch",
        "main",
        "--batch",
        "b",
        "--job",
        "j",
        "--metrics-config-path",
        FIXTURE_CONFIG,
        "--progress",
        emissions,
    )
    assert "lines=11" in result.stderr and "B/s" in result.stderr


def test_ls_errors(tmp_path):
    assert "no lake at" in lakegate("lake", "ls", "--lake", tmp_path / "none", check=False).stderr
    (tmp_path / "lake").mkdir()
    assert lakegate("lake", "ls", "--lake", tmp_path / "lake").stdout.startswith("no branches")
    missing = lakegate("lake", "ls", "--lake", tmp_path / "lake", "--branch", "x", check=False)
    assert missing.returncode == 1 and "no branch 'x'" in missing.stderr


#: Runs a command and, after its own output, prints the command's peak RSS (KiB) as the last line of stderr.
PEAK_RSS = (
    "import resource, subprocess, sys; code = subprocess.run(sys.argv[1:]).returncode; "
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); sys.exit(code)"
)


def test_a_100_mb_line_is_refused_with_bounded_memory(tmp_path, emissions):
    """One huge line used to be held and parsed whole (1 GB: 9.6 GB RSS); now it is a bad line, never held whole."""
    huge = tmp_path / "huge.jsonl"
    with huge.open("w") as handle:
        handle.write(emissions.read_text())
        handle.write('{"$metadata": {"topic": "robot_speed", "timestamp": 99}, "$data": {"speed": "')
        for _ in range(100):
            handle.write("x" * (1 << 20))
        handle.write('"}}\n')
        handle.write(line("robot_speed", 100, {"speed": 1.0}))
    result = subprocess.run(
        [
            sys.executable,
            "-c",
            PEAK_RSS,
            *CLI,
            "ingest",
            "--lake",
            str(tmp_path / "lake"),
            "--branch",
            "main",
            "--batch",
            "b",
            "--job",
            "j",
            "--metrics-config-path",
            str(FIXTURE_CONFIG),
            "--skip-bad-lines",
            str(huge),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    *errors, peak_kib = result.stderr.splitlines()
    assert result.returncode == 0, errors
    size = huge.stat().st_size - len(emissions.read_text()) - len(line("robot_speed", 100, {"speed": 1.0})) - 1
    assert f"huge.jsonl:12: line too long: {size:,} bytes, more than the limit of 16,777,216 bytes" in result.stdout
    assert "12 rows" in result.stdout and "skipped 1 bad line(s)" in result.stdout
    assert int(peak_kib) < 400 * 1024, f"peak RSS {int(peak_kib) // 1024} MiB for a 100 MiB line"
