"""The HTTP layer of `lakegate serve` under hostile requests, on real servers on 127.0.0.1: request
bodies are capped while they are read (413) and only after authentication (401 first), headers are
capped (431), slow or idle partial requests are closed (408), connections are capped (503), a
client that goes away leaves no traceback, and logins resist guessing (the same bcrypt work for an
unknown user, a backoff after repeated failures, no 500 for long passwords). Also: --port is
checked, /v1/info/state is public as in Trino, and system.runtime.queries shows a user only their
own queries.

The requests are written by hand on raw sockets, so that a test controls exactly which bytes reach
the server and when.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path

import bcrypt
import orjson
import pytest
import requests
import trino
from trino.auth import BasicAuthentication

from lakegate.gateway.server import auth
from lakegate.gateway.server.auth import Users

PASSWORDS = {"alice": "wonderland", "bob": "builder"}
HEADERS = {"X-Trino-Catalog": "lake", "X-Trino-Schema": "main", "X-Trino-User": "tester"}
MB = 1_000_000


def users_file(folder: Path, cost: int = 4) -> Path:
    path = folder / "users.txt"
    path.write_text(
        "".join(
            f"{user}:{bcrypt.hashpw(password.encode(), bcrypt.gensalt(cost)).decode()}\n"
            for user, password in PASSWORDS.items()
        )
    )
    return path


def open_socket(server, timeout: float = 10) -> socket.socket:
    return socket.create_connection((server.host, server.port), timeout=timeout)


def head(method: str, path: str, *headers: str) -> bytes:
    """A request's line and headers (ending with the blank line)."""
    return "\r\n".join([f"{method} {path} HTTP/1.1", "Host: 127.0.0.1", *headers, "", ""]).encode()


def read_response(sock: socket.socket) -> tuple[int, dict[str, str], bytes]:
    """Status, headers and body of the response on `sock`, read until the server closes it."""
    data = b""
    while True:
        chunk = sock.recv(65536)
        if not chunk:
            break
        data += chunk
    status_line, _, rest = data.partition(b"\r\n")
    header_text, _, body = rest.partition(b"\r\n\r\n")
    headers = dict(line.split(": ", 1) for line in header_text.decode("latin-1").split("\r\n") if ": " in line)
    return int(status_line.split()[1]), {k.lower(): v for k, v in headers.items()}, body


def stream(sock: socket.socket, total: int, chunk: bytes = b"x" * 65536) -> int:
    """Send up to `total` bytes; the bytes sent before the server stopped reading (or all)."""
    sent = 0
    try:
        while sent < total:
            sock.sendall(chunk)
            sent += len(chunk)
    except (BrokenPipeError, ConnectionResetError):
        pass
    return sent


def peak_rss(server) -> int:
    """The server process's peak resident memory (VmHWM), in bytes."""
    status = Path(f"/proc/{server.process.pid}/status").read_text()
    return int(next(line for line in status.splitlines() if line.startswith("VmHWM:")).split()[1]) * 1024


def select_1(server, **kwargs) -> list[list]:
    with trino.dbapi.connect(
        host=server.host, port=server.port, user=kwargs.pop("user", "tester"), catalog="lake", schema="main", **kwargs
    ) as connection:
        cursor = connection.cursor()
        cursor.execute("SELECT 1")
        return cursor.fetchall()


# --- bodies ----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fresh_server(start_server):
    """A server of its own (its peak memory is measured), with the default limits (--max-body 1 MB)."""
    server = start_server()
    assert select_1(server) == [[1]]
    return server


def test_50_mb_bodies_are_refused_with_413_without_being_read(fresh_server):
    """A statement over Trino's query.max-length (1,000,000) fails with QUERY_TEXT_TOO_LARGE, the
    error Trino's DispatchManager gives (core/trino-main/.../dispatcher/DispatchManager.java); over
    --max-body it is not even read: HTTP 413 with that error as a QueryResults document."""
    before = peak_rss(fresh_server)
    with open_socket(fresh_server) as sock:  # declared too large: refused before a byte of it is read
        sock.sendall(head("POST", "/v1/statement", f"Content-Length: {50 * MB}", "X-Trino-User: tester"))
        status, headers, body = read_response(sock)
    assert status == 413 and headers["content-type"] == "application/json"
    error = orjson.loads(body)["error"]
    assert (error["errorName"], error["errorType"]) == ("QUERY_TEXT_TOO_LARGE", "USER_ERROR")
    assert error["message"] == f"Query text length ({50 * MB}) exceeds the maximum length (1000000)"

    # no length given: counted while it streams in (or answered at once, without X-Trino-User, and the
    # connection closed: the rest is not read either)
    for path, user in [
        ("/v1/statement", "X-Trino-User: tester"),
        ("/v1/statement", "X-Trino-Source: no-user"),
        ("/dashboard/api/sessions", "Content-Type: application/json"),
    ]:
        with open_socket(fresh_server) as sock:
            sock.sendall(head("POST", path, "Transfer-Encoding: chunked", user))
            sent = stream(sock, 50 * MB, b"10000\r\n" + b"x" * 0x10000 + b"\r\n")
        assert sent < 50 * MB, (path, user)  # the server closed the connection long before
    assert peak_rss(fresh_server) - before < 20 * MB  # nothing near 50 MB was held
    assert select_1(fresh_server) == [[1]]


def test_the_body_limit_is_trinos_query_length(fresh_server):
    sql = "SELECT 1 -- " + "x" * MB  # 1,000,012 bytes
    response = requests.post(f"{fresh_server.url}/v1/statement", data=sql.encode(), headers=HEADERS, timeout=30)
    assert response.status_code == 413
    assert response.json()["error"]["errorName"] == "QUERY_TEXT_TOO_LARGE"
    with trino.dbapi.connect(host=fresh_server.host, port=fresh_server.port, user="tester") as connection:
        cursor = connection.cursor()
        cursor.execute("SELECT 1 -- " + "x" * 900_000)  # under both limits: answered
        assert cursor.fetchall() == [[1]]


@pytest.fixture(scope="module")
def auth_server(start_server, tmp_path_factory):
    return start_server("--users", str(users_file(tmp_path_factory.mktemp("users"))))


def test_an_unauthenticated_body_gets_401_before_it_is_read(auth_server):
    for path in ("/dashboard/api/sessions", "/v1/statement"):
        with open_socket(auth_server) as sock:  # 400 MB announced, none sent: the answer cannot wait for it
            sock.sendall(head("POST", path, f"Content-Length: {400 * MB}", "Content-Type: application/json"))
            status, headers, _ = read_response(sock)
        assert status == 401 and headers["www-authenticate"] == 'Basic realm="lakegate"', path
    # authenticated, the same body is refused by its size
    with open_socket(auth_server) as sock:
        sock.sendall(
            head(
                "POST",
                "/dashboard/api/sessions",
                f"Content-Length: {400 * MB}",
                "Authorization: Basic YWxpY2U6d29uZGVybGFuZA==",
            )
        )  # alice:wonderland
        status, _, body = read_response(sock)
    assert status == 413 and b"--max-body" in body


# --- headers, slow and idle clients, connections -----------------------------------------------


def test_a_huge_header_is_refused_with_431(fresh_server):
    with open_socket(fresh_server) as sock:
        sock.sendall(b"GET /v1/info HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: ")
        sent = stream(sock, 120 * MB, b"y" * 65536)  # a 120 MB header: cut off near the 64 KB limit
        status, _, body = read_response(sock)
    assert sent < 120 * MB and status == 431 and b"Request headers too large" in body
    assert select_1(fresh_server) == [[1]]


def test_a_huge_header_arriving_in_one_read_is_refused_with_431(fresh_server):
    request = head("GET", "/v1/info", "X-Big: " + "y" * 120_000)  # 120,000 bytes, sent whole at once
    with open_socket(fresh_server) as sock:
        sock.sendall(request)
        status, _, body = read_response(sock)
    assert status == 431 and b"Request headers too large (the limit is 65536 bytes)" in body
    many = head("GET", "/v1/info", *(f"X-H{i}: {'z' * 100}" for i in range(1000)))  # many small headers
    with open_socket(fresh_server) as sock:
        sock.sendall(many)
        assert read_response(sock)[0] == 431
    assert select_1(fresh_server) == [[1]]


def raw_status(server, request: bytes) -> tuple[int, bytes]:
    with open_socket(server) as sock:
        sock.sendall(request)
        status, _, body = read_response(sock)
    return status, body


def test_the_host_is_named_once_and_an_absolute_target_must_name_this_server(fresh_server):
    port = fresh_server.port
    twice = f"GET /v1/info HTTP/1.1\r\nHost: evil.example.org\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    status, body = raw_status(fresh_server, twice.encode())
    assert status == 400 and b"2 Host headers" in body
    absolute = f"GET http://evil.example.org/v1/info HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    status, body = raw_status(fresh_server, absolute.encode())
    assert status == 421 and b"request target 'evil.example.org'" in body
    own = f"GET http://127.0.0.1:{port}/v1/info HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    assert raw_status(fresh_server, own.encode())[0] == 200
    odd = f"GET ftp://127.0.0.1:{port}/v1/info HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    status, body = raw_status(fresh_server, odd.encode())
    assert status == 400 and b"request target must be a path" in body


def test_the_origin_check_compares_the_scheme(fresh_server):
    port = fresh_server.port
    for origin, expected in (
        (f"https://127.0.0.1:{port}", 403),  # the server speaks http: another origin
        (f"ws://127.0.0.1:{port}", 403),
        (f"http://127.0.0.1:{port}", 200),
    ):
        request = head("POST", "/v1/statement", f"Origin: {origin}", "X-Trino-User: me", "Content-Length: 8")
        request = request.replace(b"Host: 127.0.0.1", f"Host: 127.0.0.1:{port}".encode()) + b"SELECT 1"
        assert (
            raw_status(fresh_server, request.replace(b"\r\n\r\n", b"\r\nConnection: close\r\n\r\n", 1))[0] == expected
        ), origin


def test_200_idle_partial_requests_do_not_stop_queries(fresh_server):
    sockets = [open_socket(fresh_server) for _ in range(200)]
    try:
        for sock in sockets:
            sock.sendall(b"POST /v1/statement HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 10\r\n")
        assert select_1(fresh_server) == [[1]]
    finally:
        for sock in sockets:
            sock.close()


@pytest.fixture(scope="module")
def strict_server(start_server):
    return start_server("--request-timeout", "1", "--max-connections", "20")


def test_slow_partial_requests_are_closed_after_the_timeout(strict_server):
    with open_socket(strict_server) as sock:  # headers that trickle in, a byte every 0.1 s, never end
        started = time.monotonic()
        try:
            for byte in b"GET /v1/info HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: " + b"z" * 200:
                sock.sendall(bytes([byte]))
                time.sleep(0.1)
        except (BrokenPipeError, ConnectionResetError):
            pass
        status, _, body = read_response(sock)
    assert status == 408 and b"Request not received within 1 s" in body
    assert time.monotonic() - started < 10  # closed near the 1 s timeout, not when the client gave up
    with open_socket(strict_server) as sock:  # headers complete, body never sent
        sock.sendall(head("POST", "/v1/statement", "Content-Length: 100", "X-Trino-User: tester") + b"SELECT")
        status, _, _ = read_response(sock)
    assert status == 408
    with open_socket(strict_server) as sock:  # a connection that never sends a byte
        assert read_response(sock)[0] == 408
    assert "Traceback" not in strict_server.log.read_text()


def test_connections_beyond_the_limit_are_refused_and_freed(strict_server):
    assert select_1(strict_server) == [[1]]  # its databases are open: the files it needs are counted
    fds = Path(f"/proc/{strict_server.process.pid}/fd")
    baseline = len(list(fds.iterdir()))
    sockets = [open_socket(strict_server) for _ in range(200)]  # idle connections, holding a descriptor each
    try:
        time.sleep(0.5)
        assert len(list(fds.iterdir())) <= baseline + 25  # at most 20 held (beyond: 503 and closed)
        refused = 0
        for sock in sockets[20:]:
            status, _, body = read_response(sock)
            refused += status == 503 and body == b"Too many connections: try again later"
        assert refused == 180
    finally:
        for sock in sockets:
            sock.close()
    deadline = time.monotonic() + 10  # the held ones time out (1 s): the server answers again
    while time.monotonic() < deadline:
        try:
            assert select_1(strict_server) == [[1]]
            break
        except Exception:
            time.sleep(0.5)
    else:
        pytest.fail("the server did not answer after the idle connections timed out")


def test_a_client_that_goes_away_mid_request_leaves_no_traceback(fresh_server):
    for path in ("/v1/statement", "/dashboard/api/sessions"):
        with open_socket(fresh_server) as sock:
            sock.sendall(
                head("POST", path, "Content-Length: 1000", "Content-Type: application/json", "X-Trino-User: tester")
                + b'{"x": '
            )
            time.sleep(0.2)
    assert select_1(fresh_server) == [[1]]  # the server went on, and logged nothing about it
    time.sleep(0.2)
    assert "Traceback" not in fresh_server.log.read_text() and "Exception" not in fresh_server.log.read_text()


# --- logins ------------------------------------------------------------------------------------------


def test_a_password_over_72_bytes_gets_401_not_500(auth_server):
    for password in ("w" * 73, PASSWORDS["alice"] + "x" * 100):  # bcrypt checks at most 72 bytes: never a match
        response = requests.get(f"{auth_server.url}/v1/query/none", auth=("alice", password), timeout=30)
        assert response.status_code == 401, password


def test_unknown_users_cost_as_much_as_wrong_passwords(start_server, tmp_path, monkeypatch):
    """A wrong password costs a bcrypt check; an unknown user must cost the same, else answer times
    tell which users exist. Counted rather than timed (timings on a shared machine are noise): each
    failed login through the server makes exactly one bcrypt check, at the users file's cost."""
    hashes = {user: bcrypt.hashpw(p.encode(), bcrypt.gensalt(6)) for user, p in PASSWORDS.items()}
    hashes["carol"] = bcrypt.hashpw(b"x", bcrypt.gensalt(5))
    users = Users(hashes)
    checks: list[bytes] = []
    real = bcrypt.checkpw
    monkeypatch.setattr(auth.bcrypt, "checkpw", lambda secret, hashed: checks.append(hashed) or real(secret, hashed))
    assert not users.verify("alice", "guess") and not users.verify("nobody", "guess")
    assert not users.verify("nobody", "x" * 500)
    assert [h[:7] for h in checks] == [b"$2b$06$"] * 3  # one check each, at the slowest stored cost
    server = start_server("--users", str(users_file(tmp_path)))
    for user in ("alice", "nobody"):  # the server answers both alike
        answer = requests.get(f"{server.url}/v1/query/none", auth=(user, "guess"), timeout=30)
        assert answer.status_code == 401 and "alice" not in answer.text and "nobody" not in answer.text


def test_repeated_failed_logins_back_off_with_429(start_server, tmp_path):
    server = start_server("--users", str(users_file(tmp_path)))
    url = f"{server.url}/v1/query/none"
    for i in range(5):
        assert requests.get(url, auth=("alice", f"guess{i}"), timeout=30).status_code == 401
    refused = requests.get(url, auth=("alice", "wonderland"), timeout=30)  # even the right one must wait now
    assert refused.status_code == 429 and refused.headers["Retry-After"] == "1"
    assert requests.get(url, auth=("bob", "builder"), timeout=30).status_code == 404  # others log in
    time.sleep(1.1)
    assert requests.get(url, auth=("alice", "wonderland"), timeout=30).status_code == 404  # logged in
    assert requests.get(url, auth=("alice", "guess"), timeout=30).status_code == 401  # the count started again


def test_a_forwarded_for_header_does_not_escape_the_backoff(start_server, tmp_path):
    """Forwarding headers are not trusted by default: a rotating X-Forwarded-For is still one client."""
    server = start_server("--users", str(users_file(tmp_path)))
    url = f"{server.url}/v1/query/none"
    answers = [
        requests.get(url, auth=("alice", f"guess{i}"), headers={"X-Forwarded-For": f"10.0.0.{i}"}, timeout=30)
        for i in range(10)
    ]
    assert [a.status_code for a in answers] == [401] * 5 + [429] * 5


def test_trusted_proxies_forward_addresses_and_the_user_backs_off_over_all_of_them(start_server, tmp_path):
    """Behind a proxy named with --forwarded-allow-ips each forwarded address is its own client, and
    guesses at one user from many addresses still back off (keyed on the user too)."""
    server = start_server("--users", str(users_file(tmp_path)), "--forwarded-allow-ips", "127.0.0.1")
    url = f"{server.url}/v1/query/none"

    def guess(i: int) -> int:
        forwarded = {"X-Forwarded-For": f"10.0.{i}.1"}
        return requests.get(url, auth=("alice", f"guess{i}"), headers=forwarded, timeout=30).status_code

    assert [guess(i) for i in range(10)] == [401] * 10  # ten addresses, one guess each
    assert guess(10) == 429
    assert (
        requests.get(url, auth=("bob", "builder"), headers={"X-Forwarded-For": "10.9.9.9"}, timeout=30).status_code
        == 404
    )


def test_a_bad_forwarded_allow_ips_is_refused(server_lake):
    result = subprocess.run(
        [sys.executable, "-m", "lakegate.gateway.cli", "serve", "--lake", str(server_lake), "--port", "0"]
        + ["--forwarded-allow-ips", "10.0.0.1,proxy!"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1 and result.stderr.startswith("lakegate: --forwarded-allow-ips: 'proxy!'")


def test_guessing_user_names_backs_off_too(start_server, tmp_path):
    server = start_server("--users", str(users_file(tmp_path)))
    url = f"{server.url}/v1/query/none"
    for i in range(20):  # 20 failures from one client, each for another name
        assert requests.get(url, auth=(f"name{i}", "guess"), timeout=30).status_code == 401
    assert requests.get(url, auth=("name20", "guess"), timeout=30).status_code == 429
    assert requests.get(url, auth=("bob", "builder"), timeout=30).status_code == 429  # this client waits


def test_server_state_is_public_as_in_trino(auth_server):
    """Trino's ServerInfoResource marks GET /v1/info and GET /v1/info/state @ResourceSecurity(PUBLIC)
    (core/trino-main/src/main/java/io/trino/server/ServerInfoResource.java); the rest needs a login."""
    assert requests.get(f"{auth_server.url}/v1/info", timeout=30).status_code == 200
    state = requests.get(f"{auth_server.url}/v1/info/state", timeout=30)
    assert state.status_code == 200 and state.json() == "ACTIVE"
    assert requests.get(f"{auth_server.url}/v1/query/none", timeout=30).status_code == 401
    assert requests.get(f"{auth_server.url}/dashboard/", timeout=30).status_code == 401


def test_a_user_sees_only_their_own_queries(auth_server):
    """With --users, system.runtime.queries lists the user's own queries only (Trino filters it by
    the access control's query ownership rules: a user may view the queries they own)."""

    def rows(user: str, sql: str) -> list[list]:
        with trino.dbapi.connect(
            host=auth_server.host,
            port=auth_server.port,
            user=user,
            catalog="lake",
            schema="main",
            auth=BasicAuthentication(user, PASSWORDS[user]),
            http_scheme="http",
            allow_insecure_auth=True,
        ) as connection:
            cursor = connection.cursor()
            cursor.execute(sql)
            return cursor.fetchall()

    assert rows("alice", "SELECT 'alice secret 42'") == [["alice secret 42"]]
    seen_by_bob = rows("bob", 'SELECT "user", query FROM system.runtime.queries')
    assert seen_by_bob and {user for user, _ in seen_by_bob} == {"bob"}
    assert not any("alice secret" in query for _, query in seen_by_bob)
    assert any("alice secret 42" in query for [query] in rows("alice", "SELECT query FROM system.runtime.queries"))


# --- ports -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("command", [["serve", "--lake", "{lake}"], ["metrics", "debug", "--emissions-file", "x"]])
@pytest.mark.parametrize("port", ["99999", "-1", "http"])
def test_a_port_outside_0_to_65535_is_refused(server_lake, command, port):
    args = [a.format(lake=server_lake) for a in command]
    result = subprocess.run(
        [sys.executable, "-m", "lakegate.gateway.cli", *args, "--port", port],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "argument --port: expected a port number (0 to 65535" in result.stderr and repr(port) in result.stderr
