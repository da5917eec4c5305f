"""The Trino client protocol of `lakegate serve`, spoken over raw HTTP (requests) to a real server:
documents, paging, retries, cancelation, errors, session headers, names and system tables."""

from __future__ import annotations

import json
import re
import time
from types import SimpleNamespace
from urllib.parse import quote, unquote_plus

import pytest
import requests

from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.server.app import create_app
from lakegate.gateway.server.protocol import Progress, stats_document

from .conftest import served_in_thread

ALL_TYPES_BRANCH = "feature/all-types"  # the second branch of the test lake (conftest.py)
HEADERS = {"X-Trino-User": "tester", "X-Trino-Catalog": "lake", "X-Trino-Schema": "main"}
QUERY_ID = re.compile(r"\d{8}_\d{6}_\d{5}_[a-z0-9]{12}")  # Trino's shape, with an unguessable random tail


def post(server, sql: str | bytes, headers: dict | None = None) -> requests.Response:
    data = sql if isinstance(sql, bytes) else sql.encode()
    response = requests.post(
        f"{server.url}/v1/statement", data=data, headers={**HEADERS, **(headers or {})}, timeout=30
    )
    assert response.status_code == 200, response.text
    return response


def run(server, sql: str | bytes, headers: dict | None = None) -> tuple[list[dict], list[list]]:
    """Every document of one query (following nextUri) and all its rows."""
    documents = [post(server, sql, headers).json()]
    while "nextUri" in documents[-1]:
        response = requests.get(documents[-1]["nextUri"], timeout=30)
        assert response.status_code == 200, response.text
        documents.append(response.json())
    rows = [row for document in documents for row in document.get("data", [])]
    return documents, rows


def result(server, sql: str, headers: dict | None = None) -> list[list]:
    documents, rows = run(server, sql, headers)
    assert "error" not in documents[-1], documents[-1]["error"]
    return rows


def error(server, sql: str, headers: dict | None = None) -> dict:
    documents, _ = run(server, sql, headers)
    assert documents[-1]["stats"]["state"] == "FAILED"
    return documents[-1]["error"]


# --- documents ------------------------------------------------------------------------------------


def test_post_answers_at_once_and_the_query_runs_in_the_background(lake_server, endless):
    first = post(lake_server, endless).json()  # would take hours: the reply cannot wait for it
    assert QUERY_ID.fullmatch(first["id"])
    assert post(lake_server, "SELECT 1").json()["id"][-12:] != first["id"][-12:]  # not one per server
    assert first["stats"]["state"] in ("QUEUED", "RUNNING") and "data" not in first
    assert first["nextUri"].startswith(f"{lake_server.url}/v1/statement/executing/{first['id']}/")
    assert first["infoUri"] == f"{lake_server.url}/v1/query/{first['id']}"
    second = requests.get(first["nextUri"], timeout=30).json()
    assert second["stats"]["state"] in ("QUEUED", "RUNNING") and "data" not in second
    assert second["nextUri"] != first["nextUri"]
    info = requests.get(first["infoUri"], timeout=30).json()
    assert info["queryId"] == first["id"] and info["state"] in ("QUEUED", "RUNNING") and info["query"] == endless
    assert requests.delete(second["nextUri"], timeout=30).status_code == 204
    last = requests.get(second["nextUri"], timeout=30).json()
    assert "nextUri" not in last
    assert last["stats"]["state"] == "FAILED"
    assert (last["error"]["errorName"], last["error"]["errorType"], last["error"]["errorCode"]) == (
        "USER_CANCELED",
        "USER_ERROR",
        3,
    )


def answered_by_the_post(run_query, sql: str, attempts: int = 10) -> list[dict]:
    """The documents of a run of SQL whose POST reply held the whole answer, trying a few times.

    The POST waits `answer_wait` (20 ms) for the query: on a loaded machine one run may miss it and be
    answered by a GET, but a server that never answers in the POST fails every attempt."""
    for _ in range(attempts):
        documents = run_query(sql)
        if len(documents) == 1:
            return documents
    pytest.fail(f"in {attempts} runs of {sql!r} the POST's reply never held the answer ({len(documents)} replies)")


def test_a_small_result_is_answered_whole_in_the_posts_reply(lake_server):
    [page] = answered_by_the_post(lambda sql: run(lake_server, sql)[0], "SELECT 1, 'a' AS b")
    rows = page["data"]
    assert "nextUri" not in page and page["stats"]["state"] == "FINISHED"
    assert rows == [[1, "a"]]
    assert page["columns"] == [
        {"name": "_col0", "type": "integer", "typeSignature": {"rawType": "integer", "arguments": []}},
        {
            "name": "b",
            "type": "varchar(1)",
            "typeSignature": {"rawType": "varchar", "arguments": [{"kind": "LONG", "value": 1}]},
        },
    ]


class CountingClient:
    """A raw HTTP client that follows nextUri and counts the requests it sends."""

    def __init__(self, server):
        self.server, self.requests = server, 0
        self.session = requests.Session()
        self.session.hooks["response"].append(self._count)

    def _count(self, response: requests.Response, *args, **kwargs) -> None:
        self.requests += 1

    def run(self, sql: str) -> list[dict]:
        documents = [
            self.session.post(f"{self.server.url}/v1/statement", data=sql.encode(), headers=HEADERS, timeout=30).json()
        ]
        while "nextUri" in documents[-1]:
            documents.append(self.session.get(documents[-1]["nextUri"], timeout=30).json())
        return documents


def test_fast_queries_take_one_request(lake_server):
    client = CountingClient(lake_server)
    for _ in range(3):  # the first run of a text also translates it
        [document] = answered_by_the_post(client.run, "SELECT count(*) AS n, min(batch_id) FROM metadata")
        assert document["data"] == [[3, "b1"]] and document["stats"]["state"] == "FINISHED"
        assert [c["name"] for c in document["columns"]] == ["n", "_col1"]
        assert document["stats"]["processedRows"] == 1
    [empty] = answered_by_the_post(client.run, "SELECT job_id FROM metadata WHERE false")  # columns, no data
    assert "data" not in empty and [c["name"] for c in empty["columns"]] == ["job_id"]
    [failed] = answered_by_the_post(client.run, "SELECT nope FROM metadata")
    assert failed["stats"]["state"] == "FAILED" and failed["error"]["errorName"] == "COLUMN_NOT_FOUND"
    # the query is over: DELETE of its id is a no-op, and it still tells what it was
    assert requests.delete(f"{lake_server.url}/v1/query/{document['id']}", timeout=30).status_code == 204
    assert requests.get(document["infoUri"], timeout=30).json()["state"] == "FINISHED"


def test_slow_queries_and_results_of_several_pages_get_a_next_uri(lake_server, endless):
    client = CountingClient(lake_server)
    started = time.monotonic()
    first = post(lake_server, endless).json()
    assert time.monotonic() - started < 10  # the POST waits a little, not for the query
    assert "nextUri" in first and "data" not in first and first["stats"]["state"] in ("QUEUED", "RUNNING")
    assert requests.delete(first["nextUri"], timeout=30).status_code == 204
    documents = client.run("SELECT x FROM UNNEST(sequence(1, 5000)) AS t(x)")  # more than one reply holds
    assert "data" not in documents[0] and len(documents) > 2 and client.requests == len(documents)
    assert sorted(row[0] for document in documents for row in document.get("data", [])) == list(range(1, 5001))


#: The stats counters of a query of one split that clients show (Superset: completedSplits / totalSplits).
COUNTERS = ("queued", "scheduled", "nodes", "totalSplits", "queuedSplits", "runningSplits", "completedSplits")


def test_stats_are_filled_as_the_real_trino_fills_them(lake_server, trino_url):
    server = SimpleNamespace(url=trino_url)
    theirs, _ = run(server, "SELECT 1")
    ours, _ = run(lake_server, "SELECT 1")
    assert set(ours[-1]["stats"]) == set(theirs[-1]["stats"])  # the finished query's: every field Trino sends
    assert [ours[-1]["stats"][name] for name in COUNTERS] == [theirs[-1]["stats"][name] for name in COUNTERS]
    assert ours[-1]["stats"]["progressPercentage"] == theirs[-1]["stats"]["progressPercentage"] == 100.0
    queued = theirs[0]["stats"]  # Trino's first answer: queued, no node, no split, no progress yet
    assert queued["state"] == "QUEUED"
    assert [queued[name] for name in COUNTERS] == [stats_document(Progress("QUEUED"))[name] for name in COUNTERS]
    assert "progressPercentage" not in stats_document(Progress("QUEUED"))


def test_values_and_type_signatures_are_encoded_as_trino_does(lake_server):
    documents, rows = run(
        lake_server,
        "SELECT CAST(1.5 AS decimal(10,2)) AS d, TIMESTAMP '2024-01-02 03:04:05.123' "
        "AS ts, nan() AS n, -infinity() AS i, ARRAY['x', NULL] AS a, "
        "MAP(ARRAY['k'], ARRAY[1.25E0]) AS m, CAST(ROW(1, 'r') AS ROW(p bigint, q "
        "varchar)) AS r, DATE '2024-02-29' AS day",
    )
    assert rows == [
        ["1.50", "2024-01-02 03:04:05.123", "NaN", "-Infinity", ["x", None], {"k": 1.25}, [1, "r"], "2024-02-29"]
    ]
    columns = {c["name"]: c for c in documents[-1]["columns"]}
    assert columns["d"]["typeSignature"] == {
        "rawType": "decimal",
        "arguments": [{"kind": "LONG", "value": 10}, {"kind": "LONG", "value": 2}],
    }
    assert columns["ts"]["type"] == "timestamp(3)"
    assert columns["ts"]["typeSignature"] == {"rawType": "timestamp", "arguments": [{"kind": "LONG", "value": 3}]}
    assert columns["a"]["typeSignature"]["arguments"][0]["kind"] == "TYPE"
    assert columns["r"]["type"] == "row(p bigint, q varchar)"
    assert [a["value"]["fieldName"]["name"] for a in columns["r"]["typeSignature"]["arguments"]] == ["p", "q"]


def test_a_large_result_is_paged_and_every_row_arrives_once(lake_server):
    sql = (
        "SELECT a.x, b.y, 'row ' || CAST(a.x * 1000 + b.y AS varchar) AS label "
        "FROM UNNEST(sequence(1, 1000)) AS a(x) CROSS JOIN UNNEST(sequence(1, 200)) AS b(y)"
    )
    documents, rows = run(lake_server, sql)
    pages = [d for d in documents if d.get("data")]
    assert len(pages) > 2
    sizes = [len(json.dumps(d["data"])) for d in pages]
    assert max(sizes) < 2_000_000, sizes  # about 1 MB a page, never the whole result
    assert all("columns" in d for d in pages)
    assert len(rows) == 200_000
    assert {(x, y) for x, y, _ in rows} == {(x, y) for x in range(1, 1001) for y in range(1, 201)}
    assert all(label == f"row {x * 1000 + y}" for x, y, label in rows)
    assert documents[-1]["stats"]["state"] == "FINISHED" and documents[-1]["stats"]["processedRows"] == 200_000


def test_a_retried_get_returns_the_same_page_and_other_tokens_are_refused(lake_server):
    first = post(
        lake_server,
        "SELECT x * 1000 + y FROM UNNEST(sequence(0, 99)) AS a(x) CROSS JOIN "
        "UNNEST(sequence(1, 1000)) AS b(y) ORDER BY 1",
    ).json()
    page = requests.get(first["nextUri"], timeout=30)
    again = requests.get(first["nextUri"], timeout=30)
    assert page.status_code == again.status_code == 200 and page.content == again.content
    assert requests.head(page.json()["nextUri"], timeout=30).status_code == 200  # HEAD: no effect
    skipped = re.sub(r"/(\d+)$", lambda m: f"/{int(m.group(1)) + 1}", page.json()["nextUri"])
    assert requests.get(skipped, timeout=30).status_code == 404
    wrong_slug = re.sub(r"/[0-9a-f]{16}/", "/0000000000000000/", first["nextUri"])
    assert requests.get(wrong_slug, timeout=30).status_code == 404
    rows = page.json().get("data", [])
    document = page.json()
    while "nextUri" in document:
        document = requests.get(document["nextUri"], timeout=30).json()
        rows += document.get("data", [])
    assert [r[0] for r in rows] == list(range(1, 100_001))


def test_delete_and_head_of_unknown_or_finished_queries(lake_server):
    documents, _ = run(lake_server, "SELECT x FROM UNNEST(sequence(1, 5000)) AS t(x)")  # several pages
    query_id = documents[0]["id"]
    assert requests.delete(documents[0]["nextUri"], timeout=30).status_code == 204  # finished
    assert requests.delete(f"{lake_server.url}/v1/query/{query_id}", timeout=30).status_code == 204
    assert requests.delete(f"{lake_server.url}/v1/query/20260101_000000_00001_nopee", timeout=30).status_code == 204
    unknown = f"{lake_server.url}/v1/statement/executing/20260101_000000_00001_nopee/0123456789abcdef/1"
    assert requests.delete(unknown, timeout=30).status_code == 204
    assert requests.head(unknown, timeout=30).status_code == 404
    assert requests.get(unknown, timeout=30).status_code == 404


def test_delete_of_the_query_cancels_it(lake_server, endless):
    first = post(lake_server, endless).json()
    assert requests.delete(f"{lake_server.url}/v1/query/{first['id']}", timeout=30).status_code == 204
    document = requests.get(first["nextUri"], timeout=30).json()
    assert document["error"]["errorName"] == "USER_CANCELED" and "nextUri" not in document


def test_info(lake_server):
    info = requests.get(f"{lake_server.url}/v1/info", timeout=30).json()
    assert info["starting"] is False and info["coordinator"] is True
    assert info["nodeVersion"]["version"] == result(lake_server, "SELECT version()")[0][0]
    assert re.fullmatch(r"\d+\.\d\d[smhd]", info["uptime"])
    assert requests.get(f"{lake_server.url}/v1/info/state", timeout=30).json() == "ACTIVE"


def test_bad_requests(lake_server):
    assert requests.post(f"{lake_server.url}/v1/statement", data=b"SELECT 1", timeout=30).status_code == 400  # no user
    assert requests.post(f"{lake_server.url}/v1/statement", data=b"  ", headers=HEADERS, timeout=30).status_code == 400
    bad = requests.post(
        f"{lake_server.url}/v1/statement",
        data=b"SELECT 1",
        timeout=30,
        headers={**HEADERS, "X-Trino-Session": "no-equals-sign"},
    )
    assert bad.status_code == 400 and "X-Trino-Session" in bad.text
    failure = post(lake_server, b"SELECT '\xff'").json()["error"]
    assert failure["errorName"] == "SYNTAX_ERROR"


# --- errors ---------------------------------------------------------------------------------------


def test_a_syntax_error_has_trinos_error_fields_and_position(lake_server):
    documents, _ = run(lake_server, "SELECT 1\nFROM metadata WHERE (")
    assert len(documents) == 1 and "nextUri" not in documents[-1]  # failed at once: in the POST's reply
    failure = documents[-1]["error"]
    assert (failure["errorName"], failure["errorCode"], failure["errorType"]) == ("SYNTAX_ERROR", 1, "USER_ERROR")
    assert failure["errorLocation"]["lineNumber"] == 2
    assert failure["message"].startswith(f"line 2:{failure['errorLocation']['columnNumber']}: ")
    assert failure["failureInfo"]["type"] == "io.trino.sql.parser.ParsingException"
    assert failure["failureInfo"]["errorLocation"] == failure["errorLocation"]


def test_error_positions_are_in_the_users_sql_even_with_qualified_names(lake_server):
    sql = 'SELECT job_id\nFROM lake."main".metadata m JOIN main.odom_linear_velocity o USING (job_id)\nWHERE nope = 1'
    failure = error(lake_server, sql)
    assert failure["errorName"] == "COLUMN_NOT_FOUND"
    assert failure["errorLocation"] == {"lineNumber": 3, "columnNumber": 7}
    failure = error(lake_server, "SELECT 1 FROM lake.main.metadata, lake.main.nope")
    assert (failure["errorName"], failure["errorLocation"]) == (
        "TABLE_NOT_FOUND",
        {"lineNumber": 1, "columnNumber": 35},
    )
    assert "'lake.main.nope' does not exist" in failure["message"]


def test_unknown_catalogs_and_schemas(lake_server):
    assert error(lake_server, "SELECT * FROM hive.main.metadata")["errorName"] == "CATALOG_NOT_FOUND"
    assert error(lake_server, "SELECT * FROM nope.metadata")["errorName"] == "SCHEMA_NOT_FOUND"
    missing = error(lake_server, "SELECT * FROM metadata", {"X-Trino-Schema": ""})
    assert (missing["errorName"], missing["errorLocation"]) == (
        "MISSING_SCHEMA_NAME",
        {"lineNumber": 1, "columnNumber": 15},
    )
    assert error(lake_server, "SHOW TABLES", {"X-Trino-Catalog": ""})["errorName"] == "MISSING_CATALOG_NAME"


def test_the_endpoint_is_read_only(lake_server, server_lake):
    before = sorted(p.relative_to(server_lake) for p in server_lake.rglob("*") if "_staging" not in p.parts)
    for sql in (
        "INSERT INTO metadata (job_id) VALUES ('x')",
        "DROP TABLE metadata",
        "CREATE TABLE t AS SELECT 1",
        "DELETE FROM metadata",
        "SELECT * FROM read_parquet('/etc/passwd')",
        "COPY metadata TO '/tmp/x'",
    ):
        failure = error(lake_server, sql)
        assert failure["errorType"] == "USER_ERROR", (sql, failure)
        assert failure["errorName"] in (
            "PERMISSION_DENIED",
            "NOT_SUPPORTED",
            "SYNTAX_ERROR",
            "FUNCTION_NOT_FOUND",
            "TABLE_NOT_FOUND",
        ), (sql, failure)
    after = sorted(p.relative_to(server_lake) for p in server_lake.rglob("*") if "_staging" not in p.parts)
    assert before == after


# --- session --------------------------------------------------------------------------------------


def _session_headers(response: requests.Response) -> dict[str, str]:
    return {k.lower(): v for k, v in response.headers.items() if k.lower().startswith("x-trino-")}


def test_use_sets_catalog_and_schema(lake_server):
    response = post(lake_server, f'USE lake."{ALL_TYPES_BRANCH}"')
    document = response.json()
    assert "nextUri" not in document and document["updateType"] == "USE" and document["data"] == [[True]]
    assert _session_headers(response) == {"x-trino-set-catalog": "lake", "x-trino-set-schema": ALL_TYPES_BRANCH}
    assert error(lake_server, "USE lake.nope")["errorName"] == "SCHEMA_NOT_FOUND"
    assert error(lake_server, "USE hive.main")["errorName"] == "CATALOG_NOT_FOUND"
    rows = result(lake_server, "SELECT count(*) FROM sample", {"X-Trino-Schema": ALL_TYPES_BRANCH})
    assert rows == [[2]]


def test_session_time_zone_is_honoured(lake_server):
    """X-Trino-Time-Zone is the session zone (Trino: hour(from_unixtime(0)) is 19 in America/New_York);
    an unknown zone is Trino's NOT_SUPPORTED "Time zone not supported"."""
    sql = "SELECT hour(from_unixtime(0)), current_timezone()"
    assert result(lake_server, sql, {"X-Trino-Time-Zone": "UTC"}) == [[0, "UTC"]]
    assert result(lake_server, sql, {"X-Trino-Time-Zone": "America/New_York"}) == [[19, "America/New_York"]]
    refused = error(lake_server, sql, {"X-Trino-Time-Zone": "Mars/Olympus"})
    assert refused["errorName"] == "NOT_SUPPORTED" and "Time zone not supported: Mars/Olympus" in refused["message"]


def test_session_properties_narrow_every_table(lake_server):
    response = post(lake_server, "SET SESSION batch_id = 'b1'")
    assert response.json()["updateType"] == "SET SESSION"
    assert _session_headers(response) == {"x-trino-set-session": "batch_id=b1"}
    assert _session_headers(post(lake_server, "RESET SESSION batch_id")) == {"x-trino-clear-session": "batch_id"}
    everything = result(lake_server, "SELECT batch_id, count(*) FROM metadata GROUP BY 1 ORDER BY 1")
    assert everything == [["b1", 2], ["b2", 1]]
    narrowed = {"X-Trino-Session": "batch_id=b1"}
    sql = (
        "SELECT (SELECT count(*) FROM metadata), count(DISTINCT o.job_id), count(DISTINCT o.batch_id) "
        "FROM odom_linear_velocity o"
    )
    assert result(lake_server, sql, narrowed) == [[2, 2, 1]]
    job = result(lake_server, "SELECT job_id FROM metadata WHERE batch_id = 'b2'")[0][0]
    assert result(lake_server, sql, {"X-Trino-Session": f"job_id={quote(job)}"}) == [[1, 1, 1]]
    assert result(lake_server, sql, {"X-Trino-Session": f"batch_id=b1,job_id={quote(job)}"}) == [[0, 0, 0]]
    assert error(lake_server, "SET SESSION nope = 'x'")["errorName"] == "INVALID_SESSION_PROPERTY"
    assert (
        error(lake_server, "SELECT 1", {"X-Trino-Session": "query_max_run_time=1h"})["errorName"]
        == "INVALID_SESSION_PROPERTY"
    )
    shown = result(lake_server, "SHOW SESSION LIKE 'batch%'", narrowed)
    assert shown == [["batch_id", "b1", "", "varchar", shown[0][4]]]


def test_stateless_prepared_statements(lake_server):
    statement = "SELECT count(*) FROM metadata WHERE batch_id = ? AND experience_name <> ?"
    response = post(lake_server, f"PREPARE my_query FROM {statement}")
    name, _, text = response.headers["X-Trino-Added-Prepare"].partition("=")
    assert name == "my_query" and unquote_plus(text) == statement
    prepared = {"X-Trino-Prepared-Statement": f"my_query={text}"}
    assert result(lake_server, "EXECUTE my_query USING 'b1', 'x'", prepared) == [[2]]
    assert result(lake_server, "DESCRIBE INPUT my_query", prepared) == [[0, "unknown"], [1, "unknown"]]
    assert result(lake_server, "DESCRIBE OUTPUT my_query", prepared) == [["_col0", "", "", "", "bigint", 8, False]]
    response = post(lake_server, "DEALLOCATE PREPARE my_query", prepared)
    assert response.headers["X-Trino-Deallocated-Prepare"] == "my_query"
    assert error(lake_server, "EXECUTE my_query USING 'b1', 'x'")["errorName"] == "NOT_FOUND"
    failure = error(lake_server, "EXECUTE my_query USING 'b1'", prepared)
    assert failure["errorName"] == "INVALID_PARAMETER_USAGE"


def test_execute_immediate_with_parameters(lake_server):
    sql = (
        "EXECUTE IMMEDIATE 'SELECT table_name FROM information_schema.tables WHERE table_schema = ? "
        "AND table_name LIKE ''odom%''' USING 'main'"
    )
    assert result(lake_server, sql) == [["odom_linear_velocity"]]
    failure = error(lake_server, "EXECUTE IMMEDIATE 'SELECT\n  nope FROM metadata WHERE batch_id = ?' USING 'b1'")
    assert failure["errorLocation"] == {"lineNumber": 2, "columnNumber": 3}  # in the statement the user wrote


def test_transactions_are_accepted_and_do_nothing(lake_server):
    response = post(lake_server, "START TRANSACTION")
    transaction = response.headers["X-Trino-Started-Transaction-Id"]
    assert response.json()["updateType"] == "START TRANSACTION"
    inside = {"X-Trino-Transaction-Id": transaction}
    assert result(lake_server, "SELECT count(*) FROM metadata", inside) == [[3]]
    assert post(lake_server, "COMMIT", inside).headers["X-Trino-Clear-Transaction-Id"] == "true"
    assert post(lake_server, "ROLLBACK", inside).json()["updateType"] == "ROLLBACK"
    assert error(lake_server, "COMMIT", {"X-Trino-Transaction-Id": "NONE"})["errorName"] == "NOT_IN_TRANSACTION"


# --- names, introspection, system tables ------------------------------------------------------------


def test_a_branch_is_a_schema_named_like_it(lake_server):
    assert result(lake_server, "SHOW SCHEMAS") == [[ALL_TYPES_BRANCH], ["information_schema"], ["main"]]
    assert result(lake_server, "SHOW CATALOGS") == [["lake"], ["system"]]
    documents, _ = run(lake_server, "SHOW CATALOGS LIKE 'x%'")  # as Trino: varchar(longest name), rows or not
    assert [c["type"] for d in documents for c in d.get("columns", [])][:1] == ["varchar(6)"]
    assert result(lake_server, f'SELECT count(*) FROM "{ALL_TYPES_BRANCH}".sample') == [[2]]
    assert result(lake_server, f'SELECT count(*) FROM lake."{ALL_TYPES_BRANCH}".sample s') == [[2]]
    assert result(lake_server, 'SELECT count(*) FROM "MAIN".metadata') == [[3]]  # a unique match ignoring case
    failure = error(lake_server, f'SELECT 1 FROM metadata JOIN "{ALL_TYPES_BRANCH}".sample ON true')
    assert failure["errorName"] == "NOT_SUPPORTED" and "one schema" in failure["message"]


def test_schema_qualified_columns(lake_server):
    sql = f'SELECT "{ALL_TYPES_BRANCH}".sample.n FROM lake."{ALL_TYPES_BRANCH}".sample WHERE sample.flag'
    assert result(lake_server, sql) == [[2**62]]
    failure = error(lake_server, f'SELECT main.metadata.job_id FROM "{ALL_TYPES_BRANCH}".metadata')
    assert (failure["errorName"], failure["errorLocation"]) == (
        "COLUMN_NOT_FOUND",
        {"lineNumber": 1, "columnNumber": 8},
    )


def test_show_and_describe(lake_server):
    tables = [t for (t,) in result(lake_server, "SHOW TABLES")]
    assert tables == sorted(tables) and {"metadata", "events", "odom_linear_velocity", "goal_reached"} <= set(tables)
    assert result(lake_server, f"SHOW TABLES FROM lake.\"{ALL_TYPES_BRANCH}\" LIKE 's%'") == [["sample"]]
    documents, rows = run(lake_server, f'DESCRIBE lake."{ALL_TYPES_BRANCH}".sample')
    assert [c["name"] for c in documents[-1]["columns"]] == ["Column", "Type", "Extra", "Comment"]
    types = {name: trino_type for name, trino_type, _, _ in rows}
    assert types["flag"] == "boolean" and types["tags"] == "array(varchar)" and types["n"] == "bigint"
    assert types["metrics"].startswith("array(row(name varchar")
    assert result(lake_server, "SHOW COLUMNS FROM metadata LIKE 'build_%'") == [
        ["build_id", "varchar", "", ""],
        ["build_name", "varchar", "", ""],
        ["build_version", "varchar", "", ""],
        ["build_creation_timestamp", "timestamp(3)", "", ""],
    ]
    assert result(lake_server, "SHOW SCHEMAS FROM system") == [
        ["information_schema"],
        ["jdbc"],
        ["metadata"],
        ["runtime"],
    ]


def test_information_schema_as_sqlalchemy_asks(lake_server):
    schemas = result(lake_server, 'SELECT "schema_name" FROM "information_schema"."schemata"')
    assert sorted(schemas) == [[ALL_TYPES_BRANCH], ["information_schema"], ["main"]]
    columns = result(
        lake_server,
        f"""EXECUTE IMMEDIATE '
        SELECT "column_name", "data_type", "column_default", UPPER("is_nullable") AS "is_nullable", "comment"
        FROM "information_schema"."columns"
        WHERE "table_schema" = ? AND "table_name" = ?
        ORDER BY "ordinal_position" ASC' USING '{ALL_TYPES_BRANCH}', 'sample'""",
    )
    assert [c[:2] for c in columns[:4]] == [
        ["timestamp", "bigint"],
        ["flag", "boolean"],
        ["n", "bigint"],
        ["x", "double"],
    ]
    assert all(c[2] is None and c[3] == "YES" and c[4] is None for c in columns)
    tables = result(
        lake_server,
        "SELECT table_catalog, table_type, count(*) FROM information_schema.tables "
        "WHERE table_schema = 'main' GROUP BY 1, 2",
    )
    assert tables == [["lake", "BASE TABLE", len(result(lake_server, "SHOW TABLES"))]]
    assert result(lake_server, "SELECT count(*) FROM information_schema.views") == [[0]]
    assert result(
        lake_server, "SELECT tables.table_name FROM information_schema.tables WHERE tables.table_name = 'sample'"
    ) == [["sample"]]


def test_system_jdbc_and_metadata_tables(lake_server):
    assert result(lake_server, 'SELECT "table_cat" FROM "system"."jdbc"."catalogs" ORDER BY 1') == [
        ["lake"],
        ["system"],
    ]
    rows = result(
        lake_server,
        "SELECT column_name, data_type, type_name, column_size, decimal_digits, num_prec_radix "
        "FROM system.jdbc.columns WHERE table_cat = 'lake' AND table_schem = 'main' "
        "AND table_name = 'metadata' AND column_name IN ('org_id', 'build_creation_timestamp', "
        "'experience_tag_names') ORDER BY ordinal_position",
    )
    assert rows == [
        ["org_id", 12, "varchar", 2147483647, None, None],
        ["build_creation_timestamp", 93, "timestamp(3)", 25, 3, None],
        ["experience_tag_names", 2003, "array(varchar)", None, None, None],
    ]
    assert ["TABLE"] in result(lake_server, "SELECT table_type FROM system.jdbc.table_types")
    assert result(lake_server, "SELECT count(*) FROM system.jdbc.schemas WHERE table_catalog = 'lake'") == [[3]]
    comment = result(
        lake_server,
        'EXECUTE IMMEDIATE \'SELECT "comment" FROM "system"."metadata"."table_comments" '
        'WHERE "catalog_name" = ? AND "schema_name" = ? AND "table_name" = ?\' '
        "USING 'lake', 'main', 'metadata'",
    )
    assert comment == [[None]]
    failure = error(lake_server, "SELECT * FROM information_schema.tables, system.jdbc.tables")
    assert failure["errorName"] == "NOT_SUPPORTED"
    assert error(lake_server, "SELECT * FROM metadata, system.jdbc.tables")["errorName"] == "NOT_SUPPORTED"


def test_functions_the_endpoint_answers(lake_server):
    assert result(lake_server, "SELECT version(), current_timezone()") == [["476", "UTC"]]
    documents, _ = run(lake_server, "SELECT version() AS v")
    assert documents[-1]["columns"][0]["type"] == "varchar"


def test_kill_query(lake_server, endless):
    victim = post(lake_server, endless).json()
    listed = result(
        lake_server, f"SELECT state, \"user\", query FROM system.runtime.queries WHERE query_id = '{victim['id']}'"
    )
    assert listed[0][1:] == ["tester", endless] and listed[0][0] in ("QUEUED", "RUNNING")
    response = post(lake_server, f"CALL system.runtime.kill_query(query_id => '{victim['id']}', message => 'enough')")
    assert response.json()["updateType"] == "CALL" and "error" not in response.json()
    document = requests.get(victim["nextUri"], timeout=30).json()
    assert (document["error"]["errorName"], document["error"]["message"]) == (
        "ADMINISTRATIVELY_KILLED",
        "Query killed. Message: enough",
    )
    again = post(lake_server, f"CALL system.runtime.kill_query('{victim['id']}')").json()["error"]
    assert again["errorName"] == "NOT_SUPPORTED" and "not running" in again["message"]
    unknown = post(lake_server, "CALL system.runtime.kill_query('20260101_000000_00001_nopee')").json()["error"]
    assert unknown["errorName"] == "NOT_FOUND"
    assert post(lake_server, "CALL system.nope()").json()["error"]["errorName"] == "PROCEDURE_NOT_FOUND"


# --- query lifecycle, on an in-process server with tiny limits --------------------------------------


@pytest.fixture(scope="module")
def short_lived(server_lake):
    """An app with a 1 s client timeout and retention, served by uvicorn in a thread."""
    backend = DuckDBBackend(server_lake, memory_limit="512MB", threads=2)
    engine = Engine(backend, limits=Limits(client_timeout=1.0, retention=1.0, wait=0.2), owns_backend=True)
    app = create_app(engine)
    with served_in_thread(app, check_stopped=True) as url:
        yield SimpleNamespace(url=url), app
    engine.close()


def test_protocol_routes_keep_the_host_check_and_the_frameworks_answers(short_lived):
    """The protocol routes' short path (past FastAPI's layers) still refuses a foreign Host or Origin,
    and a method no route takes still gets FastAPI's 405."""
    server, _ = short_lived
    statement = f"{server.url}/v1/statement"
    foreign = requests.post(statement, data="SELECT 1", headers={"Host": "evil.example.org"}, timeout=30)
    assert foreign.status_code == 421 and "Host" in foreign.text
    origin = requests.post(statement, data="SELECT 1", headers={"Origin": "http://evil.example.org"}, timeout=30)
    assert origin.status_code == 403 and "Origin" in origin.text
    answered = requests.post(statement, data="SELECT 1", headers={"X-Trino-User": "tester"}, timeout=30).json()
    assert answered.get("data") == [[1]] or "nextUri" in answered
    wrong = requests.put(statement, data="SELECT 1", timeout=30)
    assert wrong.status_code == 405 and wrong.json() == {"detail": "Method Not Allowed"}


def test_abandoned_queries_are_canceled_and_finished_ones_forgotten(short_lived, endless):
    server, app = short_lived
    manager = app.state.manager
    abandoned = post(server, endless).json()
    finished = run(server, "SELECT x FROM UNNEST(sequence(1, 5000)) AS t(x)")[0][0]  # several pages
    query = manager.get(abandoned["id"])
    deadline = time.monotonic() + 30
    while (query.failure is None or manager.get(finished["id"]) is not None) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert query.failure.error_name == "ABANDONED_QUERY"
    assert manager.get(finished["id"]) is None
    assert requests.get(finished["nextUri"], timeout=30).status_code == 404
    while manager.get(abandoned["id"]) is not None and time.monotonic() < deadline:
        time.sleep(0.1)
    assert manager.get(abandoned["id"]) is None
    assert not [q for q in manager.queries() if q.running]
