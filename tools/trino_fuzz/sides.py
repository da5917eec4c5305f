"""The two sides a fuzzed query runs on, each giving an `Outcome` in the Trino client protocol's
encoding: lakegate (its Engine, as `lakegate query` runs it) and the real Trino (its HTTP protocol,
read raw so that no client library decodes the values on one side only).
"""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from trino_answers import alive

from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.trino_ddl import ddl
from lakegate.gateway.engine.trino_values import encode_rows, protocol_type

#: Seconds one query may run on either side.
QUERY_SECONDS = 20.0
USER = "lakegate-fuzzer"


@dataclass
class Outcome:
    """A result (column types and rows, protocol-encoded) or an error (Trino's name and message)."""

    types: list[str] = field(default_factory=list)
    rows: list[list[Any]] = field(default_factory=list)
    error: str | None = None
    message: str = ""
    #: Wall seconds the side took (lakegate: in its Engine; Trino: from submission to the last page)
    #: and, for Trino, the CPU seconds its query stats report.
    seconds: float = 0.0
    cpu_seconds: float = 0.0

    def as_dict(self) -> dict:
        if self.error is not None:
            return {"error": self.error, "message": self.message}
        return {"types": self.types, "rows": self.rows}


class Lakegate:
    """lakegate's Engine over the lake, in a UTC session on branch `main`."""

    def __init__(self, lake: Path):
        self.engine = Engine.open(lake, limits=Limits(query_timeout=QUERY_SECONDS), isolated=True)
        self.session = self.engine.session(branch="main", time_zone="UTC")

    def run(self, sql: str) -> Outcome:
        began = time.monotonic()
        outcome = self._answer(sql)
        outcome.seconds = time.monotonic() - began
        return outcome

    def _answer(self, sql: str) -> Outcome:
        try:
            result = self.engine.execute(sql, self.session)
            rows = [row for batch in result.batches for row in encode_rows(result.columns, batch)]
        except DialectError as error:
            return Outcome(error=error.error_name, message=error.message)
        except Exception as error:  # noqa: BLE001 - an internal failure is an answer to report, not a crash
            return Outcome(error="LAKEGATE_INTERNAL", message=f"{type(error).__name__}: {error}")
        return Outcome(types=[protocol_type(t) for _, t in result.columns], rows=[list(r) for r in rows])

    def close(self) -> None:
        self.engine.close()


class Trino:
    """The real Trino over HTTP, in catalog `hive`, schema `schema`, session zone UTC."""

    def __init__(self, url: str, schema: str):
        self.url, self.schema = url.rstrip("/"), schema

    def _request(self, url: str, body: bytes | None = None, *, schema: bool = True) -> dict:
        headers = {
            "X-Trino-User": USER,
            "X-Trino-Time-Zone": "UTC",
            "X-Trino-Catalog": "hive",
            "X-Trino-Client-Capabilities": "PARAMETRIC_DATETIME",  # as the trino clients send it
        }
        if schema:
            headers["X-Trino-Schema"] = self.schema
        headers["X-Trino-Session"] = f"query_max_run_time={int(QUERY_SECONDS)}s"
        request = urllib.request.Request(url, data=body, headers=headers, method="POST" if body else "GET")
        for attempt in range(20):
            try:
                with urllib.request.urlopen(request, timeout=QUERY_SECONDS + 30) as response:
                    return json.load(response)
            except urllib.error.HTTPError as error:
                if error.code not in (429, 502, 503) or attempt == 19:
                    raise
                time.sleep(0.05 * (attempt + 1))
        raise AssertionError("unreachable")

    def run(self, sql: str, *, schema: bool = True) -> Outcome:
        began = time.monotonic()
        reply = self._request(f"{self.url}/v1/statement", sql.encode(), schema=schema)
        columns, rows = None, []
        while True:
            if "error" in reply:
                error = reply["error"]
                outcome = Outcome(error=error.get("errorName", "UNKNOWN"), message=error.get("message", ""))
                break
            columns = reply.get("columns", columns)
            rows.extend(reply.get("data") or [])
            if "nextUri" not in reply:
                outcome = Outcome(types=[c["type"] for c in columns or []], rows=rows)
                break
            reply = self._request(reply["nextUri"])
        outcome.seconds = time.monotonic() - began
        outcome.cpu_seconds = reply.get("stats", {}).get("cpuTimeMillis", 0) / 1000
        return outcome

    def execute(self, sql: str) -> None:
        """Run a statement that must succeed (DDL), RuntimeError with Trino's message otherwise."""
        outcome = self.run(sql, schema=False)
        if outcome.error:
            raise RuntimeError(f"Trino refused {sql[:200]!r}: {outcome.error}: {outcome.message}")


def register(trino: Trino, lake: Path, schema_prefix: str) -> None:
    """Register the lake's branch `main` in Trino's hive catalog as `<schema_prefix>main`, with the
    project's DDL generator (its tables replaced, so a rebuilt lake is read afresh)."""
    schema = f"{schema_prefix}main"
    existing = trino.run(f"SHOW TABLES FROM hive.{schema}", schema=False)
    for (table,) in existing.rows if not existing.error else []:
        trino.execute(f'DROP TABLE hive.{schema}."{table}"')
    script = ddl(lake.resolve(), f"local://{lake.resolve()}", schema_prefix=schema_prefix, branches=["main"])
    for statement in script.split(";\n"):
        text = "\n".join(line for line in statement.splitlines() if not line.startswith("--")).strip()
        if text:
            trino.execute(text)


def unregister(trino: Trino, schema: str) -> None:
    """Drop the schema `register` made (its external tables' files stay)."""
    existing = trino.run(f"SHOW TABLES FROM hive.{schema}", schema=False)
    for (table,) in existing.rows if not existing.error else []:
        trino.execute(f'DROP TABLE hive.{schema}."{table}"')
    trino.execute(f"DROP SCHEMA IF EXISTS hive.{schema}")


def drop_orphans(trino: Trino, prefix: str) -> None:
    """Drop the schemas `<prefix><pid>_main` whose run no longer runs on this machine (one that was
    killed before it could drop its schema)."""
    schemas = trino.run(f"SHOW SCHEMAS FROM hive LIKE '{prefix}%'", schema=False)
    for (name,) in schemas.rows if not schemas.error else []:
        pid = name[len(prefix) :].split("_")[0]
        if pid.isdigit() and not alive(int(pid)):
            unregister(trino, name)
