"""The official Trino CLI (io.trino:trino-cli:476, its executable jar) in batch mode against a real
`lakegate serve`: `--execute` with `--output-format CSV` and `JSON`. Queries that read no table
print exactly what the same CLI prints against the real Trino 476; queries over the lake print the
rows DuckDB reads from the lake's Parquet files, and exactly what the CLI prints against the real
Trino reading the same Parquet files through its hive catalog (`lakegate trino-ddl --apply`).
"""

from __future__ import annotations

import csv
import io
import json
import shutil
import subprocess
import sys
import uuid
from collections.abc import Callable
from pathlib import Path

import duckdb
import pytest

from lakegate.lake import paths

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]

#: Literal queries: one of each type a CLI renders, with the characters CSV and JSON must escape.
LITERALS = [
    "SELECT 1 AS one, BIGINT '-9007199254740993' AS big, 'héllo, \"wörld\"' AS s, "
    "'two\nlines' AS nl, CAST(NULL AS varchar) AS n, true AS b",
    "SELECT DOUBLE '1e300' AS d, -0.1E0 AS neg, nan() AS nan, infinity() AS inf, REAL '1.5' AS re, "
    "DECIMAL '12.30' AS dec, DECIMAL '-0.001' AS small",
    "SELECT DATE '2024-02-29' AS dt, TIMESTAMP '2024-01-02 03:04:05.123' AS ts, "
    "TIMESTAMP '2024-01-02 03:04:05.123456' AS ts6, X'0aff' AS bin",
    "SELECT ARRAY[1, 2] AS a, ARRAY['x,y', NULL] AS sa, MAP(ARRAY['k'], ARRAY[1.5]) AS m, "
    "ROW(1, 'x') AS r, CAST(ROW(2, 'y') AS ROW(id bigint, name varchar)) AS named",
    "SELECT x, x * 2 AS twice FROM UNNEST(sequence(1, 5)) AS t(x) ORDER BY x DESC",
    "SELECT * FROM (VALUES 1, 2) AS t(x) WHERE x > 5",
]
#: Literal queries the CLI can print as JSON (its JSON writer cannot write arrays, maps or rows).
JSON_LITERALS = [q for q in LITERALS if "ARRAY[1, 2]" not in q]


@pytest.fixture(scope="module")
def trino_cli(jdk, trino_jar) -> Callable[..., subprocess.CompletedProcess]:
    """`cli(url, *args)`: the Trino CLI run once in batch mode (standard input closed)."""
    jar = trino_jar("trino-cli")

    def run(url: str, *args: str) -> subprocess.CompletedProcess:
        command = [str(jdk / "bin" / "java"), "-XX:TieredStopAtLevel=1", "-jar", str(jar), "--server", url]
        return subprocess.run(
            [*command, "--user", "tester", *args], stdin=subprocess.DEVNULL, capture_output=True, timeout=180
        )

    return run


def _errors(stderr: bytes) -> list[str]:
    """What the CLI prints of its errors, without the query ids and the JVM's warnings about jline's
    terminal: each `Query <id> failed: <message>` as its message, then the statement's line and caret."""
    lines = stderr.decode().splitlines()
    out = []
    for i, line in enumerate(lines):
        if line.startswith("Query ") and " failed: " in line:
            out.append(line.split(" failed: ", 1)[1])
            out += [text for text in lines[i + 1 : i + 3] if text.startswith("LINE ") or text.strip() == "^"]
        elif line.startswith("\x1b[31"):  # an error of the CLI itself, in red
            out.append(line)
    return out


@pytest.mark.parametrize("output_format", ["CSV", "JSON"])
def test_literal_queries_print_as_trino_prints_them(output_format, lake_server, trino_url, trino_cli):
    queries = LITERALS if output_format == "CSV" else JSON_LITERALS
    args = ["--output-format", output_format, "--execute", ";\n".join(queries)]
    lakegate = trino_cli(lake_server.url, *args)
    judge = trino_cli(trino_url, *args)
    assert judge.returncode == 0, judge.stderr.decode()[-2000:]
    assert lakegate.returncode == 0, lakegate.stderr.decode()[-2000:]
    assert lakegate.stdout.decode() == judge.stdout.decode()
    lines = lakegate.stdout.decode()
    if output_format == "CSV":
        first = next(csv.reader(io.StringIO(lines)))
        assert first == ["1", "-9007199254740993", 'héllo, "wörld"', "two\nlines", "", "true"]
    else:
        first = json.loads(lines.splitlines()[0])
        assert first == {
            "one": 1,
            "big": -9007199254740993,
            "s": 'héllo, "wörld"',
            "nl": "two\nlines",
            "n": None,
            "b": True,
        }


def test_json_of_nested_values_fails_as_on_trino(lake_server, trino_url, trino_cli):
    """The CLI's JSON writer cannot write an array: it stops with the same message on both servers."""
    args = ["--output-format", "JSON", "--execute", "SELECT ARRAY[1, 2] AS a"]
    lakegate, judge = trino_cli(lake_server.url, *args), trino_cli(trino_url, *args)
    assert (lakegate.returncode, lakegate.stdout) == (judge.returncode, judge.stdout)
    assert judge.returncode != 0
    assert _errors(lakegate.stderr) == _errors(judge.stderr) != []


def test_errors_print_as_trino_prints_them(lake_server, trino_url, trino_cli):
    """Errors go on (`--ignore-errors`) with the same messages, positions and carets as on Trino."""
    sql = "SELECT 1 / 0; SELECT nosuch(1); SELECT 2 AS two; SELEC 1; SELECT x FROM (VALUES 1) AS t(y)"
    args = ["--ignore-errors", "--output-format", "CSV", "--execute", sql]
    lakegate, judge = trino_cli(lake_server.url, *args), trino_cli(trino_url, *args)
    assert (lakegate.returncode, lakegate.stdout) == (judge.returncode, judge.stdout) == (1, b'"2"\n')
    assert _errors(lakegate.stderr) == _errors(judge.stderr)
    assert len(_errors(judge.stderr)) == 10  # four messages, three with their line and caret


@pytest.mark.parametrize("output_format", ["CSV", "JSON"])
def test_lake_queries(output_format, lake_server, server_lake: Path, trino_cli):
    sql = (
        "SELECT batch_id, job_id, experience_name, test_suite_revision, build_creation_timestamp "
        "FROM metadata ORDER BY job_id"
    )
    done = trino_cli(
        lake_server.url, "--catalog", "lake", "--schema", "main", "--output-format", output_format, "--execute", sql
    )
    assert done.returncode == 0, done.stderr.decode()[-2000:]
    rows = duckdb.sql(
        "SELECT batch_id, job_id, experience_name, test_suite_revision, "
        "strftime(build_creation_timestamp, '%Y-%m-%d %H:%M:%S.%g') "
        f"FROM read_parquet('{paths.table_glob(server_lake, 'main', 'metadata')}', hive_partitioning = true, "
        "hive_types = {'batch_id': VARCHAR}) ORDER BY job_id"
    ).fetchall()
    assert rows
    text = done.stdout.decode()
    if output_format == "CSV":
        printed = [tuple(row) for row in csv.reader(io.StringIO(text))]
        assert printed == [tuple("" if v is None else str(v) for v in row) for row in rows]
    else:
        printed = [json.loads(line) for line in text.splitlines()]
        names = ["batch_id", "job_id", "experience_name", "test_suite_revision", "build_creation_timestamp"]
        assert printed == [{k: v for k, v in zip(names, row) if v is not None} | _nulls(names, row) for row in rows]


def _nulls(names: list[str], row: tuple) -> dict:
    return {k: None for k, v in zip(names, row) if v is None}


LAKE_QUERIES = (
    "SELECT batch_id, job_id, experience_name, experience_tag_names, test_suite_revision, build_creation_timestamp "
    "FROM metadata ORDER BY job_id;\n"
    "SELECT job_id, count(*) AS n, min(x) AS lo, max(x) AS hi, min(timestamp) AS first "
    "FROM odom_linear_velocity GROUP BY job_id ORDER BY job_id"
)


@pytest.fixture(scope="module")
def trino_schema(server_lake, trino_url, tmp_path_factory):
    """The test lake's branch main as a schema of the real Trino's hive catalog, reading a copy of
    the very same Parquet files (`lakegate trino-ddl --apply`; dropped at the end)."""
    lake = tmp_path_factory.mktemp("cli-lake") / "lake"
    shutil.copytree(server_lake, lake)
    prefix = f"clients_cli_{uuid.uuid4().hex[:8]}_"

    def lakegate(*args: str) -> None:
        done = subprocess.run([*CLI, *args, "--lake", str(lake), "--trino-url", trino_url], capture_output=True)
        assert done.returncode == 0, done.stderr.decode()[-2000:]

    lakegate("trino-ddl", "--apply", "--schema-prefix", prefix)
    yield f"{prefix}main"
    lakegate("trino-ddl", "--drop")


@pytest.mark.parametrize("output_format", ["CSV_HEADER", "JSON"])
def test_lake_queries_print_as_trino_prints_them(output_format, lake_server, trino_url, trino_schema, trino_cli):
    queries = LAKE_QUERIES if output_format != "JSON" else LAKE_QUERIES.split(";\n")[1]  # JSON: no arrays
    args = ["--output-format", output_format, "--execute", queries]
    lakegate = trino_cli(lake_server.url, "--catalog", "lake", "--schema", "main", *args)
    judge = trino_cli(trino_url, "--catalog", "hive", "--schema", trino_schema, *args)
    assert judge.returncode == 0, judge.stderr.decode()[-2000:]
    assert lakegate.returncode == 0, lakegate.stderr.decode()[-2000:]
    assert lakegate.stdout == judge.stdout
    assert lakegate.stdout.count(b"\n") >= 3  # a row per job at least
