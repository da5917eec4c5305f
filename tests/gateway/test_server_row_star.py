"""row_expression.* through the real server and the official trino client: the protocol carries one
column per field, named as Trino names them (the field's name, the AS alias, or _colN)."""

from __future__ import annotations

import pytest
import trino


def _query(server, sql: str) -> tuple[list, list[tuple[str, str]]]:
    with trino.dbapi.connect(host="127.0.0.1", port=server.port, user="me", catalog="lake", schema="main") as conn:
        cursor = conn.cursor()
        cursor.execute(sql)
        rows = cursor.fetchall()
        return rows, [(column[0], column[1]) for column in cursor.description]


def test_row_star_columns_reach_the_trino_client(lake_server):
    rows, columns = _query(
        lake_server,
        "SELECT (ROW(1, true)).*, CAST(ROW(2, 'a') AS ROW(x bigint, y varchar)).*, (3, 4).* AS (p, q)",
    )
    assert rows == [[1, True, 2, "a", 3, 4]]
    assert columns == [
        ("_col0", "integer"),
        ("_col1", "boolean"),
        ("x", "bigint"),
        ("y", "varchar"),
        ("p", "integer"),
        ("q", "integer"),
    ]


def test_alias_count_mismatch_is_trinos_error(lake_server):
    with pytest.raises(trino.exceptions.TrinoUserError) as error:
        _query(lake_server, "SELECT (1, 2).* AS (a)")
    assert error.value.error_name == "MISMATCHED_COLUMN_ALIASES"
    assert "Column alias list has 1 entries but relation has 2 columns" in error.value.message
