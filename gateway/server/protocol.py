"""The Trino client protocol's documents: query ids, QueryResults, errors, column descriptions and
the server info (shared/notes/trino-protocol.md, sections 4-6).

Documents are built as bytes with orjson; a page's `data` arrives already serialised (the query
worker encodes rows off the event loop) and is spliced in with `orjson.Fragment`.
"""

from __future__ import annotations

import functools
import secrets
import string
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

import orjson

from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine.planner import TRINO_VERSION
from lakegate.gateway.engine.trino_values import protocol_type, type_signature

ENVIRONMENT = "lakegate"

USER_ERROR, INTERNAL_ERROR, INSUFFICIENT_RESOURCES = "USER_ERROR", "INTERNAL_ERROR", "INSUFFICIENT_RESOURCES"
#: Trino's StandardErrorCode values for the error names lakegate reports (name -> code, type).
ERRORS: dict[str, tuple[int, str]] = {
    **{
        name: (code, USER_ERROR)
        for name, code in (
            ("GENERIC_USER_ERROR", 0),
            ("SYNTAX_ERROR", 1),
            ("ABANDONED_QUERY", 2),
            ("USER_CANCELED", 3),
            ("PERMISSION_DENIED", 4),
            ("NOT_FOUND", 5),
            ("FUNCTION_NOT_FOUND", 6),
            ("INVALID_FUNCTION_ARGUMENT", 7),
            ("DIVISION_BY_ZERO", 8),
            ("INVALID_CAST_ARGUMENT", 9),
            ("NOT_SUPPORTED", 13),
            ("INVALID_SESSION_PROPERTY", 14),
            ("NUMERIC_VALUE_OUT_OF_RANGE", 19),
            ("NOT_IN_TRANSACTION", 21),
            ("SUBQUERY_MULTIPLE_ROWS", 28),
            ("PROCEDURE_NOT_FOUND", 29),
            ("INVALID_PROCEDURE_ARGUMENT", 30),
            ("QUERY_TEXT_TOO_LARGE", 35),
            ("ADMINISTRATIVELY_KILLED", 38),
            ("CATALOG_NOT_FOUND", 44),
            ("SCHEMA_NOT_FOUND", 45),
            ("TABLE_NOT_FOUND", 46),
            ("COLUMN_NOT_FOUND", 47),
            ("DUPLICATE_NAMED_QUERY", 53),
            ("MISSING_CATALOG_NAME", 56),
            ("MISSING_SCHEMA_NAME", 57),
            ("TYPE_MISMATCH", 58),
            ("INVALID_LITERAL", 59),
            ("MISMATCHED_COLUMN_ALIASES", 61),
            ("AMBIGUOUS_NAME", 62),
            ("INVALID_COLUMN_REFERENCE", 63),
            ("MISSING_OVER", 66),
            ("FUNCTION_NOT_WINDOW", 71),
            ("FUNCTION_NOT_AGGREGATE", 72),
            ("EXPRESSION_NOT_AGGREGATE", 73),
            ("INVALID_PARAMETER_USAGE", 80),
            ("NULL_TREATMENT_NOT_ALLOWED", 83),
        )
    },
    "GENERIC_INTERNAL_ERROR": (65536, INTERNAL_ERROR),
    "SERVER_SHUTTING_DOWN": (65545, INTERNAL_ERROR),
    "GENERIC_INSUFFICIENT_RESOURCES": (131072, INSUFFICIENT_RESOURCES),
    "EXCEEDED_GLOBAL_MEMORY_LIMIT": (131073, INSUFFICIENT_RESOURCES),
    "QUERY_QUEUE_FULL": (131074, INSUFFICIENT_RESOURCES),
    "EXCEEDED_TIME_LIMIT": (131075, INSUFFICIENT_RESOURCES),
    "HIVE_FILE_NOT_FOUND": (16777220, "EXTERNAL"),  # io.trino.plugin.hive.HiveErrorCode
    "HIVE_BAD_DATA": (16777223, "EXTERNAL"),
}


@dataclass(frozen=True)
class Failure:
    """Why a query failed: Trino's error name, a message, and the 1-based position in the SQL."""

    message: str
    error_name: str = "GENERIC_USER_ERROR"
    line: int | None = None
    column: int | None = None

    @classmethod
    def of(cls, error: BaseException) -> Failure:
        """The failure for an exception: a DialectError keeps its name and position; anything
        else is a GENERIC_INTERNAL_ERROR."""
        if isinstance(error, DialectError):
            message = error.message
            if error.error_name == "EXCEEDED_GLOBAL_MEMORY_LIMIT":  # DuckDB adds tuning hints
                message = f"{message.splitlines()[0].strip()} (lakegate serve --memory-limit)"
            return cls(message, error.error_name, error.line, error.column)
        return cls("internal error: lakegate failed on this query (the server's log has why)", "GENERIC_INTERNAL_ERROR")

    @property
    def error_type(self) -> str:
        return ERRORS.get(self.error_name, (0, USER_ERROR))[1]

    def document(self) -> dict:
        """The QueryResults `error` object: Trino's message (prefixed `line L:C: ` when the position
        is known), errorCode/errorName/errorType, errorLocation and failureInfo."""
        code, kind = ERRORS.get(self.error_name, (0, USER_ERROR))
        message = self.message
        error: dict = {"message": message, "errorCode": code, "errorName": self.error_name, "errorType": kind}
        location = None
        if self.line is not None and self.column is not None:
            location = {"lineNumber": self.line, "columnNumber": self.column}
            error["message"] = message = f"line {self.line}:{self.column}: {message}"
            error["errorLocation"] = location
        exception = (
            "io.trino.sql.parser.ParsingException"
            if self.error_name == "SYNTAX_ERROR"
            else "io.trino.spi.TrinoException"
        )
        error["failureInfo"] = {
            "type": exception,
            "message": message,
            "suppressed": [],
            "stack": [],
            "errorLocation": location,
            "cause": None,
        }
        return error


class QueryIds:
    """Trino-style query ids, `YYYYMMDD_HHMMSS_<5-digit counter>_<random>`: the random part (12
    lower-case letters and digits, from `secrets`) makes another query's id unguessable from one's own."""

    RANDOM_CHARACTERS = 12

    def __init__(self) -> None:
        self._counter = 0
        self._second, self._prefix = -1, ""  # the time prefix, formatted once a second
        self._lock = threading.Lock()

    def next(self) -> str:
        second = int(time.time())
        tail = "".join(secrets.choice(_ID_ALPHABET) for _ in range(self.RANDOM_CHARACTERS))
        with self._lock:
            self._counter = self._counter % 99_999 + 1
            if second != self._second:
                self._second, self._prefix = second, f"{datetime.fromtimestamp(second, UTC):%Y%m%d_%H%M%S}"
            return f"{self._prefix}_{self._counter:05d}_{tail}"


_ID_ALPHABET = string.ascii_lowercase + string.digits


def columns_document(columns: Sequence[tuple[str, str]]) -> list[dict]:
    """QueryResults `columns`: name, Trino type name and full typeSignature of each column."""
    return [{"name": name, **_column_type(trino_type)} for name, trino_type in columns]


@functools.lru_cache(maxsize=1024)
def _column_type(trino_type: str) -> dict:
    """A column's `type` and `typeSignature` (parsed once per type name: the caller copies the dict,
    and the documents are only serialised)."""
    return {"type": protocol_type(trino_type), "typeSignature": type_signature(trino_type)}


@dataclass
class Progress:
    """What a query has done so far, for `stats`."""

    state: str
    queued_ms: int = 0
    elapsed_ms: int = 0
    rows: int = 0
    bytes: int = 0


def stats_document(progress: Progress) -> dict:
    """QueryResults `stats` as Trino fills them for a query of one split (clients read `state`;
    Superset shows completedSplits / totalSplits): a queued query has no node and no split yet, and
    only a finished one has a progress percentage."""
    queued, finished = progress.state == "QUEUED", progress.state == "FINISHED"
    stats = {
        "state": progress.state,
        "queued": queued,
        "scheduled": not queued,
        "nodes": int(not queued),
        "totalSplits": int(not queued),
        "queuedSplits": 0,
        "runningSplits": int(progress.state == "RUNNING"),
        "completedSplits": int(progress.state in ("FINISHED", "FAILED")),
        "planningTimeMillis": 0,
        "analysisTimeMillis": 0,
        "cpuTimeMillis": 0,
        "wallTimeMillis": progress.elapsed_ms,
        "queuedTimeMillis": progress.queued_ms,
        "elapsedTimeMillis": progress.elapsed_ms,
        "finishingTimeMillis": 0,
        "physicalInputTimeMillis": 0,
        "processedRows": progress.rows,
        "processedBytes": progress.bytes,
        "physicalInputBytes": 0,
        "physicalWrittenBytes": 0,
        "internalNetworkInputBytes": 0,
        "peakMemoryBytes": 0,
        "spilledBytes": 0,
        "rootStage": None,
    }
    if finished:
        stats.update(progressPercentage=100.0, runningPercentage=0.0)
    return stats


def results_document(
    *,
    query_id: str,
    info_uri: str,
    progress: Progress,
    next_uri: str | None = None,
    columns: list[dict] | None = None,
    data: bytes | None = None,
    failure: Failure | None = None,
    update_type: str | None = None,
    update_count: int | None = None,
) -> bytes:
    """One QueryResults document as JSON bytes. `data` is the already serialised JSON array of rows;
    `next_uri` is absent on the last document of a query."""
    document: dict = {"id": query_id, "infoUri": info_uri}
    if next_uri is not None:
        document["nextUri"] = next_uri
    if columns is not None:
        document["columns"] = columns
    if data is not None:
        document["data"] = orjson.Fragment(data)
    document["stats"] = stats_document(progress)
    if failure is not None:
        document["error"] = failure.document()
    document["warnings"] = []
    if update_type is not None:
        document["updateType"] = update_type
        if update_count is not None:
            document["updateCount"] = update_count
    return orjson.dumps(document)


def info_document(started: float) -> bytes:
    """GET /v1/info: the node version, environment and uptime (`started` is a time.monotonic())."""
    return orjson.dumps(
        {
            "nodeVersion": {"version": TRINO_VERSION},
            "environment": ENVIRONMENT,
            "coordinator": True,
            "starting": False,
            "uptime": _duration(time.monotonic() - started),
        }
    )


def _duration(seconds: float) -> str:
    """Airlift's Duration text, as Trino prints uptime: `12.34s`, `5.20m`, `3.10h`, `2.00d`."""
    for unit, size in (("d", 86_400), ("h", 3_600), ("m", 60)):
        if seconds >= size:
            return f"{seconds / size:.2f}{unit}"
    return f"{seconds:.2f}s"
