"""`POST /v1/arrow` of a real `lakegate serve`: a result as an Arrow IPC stream, with the values the
Trino protocol's JSON pages carry, errors as Trino error documents, and the row limit kept."""

from __future__ import annotations

import pyarrow as pa
import pytest
import requests
import urllib3

from lakegate.gateway.engine.trino_values import encode_rows

HEADERS = {"X-Trino-User": "tester", "X-Trino-Catalog": "lake", "X-Trino-Schema": "main"}
SQL = (
    "SELECT a.x, b.y, 'row ' || CAST(a.x * 1000 + b.y AS varchar) AS label, CAST(a.x AS double) / 3 AS third, "
    "CAST(b.y AS decimal(12, 3)) / 8 AS price, date_add('day', b.y, DATE '2024-02-28') AS day "
    "FROM UNNEST(sequence(1, 1000)) AS a(x) CROSS JOIN UNNEST(sequence(1, 200)) AS b(y)"
)


def arrow(server, sql: str) -> requests.Response:
    return requests.post(f"{server.url}/v1/arrow", data=sql.encode(), headers=HEADERS, timeout=60, stream=True)


def protocol_rows(server, sql: str) -> tuple[list[dict], list[list]]:
    """Columns and rows through the Trino protocol (following nextUri)."""
    document = requests.post(f"{server.url}/v1/statement", data=sql.encode(), headers=HEADERS, timeout=60).json()
    columns, rows = document.get("columns"), list(document.get("data", []))
    while "nextUri" in document:
        document = requests.get(document["nextUri"], timeout=60).json()
        columns = columns or document.get("columns")
        rows += document.get("data", [])
    assert "error" not in document, document["error"]
    return columns, rows


def test_arrow_stream_holds_what_the_protocol_answers(lake_server):
    response = arrow(lake_server, SQL)
    assert response.status_code == 200 and response.headers["content-type"] == "application/vnd.apache.arrow.stream"
    table = pa.ipc.open_stream(response.raw).read_all()
    columns, rows = protocol_rows(lake_server, SQL)
    assert [(f.name, f.metadata[b"trino_type"].decode()) for f in table.schema] == [
        (c["name"], c["type"]) for c in columns
    ]
    pairs = [(c["name"], c["type"]) for c in columns]
    mine = [list(row) for batch in table.to_batches() for row in encode_rows(pairs, batch)]
    assert len(mine) == 200_000 and sorted(mine) == sorted(rows)


def test_a_lake_table_to_pandas(lake_server, server_lake):
    sql = "SELECT job_id, count(*) AS n, avg(x) AS mean_x FROM odom_linear_velocity GROUP BY 1"
    result = pa.ipc.open_stream(arrow(lake_server, sql).raw).read_pandas().sort_values("job_id")
    _, rows = protocol_rows(lake_server, sql)
    assert len(rows) == 3
    assert [list(r) for r in result.itertuples(index=False)] == sorted(rows)


@pytest.mark.parametrize(
    ("sql", "name"),
    [
        ("SELECT nope FROM odom_linear_velocity", "COLUMN_NOT_FOUND"),
        ("USE lake.main", "NOT_SUPPORTED"),
        ("SELECT current_timestamp AS now", "NOT_SUPPORTED"),
        ("SELECT ARRAY[1][3]", "INVALID_FUNCTION_ARGUMENT"),
    ],
)
def test_errors_are_trino_error_documents(lake_server, sql, name):
    response = arrow(lake_server, sql)
    assert response.status_code == 400
    assert response.json()["error"]["errorName"] == name


def test_the_row_limit_is_kept(start_server):
    server = start_server("--max-rows", "1000")
    response = arrow(server, SQL)  # the first batch already passes the limit: refused before any row
    assert response.status_code == 400
    assert response.json()["error"]["errorName"] == "GENERIC_INSUFFICIENT_RESOURCES"
    server = start_server("--max-rows", "150000")
    response = arrow(server, SQL)  # the first batch fits, a later one passes the limit: the stream breaks off
    assert response.status_code == 200
    with pytest.raises((urllib3.exceptions.ProtocolError, requests.exceptions.ChunkedEncodingError)):
        pa.ipc.open_stream(response.raw).read_all()
