"""Trino's spooling protocol: result pages as encoded segments, inline or spooled.

A client that sends `X-Trino-Query-Data-Encoding` (a comma list in its order of preference) gets,
in the GET replies of its query, `data` as an object instead of an array of rows (Trino 466 and
newer; trinodb/trino `client-protocol.md`, the trino client's `encoding=` option):

    {"encoding": "json+zstd",
     "segments": [{"type": "inline", "data": "<base64>", "metadata": {...}},
                  {"type": "spooled", "uri": ".../v1/spooled/download/ID",
                   "ackUri": ".../v1/spooled/ack/ID", "metadata": {...}}]}

Each segment's payload is the JSON array of its rows (the direct protocol's encoding of values),
compressed as the encoding says: `json` not at all, `json+zstd` a zstd frame, `json+lz4` a raw LZ4
block. `metadata` holds `rowOffset`, `rowsCount`, `segmentSize` (bytes of the payload) and, for a
compressed payload, `uncompressedSize`. A page of at most `INLINE_MAX_ROWS` rows and
`INLINE_MAX_BYTES` bytes is inlined (Trino's `protocol.spooling.inlining.*` defaults); a larger one
is spooled: kept in the server's `SegmentStore` until the client acknowledges it (GET `ackUri`, or
DELETE of its `uri`, as Trino's segment resource takes) or `ttl` seconds after it was handed out.
A store over its byte budget inlines instead, so a client that never acknowledges costs bounded
memory and time. Segment URIs hold a 256-bit random identifier and need no credentials (the trino
client fetches them unauthenticated, as from object storage).

The POST's reply never carries a segment object (clients map the POST's `data` as rows): a fast
query answered whole in the POST keeps the direct protocol's array, which every client accepts.
"""

from __future__ import annotations

import base64
import secrets
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass

import lz4.block
import orjson
import zstandard

HEADER = "x-trino-query-data-encoding"
#: The encodings lakegate speaks (Trino 476 speaks these three, and Arrow in later versions).
ENCODINGS = ("json+zstd", "json+lz4", "json")
INLINE_MAX_ROWS = 1000
INLINE_MAX_BYTES = 128 * 1024
SEGMENT_PATH = "/v1/spooled/download/{segment_id}"
ACK_PATH = "/v1/spooled/ack/{segment_id}"


def negotiate(header: str | None) -> str | None:
    """The first encoding of the client's `X-Trino-Query-Data-Encoding` list that lakegate speaks
    (None: the direct protocol, as for a client that sends none or only unknown ones)."""
    if not header:
        return None
    for name in header.split(","):
        name = name.strip().lower()
        if name in ENCODINGS:
            return name
    return None


def encode(encoding: str, rows_json: bytes) -> tuple[bytes, dict[str, int]]:
    """The payload of a segment holding the JSON array `rows_json`, and its size attributes."""
    if encoding == "json":
        return rows_json, {"segmentSize": len(rows_json)}
    if encoding == "json+zstd":
        payload = zstandard.ZstdCompressor(level=1).compress(rows_json)
    elif encoding == "json+lz4":
        payload = lz4.block.compress(rows_json, store_size=False)
    else:
        raise ValueError(f"unknown query data encoding {encoding!r}")
    return payload, {"segmentSize": len(payload), "uncompressedSize": len(rows_json)}


@dataclass
class _Segment:
    payload: bytes
    expires: float


class SegmentStore:
    """Spooled segments kept for download until acknowledged or expired.

    `ttl`: seconds a segment is kept after it was handed out; `max_bytes`: the payload bytes held at
    once (past them `has_room` is False and pages are inlined). Thread-safe.
    """

    def __init__(self, ttl: float, max_bytes: int):
        self.ttl, self.max_bytes = ttl, max_bytes
        self._segments: dict[str, _Segment] = {}
        self._bytes = 0
        self._lock = threading.Lock()

    @property
    def held_bytes(self) -> int:
        return self._bytes

    def __len__(self) -> int:
        return len(self._segments)

    def has_room(self, size: int) -> bool:
        return self._bytes + size <= self.max_bytes

    def add(self, payload: bytes) -> str:
        """Keep `payload` and return its segment's identifier."""
        segment_id = secrets.token_urlsafe(32)
        with self._lock:
            self._segments[segment_id] = _Segment(payload, time.monotonic() + self.ttl)
            self._bytes += len(payload)
        return segment_id

    def get(self, segment_id: str) -> bytes | None:
        with self._lock:
            segment = self._segments.get(segment_id)
        return None if segment is None else segment.payload

    def ack(self, segment_id: str) -> bool:
        """Forget the segment (the client has it); False if it was not held."""
        with self._lock:
            segment = self._segments.pop(segment_id, None)
            if segment is not None:
                self._bytes -= len(segment.payload)
        return segment is not None

    def expire(self, now: float | None = None) -> int:
        """Forget the segments whose time is up; how many."""
        now = time.monotonic() if now is None else now
        with self._lock:
            old = [k for k, s in self._segments.items() if s.expires <= now]
            for segment_id in old:
                self._bytes -= len(self._segments.pop(segment_id).payload)
        return len(old)


def segments_data(
    encoding: str,
    payload: bytes,
    sizes: Mapping[str, int],
    *,
    rows: int,
    row_offset: int,
    base: str,
    store: SegmentStore,
) -> bytes:
    """The `data` object (JSON bytes) of one page of `rows` rows: its payload inlined when small
    (or when the store is full), else spooled in `store` under URIs below `base`."""
    metadata = {"rowOffset": row_offset, "rowsCount": rows, **sizes}
    if (rows <= INLINE_MAX_ROWS and len(payload) <= INLINE_MAX_BYTES) or not store.has_room(len(payload)):
        segment: dict = {"type": "inline", "data": base64.b64encode(payload).decode("ascii"), "metadata": metadata}
    else:
        segment_id = store.add(payload)
        segment = {
            "type": "spooled",
            "uri": base + SEGMENT_PATH.format(segment_id=segment_id),
            "ackUri": base + ACK_PATH.format(segment_id=segment_id),
            "metadata": metadata,
        }
    return orjson.dumps({"encoding": encoding, "segments": [segment]})
