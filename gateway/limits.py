"""What one query and the SQL endpoint may use (`lakegate serve` options; kept free of heavy imports)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Limits:
    """What one query and the server may use; every limit gives a Trino error when exceeded."""

    query_timeout: float = 300.0        # seconds a query may run (queued time not counted)
    max_rows: int = 10_000_000          # rows a result may have
    max_concurrent_queries: int = 8     # queries running at once; more wait in a queue
    max_queued_queries: int = 200       # queries waiting to run; more fail with QUERY_QUEUE_FULL
    client_timeout: float = 30.0        # a query whose client stops polling for this long is abandoned
    retention: float = 15.0             # a finished query is kept this long for retried requests
    page_bytes: int = 1_000_000         # target size of one page of rows
    wait: float = 1.0                   # longest a GET waits for the next page
    answer_wait: float = 0.02           # longest a POST waits to answer a fast query (whole) in its reply
