"""The Emitter's delivery: lifecycle, the flush policy, threads, exits and kills, forked children, a full disk."""

from __future__ import annotations

import gc
import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

from lakegate.lake.emitter import Emitter
from tests.lake.emitter_support import FIXTURE_CONFIG, ODOM, read_lines, strict_loads

# --- lifecycle, threads and flushing ----------------------------------------------------


def test_close_is_idempotent_and_emit_after_close_raises(out: Path):
    em = Emitter(FIXTURE_CONFIG, out)
    em.close()
    em.close()
    with pytest.raises(ValueError, match="closed"):
        em.emit("robot_speed", {"speed": 1.0}, 1)


def test_flush_interval_must_be_positive(out: Path):
    with pytest.raises(ValueError, match="flush_interval"):
        Emitter(output_path=out, flush_interval=0)


def wait_for_lines(path: Path, count: int) -> int:
    deadline = time.monotonic() + 10
    while len(path.read_bytes().splitlines()) < count and time.monotonic() < deadline:
        time.sleep(0.01)
    return len(read_lines(path))


def test_lines_reach_the_file_every_flush_interval(out: Path):
    with Emitter(FIXTURE_CONFIG, out, flush_interval=0.05) as em:
        em.emit("robot_speed", {"speed": 1.0}, 1)
        assert wait_for_lines(out, 1) == 1


def test_a_full_chunk_is_written_without_waiting_for_the_interval(out: Path):
    with Emitter(FIXTURE_CONFIG, out, flush_interval=3600) as em:
        em.emit_series("robot_speed", {"speed": [1.0] * 10_000}, list(range(10_000)))
        assert wait_for_lines(out, 10_000) == 10_000


def test_garbage_collected_emitter_flushes_and_stops_its_thread(out: Path):
    before = set(threading.enumerate())
    em = Emitter(FIXTURE_CONFIG, out, flush_interval=3600)
    (flusher,) = [t for t in set(threading.enumerate()) - before if t.name.startswith("emitter-flush")]
    em.emit("robot_speed", {"speed": 1.0}, 1)
    del em
    gc.collect()
    assert len(read_lines(out)) == 1
    flusher.join(timeout=10)
    assert not flusher.is_alive()


def test_threads_share_one_emitter_without_loss_or_interleaving(out: Path):
    threads, per_thread = 8, 50_000
    with Emitter(FIXTURE_CONFIG, out, flush_interval=0.01) as em:

        def work(k: int) -> None:  # half the threads emit lines of a text topic, half rows of a numeric one
            for i in range(per_thread):
                if k % 2:
                    em.emit("covariance_accuracy", {"error_m": float(k), "sigma_m": 1.0, "within_1_sigma": i}, i)
                else:
                    em.emit("goal_distance", {"goal_name": f"thread-{k}", "distance_m": float(i)}, i)

        workers = [threading.Thread(target=work, args=(k,)) for k in range(threads)]
        for worker in workers:
            worker.start()
        for worker in workers:
            worker.join()
    seen: dict[str, list[int]] = {f"thread-{k}": [] for k in range(threads)}
    with out.open() as lines:
        for line in lines:
            record = strict_loads(line)
            thread = record["$data"].get("goal_name") or f"thread-{record['$data']['error_m']:.0f}"
            seen[thread].append(record["$metadata"]["timestamp"])
    assert all(stamps == list(range(per_thread)) for stamps in seen.values())


def run_child(script: str, *args: str, **popen) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(script), *args], text=True, **popen)


def test_sigkill_loses_at_most_the_last_flush_interval(out: Path):
    child = run_child(
        """
        import sys, time
        from lakegate.lake.emitter import Emitter
        em = Emitter(sys.argv[1], sys.argv[2], flush_interval=0.1)
        for i in range(1000):
            em.emit("robot_speed", {"speed": 1.0}, i)
        time.sleep(1.0)  # ten flush intervals
        print("slept", flush=True)
        em.emit("robot_speed", {"speed": 2.0}, 1000)  # may be lost: within the last interval
        time.sleep(3600)
        """,
        str(FIXTURE_CONFIG),
        str(out),
        stdout=subprocess.PIPE,
    )
    try:
        assert child.stdout.readline() == "slept\n"
        os.kill(child.pid, signal.SIGKILL)
        assert child.wait(timeout=30) == -signal.SIGKILL
    finally:
        child.kill()
        child.stdout.close()
    stamps = [line["$metadata"]["timestamp"] for line in read_lines(out)]
    assert stamps[:1000] == list(range(1000)) and len(stamps) <= 1001


def test_interpreter_exit_flushes_without_close(out: Path):
    child = run_child(
        """
        import sys, threading, time
        from lakegate.lake.emitter import Emitter
        held = Emitter(sys.argv[1], sys.argv[2], flush_interval=3600)
        for i in range(100):
            held.emit("robot_speed", {"speed": 1.0}, i)
        # only a daemon thread holds it, so it is never finalized: atexit must write its lines
        holder = threading.Thread(target=lambda em: time.sleep(3600), args=(held,), daemon=True)
        holder.start()
        del held
        dropped = Emitter(sys.argv[1], sys.argv[2] + ".2", flush_interval=3600)
        dropped.emit("robot_speed", {"speed": 1.0}, 0)
        del dropped  # garbage-collected before exit
        """,
        str(FIXTURE_CONFIG),
        str(out),
    )
    assert child.wait(timeout=60) == 0
    assert len(read_lines(out)) == 100
    assert len(read_lines(Path(str(out) + ".2"))) == 1


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_forked_child_does_not_write_the_parents_lines_twice(out: Path):
    with Emitter(FIXTURE_CONFIG, out, flush_interval=3600) as em:
        em.emit("robot_speed", {"speed": 1.0}, 1)  # still buffered at the fork
        pid = os.fork()
        if pid == 0:  # child: emit its own line, exit without running pytest's cleanup
            try:
                em.emit("robot_speed", {"speed": 2.0}, 2)
                em.close()
            finally:
                os._exit(0)
        assert os.waitpid(pid, 0)[1] == 0
    assert sorted(line["$metadata"]["timestamp"] for line in read_lines(out)) == [1, 2]


# --- forked children -------------------------------------------------------------------------

FORK_SCRIPT = """
import multiprocessing, os, sys
from lakegate.lake.emitter import Emitter

mode, lines = sys.argv[3], 500
em = Emitter(sys.argv[1], sys.argv[2], flush_interval=3600)  # only exit paths write, never the interval


def work(k):
    for i in range(lines):  # a line of a text topic and a row of a numeric one
        em.emit("goal_distance", {"goal_name": f"child-{k}", "distance_m": float(i)}, i)
        em.emit("covariance_accuracy", {"error_m": float(k), "sigma_m": 1.0, "within_1_sigma": i}, i)
    return k


em.emit("goal_distance", {"goal_name": "parent", "distance_m": 0.0}, 0)  # queued at the fork: the parent's
ctx = multiprocessing.get_context("fork")
if mode == "process":
    children = [ctx.Process(target=work, args=(k,)) for k in range(8)]
    for child in children:
        child.start()
    for child in children:
        child.join()
    assert all(child.exitcode == 0 for child in children)
elif mode == "pool":
    with ctx.Pool(4) as pool:  # leaving the block terminates the workers (SIGTERM)
        assert sorted(pool.map(work, range(8), chunksize=1)) == list(range(8))
else:
    pids = []
    for k in range(8):
        pid = os.fork()
        if pid == 0:
            work(k)
            os._exit(0)  # no atexit, no finalizers, no flush
        pids.append(pid)
    assert all(os.waitpid(pid, 0)[1] == 0 for pid in pids)
"""


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
@pytest.mark.parametrize("mode", ["process", "pool", "os_fork_os_exit"])
def test_lines_of_forked_children_are_all_written(out: Path, mode: str):
    """Each of 8 children emits 1,000 lines: every line is in the file once, whole, in each child's order."""
    child = run_child(FORK_SCRIPT, str(FIXTURE_CONFIG), str(out), mode)
    assert child.wait(timeout=60) == 0
    seen: dict[str, list[int]] = {}
    for line in read_lines(out):
        data = line["$data"]
        who = data["goal_name"] if "goal_name" in data else f"child-{data['error_m']:.0f} rows"
        seen.setdefault(who, []).append(line["$metadata"]["timestamp"])
    children = {f"child-{k}{kind}": list(range(500)) for k in range(8) for kind in ("", " rows")}
    assert seen == {"parent": [0], **children}


# --- write errors: a full disk ---------------------------------------------------------------


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_write_errors_are_raised_to_the_caller():
    em = Emitter(FIXTURE_CONFIG, "/dev/full", flush_interval=0.01)
    em.emit("robot_speed", {"speed": 1.0}, 1)
    deadline = time.monotonic() + 10  # the flusher thread fails; the next emit raises its error
    with pytest.raises(OSError, match="No space left on device") as info:
        while time.monotonic() < deadline:
            em.emit("robot_speed", {"speed": 1.0}, 2)
            time.sleep(0.01)
    assert "could not write /dev/full" in str(info.value)
    with pytest.raises(OSError, match=r"No space left on device \(\d+ line\(s\) not written\)"):
        em.flush()
    with pytest.raises(OSError, match="not written"):
        em.close()
    em.close()  # closed now: nothing more to say


@pytest.fixture
def tiny_disk(tmp_path: Path):
    """A 64 KiB tmpfs (needs root and mount; skipped where not permitted)."""
    mount_point = tmp_path / "tiny"
    mount_point.mkdir()
    try:
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount_point)], capture_output=True, timeout=10
        )
    except (OSError, subprocess.SubprocessError):
        pytest.skip("mount is not available")
    if done.returncode != 0:
        pytest.skip(f"mounting a tmpfs is not permitted: {done.stderr.decode(errors='replace').strip()}")
    try:
        yield mount_point
    finally:
        subprocess.run(["umount", "-l", str(mount_point)], timeout=10, check=True)  # lazy: even if a file is open


def _half_full(tiny_disk: Path) -> tuple[Path, Path, Emitter]:
    """A filler of 32 KiB on the tiny disk, and an Emitter writing there that flushes only when asked."""
    filler = tiny_disk / "filler"
    filler.write_bytes(b"x" * 32 * 1024)
    out = tiny_disk / "emissions.resim.jsonl"
    return filler, out, Emitter(FIXTURE_CONFIG, out, flush_interval=3600)


def _flush_onto_the_full_disk(em: Emitter, out: Path, count: int) -> int:
    """Flush `count` queued lines onto the full disk: a prefix of whole lines is written (nothing glued)
    and the error counts the rest; how many were written."""
    with pytest.raises(OSError, match="No space left on device") as info:
        em.flush()
    text = out.read_bytes()
    written = len(text.splitlines())
    assert 0 < written < count and text.endswith(b"\n")
    assert f"({count - written} line(s) not written)" in str(info.value)
    return written


def test_full_disk_leaves_only_whole_lines_and_keeps_the_rest_queued(tiny_disk: Path):
    filler, out, em = _half_full(tiny_disk)
    count = 450  # about 43 KB: more than the free space, less than the disk
    em.emit_series(
        "goal_distance",
        {"goal_name": [f"goal-{i:04}" for i in range(count)], "distance_m": [float(i) for i in range(count)]},
        list(range(count)),
    )
    written = _flush_onto_the_full_disk(em, out, count)
    assert [line["$metadata"]["timestamp"] for line in read_lines(out)] == list(range(written))
    filler.unlink()  # space again: the lines kept in the queue are written, in order, once
    em.close()
    assert [line["$metadata"]["timestamp"] for line in read_lines(out)] == list(range(count))


def test_full_disk_with_queued_rows_leaves_only_whole_lines(tiny_disk: Path):
    """Rows of a numeric topic become lines when written: on a full disk too, only whole lines, in order."""
    filler, out, em = _half_full(tiny_disk)
    count = 400  # about 46 KB: more than the free space, less than the disk
    for i in range(count):
        em.emit(ODOM, {"x": i / 3, "y": -i / 7, "z": 1e-5 * i}, timestamp=i)
    _flush_onto_the_full_disk(em, out, count)
    filler.unlink()
    em.close()
    expected = [
        json.dumps({"$metadata": {"topic": ODOM, "timestamp": i}, "$data": {"x": i / 3, "y": -i / 7, "z": 1e-5 * i}})
        for i in range(count)
    ]
    assert out.read_text().splitlines() == expected


def test_full_disk_during_a_long_series_leaves_only_whole_lines(tiny_disk: Path):
    filler, out, em = _half_full(tiny_disk)
    count = 10_000  # a series this long is written by the emitting thread, in blocks of lines
    em.emit_series("robot_speed", {"speed": [i / 7 for i in range(count)]}, list(range(count)))
    written = _flush_onto_the_full_disk(em, out, count)
    assert [line["$metadata"]["timestamp"] for line in read_lines(out)] == list(range(written))
    with pytest.raises(OSError, match="not written"):
        em.close()


def test_a_chunk_is_written_by_the_emit_that_fills_it(out: Path):
    """The emit that queues the 1024th line writes the chunk itself, before it returns: no flusher needed."""
    with Emitter(FIXTURE_CONFIG, out, flush_interval=3600) as em:
        for i in range(1023):
            em.emit(ODOM, {"x": i / 3, "y": 0.0, "z": -1.5}, timestamp=i)
        assert out.read_bytes() == b""
        em.emit(ODOM, {"x": 1.0, "y": 0.0, "z": -1.5}, timestamp=1023)
        lines = out.read_bytes().splitlines()
        assert len(lines) == 1024 and lines[-1].startswith(
            b'{"$metadata": {"topic": "odom_linear_velocity", "timestamp": 1023}'
        )
