"""The memory of a process as Linux counts it (`/proc/PID/statm`): what the query worker pool
watches, and what a worker caps its address space from."""

from __future__ import annotations

import resource

_PAGE = resource.getpagesize()


def statm(pid: int | str = "self") -> tuple[int, int]:
    """(virtual size, resident set) in bytes of process `pid`; (0, 0) when it is gone or the system
    has no /proc."""
    try:
        with open(f"/proc/{pid}/statm", "rb") as file:
            size, rss = file.read().split()[:2]
    except (OSError, ValueError):
        return 0, 0
    return int(size) * _PAGE, int(rss) * _PAGE


def resident(pid: int) -> int:
    """Resident bytes of process `pid` (0 when it is gone)."""
    return statm(pid)[1]
