"""The dashboard's share of the query slots: one user's dashboard requests that run queries run at
most `Limits.user_slots` at once (every slot but one by default), as one user's queries through the
SQL endpoint do, so that the dashboard never takes every slot and another user's client always finds
one free. A request past that waits, off the server's threads, for one of the same user's to end; after
the query time limit it gets 503."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import anyio
from fastapi import HTTPException


class UserSlots:
    """At most `slots` requests of one user at once; a request waits at most `wait` seconds for one."""

    def __init__(self, slots: int, wait: float):
        self.slots, self.wait = slots, wait
        self._held: dict[str | None, anyio.Semaphore] = {}

    @asynccontextmanager
    async def held(self, user: str | None) -> AsyncIterator[None]:
        """One of `user`'s slots, for the body of the `async with`."""
        semaphore = self._held.setdefault(user, anyio.Semaphore(self.slots))
        acquired = False
        with anyio.move_on_after(self.wait):
            await semaphore.acquire()
            acquired = True
        if not acquired:
            raise HTTPException(
                503,
                f"the dashboard already runs {self.slots} queries of "
                f"{'user ' + repr(user) if user else 'its user'} at once (--max-queries-per-user); "
                f"none ended within {self.wait:g}s: try again",
            )
        try:
            yield
        finally:
            semaphore.release()
