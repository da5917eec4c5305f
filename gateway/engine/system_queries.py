"""A translated query over materialised system tables (`system_tables.SystemCatalog` makes them, as
Arrow tables), run on an in-memory DuckDB database: in a query worker process when the backend is
isolated (so that a runaway allocation over a system table costs only that worker), else here."""

from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence

import duckdb
import pyarrow as pa

from lakegate.dialect.errors import runtime_error
from lakegate.gateway.engine import udfs
from lakegate.gateway.engine.backend import BATCH_ROWS, QueryResult
from lakegate.gateway.engine.query_run import Run, in_zones


class SystemDatabase:
    """An in-memory DuckDB database (one thread, `memory_limit`, no file access, lakegate's
    functions) that runs queries over Arrow tables registered for each query."""

    def __init__(self, memory_limit: str):
        self._db = duckdb.connect(
            ":memory:",
            config={
                "threads": 1,
                "memory_limit": memory_limit,
                "autoinstall_known_extensions": False,
                "autoload_known_extensions": False,
                "python_enable_replacements": False,
            },
        )
        udfs.install(self._db)
        self._db.execute("SET TimeZone = 'UTC'")
        self._db.execute("SET enable_external_access = false")
        self._db.execute("SET lock_configuration = true")
        self._lock = threading.Lock()

    def run(
        self,
        duckdb_sql: str,
        tables: Mapping[str, pa.Table],
        columns: Sequence[tuple[str, str]],
        zones: Sequence[str | None],
        *,
        timeout: float | None = None,
    ) -> QueryResult:
        """Start `duckdb_sql` over `tables` (by name), whose result has `columns` (Trino names and
        types) shown in `zones`; interrupted after `timeout` seconds (None: never). Raises DialectError."""
        with self._lock:
            cursor = self._db.cursor()
        try:
            for name, table in tables.items():
                cursor.register(name, table)
            relation = cursor.sql(duckdb_sql)
        except BaseException as error:
            cursor.close()
            raise runtime_error(str(error)) if isinstance(error, duckdb.Error) else error from None
        run = Run(
            cursor,
            in_zones(lambda: relation.to_arrow_reader(BATCH_ROWS), zones),
            timeout=timeout,
            remaining=timeout or 0.0,
        )
        return QueryResult(columns=list(columns), batches=run, duckdb_sql=duckdb_sql, _cancel=run.cancel)

    def close(self) -> None:
        self._db.close()
