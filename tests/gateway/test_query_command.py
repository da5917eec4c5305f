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
        "TIMESTAMP '2024-01-02 03:04:05.1' AS t, ARRAY['x'] AS arr UNION ALL "
        "SELECT NULL, 2.5E0, NULL, NULL, ARRAY[]",
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == {
        "columns": [
            {"name": "a", "type": "integer"},
            {"name": "b", "type": "double"},
            {"name": "c", "type": "decimal(3,2)"},
            {"name": "t", "type": "timestamp(1)"},
            {"name": "arr", "type": "array(varchar(1))"},
        ],
        "rows": [[3, "NaN", "1.50", "2024-01-02 03:04:05.1", ["x"]], [None, 2.5, None, None, []]],
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
    assert done.stdout.splitlines() == ["Table", "events", "metadata", "never_emitted", "odom", "time_to_goal"]
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
