"""One query's run on its own DuckDB cursor, streamed as Arrow record batches (`Run`), and the zones
its timestamp with time zone columns are shown in (`in_zones`)."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Iterator, Sequence

import duckdb
import pyarrow as pa

from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine.deadlines import DEADLINES
from lakegate.gateway.engine.failures import duckdb_failure, time_limit_error


def in_zones(
    produce: Callable[[], Iterable[pa.RecordBatch]], zones: Sequence[str | None]
) -> Callable[[], Iterable[pa.RecordBatch]]:
    """`produce` with each timestamp with time zone column in the zone its values carry (`zones`, per
    column, from the translation): DuckDB gives them in UTC; Arrow keeps the zone in the column type, so
    the values show and convert (to_pylist) in it."""
    if all(zone in (None, "UTC") for zone in zones):
        return produce

    def zoned() -> Iterator[pa.RecordBatch]:
        for batch in produce():
            columns = [
                column if zone in (None, "UTC") else column.cast(pa.timestamp(column.type.unit, zone))
                for column, zone in zip(batch.columns, zones)
            ]
            yield pa.record_batch(columns, names=batch.schema.names)

    return zoned


class Run:
    """One query's DuckDB work on its own cursor, as an iterator of record batches: started lazily by
    the first read (so it can be canceled first), holding one of the backend's slots until it ends
    (`release`), and interrupted by a timer when its time is up (it then fails EXCEEDED_TIME_LIMIT)."""

    def __init__(
        self,
        cursor: duckdb.DuckDBPyConnection,
        produce: Callable[[], Iterable[pa.RecordBatch]],
        *,
        release: Callable[[], None] = lambda: None,
        timeout: float | None = None,
        remaining: float = 0.0,
        failure: Callable[[BaseException], DialectError] = duckdb_failure,
        recycle: Callable[[duckdb.DuckDBPyConnection], None] | None = None,
    ):
        self.cursor, self._produce, self._release, self._failure = cursor, produce, release, failure
        self._recycle = recycle  # takes the cursor back once every batch was read (else it closes)
        self._done = False  # the cursor is recycled or closed: nothing may interrupt it any more
        self.timeout = timeout
        self.reason: DialectError | None = None  # why the query was stopped, if it was
        self._lock = threading.Lock()
        self._held = True
        self._timer = None if timeout is None else DEADLINES.at(remaining, self._expire)
        self._batches = self._read()

    def __iter__(self) -> Run:
        return self

    def __next__(self) -> pa.RecordBatch:
        return next(self._batches)

    def close(self) -> None:
        """Stop reading: the cursor closes (unless every batch was read and it was recycled) and the
        slot is free."""
        self._batches.close()
        self._finish(completed=False)
        self._free()

    def cancel(self) -> None:
        self.stop(DialectError("Query was canceled", error_name="USER_CANCELED"))

    def stop(self, reason: DialectError) -> None:
        """Interrupt the query: reading on raises `reason` (the first one given)."""
        with self._lock:  # with `reason` set first, `_finish` closes the cursor rather than recycle it
            self.reason = self.reason or reason
            if self._done:
                return  # ended: the cursor may already serve another query
        try:
            self.cursor.interrupt()
        except duckdb.Error:
            pass  # already closed: nothing runs

    def _expire(self) -> None:
        self.stop(time_limit_error(self.timeout))
        self._free()  # the slot is free even if nobody reads on

    def _free(self) -> None:
        with self._lock:
            held, self._held = self._held, False
        if self._timer is not None:
            self._timer.cancel()
        if held:
            self._release()

    def _read(self) -> Iterator[pa.RecordBatch]:
        completed = False
        try:
            try:
                for batch in self._produce():
                    if self.reason is not None:
                        break
                    yield batch
            except (duckdb.Error, OSError, pa.ArrowException) as error:
                raise self.reason or self._failure(error) from None
            if self.reason is not None:
                raise self.reason
            completed = True
        finally:
            self._finish(completed=completed)
            self._free()

    def _finish(self, *, completed: bool) -> None:
        """End the cursor once: recycled if every batch was read and nothing stopped the query (no
        open result, no interrupt pending), otherwise closed."""
        with self._lock:
            if self._done:
                return
            self._done = True
            reuse = completed and self.reason is None and self._recycle is not None
        if reuse:
            self._recycle(self.cursor)
        else:
            self.cursor.close()
