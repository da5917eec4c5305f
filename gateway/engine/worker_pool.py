"""A small pool of query worker processes (`query_worker`), and the watch that holds their memory.

Each query runs in a worker process of its own, taken from the pool for the whole query (the pool's
size is the number of queries that run at once). A worker is warm: forked from a server process
that already imported DuckDB and lakegate, its database open and the branches' schemas read, so a
query costs a round trip over a pipe and its batches in Arrow IPC, not a start.

What a worker may use is held from outside: while queries run, a watch thread reads every busy
worker's resident set (`/proc/PID/statm`) every `WATCH_INTERVAL` seconds and kills a worker whose
query grew it more than the memory limit (EXCEEDED_LOCAL_MEMORY_LIMIT), or, when the queries
together grew their workers past the limit, the one that grew most (EXCEEDED_GLOBAL_MEMORY_LIMIT);
each worker's address space is also capped (RLIMIT_AS) at its warm size plus the limit and
`HEADROOM`, which stops an allocation faster than the watch looks. A query past its time that does
not stop when DuckDB is interrupted (a Python function never returns to DuckDB) is ended by killing
its worker. A killed worker is replaced in the background; a worker that kept much memory after its
query is retired.
"""

from __future__ import annotations

import multiprocessing
import os
import re
import signal
import threading
import time
import weakref
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from pathlib import Path

from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine import query_worker
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.process_memory import resident

#: Seconds between two looks at the busy workers' memory.
WATCH_INTERVAL = 0.02
#: Seconds between two looks at the idle workers (to end those idle for IDLE_SECONDS) while none is
#: busy: an idle worker's memory does not grow, so the watch sleeps until a worker is taken.
IDLE_LOOK = 1.0
#: Bytes of address space a worker may take beyond its warm size and the memory limit (thread
#: stacks and allocator arenas of a running query reserve address space they do not use).
HEADROOM = 1 << 30
#: A worker that holds this much more than when it was warm after a query is retired.
RETIRE_BYTES = 64 << 20
#: Seconds an idle worker beyond the warm ones lives.
IDLE_SECONDS = 60.0
#: Longest wait for a new worker to be ready.
START_SECONDS = 60.0
#: Longest wait at close for workers being started to be handed their task (a process that
#: exits while one is, leaves it a traceback to print).
CLOSE_SECONDS = 10.0
_UNITS = {"": 1, "B": 1, "KB": 10**3, "MB": 10**6, "GB": 10**9, "TB": 10**12}
_UNITS.update({"KIB": 1 << 10, "MIB": 1 << 20, "GIB": 1 << 30, "TIB": 1 << 40})


def size_bytes(text: str) -> int:
    """Bytes of a size as DuckDB's memory_limit reads it ('1GB' = 10^9, '1GiB' = 2^30)."""
    match = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([KMGT]i?B|B)?\s*", text, re.IGNORECASE)
    if match is None:
        raise ValueError(f"not a memory size: {text!r} (e.g. 512MB, 2GB, 1GiB)")
    return int(float(match.group(1)) * _UNITS[(match.group(2) or "").upper()])


def memory_error(error_name: str, limit: str) -> DialectError:
    """Trino's error of a query that grew past the memory limit."""
    if error_name == "EXCEEDED_LOCAL_MEMORY_LIMIT":
        text = f"Query exceeded per-node memory limit of {limit} (--memory-limit)"
    else:
        text = f"Query exceeded distributed user memory limit of {limit}: the queries running together grew past it"
    return DialectError(text, error_name=error_name)


@dataclass(eq=False)
class WorkerProcess:
    """The pool's end of one worker: its process, its pipe and why it was stopped, if it was."""

    process: multiprocessing.process.BaseProcess
    connection: Connection
    warm_rss: int = 0
    busy: bool = False
    idle_since: float = field(default_factory=time.monotonic)
    killed: DialectError | None = None  # the query's error when the pool killed the worker

    @property
    def pid(self) -> int:
        return self.process.pid or 0

    def grown(self) -> int:
        """Bytes the worker holds beyond its warm size."""
        return max(0, resident(self.pid) - self.warm_rss)

    def kill(self, reason: DialectError | None = None) -> None:
        """End the process at once (its query, if any, fails with `reason`); the reader of its pipe
        sees it end."""
        self.killed = self.killed or reason
        if self.process.exitcode is None:
            try:
                os.kill(self.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass

    def dispose(self) -> None:
        """Kill the process, close the pipe and collect the process."""
        self.kill()
        self.connection.close()
        self.process.join(timeout=5)


class WorkerPool:
    """Worker processes over `lake`: at most `size` busy (queries running at once) and `warm` more
    kept ready, so that the next query starts at once even while `size` run or after one was killed;
    at least `keep` live (started at once: a burst of queries finds them ready).

    `take` hands out an idle worker while fewer than `size` are busy (starting one when none is idle;
    waiting until the deadline otherwise); `give_back` returns it when its query ended.
    """

    def __init__(
        self,
        lake: Path | None,
        *,
        memory_limit: str,
        threads: int,
        limits: Limits,
        size: int,
        warm: int = 1,
        keep: int = 1,
    ):
        self.lake, self.memory_limit, self.threads, self.limits = lake, memory_limit, threads, limits
        self.limit_bytes = size_bytes(memory_limit)
        self.size, self.warm, self.keep = size, min(warm, size), min(max(keep, warm), size + warm)
        self._context = multiprocessing.get_context("forkserver")
        self._context.set_forkserver_preload(["lakegate.gateway.engine.query_worker"])
        self._lock = threading.Condition()
        self._taken = threading.Condition(self._lock)  # the watch waits on it while no worker is busy
        self._idle: list[WorkerProcess] = []
        self._busy: set[WorkerProcess] = set()
        self._starting = 0  # workers being started
        self._takers = 0  # callers of `take` waiting for a worker
        self._launched: weakref.WeakSet[WorkerProcess] = weakref.WeakSet()  # every worker started
        self._closed = False
        self._watch = threading.Thread(target=self._watch_memory, name="lakegate-worker-watch", daemon=True)
        self._watch.start()
        self._fill()

    # -- workers ------------------------------------------------------------------------------

    def _start(self) -> WorkerProcess | None:
        """A new, ready worker (None when it could not start: the error is the caller's to give)."""
        context = self._context
        ours, theirs = context.Pipe()
        process = context.Process(
            target=query_worker.serve,
            args=(theirs, self.lake, self.memory_limit, self.threads, self.limits, self.limit_bytes + HEADROOM),
            name="lakegate-query-worker",
            daemon=True,
        )
        process.start()
        theirs.close()
        worker = WorkerProcess(process, ours)
        with self._lock:
            self._launched.add(worker)
            if self._closed:
                worker.kill()
        try:
            if ours.poll(START_SECONDS) and ours.recv() == ("ready",):
                worker.warm_rss = resident(worker.pid)
                return worker
        except (EOFError, OSError):
            pass
        worker.dispose()
        return None

    def _fill(self) -> None:
        """Start workers in the background until `warm` are idle and `keep` live (or starting)."""
        with self._lock:
            live = len(self._idle) + len(self._busy) + self._starting
            missing = max(self.warm - len(self._idle) - self._starting, self.keep - live)
            missing = min(missing, self.size + self.warm - len(self._idle) - len(self._busy) - self._starting)
            if self._closed or missing <= 0:
                return
            self._starting += missing
        for _ in range(missing):
            threading.Thread(target=self._add_idle, name="lakegate-worker-start", daemon=True).start()

    def _add_idle(self) -> None:
        """Start a worker and count it as idle once ready."""
        worker = self._start()
        with self._lock:
            self._starting -= 1
            if worker is not None and not self._closed:
                self._idle.append(worker)
                worker = None
            self._lock.notify_all()
        if worker is not None:
            worker.dispose()

    def _room(self) -> bool:
        """Whether another worker may start: at most `size` busy and `warm` more (lock held)."""
        return len(self._idle) + len(self._busy) + self._starting < self.size + self.warm

    def wait_ready(self, timeout: float) -> bool:
        """Wait until the workers kept are ready (at most `timeout` seconds); whether they are."""
        deadline = time.monotonic() + timeout
        with self._lock:
            while len(self._idle) < self.keep and not self._closed:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._lock.wait(remaining)
        return True

    def take(self, deadline: float) -> WorkerProcess | None:
        """An idle worker, marked busy (None when none is free before `deadline`, a time.monotonic())."""
        with self._lock:
            self._takers += 1
            try:
                while True:
                    if self._closed:
                        return None
                    if len(self._busy) < self.size and self._idle:
                        worker = self._idle.pop()
                        break
                    if len(self._busy) < self.size and self._starting < self._takers and self._room():
                        self._starting += 1  # a worker for this taker (one already starting may serve another)
                        worker = None
                        break
                    remaining = deadline - time.monotonic()
                    if remaining <= 0:
                        return None
                    self._lock.wait(remaining)
            finally:
                self._takers -= 1
        if worker is None:
            worker = self._start()
            with self._lock:
                self._starting -= 1
                self._lock.notify_all()
            if worker is None:
                raise DialectError(
                    "A query worker process could not be started", error_name="GENERIC_INSUFFICIENT_RESOURCES"
                )
        with self._lock:
            worker.busy, worker.killed = True, None
            self._busy.add(worker)
            self._taken.notify()
        self._fill()
        return worker

    def give_back(self, worker: WorkerProcess, *, healthy: bool) -> None:
        """Return a worker whose query ended; one that is not `healthy` (stopped mid-answer), that was
        killed, or that kept much memory is ended, and a new one started if fewer than `warm` idle."""
        keep = healthy and worker.killed is None and worker.process.is_alive() and worker.grown() < RETIRE_BYTES
        with self._lock:
            self._busy.discard(worker)
            worker.busy = False
            worker.idle_since = time.monotonic()
            if keep and not self._closed:
                self._idle.append(worker)
            self._lock.notify_all()
        if not keep:  # a large process takes a while to end: not on the caller's time
            worker.kill()
            threading.Thread(target=worker.dispose, name="lakegate-worker-end", daemon=True).start()
        self._fill()

    # -- the watch ----------------------------------------------------------------------------

    def _watch_memory(self) -> None:
        """Kill the workers past the memory limit; end idle workers beyond `warm` (and `keep` live)
        after IDLE_SECONDS."""
        while True:
            with self._lock:
                if not self._busy and not self._closed:
                    self._taken.wait(IDLE_LOOK)
                if self._closed:
                    return
            time.sleep(WATCH_INTERVAL)
            with self._lock:
                busy = list(self._busy)
                now = time.monotonic()
                surplus = min(len(self._idle) - self.warm, len(self._idle) + len(self._busy) - self.keep)
                spare = [w for w in self._idle[: max(0, surplus)] if now - w.idle_since > IDLE_SECONDS]
                for worker in spare:
                    self._idle.remove(worker)
            for worker in spare:
                worker.dispose()
            if not busy:
                continue
            grown = {worker: worker.grown() for worker in busy}
            for worker, used in grown.items():
                if used > self.limit_bytes:
                    worker.kill(memory_error("EXCEEDED_LOCAL_MEMORY_LIMIT", self.memory_limit))
            alive = {worker: used for worker, used in grown.items() if worker.killed is None}
            if alive and sum(alive.values()) > self.limit_bytes:
                largest = max(alive, key=alive.__getitem__)
                largest.kill(memory_error("EXCEEDED_GLOBAL_MEMORY_LIMIT", self.memory_limit))

    def pids(self) -> list[int]:
        """The process ids of the live workers."""
        with self._lock:
            return [worker.pid for worker in [*self._idle, *self._busy]]

    def close(self) -> None:
        """End every worker (running queries fail as killed)."""
        with self._lock:
            self._closed = True
            workers, idle = list(self._launched), list(self._idle)
            self._idle.clear()
            self._lock.notify_all()
            self._taken.notify_all()
        for worker in workers:
            worker.kill(DialectError("The server is shutting down", error_name="SERVER_SHUTTING_DOWN"))
        for worker in idle:
            worker.dispose()  # a busy or starting one is disposed by its reader, which sees it end
        deadline = time.monotonic() + CLOSE_SECONDS
        with self._lock:  # a starting worker is killed as soon as it has started (see _start)
            while self._starting and (remaining := deadline - time.monotonic()) > 0:
                self._lock.wait(remaining)
        self._watch.join(timeout=1)
