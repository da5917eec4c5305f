"""Security and limits of `lakegate serve`, on real servers: where it may listen, HTTP Basic users
(bcrypt), TLS with the trino client, and the per-query time, row, memory and concurrency limits,
each a clear Trino error after which the server keeps answering."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import bcrypt
import pytest
import requests
import trino
from trino.auth import BasicAuthentication

from lakegate.gateway.cli import main as cli

PASSWORDS = {"alice": "wonderland", "bob": "builder"}
HEADERS = {"X-Trino-Catalog": "lake", "X-Trino-Schema": "main"}


def lakegate(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "lakegate.gateway.cli", *args], capture_output=True, text=True, timeout=120
    )


@pytest.fixture(scope="module")
def users_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("users") / "users.txt"
    lines = ["# lakegate users", ""] + [
        f"{user}:{bcrypt.hashpw(password.encode(), bcrypt.gensalt(4)).decode()}" for user, password in PASSWORDS.items()
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def certificate(tmp_path_factory, make_certificate):
    """A self-signed certificate for 127.0.0.1 and its key (PEM files)."""
    return make_certificate(tmp_path_factory.mktemp("tls"))


# --- where it may listen ---------------------------------------------------------------------------


def _refused(result: subprocess.CompletedProcess, *words: str) -> None:
    assert result.returncode == 1, (result.stdout, result.stderr)
    assert "Traceback" not in result.stderr and result.stderr.startswith("lakegate: ")
    for word in words:
        assert word in result.stderr, result.stderr


def test_listening_beyond_loopback_needs_users_and_tls(server_lake, users_file):
    _refused(
        lakegate("serve", "--lake", str(server_lake), "--host", "0.0.0.0", "--port", "0"),
        "refusing to serve on 0.0.0.0 without authentication",
        "--users",
    )
    _refused(
        lakegate("serve", "--lake", str(server_lake), "--host", "0.0.0.0", "--port", "0", "--users", str(users_file)),
        "without TLS",
        "--tls-cert",
    )


@pytest.mark.parametrize(
    "arguments, words",
    [
        (["--tls-cert", "{cert}"], ["go together"]),
        (["--tls-cert", "{key}", "--tls-key", "{key}"], ["cannot use the TLS certificate"]),
        (["--users", "{bad_users}"], ["{bad_users}:1:", "bcrypt"]),
        (["--memory-limit", "lots"], ["--memory-limit", "lots"]),
        (["--catalog", "System"], ["--catalog", "lower-case identifier"]),
        (["--host", "::", "--users", "{users}"], ["without TLS"]),
        (["--max-queries-per-user", "9"], ["--max-queries-per-user 9: at most --max-concurrent-queries (8)"]),
    ],
)
def test_bad_options_are_refused_in_one_line(server_lake, users_file, certificate, tmp_path, capsys, arguments, words):
    bad_users = tmp_path / "users.txt"
    bad_users.write_text("alice:$2b$12$abc\n")
    names = {"cert": certificate[0], "key": certificate[1], "bad_users": bad_users, "users": users_file}
    assert cli.main(["serve", "--lake", str(server_lake), *(a.format(**names) for a in arguments)]) == 1
    error = capsys.readouterr().err
    assert error.startswith("lakegate: ") and error.count("\n") == 1
    for word in words:
        assert word.format(**names) in error, error


@pytest.mark.parametrize("value", ["0", "-1"])
def test_a_per_user_cap_below_one_is_a_usage_error(server_lake, capsys, value):
    with pytest.raises(SystemExit) as exited:
        cli.main(["serve", "--lake", str(server_lake), "--max-queries-per-user", value])
    assert exited.value.code == 2
    assert f"argument --max-queries-per-user: expected a positive number, got '{value}'" in capsys.readouterr().err


# --- users ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def auth_server(start_server, users_file):
    """Logins of alice and bob; one query of each user runs at once."""
    return start_server("--users", str(users_file), "--max-queries-per-user", "1")


def _post(server, sql: str, auth=None, **headers) -> requests.Response:
    return requests.post(
        f"{server.url}/v1/statement",
        data=sql.encode(),
        auth=auth,
        timeout=30,
        headers={**HEADERS, **headers},
        verify=getattr(server, "verify", True),
    )


def test_missing_or_wrong_credentials_get_401_and_no_data(auth_server, endless):
    for auth in (None, ("alice", "wrong"), ("nobody", "wonderland"), ("alice", "")):
        response = _post(auth_server, "SELECT count(*) FROM metadata", auth=auth)
        assert response.status_code == 401, auth
        assert response.headers["WWW-Authenticate"] == 'Basic realm="lakegate"'
        assert "data" not in response.text and "nextUri" not in response.text
    assert requests.get(f"{auth_server.url}/v1/info", timeout=30).status_code == 200  # probes need no login

    first = _post(auth_server, endless, auth=("alice", "wonderland"))  # still running: it has a nextUri
    assert first.status_code == 200
    next_uri = first.json()["nextUri"]
    assert requests.get(next_uri, timeout=30).status_code == 401
    assert requests.get(next_uri, auth=("alice", "nope"), timeout=30).status_code == 401
    # another user neither sees nor cancels alice's query
    assert requests.get(next_uri, auth=("bob", "builder"), timeout=30).status_code == 404
    requests.delete(next_uri, auth=("bob", "builder"), timeout=30)
    document = requests.get(next_uri, auth=("alice", "wonderland"), timeout=30).json()
    assert "error" not in document and "nextUri" in document
    assert requests.delete(document["nextUri"], auth=("alice", "wonderland"), timeout=30).status_code == 204
    document = _post(auth_server, "SELECT count(*) FROM metadata", auth=("alice", "wonderland")).json()
    while "nextUri" in document:
        document = requests.get(document["nextUri"], auth=("alice", "wonderland"), timeout=30).json()
    assert document["data"] == [[3]]


def test_the_session_user_is_the_authenticated_one(auth_server, endless):
    assert _post(auth_server, "SELECT 1", auth=("alice", "wonderland"), **{"X-Trino-User": "bob"}).status_code == 403
    victim = _post(auth_server, endless, auth=("alice", "wonderland")).json()
    kill = f"CALL system.runtime.kill_query(query_id => '{victim['id']}', message => 'mine now')"
    refused = _post(auth_server, kill, auth=("bob", "builder")).json()["error"]
    # alice's query is not there for bob: Trino's words for a missing query, and not alice's name
    assert refused["errorName"] == "NOT_FOUND" and refused["message"] == f"Target query not found: {victim['id']}"
    assert "error" not in _post(auth_server, kill, auth=("alice", "wonderland")).json()
    with trino.dbapi.connect(
        host=auth_server.host,
        port=auth_server.port,
        user="bob",
        catalog="lake",
        schema="main",
        auth=BasicAuthentication("bob", "builder"),
        http_scheme="http",
        allow_insecure_auth=True,
    ) as connection:  # loopback: no TLS needed
        cursor = connection.cursor()
        cursor.execute('SELECT DISTINCT "user" FROM system.runtime.queries ORDER BY 1')
        assert cursor.fetchall() == [["bob"]]  # alice's queries (and their SQL text) are hidden from bob
        cursor.execute("SELECT current_timezone()")
        assert cursor.fetchall() == [["UTC"]]


def test_the_per_user_cap_counts_the_authenticated_user(auth_server, endless):
    alice, bob, stop = ("alice", "wonderland"), ("bob", "builder"), threading.Event()
    mine = [
        _post(auth_server, endless, alice).json(),
        _post(auth_server, endless, alice, **{"X-Trino-User": "alice"}).json(),
    ]

    def poll(document: dict) -> None:  # alice is still there: her queued query is not dropped
        while "nextUri" in document and not stop.is_set():
            document = requests.get(document["nextUri"], auth=alice, timeout=30).json()

    def states() -> list[str]:
        return sorted(requests.get(d["infoUri"], auth=alice, timeout=30).json()["state"] for d in mine)

    for document in mine:
        threading.Thread(target=poll, args=(document,), daemon=True).start()
    try:
        deadline = time.monotonic() + 30
        while states() != ["QUEUED", "RUNNING"]:  # with a header naming her or none, both are alice's
            assert time.monotonic() < deadline, states()
            time.sleep(0.1)
        # naming another user to get past her cap is refused (Trino's impersonation check)
        assert _post(auth_server, endless, alice, **{"X-Trino-User": "bob"}).status_code == 403
        document = _post(auth_server, "SELECT 1", bob).json()
        while "nextUri" in document:
            document = requests.get(document["nextUri"], auth=bob, timeout=30).json()
        assert document["data"] == [[1]] and states() == ["QUEUED", "RUNNING"]  # bob did not wait for alice
    finally:
        stop.set()
        for d in mine:
            requests.delete(d["infoUri"], auth=alice, timeout=30)


def test_tls_with_the_trino_client(start_server, users_file, certificate, monkeypatch):
    cert, key = certificate
    # requests lets these variables override a session's `verify`, which is how the trino client passes its CA
    monkeypatch.delenv("REQUESTS_CA_BUNDLE", raising=False)
    monkeypatch.delenv("CURL_CA_BUNDLE", raising=False)
    server = start_server("--users", str(users_file), "--tls-cert", str(cert), "--tls-key", str(key))
    assert server.url.startswith("https://127.0.0.1:")

    def connect(password: str) -> trino.dbapi.Connection:
        return trino.dbapi.connect(
            host=server.host,
            port=server.port,
            user="alice",
            catalog="lake",
            schema="main",
            http_scheme="https",
            auth=BasicAuthentication("alice", password),
            verify=str(cert),
        )

    with connect("wonderland") as connection:
        cursor = connection.cursor()
        cursor.execute("SELECT count(*) FROM odom_linear_velocity WHERE batch_id = ?", ("b2",))
        assert cursor.fetchall()[0][0] > 0
        assert cursor.info_uri.startswith(server.url)
    with pytest.raises(trino.exceptions.HttpError, match="401"):
        with connect("wrong") as connection:
            connection.cursor().execute("SELECT 1")
    with pytest.raises(requests.exceptions.SSLError):
        requests.get(f"{server.url}/v1/info", timeout=30)  # an unknown certificate is not trusted
    with pytest.raises(requests.exceptions.ConnectionError):
        requests.get(server.url.replace("https:", "http:") + "/v1/info", timeout=30)


# --- limits -----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def limited(start_server):
    return start_server(
        "--query-timeout",
        "3",
        "--max-rows",
        "1000",
        "--memory-limit",
        "64MB",
        "--max-concurrent-queries",
        "1",
        "--max-queued-queries",
        "1",
    )


def _fetch(server, sql: str) -> list[list]:
    with trino.dbapi.connect(
        host=server.host, port=server.port, user="tester", catalog="lake", schema="main", request_timeout=60
    ) as connection:
        cursor = connection.cursor()
        cursor.execute(sql)
        return cursor.fetchall()


def _failure(server, sql: str) -> trino.exceptions.TrinoQueryError:
    with pytest.raises(trino.exceptions.TrinoQueryError) as caught:
        _fetch(server, sql)
    return caught.value


def _healthy(server) -> None:
    assert _fetch(server, "SELECT count(*) FROM metadata") == [[3]]


def test_time_limit(limited, endless):
    error = _failure(limited, endless)
    assert (error.error_name, error.error_type, error.error_code) == (
        "EXCEEDED_TIME_LIMIT",
        "INSUFFICIENT_RESOURCES",
        131075,
    )
    assert "3.00s" in error.message
    _healthy(limited)


def test_row_limit(limited):
    assert len(_fetch(limited, "SELECT x FROM UNNEST(sequence(1, 1000)) AS t(x)")) == 1000
    error = _failure(limited, "SELECT x FROM UNNEST(sequence(1, 1001)) AS t(x)")
    assert (error.error_name, error.error_type) == ("GENERIC_INSUFFICIENT_RESOURCES", "INSUFFICIENT_RESOURCES")
    assert "1000 rows" in error.message and "--max-rows" in error.message
    _healthy(limited)


def test_memory_limit(limited):
    error = _failure(
        limited,
        "SELECT length(array_join(array_agg(CAST(x AS varchar)), ',')) "
        "FROM UNNEST(sequence(1, 10000)) AS t(x) CROSS JOIN UNNEST(sequence(1, 2000)) AS u(y)",
    )
    assert (error.error_name, error.error_type, error.error_code) == (
        "EXCEEDED_GLOBAL_MEMORY_LIMIT",
        "INSUFFICIENT_RESOURCES",
        131073,
    )
    assert "--memory-limit" in error.message and "\n" not in error.message
    _healthy(limited)


def _state(server, query_id: str) -> str:
    return requests.get(f"{server.url}/v1/query/{query_id}", timeout=30).json()["state"]


def test_concurrency_bound_queues_then_refuses(limited, endless):
    headers = {"X-Trino-User": "tester", **HEADERS}

    def post(sql: str) -> dict:
        return requests.post(f"{limited.url}/v1/statement", data=sql, headers=headers, timeout=30).json()

    running = post(endless)
    requests.get(running["nextUri"], timeout=30)
    assert _state(limited, running["id"]) == "RUNNING"
    queued = post(endless)
    assert _state(limited, queued["id"]) == "QUEUED"
    refused = post("SELECT 1")
    assert "nextUri" not in refused and refused["stats"]["state"] == "FAILED"
    assert (refused["error"]["errorName"], refused["error"]["errorType"]) == (
        "QUERY_QUEUE_FULL",
        "INSUFFICIENT_RESOURCES",
    )
    for query in (running, queued):
        assert requests.delete(f"{limited.url}/v1/query/{query['id']}", timeout=30).status_code == 204
    _healthy(limited)
