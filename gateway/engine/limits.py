"""What one query and the SQL endpoint may use (`lakegate serve` options; kept free of heavy imports)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Limits:
    """What one query and the server may use; every limit gives a Trino error when exceeded."""

    query_timeout: float = 300.0  # seconds a query may run (queued time not counted)
    max_rows: int = 10_000_000  # rows a result may have
    max_concurrent_queries: int = 8  # queries running at once; more wait in a queue
    max_queries_per_user: int | None = None  # queries one user runs at once; None: all slots but one
    max_queued_queries: int = 200  # queries waiting to run; more fail with QUERY_QUEUE_FULL
    client_timeout: float = 30.0  # a query whose client stops polling for this long is abandoned
    heartbeat_timeout: float = 10.0  # a query waiting for its client to read is abandoned after this silence
    retention: float = 15.0  # a finished query is kept this long for retried requests
    page_bytes: int = 1_000_000  # target size of one page of rows
    wait: float = 1.0  # longest a GET waits for the next page
    answer_wait: float = 0.02  # longest a POST waits to answer a fast query (whole) in its reply
    max_body: int = 1_000_000  # bytes of a request body (Trino's query.max-length); more: HTTP 413
    max_header_bytes: int = 65_536  # bytes of a request's line and headers; more: HTTP 431
    request_timeout: float = 30.0  # seconds a request's headers and body may take to arrive; then 408
    keep_alive: int = 5  # seconds an idle keep-alive connection stays open
    max_connections: int = 1000  # open connections; more are answered 503 and closed

    @property
    def user_slots(self) -> int:
        """Queries one user may run at once, as a Trino resource group's per-user (`${USER}`) subgroup
        with a hardConcurrencyLimit: `max_queries_per_user`, by default every slot but one (at least
        one), so that another user always finds a slot free."""
        if self.max_queries_per_user is not None:
            return self.max_queries_per_user
        return max(1, self.max_concurrent_queries - 1)
