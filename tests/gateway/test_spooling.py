"""Trino's spooling protocol on `lakegate serve`: the official `trino` client with each of its
`encoding=` values (json, json+zstd, json+lz4) against a real server, the segment documents as raw
HTTP sees them, and a client that never acknowledges its segments (in-process server, short limits)."""

from __future__ import annotations

import base64
import json
import threading
import time

import lz4.block
import pytest
import requests
import trino
import zstandard

from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.server.app import create_app

from .conftest import served_in_thread

HEADERS = {"X-Trino-User": "tester", "X-Trino-Catalog": "lake", "X-Trino-Schema": "main"}
ROWS = 200_000
SQL = (
    "SELECT a.x, b.y, 'row ' || CAST(a.x * 1000 + b.y AS varchar) AS label, CAST(a.x AS double) / 3 AS third "
    "FROM UNNEST(sequence(1, 1000)) AS a(x) CROSS JOIN UNNEST(sequence(1, 200)) AS b(y)"
)


def expected_rows() -> set[tuple]:
    return {(x, y, f"row {x * 1000 + y}", x / 3) for x in range(1, 1001) for y in range(1, 201)}


class Requests:
    """The URLs every requests session of this process sent (the trino client opens one of its own
    for segments)."""

    def __init__(self, monkeypatch):
        self.urls: list[str] = []
        self._lock = threading.Lock()
        send = requests.adapters.HTTPAdapter.send

        def counted(adapter, request, *args, **kwargs):
            with self._lock:
                self.urls.append(f"{request.method} {request.url}")
            return send(adapter, request, *args, **kwargs)

        monkeypatch.setattr(requests.adapters.HTTPAdapter, "send", counted)

    def count(self, part: str) -> int:
        with self._lock:
            return sum(part in url for url in self.urls)


@pytest.mark.parametrize("encoding", ["json", "json+zstd", "json+lz4"])
def test_the_official_client_reads_every_encoding(lake_server, encoding, monkeypatch):
    seen = Requests(monkeypatch)
    connection = trino.dbapi.connect(
        host=lake_server.host,
        port=lake_server.port,
        user="tester",
        catalog="lake",
        schema="main",
        encoding=encoding,
    )
    cursor = connection.cursor()
    cursor.execute(SQL)
    rows = cursor.fetchall()
    assert [d[0] for d in cursor.description] == ["x", "y", "label", "third"]
    assert len(rows) == ROWS and {tuple(r) for r in rows} == expected_rows()
    downloads = seen.count("/v1/spooled/download/")
    assert downloads > 0  # segments were spooled, not all inlined
    deadline = time.monotonic() + 10  # the client acknowledges in a background thread
    while seen.count("/v1/spooled/ack/") < downloads and time.monotonic() < deadline:
        time.sleep(0.05)
    assert seen.count("/v1/spooled/ack/") == downloads
    # a small result in the POST's reply keeps the direct protocol's array: the client maps it as rows
    cursor.execute("SELECT 1 AS one, 'a' AS s")
    assert cursor.fetchall() == [[1, "a"]]


def _decode(encoding: str, payload: bytes, metadata: dict) -> list:
    assert metadata["segmentSize"] == len(payload)
    if encoding == "json":
        assert "uncompressedSize" not in metadata
        return json.loads(payload)
    raw = (
        zstandard.ZstdDecompressor().decompress(payload)
        if encoding == "json+zstd"
        else lz4.block.decompress(payload, uncompressed_size=metadata["uncompressedSize"])
    )
    assert metadata["uncompressedSize"] == len(raw)
    return json.loads(raw)


def _documents(url: str, sql: str, headers: dict) -> list[dict]:
    response = requests.post(f"{url}/v1/statement", data=sql.encode(), headers={**HEADERS, **headers}, timeout=30)
    documents = [response.json()]
    while "nextUri" in documents[-1]:
        documents.append(requests.get(documents[-1]["nextUri"], timeout=30).json())
    return documents


@pytest.mark.parametrize("encoding", ["json+lz4", "json+zstd", "json"])
def test_segment_documents_as_trino_sends_them(lake_server, encoding):
    header = {"X-Trino-Query-Data-Encoding": f"arrow, {encoding}, json"}  # the first one spoken is taken
    documents = _documents(lake_server.url, SQL, header)
    assert "data" not in documents[0]  # never segments in the POST's reply
    rows, offset, types = [], 0, []
    for document in documents[1:]:
        if "data" not in document:
            continue
        data = document["data"]
        assert data["encoding"] == encoding and "columns" in document
        for segment in data["segments"]:
            metadata = segment["metadata"]
            assert metadata["rowOffset"] == offset
            types.append(segment["type"])
            if segment["type"] == "inline":
                payload = base64.b64decode(segment["data"])
                assert metadata["rowsCount"] <= 1000 and len(payload) <= 128 * 1024
            else:
                assert segment["uri"].startswith(f"{lake_server.url}/v1/spooled/download/")
                assert segment["ackUri"].startswith(f"{lake_server.url}/v1/spooled/ack/")
                payload = requests.get(segment["uri"], timeout=30).content  # no credentials needed
                assert requests.get(segment["ackUri"], timeout=30).status_code == 200
                assert requests.get(segment["uri"], timeout=30).status_code == 404  # acknowledged: gone
            page = _decode(encoding, payload, metadata)
            assert len(page) == metadata["rowsCount"]
            rows.extend(page)
            offset += len(page)
    assert types[0] == "inline" and "spooled" in types
    assert len(rows) == ROWS and {tuple(r) for r in rows} == expected_rows()
    assert documents[-1]["stats"]["state"] == "FINISHED"


def test_unknown_encodings_get_the_direct_protocol(lake_server):
    documents = _documents(lake_server.url, SQL, {"X-Trino-Query-Data-Encoding": "arrow,protobuf"})
    assert sum(len(d.get("data", [])) for d in documents) == ROWS
    assert all(isinstance(d.get("data", []), list) for d in documents)


@pytest.fixture(scope="module")
def forgetful(server_lake):
    """An in-process server whose unacknowledged segments live 3 s (the client timeout)."""
    backend = DuckDBBackend(server_lake, memory_limit="512MB", threads=2)
    engine = Engine(backend, limits=Limits(client_timeout=3.0, retention=1.0, wait=0.5), owns_backend=True)
    app = create_app(engine)
    with served_in_thread(app) as url:
        yield url, app
    engine.close()


def test_a_client_that_never_acknowledges(forgetful):
    url, app = forgetful
    store = app.state.segments
    headers = {**HEADERS, "X-Trino-Query-Data-Encoding": "json+zstd"}
    documents = [requests.post(f"{url}/v1/statement", data=SQL.encode(), headers=headers, timeout=30).json()]
    rows, spooled = [], []
    while "nextUri" in documents[-1]:
        documents.append(requests.get(documents[-1]["nextUri"], timeout=30).json())
        for segment in documents[-1].get("data", {"segments": []})["segments"]:
            if segment["type"] == "inline":
                payload = base64.b64decode(segment["data"])
            else:  # downloaded at once, as a client does, and never acknowledged
                spooled.append(segment)
                response = requests.get(segment["uri"], timeout=30)
                assert response.status_code == 200
                payload = response.content
            rows.extend(_decode("json+zstd", payload, segment["metadata"]))
    assert len(rows) == ROWS and {tuple(r) for r in rows} == expected_rows()
    assert documents[-1]["stats"]["state"] == "FINISHED"
    assert spooled and len(store) <= len(spooled)
    deadline = time.monotonic() + 15
    while len(store) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert len(store) == 0 and store.held_bytes == 0  # expired: their memory is free
    assert requests.get(spooled[0]["uri"], timeout=30).status_code == 404
    assert requests.get(spooled[0]["ackUri"], timeout=30).status_code == 404


def test_a_full_store_inlines(forgetful):
    url, app = forgetful
    store = app.state.segments
    budget = store.max_bytes
    store.max_bytes = 0
    try:
        documents = _documents(url, SQL, {"X-Trino-Query-Data-Encoding": "json+lz4"})
    finally:
        store.max_bytes = budget
    segments = [s for d in documents[1:] if "data" in d for s in d["data"]["segments"]]
    assert segments and {s["type"] for s in segments} == {"inline"}
    rows = [r for s in segments for r in _decode("json+lz4", base64.b64decode(s["data"]), s["metadata"])]
    assert len(rows) == ROWS and {tuple(r) for r in rows} == expected_rows()
