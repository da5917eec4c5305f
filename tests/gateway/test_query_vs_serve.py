"""`lakegate query` and `lakegate serve` answer alike: the same column names and types, the same
values (in the Trino protocol's JSON encoding), the same error message at the same position, for
every conformance case and for SHOW / DESCRIBE / information_schema / system statements.

Both run over the server tests' lake (conftest.py): the query command in this process through its
real entry point (`lakegate.gateway.cli.main.main`, `--format json`), its query workers taken from
one pool kept for the module (as the server keeps its pool) instead of one started per query: the
command's own start-up is tested by test_query_command.py, the answers are what is compared here. The server as a real
`lakegate serve` subprocess read by the official `trino` client with raw protocol values
(`legacy_primitive_types`). The expected side is the server: neither answer is written here.
"""

from __future__ import annotations

import json

import pytest
import trino
from functions_doc import load_cases

from lakegate.gateway.cli import backends
from lakegate.gateway.cli.main import main
from lakegate.gateway.engine.isolated_backend import IsolatedBackend

#: What both sides must answer alike beyond the conformance cases: the lake's names, as Trino shows them.
INTROSPECTION = [
    "SHOW CATALOGS",
    "SHOW CATALOGS LIKE 'la%'",
    "SHOW SCHEMAS",
    "SHOW SCHEMAS FROM lake",
    "SHOW SCHEMAS FROM lakegate",
    "SHOW TABLES",
    "SHOW TABLES FROM lake.main LIKE 'odom%'",
    'SHOW TABLES FROM "feature/all-types"',
    "SHOW TABLES FROM nowhere",
    "SHOW COLUMNS FROM metadata",
    "SHOW COLUMNS FROM lake.main.odom_linear_velocity LIKE '%\\_id' ESCAPE '\\'",
    "SHOW SESSION LIKE 'batch%'",
    "SHOW FUNCTIONS",
    "DESCRIBE odom_linear_velocity",
    'DESCRIBE lake."feature/all-types".sample',
    "DESCRIBE nothing",
    "DESC main.metadata",
    "SELECT count(*) FROM main.metadata",
    "SELECT table_schema, table_name FROM information_schema.tables WHERE table_schema <> 'information_schema' "
    "ORDER BY 1, 2",
    "SELECT column_name, data_type FROM lake.information_schema.columns WHERE table_name = 'sample' ORDER BY 1",
    "SELECT schema_name FROM information_schema.schemata ORDER BY 1",
    "SELECT catalog_name FROM system.metadata.catalogs ORDER BY 1",
    "SELECT table_name FROM system.jdbc.tables WHERE table_schem = 'main' AND table_name LIKE 'odom%' ORDER BY 1",
    "SELECT current_catalog, current_schema, version()",
    "SELECT * FROM lakegate.main.metadata",
    "SELECT x FROM nowhere.odom_linear_velocity",
    "EXPLAIN SELECT count(*) FROM system.metadata.catalogs",
    "USE main",
    "USE nowhere",
    "SET SESSION batch_id = 'b1'",
    "SET SESSION no_such_property = 'x'",
    "INSERT INTO metadata VALUES (1)",
    "SELEC 1",
]


@pytest.fixture(scope="module")
def worker_pool(server_lake):
    """The query workers of the module's `lakegate query` runs: those of one backend as the command
    makes it (`IsolatedBackend(lake)`), closed at the end of the module."""
    backend = IsolatedBackend(server_lake)
    yield backend.pool
    backend.close()


@pytest.fixture(autouse=True)
def query_command_on_shared_workers(worker_pool, monkeypatch):
    """`lakegate query` makes its backend as it always does, over the module's workers."""
    monkeypatch.setattr(backends, "IsolatedBackend", lambda lake: IsolatedBackend(lake, pool=worker_pool))


def cli_answer(lake, sql: str, capsys, time_zone: str = "UTC") -> str:
    """What `lakegate query --format json` prints: the JSON document, or the error line."""
    code = main(["query", "--lake", str(lake), "--format", "json", f"--time-zone={time_zone}", sql])
    out, err = capsys.readouterr()
    if code:
        return err.strip()
    document = json.loads(out)
    return _canonical([(c["name"], c["type"]) for c in document["columns"]], document["rows"])


def server_answer(server, sql: str, time_zone: str = "UTC") -> str:
    """The same as `cli_answer`, from the server: its columns and raw values, or its error as the
    command line would print it. The session zone is the client's timezone=, or for an offset (which
    the python client does not take there) SET TIME ZONE."""
    offset = time_zone[0] in "+-"
    with trino.dbapi.connect(
        host=server.host,
        port=server.port,
        user="tester",
        catalog="lake",
        schema="main",
        legacy_primitive_types=True,
        timezone="UTC" if offset else time_zone,
    ) as connection:
        cursor = connection.cursor()
        if offset:
            cursor.execute(f"SET TIME ZONE '{time_zone}'")
            cursor.fetchall()
        try:
            cursor.execute(sql)
            rows = cursor.fetchall()
        except trino.exceptions.TrinoQueryError as error:
            if error.error_location is None:
                return f"lakegate: {error.message}"
            line, column = error.error_location  # Trino's message starts with them too: `line 1:5: ...`
            return f"lakegate: line {line}, column {column}: {error.message.removeprefix(f'line {line}:{column}: ')}"
        return _canonical([(d[0], d[1]) for d in cursor.description or []], rows)


def _canonical(columns: list[tuple[str, str]], rows: list) -> str:
    """Columns, then the rows as a sorted list (the order is compared by the conformance suite)."""
    encoded = sorted(json.dumps(row, ensure_ascii=False, sort_keys=True) for row in rows)
    return json.dumps({"columns": columns, "rows": encoded}, ensure_ascii=False, indent=1)


@pytest.mark.parametrize("sql", INTROSPECTION)
def test_introspection_answers_alike(sql, server_lake, lake_server, capsys):
    assert cli_answer(server_lake, sql, capsys) == server_answer(lake_server, sql)


#: An empty text never reaches the server's engine: it is refused with HTTP 400, as Trino does.
CASES = [case for case in load_cases() if case.sql.strip()]


@pytest.mark.parametrize("case", CASES, ids=lambda case: case.id)
def test_conformance_case_answers_alike(case, server_lake, lake_server, capsys):
    assert cli_answer(server_lake, case.sql, capsys, case.time_zone) == server_answer(
        lake_server, case.sql, case.time_zone
    )
