"""Answers of the real Trino (tools/trino_server.py) in the client protocol's JSON encoding: the
(name, type) of each column and the rows as the protocol's `data`, or the error name Trino raised.

`TrinoAnswers` asks many queries at once (a few at a time, one connection per thread and session
zone) and registers folders of Parquet files as external tables of the hive catalog, in a schema of
their own that `drop_schema` removes again.
"""

from __future__ import annotations

import os
import re
import threading
from collections.abc import Iterable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

import requests
import sqlglot
import trino
from sqlglot import exp

#: How many one-row queries are asked as one.
BATCH = 25
#: A query that runs longer is stopped by Trino itself (EXCEEDED_TIME_LIMIT).
MAX_RUN_TIME = "60s"
_SCHEMA_NAME = re.compile(r"[a-z_][a-z0-9_]*")


@dataclass(frozen=True)
class Answer:
    """One query's answer: columns and rows, or the error Trino raised."""

    columns: tuple[tuple[str, str], ...] = ()  # (name, Trino type) per column
    rows: tuple[list, ...] = ()  # values in the client-protocol JSON encoding
    error: str | None = None  # Trino's error name (DIVISION_BY_ZERO, ...)
    message: str = ""

    def __str__(self) -> str:
        if self.error is not None:
            return f"{self.error}: {self.message}"
        return f"{[f'{n} {t}' for n, t in self.columns]} {list(self.rows)}"


class TrinoAnswers:
    """Queries to the Trino at `url`, in catalog `catalog` and schema `schema`."""

    def __init__(self, url: str, *, catalog: str = "hive", schema: str | None = None, threads: int = 4):
        parts = urlsplit(url)
        self.host, self.port = parts.hostname or "127.0.0.1", parts.port or 8080
        self.catalog, self.schema, self.threads = catalog, schema, threads
        self._local = threading.local()

    def _cursor(self, time_zone: str):
        connections = self._local.__dict__.setdefault("connections", {})
        if time_zone not in connections:
            connections[time_zone] = trino.dbapi.connect(
                host=self.host,
                port=self.port,
                user="lakegate-conformance",
                catalog=self.catalog,
                schema=self.schema,
                http_session=_ZoneSession(time_zone),
                session_properties={"query_max_run_time": MAX_RUN_TIME},
                legacy_primitive_types=True,  # values exactly as the protocol's JSON carries them
            )
        return connections[time_zone].cursor()

    def ask(self, sql: str, time_zone: str = "UTC") -> Answer:
        """Trino's answer to one query in the session zone `time_zone`."""
        cursor = self._cursor(time_zone)
        try:
            cursor.execute(sql)
            rows = cursor.fetchall()
        except trino.exceptions.TrinoQueryError as error:
            return Answer(error=error.error_name, message=error.message)
        except trino.exceptions.HttpError as error:  # refused before it became a query: an empty text
            return Answer(error="HTTP_ERROR", message=str(error))
        finally:
            cursor.close()
        columns = tuple((d[0], d[1]) for d in cursor.description or ())
        return Answer(columns=columns, rows=tuple(rows))

    def ask_all(self, queries: Iterable[tuple[str, str]], *, batch: bool = True) -> list[Answer]:
        """Trino's answers to (sql, time zone) queries, in their order, `threads` at a time. Queries
        that give one row by their shape (a SELECT without FROM, WHERE, GROUP BY, HAVING or LIMIT)
        are asked BATCH at a time as one cross join of them (a planned query costs Trino tens of
        milliseconds); a batch that fails or does not split cleanly is asked again in halves.
        `batch=False` asks each query alone (for queries expected to fail)."""
        queries = list(queries)
        answers: list[Answer | None] = [None] * len(queries)
        batches: dict[str, list[tuple[int, int]]] = {}
        singles = []
        for index, (sql, zone) in enumerate(queries):
            width = single_row_width(sql) if batch else None
            if width is None:
                singles.append(index)
            else:
                batches.setdefault(zone, []).append((index, width))
        jobs = [[index] for index in singles]
        for members in batches.values():
            jobs += [members[i : i + BATCH] for i in range(0, len(members), BATCH)]

        def run(job) -> None:
            if isinstance(job[0], int):
                answers[job[0]] = self.ask(*queries[job[0]])
                return
            for index, answer in zip((i for i, _ in job), self._ask_batch([(queries[i], w) for i, w in job])):
                answers[index] = answer

        with ThreadPoolExecutor(self.threads) as pool:
            list(pool.map(run, jobs))
        return answers  # type: ignore[return-value]

    def _ask_batch(self, members: list[tuple[tuple[str, str], int]]) -> list[Answer]:
        zone = members[0][0][1]
        sql = "SELECT * FROM " + " CROSS JOIN ".join(f"({query.strip()})" for (query, _), _ in members)
        combined = self.ask(sql, zone)
        widths = [width for _, width in members]
        if combined.error is not None or len(combined.rows) != 1 or len(combined.columns) != sum(widths):
            if len(members) == 1:
                return [self.ask(*members[0][0])]
            half = len(members) // 2
            return self._ask_batch(members[:half]) + self._ask_batch(members[half:])
        answers, start = [], 0
        for width in widths:
            columns = combined.columns[start : start + width]
            answers.append(Answer(columns=columns, rows=(list(combined.rows[0][start : start + width]),)))
            start += width
        return answers

    def run(self, statements: Sequence[str]) -> None:
        """Run statements (DDL) one after the other; the first error raises."""
        for sql in statements:
            answer = self.ask(sql)
            if answer.error is not None:
                raise RuntimeError(f"Trino refused {sql!r}: {answer}")

    def register(self, schema: str, tables: Mapping[str, tuple[Path, Mapping[str, str]]]) -> None:
        """Create `schema` in the hive catalog with one external Parquet table per entry of `tables`
        (name -> (folder of its Parquet files, column -> Trino type))."""
        _check_schema(schema)
        statements = [f"CREATE SCHEMA hive.{schema}"]
        for table, (folder, columns) in tables.items():
            spec = ", ".join(f"{_quoted(name)} {type_name}" for name, type_name in columns.items())
            location = "local://" + str(Path(folder).resolve()).replace("'", "''")
            statements.append(
                f"CREATE TABLE hive.{schema}.{_quoted(table)} ({spec}) "
                f"WITH (external_location = '{location}', format = 'PARQUET')"
            )
        self.run(statements)

    def drop_schema(self, schema: str) -> None:
        """Drop `schema` of the hive catalog with its tables and views (external tables: their files
        stay); nothing when there is no such schema."""
        _check_schema(schema)
        listed = self.ask(
            f"SELECT table_name, table_type FROM hive.information_schema.tables WHERE table_schema = '{schema}'"
        )
        kinds = {"BASE TABLE": "TABLE", "VIEW": "VIEW"}
        self.run([f"DROP {kinds[kind]} hive.{schema}.{_quoted(name)}" for name, kind in listed.rows])
        self.run([f"DROP SCHEMA IF EXISTS hive.{schema}"])

    def drop_orphans(self, prefix: str) -> None:
        """Drop the schemas `<prefix><pid>_...` whose process no longer runs on this machine (left by a
        test run that was killed before it could drop them)."""
        schemas = self.ask(f"SHOW SCHEMAS FROM hive LIKE '{prefix}%'")
        for (name,) in schemas.rows:
            pid = name[len(prefix) :].split("_")[0]
            if pid.isdigit() and not alive(int(pid)):
                self.drop_schema(name)


class _ZoneSession(requests.Session):
    """HTTP requests in the session zone `zone`: the trino client accepts only zones Python knows,
    Trino also offsets such as `-08:30`."""

    def __init__(self, zone: str):
        super().__init__()
        self.zone = zone

    def prepare_request(self, request: requests.Request) -> requests.PreparedRequest:
        prepared = super().prepare_request(request)
        prepared.headers["X-Trino-Time-Zone"] = self.zone
        return prepared


def single_row_width(sql: str) -> int | None:
    """How many columns `sql` gives when its shape makes it exactly one row (a SELECT without FROM,
    WHERE, GROUP BY, HAVING, LIMIT, OFFSET and without `*`), else None."""
    try:
        tree = sqlglot.parse_one(sql, read="trino")
    except sqlglot.errors.SqlglotError:
        return None
    if not isinstance(tree, exp.Select) or any(tree.args.get(key) for key in _MORE_THAN_ONE_ROW):
        return None
    if any(isinstance(e, exp.Star) or isinstance(e.unalias(), exp.Star) for e in tree.expressions):
        return None
    return len(tree.expressions)


_MORE_THAN_ONE_ROW = (
    "from",
    "from_",
    "joins",
    "where",
    "group",
    "having",
    "limit",
    "offset",
    "order",
    "qualify",
    "with",
)


def alive(pid: int) -> bool:
    """Whether process `pid` still runs (a schema named for a gone process is left over)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _check_schema(schema: str) -> None:
    if not _SCHEMA_NAME.fullmatch(schema):
        raise ValueError(f"schema name {schema!r} is not [a-z_][a-z0-9_]*")


def _quoted(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'
