"""Shared fixture tables for the dialect tests: real Parquet files, DuckDB views over them, and the
Trino schema the translator is given.

Tables (session-scoped, written once per test process):

- ``t``: one row per kind of value, with NULLs, negative numbers, an empty array, a unicode string;
- ``odom``: a topic (``timestamp`` bigint nanoseconds, x/y/z double, batch_id, job_id);
- ``metadata``: one row per job, with array columns;
- ``events``: columns named ``timestamp``, ``count``, ``sum``, ``my col`` and ``größe``.

The session time zone of every connection is UTC, as the conformance cases assume.
"""

from __future__ import annotations

import datetime as dt
import hashlib
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from lakegate.gateway.engine import udfs

_J1 = '{"name": "alpha", "n": 1, "tags": ["a", "b"], "pos": {"x": 1.5}}'

#: table -> (column -> (Trino type, Arrow type)), in column order.
_COLUMNS = {
    "t": {
        "id": ("bigint", pa.int64()),
        "a": ("bigint", pa.int64()),
        "b": ("bigint", pa.int64()),
        "i": ("integer", pa.int32()),
        "d": ("double", pa.float64()),
        "dec": ("decimal(10,2)", pa.decimal128(10, 2)),
        "s": ("varchar", pa.string()),
        "g": ("varchar", pa.string()),
        "arr": ("array(varchar)", pa.list_(pa.string())),
        "nums": ("array(bigint)", pa.list_(pa.int64())),
        "ts": ("timestamp(3)", pa.timestamp("ms")),
        "flag": ("boolean", pa.bool_()),
        "js": ("varchar", pa.string()),
    },
    "odom": {
        "timestamp": ("bigint", pa.int64()),
        "x": ("double", pa.float64()),
        "y": ("double", pa.float64()),
        "z": ("double", pa.float64()),
        "batch_id": ("varchar", pa.string()),
        "job_id": ("varchar", pa.string()),
    },
    "metadata": {
        "job_id": ("varchar", pa.string()),
        "batch_id": ("varchar", pa.string()),
        "experience_name": ("varchar", pa.string()),
        "build_version": ("varchar", pa.string()),
        "experience_tag_names": ("array(varchar)", pa.list_(pa.string())),
        "experience_tag_ids": ("array(varchar)", pa.list_(pa.string())),
        "custom_field_keys": ("array(varchar)", pa.list_(pa.string())),
        "custom_field_values": ("array(varchar)", pa.list_(pa.string())),
        "job_status": ("varchar", pa.string()),
    },
    "events": {
        "timestamp": ("bigint", pa.int64()),
        "count": ("bigint", pa.int64()),
        "sum": ("double", pa.float64()),
        "my col": ("varchar", pa.string()),
        "größe": ("double", pa.float64()),
    },
}


def _ts(text: str) -> dt.datetime:
    return dt.datetime.fromisoformat(text)


_ROWS = {
    "t": [
        (
            1,
            5,
            2,
            10,
            1.5,
            Decimal("12.34"),
            "apple",
            "g1",
            ["x", "y"],
            [1, 2, 3],
            _ts("2024-01-02 03:04:05.123"),
            True,
            _J1,
        ),
        (
            2,
            -7,
            3,
            -4,
            -2.25,
            Decimal("0.50"),
            "Banana",
            "g1",
            ["y"],
            [10, 20],
            _ts("2024-01-15 12:00:00.000"),
            False,
            '{"name": "beta", "n": 2.50, "tags": []}',
        ),
        (
            3,
            9,
            0,
            0,
            0.0,
            Decimal("-3.10"),
            "cherry pie",
            "g2",
            [],
            [],
            _ts("2024-02-29 23:59:59.999"),
            True,
            '{"name": null}',
        ),
        (4, None, 4, 7, None, None, None, "g2", None, None, None, None, None),
        (
            5,
            12,
            None,
            None,
            3.0,
            Decimal("100.00"),
            "",
            "g3",
            ["z", None],
            [5, None, 7],
            _ts("2023-12-31 00:00:00.000"),
            False,
            "not json",
        ),
        (
            6,
            12,
            5,
            3,
            10.0,
            Decimal("7.25"),
            "Äpfel ü",
            None,
            ["x"],
            [4],
            _ts("2024-03-10 08:30:00.500"),
            True,
            '{"name": "ü", "n": -3}',
        ),
    ],
    "odom": [
        (0, 3.0, 4.0, 0.0, "b1", "j1"),
        (1_000_000_000, 6.0, 8.0, 0.0, "b1", "j1"),
        (2_000_000_000, 0.0, 0.0, 0.0, "b1", "j1"),
        (3_000_000_000, 1.5, 2.0, 0.0, "b1", "j1"),
        (0, 1.0, 0.0, 1.0, "b1", "j2"),
        (500_000_000, 2.0, 0.0, 1.0, "b1", "j2"),
        (1_000_000_000, 3.0, 0.0, 1.0, "b1", "j2"),
        (1_500_000_000, 4.0, 0.0, 1.0, "b1", "j2"),
        (2_000_000_000, -1.0, 0.0, 0.0, "b2", "j3"),
    ],
    "metadata": [
        ("j1", "b1", "Parking lot", "v1.2.0", ["night", "rain"], ["t1", "t2"], ["weather"], ["rain"], "SUCCEEDED"),
        ("j2", "b1", "Highway merge", "v1.2.0", ["day"], ["t3"], [], [], "FAILED"),
        ("j3", "b2", "Parking lot", "v1.3.0", [], [], ["weather", "driver"], ["sun", "bot"], "SUCCEEDED"),
    ],
    "events": [
        (100, 3, 1.5, "first", 1.25),
        (200, 5, 2.5, "second", 2.5),
        (300, None, None, None, None),
    ],
}

#: The schema handed to the translator: table -> column -> Trino type name.
SCHEMA: dict[str, dict[str, str]] = {
    table: {name: trino for name, (trino, _) in columns.items()} for table, columns in _COLUMNS.items()
}


@dataclass
class FixtureLake:
    """Parquet files of the fixture tables, and how to query them."""

    root: Path
    schema: dict[str, dict[str, str]]
    #: What the tables hold, as a hash (recorded answers of the real Trino are of these rows).
    fingerprint: str = hashlib.sha256(repr((_COLUMNS, _ROWS)).encode()).hexdigest()[:16]
    _shared: duckdb.DuckDBPyConnection | None = field(default=None, repr=False)

    def file(self, table: str) -> Path:
        """The Parquet file of `table`, alone in its own folder (so that a real Trino can register the
        folder as an external table)."""
        return self.root / table / f"{table}.parquet"

    def connect(self) -> duckdb.DuckDBPyConnection:
        """A new in-memory DuckDB connection with one view per table, in UTC, that can read only the
        fixture directory and whose configuration is locked."""
        con = duckdb.connect()
        udfs.install(con)
        con.execute("SET TimeZone = 'UTC'")
        for table in self.schema:
            path = str(self.file(table)).replace("'", "''")
            con.execute(f"CREATE VIEW \"{table}\" AS SELECT * FROM read_parquet('{path}')")
        con.execute("SET allowed_directories = ?", [[str(self.root)]])
        con.execute("SET enable_external_access = false")
        con.execute("SET lock_configuration = true")
        return con

    @contextmanager
    def transaction(self) -> Iterator[duckdb.DuckDBPyConnection]:
        """A cursor on one shared connection (connecting costs ~50 ms), inside a transaction that
        is rolled back, so that nothing a query does outlives it."""
        if self._shared is None:
            self._shared = self.connect()
        cursor = self._shared.cursor()
        cursor.execute("BEGIN TRANSACTION")
        try:
            yield cursor
        finally:
            try:
                cursor.execute("ROLLBACK")
            except duckdb.Error:  # the query ended the transaction itself: start afresh next time
                self._shared = None
            cursor.close()


def write_tables(root: Path) -> None:
    """Write every fixture table as `<root>/<table>/<table>.parquet`."""
    for table, columns in _COLUMNS.items():
        (root / table).mkdir(parents=True, exist_ok=True)
        arrow_schema = pa.schema([(name, arrow) for name, (_, arrow) in columns.items()])
        rows = _ROWS[table]
        data = {name: [row[k] for row in rows] for k, name in enumerate(columns)}
        pq.write_table(pa.table(data, schema=arrow_schema), root / table / f"{table}.parquet")


@pytest.fixture(scope="session")
def fixture_lake(tmp_path_factory: pytest.TempPathFactory) -> FixtureLake:
    root = tmp_path_factory.mktemp("dialect-tables")
    write_tables(root)
    return FixtureLake(root=root, schema=SCHEMA)
