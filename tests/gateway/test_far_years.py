"""Dates and timestamps of years outside 0..9999 through the real server's Trino protocol, as the real
Trino 476 writes them: java.time's text, a year past 9999 signed (`+10000-06-01`), one before year 0 of
four digits after its sign (`-0500-06-01`)."""

from __future__ import annotations

import requests

SQL = (
    "SELECT date_add('year', 1, TIMESTAMP '9999-06-01 00:00:00'), "
    "TIMESTAMP '9999-12-31 23:00:00.123456' + INTERVAL '2' HOUR, "
    "date_add('year', 1, DATE '9999-06-01'), "
    "date_add('year', 1, TIMESTAMP '9999-06-01 00:00:00.1234 UTC'), "
    "date_add('day', 100000, TIMESTAMP '9999-06-01 00:00:00.12'), "
    "date_add('year', -2000, TIMESTAMP '1500-06-01 00:00:00.5'), "
    "date_add('year', -2000, DATE '1500-06-01'), "
    "date_add('year', -2000, TIMESTAMP '1500-06-01 00:00:00 UTC'), "
    "date_add('year', -1506, TIMESTAMP '1500-06-01 00:00:00.12345')"
)


def protocol_answer(url: str, sql: str, catalog: str) -> tuple[list[str], list[list]]:
    """Column types and rows of `sql` through the Trino protocol at `url` (following nextUri)."""
    headers = {"X-Trino-User": "tester", "X-Trino-Catalog": catalog, "X-Trino-Schema": "default"}
    headers["X-Trino-Client-Capabilities"] = "PARAMETRIC_DATETIME"  # types with their precision, as clients ask
    document = requests.post(f"{url}/v1/statement", data=sql.encode(), headers=headers, timeout=60).json()
    columns, rows = document.get("columns"), list(document.get("data", []))
    while "nextUri" in document:
        document = requests.get(document["nextUri"], headers=headers, timeout=60).json()
        columns = columns or document.get("columns")
        rows += document.get("data", [])
    assert "error" not in document, document["error"]
    return [column["type"] for column in columns], rows


def test_years_outside_four_digits_as_the_real_trino_writes_them(lake_server, trino_url):
    types, rows = protocol_answer(lake_server.url, SQL, "lake")
    assert rows[0][0] == "+10000-06-01 00:00:00" and rows[0][6] == "-0500-06-01"
    assert (types, rows) == protocol_answer(trino_url, SQL, "memory")
