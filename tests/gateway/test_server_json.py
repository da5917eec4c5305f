"""json results through a real `lakegate serve` on 127.0.0.1 and the official `trino` client: a
column of type json is sent as its JSON text, with Trino's type signature (functions/json.md; the
client maps type `json` to a string)."""

from __future__ import annotations

import json

import trino


def test_json_values_arrive_as_their_text(lake_server):
    sql = (
        'SELECT JSON \'{"b": 1, "a": [1, 2.50]}\', CAST(ARRAY[1, NULL] AS JSON), '
        "json_extract('{\"x\": {\"y\": \"é\"}}', '$.x'), CAST(ARRAY['k'] AS ARRAY(JSON)), CAST(NULL AS JSON)"
    )
    with trino.dbapi.connect(host=lake_server.host, port=lake_server.port, user="tester", catalog="lake") as c:
        cursor = c.cursor()
        cursor.execute(sql)
        rows = cursor.fetchall()
        types = [d[1] for d in cursor.description]
    assert rows == [['{"a":[1,2.5],"b":1}', "[1,null]", '{"y":"é"}', ['"k"'], None]]
    assert types == ["json", "json", "json", "array(json)", "json"]
    assert json.loads(rows[0][0]) == {"a": [1, 2.5], "b": 1}
