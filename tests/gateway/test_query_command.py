"""`lakegate query`, run as a real subprocess: the three output formats, --explain, scopes on a real
lake, SHOW, and one-line errors with their position."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location("backend_tests", Path(__file__).with_name("test_backend.py"))
_backend_tests = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_backend_tests)


def lakegate(*args: str, stdin: str | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "lakegate.gateway.cli", "query", *args],
        input=stdin,
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.fixture(scope="module")
def lake(tmp_path_factory) -> Path:
    return _backend_tests.build_lake(tmp_path_factory.mktemp("query-command"))


def test_table_format():
    done = lakegate("SELECT 5 / 2 AS quotient, 'x' AS s, NULL AS nothing, ARRAY[1, 2] AS arr")
    assert done.returncode == 0, done.stderr
    assert done.stdout == (
        " quotient | s | nothing |  arr\n----------+---+---------+--------\n        2 | x | NULL    | [1, 2]\n(1 row)\n"
    )


def test_json_format_encodes_values_as_the_trino_protocol():
    done = lakegate(
        "--format",
        "json",
        "SELECT 7 / 2 AS a, nan() AS b, DECIMAL '1.50' AS c, "
        "TIMESTAMP '2024-01-02 03:04:05.1' AS t, ARRAY['x'] AS arr, TIME '01:02:03.456 -00:35' AS z UNION ALL "
        "SELECT NULL, 2.5E0, NULL, NULL, ARRAY[], NULL",
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == {
        "columns": [
            {"name": "a", "type": "integer"},
            {"name": "b", "type": "double"},
            {"name": "c", "type": "decimal(3,2)"},
            {"name": "t", "type": "timestamp(1)"},
            {"name": "arr", "type": "array(varchar(1))"},
            {"name": "z", "type": "time(3) with time zone"},
        ],
        "rows": [
            [3, "NaN", "1.50", "2024-01-02 03:04:05.1", ["x"], "01:02:03.456-00:35"],
            [None, 2.5, None, None, [], None],
        ],
    }


def test_csv_format_is_rfc_4180():
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "lakegate.gateway.cli",
            "query",
            "--format",
            "csv",
            "SELECT 'a,b' AS \"x y\", NULL AS n UNION ALL SELECT 'say \"hi\"', 'z'",
        ],
        capture_output=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == b'x y,n\r\n"a,b",\r\n"say ""hi""",z\r\n'


def test_an_error_is_one_line_with_its_position():
    done = lakegate("SELECT 1,\n  shuffle(ARRAY['a'])")
    assert done.returncode == 1
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("lakegate: line 2, column 3: ")
    refused = lakegate("COPY x TO '/tmp/x.csv'")
    assert refused.returncode == 1 and refused.stderr.startswith("lakegate: line 1, column 1: Access Denied: COPY")


@pytest.mark.parametrize("output", ["json", "csv", "table"])
def test_a_run_time_error_prints_no_partial_result(output):
    done = lakegate("--format", output, "SELECT ARRAY[1, 2][5]")
    assert done.returncode == 1
    assert done.stdout == ""
    assert done.stderr == "lakegate: Array subscript must be less than or equal to array length: 5 > 2\n"


def test_explain_prints_the_duckdb_sql():
    done = lakegate("--explain", "SELECT 5 / 2")
    assert done.returncode == 0, done.stderr
    assert "//" in done.stdout and done.stdout.lstrip().upper().startswith("SELECT")


def test_scoped_queries_on_a_lake(lake):
    sql = "SELECT job_id, count(*) AS n FROM odom GROUP BY 1 ORDER BY 1"
    done = lakegate("--lake", str(lake), "--format", "csv", "--batch", "b1", sql)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["job_id,n", "j1,3", "j2,2"]
    done = lakegate("--lake", str(lake), "--format", "csv", "--job", "j3", "-", stdin=sql)
    assert done.stdout.splitlines() == ["job_id,n", "j3,4"]


def test_show_tables_and_describe(lake):
    done = lakegate("--lake", str(lake), "--format", "csv", "SHOW TABLES")
    assert done.stdout.splitlines() == [
        "Table",
        *("container_performance", "events", "metadata", "never_emitted", "odom", "test_length_seconds"),
        "time_to_goal",
    ]
    done = lakegate("--lake", str(lake), "--format", "json", "DESCRIBE time_to_goal")
    described = json.loads(done.stdout)
    assert [c["name"] for c in described["columns"]] == ["Column", "Type", "Extra", "Comment"]
    assert described["rows"][:3] == [
        ["timestamp", "bigint", "", ""],
        ["goal_name", "varchar", "", ""],
        ["time_s", "double", "", ""],
    ]


def test_a_missing_lake_or_branch_is_a_user_error(tmp_path, lake):
    done = lakegate("--lake", str(tmp_path / "nowhere"), "SELECT 1")
    assert done.returncode == 1 and done.stderr.startswith("lakegate: no lake at ")
    done = lakegate("--lake", str(lake), "--branch", "feature/x", "SELECT 1")
    assert done.returncode == 1 and "Schema 'feature/x' does not exist" in done.stderr


# --- binary formats for dataframes --------------------------------------------------------------

BULK_SQL = (
    "SELECT a.x * 1000 + b.y AS n, CAST(a.x AS double) / 7 AS d, REAL '1.1' AS r, "
    "'r' || CAST(b.y AS varchar) AS label, "
    "date_add('day', a.x, DATE '2020-01-01') AS day, CAST(b.y AS decimal(10, 2)) / 4 AS price, "
    "TIMESTAMP '2020-01-01 00:00:00.123456' AS ts, ARRAY[a.x, NULL] AS arr, IF(b.y = 2, NULL, b.y > 1) AS flag "
    "FROM UNNEST(sequence(1, 30)) AS a(x) CROSS JOIN UNNEST(sequence(1, 70)) AS b(y)"
)


def _binary(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "lakegate.gateway.cli", "query", *args], capture_output=True, timeout=120
    )


def _json_rows(sql: str, *args: str) -> dict:
    done = lakegate("--format", "json", *args, sql)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def _as_protocol_values(table, columns: list[dict]) -> list[list]:
    """The Arrow table's values in the JSON output's encoding, through the same encoder."""
    from lakegate.gateway.engine.trino_values import encode_rows

    pairs = [(c["name"], c["type"]) for c in columns]
    return [list(row) for batch in table.to_batches() for row in encode_rows(pairs, batch)]


def test_arrow_format_holds_the_values_and_types_of_the_json_format():
    import pyarrow as pa

    done = _binary("--format", "arrow", BULK_SQL)
    assert done.returncode == 0, done.stderr
    table = pa.ipc.open_stream(done.stdout).read_all()
    expected = _json_rows(BULK_SQL)
    assert table.num_rows == 2100
    assert [(f.name, f.metadata[b"trino_type"].decode()) for f in table.schema] == [
        (c["name"], c["type"]) for c in expected["columns"]
    ]
    assert [str(f.type) for f in table.schema] == [
        *("int64", "double", "float", "string", "date32[day]", "decimal128(10, 2)"),
        *("timestamp[us]", "list<item: int64>", "bool"),
    ]
    assert _as_protocol_values(table, expected["columns"]) == expected["rows"]
    frame = table.to_pandas()
    assert frame["n"].sum() == sum(x * 1000 + y for x in range(1, 31) for y in range(1, 71))


def test_parquet_format_to_a_file_on_a_lake(lake, tmp_path):
    import pyarrow.parquet as pq

    sql = "SELECT job_id, timestamp FROM odom ORDER BY job_id, timestamp"
    out = tmp_path / "odom.parquet"
    done = _binary("--lake", str(lake), "--format", "parquet", "--output", str(out), sql)
    assert done.returncode == 0, done.stderr
    table = pq.read_table(out)
    expected = _json_rows(sql, "--lake", str(lake))
    assert _as_protocol_values(table, expected["columns"]) == expected["rows"]
    assert not list(tmp_path.glob("*.partial"))


def test_binary_formats_refuse_types_arrow_cannot_carry(tmp_path):
    out = tmp_path / "zoned.arrow"
    done = lakegate("--format", "arrow", "--output", str(out), "SELECT current_timestamp AS now, 1 AS one")
    assert done.returncode == 1
    assert done.stderr == (
        "lakegate: column 'now' of type timestamp(3) with time zone cannot be written as Arrow or Parquet "
        "(Arrow keeps no time zone per value): use --format json or csv, or CAST it (for example to varchar)\n"
    )
    assert not out.exists() and not list(tmp_path.iterdir())
    done = lakegate("--format", "parquet", "--output", str(out), "SELECT CAST(NULL AS timestamp(9)) AS t")
    assert done.returncode == 1 and "Arrow keeps at most microseconds" in done.stderr


def test_a_run_time_error_leaves_no_binary_file(tmp_path):
    out = tmp_path / "r.parquet"
    done = lakegate("--format", "parquet", "--output", str(out), "SELECT ARRAY[1, 2][5]")
    assert done.returncode == 1 and "subscript" in done.stderr
    assert not list(tmp_path.iterdir())
