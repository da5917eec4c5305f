"""One thread that calls functions at their time: the time limits of every query of a process,
instead of a `threading.Timer` (a thread started and ended) per query, which cost a fast query most
of its CPU."""

from __future__ import annotations

import heapq
import itertools
import logging
import os
import threading
import time
from collections.abc import Callable

log = logging.getLogger("lakegate.deadlines")


class Deadline:
    """A call scheduled by `Deadlines.at`; `cancel` keeps it from being made."""

    __slots__ = ("call", "owner")

    def __init__(self, call: Callable[[], None], owner: Deadlines):
        self.call: Callable[[], None] | None = call
        self.owner = owner

    def cancel(self) -> None:
        if self.call is not None:
            self.call = None
            self.owner._cancelled()


class Deadlines:
    """Scheduled calls, made in time order by one daemon thread (started on first use, and again in
    a child process after a fork). A call runs in that thread: it must be short."""

    def __init__(self, name: str = "lakegate-deadlines"):
        self.name = name
        self._heap: list[tuple[float, int, Deadline]] = []
        self._order = itertools.count()
        self._wake = threading.Condition(threading.Lock())
        self._cancelled_count = 0
        self._pid: int | None = None

    def at(self, seconds: float, call: Callable[[], None]) -> Deadline:
        """Call `call` in `seconds` seconds (time.monotonic), unless the returned deadline is canceled."""
        deadline = Deadline(call, self)
        when = time.monotonic() + seconds
        with self._wake:
            if self._pid != os.getpid():  # first use in this process
                self._pid, self._heap, self._cancelled_count = os.getpid(), [], 0
                threading.Thread(target=self._run, name=self.name, daemon=True).start()
            heapq.heappush(self._heap, (when, next(self._order), deadline))
            if self._heap[0][2] is deadline:  # the earliest now: the thread waits for it
                self._wake.notify()
        return deadline

    def _cancelled(self) -> None:
        """Forget canceled calls once they are most of the heap (a long time limit keeps each for long)."""
        with self._wake:
            self._cancelled_count += 1
            if self._cancelled_count > 64 and self._cancelled_count * 2 > len(self._heap):
                self._heap = [entry for entry in self._heap if entry[2].call is not None]
                heapq.heapify(self._heap)
                self._cancelled_count = 0

    def _run(self) -> None:
        while True:
            with self._wake:
                while True:
                    while self._heap and self._heap[0][2].call is None:
                        heapq.heappop(self._heap)
                        self._cancelled_count = max(0, self._cancelled_count - 1)
                    if not self._heap:
                        self._wake.wait()
                        continue
                    remaining = self._heap[0][0] - time.monotonic()
                    if remaining <= 0:
                        break
                    self._wake.wait(remaining)
                deadline = heapq.heappop(self._heap)[2]
                call, deadline.call = deadline.call, None
            if call is not None:
                try:
                    call()
                except Exception:  # a failing call must not stop the others
                    log.exception("a scheduled call failed")


#: The process's deadlines (query time limits).
DEADLINES = Deadlines()
