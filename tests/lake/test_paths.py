"""Lake layout: branch-name encoding, id checks, atomic publish, staging and locks."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import time
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from lakegate.lake import paths

HOSTILE = [
    "main",
    "feature/x",
    "feature/x/y",
    "..",
    ".",
    "...",
    ".hidden",
    "_staging",
    "_configs",
    "a b",
    "ünïcödé/枝",
    "a%2Fb",
    "%",
    "a=b",
    "*",
    "a?b",
    "[x]",
    "{a,b}",
    "back\\slash",
    "quote'\"",
    "tab\tnew\nline",
    "emoji 🚀",
    "-dash",
    "UPPER",
    "x" * 70,
    "nul\x00byte",
    "C:\\path",
    "~user",
    "$HOME",
    "a;rm -rf /",
]


@pytest.mark.parametrize("name", HOSTILE)
def test_branch_names_encode_to_one_safe_segment_and_back(name, tmp_path):
    segment = paths.encode_branch(name)
    assert paths.decode_branch(segment) == name
    assert "/" not in segment and "\\" not in segment and "\x00" not in segment
    assert segment not in (".", "..") and not segment.startswith((".", "_"))
    assert not set(segment) & set("*?[]{}=")
    # it is really one directory that DuckDB's glob finds again
    directory = tmp_path / segment
    directory.mkdir()
    assert [p.name for p in tmp_path.iterdir()] == [segment]


def test_branch_encoding_is_injective_on_lookalikes():
    names = ["a/b", "a%2Fb", "a%252Fb", "a_b", "_a", "%5Fa", ".a", "%2Ea"]
    assert len({paths.encode_branch(n) for n in names}) == len(names)


@pytest.mark.parametrize("segment", ["", "a/b", "..", "%2", "%zz", "a b", "%5Fa%", "_x", ".x", "%61"])
def test_decode_refuses_what_encode_never_makes(segment):
    with pytest.raises(paths.LakePathError):
        paths.decode_branch(segment)


def test_branch_name_errors():
    with pytest.raises(paths.LakePathError, match="non-empty"):
        paths.encode_branch("")
    with pytest.raises(paths.LakePathError, match="too long"):
        paths.encode_branch("é" * 200)


@pytest.mark.parametrize(
    "value, fragment",
    [
        ("", "non-empty"),
        (".", "not allowed"),
        ("..", "not allowed"),
        ("a/b", "'/'"),
        ("a*", "glob character '\\*'"),
        ("a?", "glob"),
        ("[a]", "glob"),
        ("{a}", "glob"),
        ("a=b", "'='"),
        ("a%20b", "'%'"),
        ("a\\b", "'\\\\'"),
        ("a\nb", "control character"),
        ("__HIVE_DEFAULT_PARTITION__", "reserved"),
    ],
)
def test_bad_ids_are_refused_with_a_clear_message(value, fragment):
    with pytest.raises(paths.LakePathError, match=fragment) as caught:
        paths.check_segment(value, "batch id")
    assert "batch id" in str(caught.value)


@pytest.mark.parametrize(
    "value", ["b1", "0f8c2a1e-1111-4c4c-9d9d-123456789abc", "it's", "a b", "ünï", "007", "NULL", "x:y"]
)
def test_ids_that_are_allowed_read_back_exactly_as_hive_partitions(value, tmp_path):
    target = paths.new_data_file(tmp_path, "main", "t", value, value)
    target.parent.mkdir(parents=True)
    pq.write_table(pa.table({"v": [1]}), target)
    glob = paths.table_glob(tmp_path, "main", "t").replace("'", "''")
    hive = "hive_partitioning = true, hive_types = {'batch_id': VARCHAR}"
    row = duckdb.connect().execute(f"SELECT batch_id FROM read_parquet('{glob}', {hive})").fetchone()
    assert row == (value,)
    assert target.name.endswith(f"-{value}.parquet")  # the job id, for humans


def test_table_names_that_would_collide_are_refused():
    for name in ("metadata", "events", "_x", ".x", "a=b", "a*b"):
        with pytest.raises(paths.LakePathError):
            paths.check_table_name(name)
    assert paths.check_table_name("odom_linear_velocity") == "odom_linear_velocity"


def test_layout(tmp_path):
    fresh = paths.new_data_file(tmp_path, "feature/x", "odom", "b1", "j1")
    assert fresh.parent == tmp_path / "feature%2Fx" / "odom" / "batch_id=b1"
    assert fresh.name.startswith(f"{os.getpid()}-") and fresh.name.endswith("-j1.parquet")
    assert fresh != paths.new_data_file(tmp_path, "feature/x", "odom", "b1", "j1")  # never overwrites a file
    assert (
        paths.new_data_file(tmp_path, "main", "metric_results", "b1", None).parent
        == tmp_path / "main" / "metric_results" / "batch_id=b1"
    )
    assert paths.table_glob(tmp_path, "main", "odom") == str(tmp_path / "main" / "odom" / "batch_id=*" / "*.parquet")
    assert paths.quarantine_file(tmp_path, "main", "b1", "j1") == tmp_path / "main" / "_quarantine" / "b1" / "j1.jsonl"


def test_publish_replaces_atomically_and_remove_cleans_empty_partitions(tmp_path):
    target = paths.new_data_file(tmp_path, "main", "t", "b", "j")
    first = tmp_path / "first"
    first.write_text("one")
    paths.publish(first, target)
    second = tmp_path / "second"
    second.write_text("two")
    paths.publish(second, target)
    assert target.read_text() == "two" and not first.exists() and not second.exists()
    paths.remove_published(target)
    assert not (tmp_path / "main" / "t" / "batch_id=b").exists()
    assert (tmp_path / "main" / "t").is_dir()
    paths.remove_published(target)  # already gone: no error


def test_staging_is_removed_afterwards_and_abandoned_scratch_is_cleaned(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    abandoned = paths.branch_dir(tmp_path, "main") / paths.STAGING / f"{dead.stdout.strip()}-0123"
    abandoned.mkdir(parents=True)
    (abandoned / "half.parquet").write_bytes(b"PAR1")
    alive = paths.branch_dir(tmp_path, "main") / paths.STAGING / f"{os.getpid()}-other"
    alive.mkdir()
    with paths.staging(tmp_path, "main") as scratch:
        assert scratch.is_dir() and scratch.parent.name == paths.STAGING
        assert not abandoned.exists()
        assert alive.exists()  # our own process is alive: not touched
    assert not scratch.exists()
    # nothing staged is ever matched by a table glob
    assert not list(Path(tmp_path).glob("main/*/batch_id=*/*.parquet"))


def test_job_lock_serialises_writers_of_one_job(tmp_path):
    """The waiter acquires the lock only after the holder released it (wall-clock order, so the
    test holds on a loaded machine: the holder keeps the lock until told to let go)."""
    holder_script = (
        "import sys, time; from pathlib import Path; from lakegate.lake import paths\n"
        "with paths.job_lock(Path(sys.argv[1]), 'main', 'b', 'j'):\n"
        "    print('locked', flush=True); sys.stdin.readline(); released = time.time()\n"
        "print(released, flush=True)\n"
    )
    waiter_script = (
        "import sys, time; from pathlib import Path; from lakegate.lake import paths\n"
        "print('trying', flush=True)\n"
        "with paths.job_lock(Path(sys.argv[1]), 'main', 'b', 'j'): print(time.time(), flush=True)\n"
    )
    popen = {"stdout": subprocess.PIPE, "text": True}
    holder = subprocess.Popen([sys.executable, "-c", holder_script, str(tmp_path)], stdin=subprocess.PIPE, **popen)
    waiter = None
    try:
        assert holder.stdout.readline().strip() == "locked"
        waiter = subprocess.Popen([sys.executable, "-c", waiter_script, str(tmp_path)], **popen)
        assert waiter.stdout.readline().strip() == "trying"
        time.sleep(0.3)
        assert waiter.poll() is None  # blocked on the holder's lock
        holder.stdin.write("\n")
        holder.stdin.close()
        released = float(holder.stdout.readline())
        acquired = float(waiter.stdout.readline())
        assert acquired >= released
    finally:
        holder.kill()
        holder.wait()
        if waiter is not None:
            waiter.kill()
            waiter.wait()


def test_the_files_lock_of_batches_sharing_a_lock_file_is_taken_once(tmp_path):
    stripe = hashlib.sha1(b"a").digest()[0] % 64
    other = next(f"b{i}" for i in range(10_000) if hashlib.sha1(f"b{i}".encode()).digest()[0] % 64 == stripe)
    with paths.batch_files_lock(tmp_path, "main", "a", other):  # flock twice in one process would wait forever
        locks = sorted(p.name for p in (paths.branch_dir(tmp_path, "main") / paths.STAGING / "locks").iterdir())
    assert locks == [f"files-{stripe:02d}.lock"]
