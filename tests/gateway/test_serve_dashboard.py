"""`lakegate serve` serves the dashboard beside the SQL endpoint, for every branch and batch of the lake."""

from __future__ import annotations

import hashlib
import json
import shutil
import urllib.error
import urllib.parse
import urllib.request
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
import trino

from lakegate.lake import paths
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file

from .conftest import serve

NAV_SET = "Nav Metrics"


def _get(url: str) -> tuple[int, bytes]:
    with urllib.request.urlopen(url, timeout=30) as response:
        return response.status, response.read()


def _json(method: str, url: str, body: Any = None) -> Any:
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(url, data=data, method=method, headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(request, timeout=60) as response:
        assert response.status == 200
        return json.loads(response.read())


def _digests(folder: Path) -> dict[str, str]:
    """sha256 of every file under `folder`, by relative path."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_serve_mounts_the_dashboard_page_and_its_lake_listing(lake_server):
    status, page = _get(f"{lake_server.url}/dashboard/")
    assert status == 200 and b"<html" in page.lower()

    status, body = _get(f"{lake_server.url}/dashboard/api/lake")
    listing = json.loads(body)
    text = json.dumps(listing)
    assert status == 200
    assert '"main"' in text and '"b1"' in text and '"b2"' in text

    status, script = _get(f"{lake_server.url}/dashboard/static/plotly.min.js")
    assert status == 200 and len(script) > 1_000_000


@pytest.fixture
def evaluated_lake(nav_jobs, tmp_path: Path, run_lakegate) -> Path:
    """A lake with the three nav jobs in batch `nightly` on `main`, synced and evaluated by `metrics run`."""
    lake = tmp_path / "lake"
    config = load_config([nav_jobs.config])
    for job in nav_jobs.jobs:
        ingest_job(
            lake,
            "main",
            "nightly",
            job.job_id,
            [job.emissions_path],
            config=config,
            metadata=load_metadata_file(job.metadata_path),
        )
        shutil.copytree(job.logs_dir, paths.logs_dir(lake, "main", "nightly", job.job_id))
    common = ["--lake", str(lake), "--branch", "main"]
    synced = run_lakegate(["metrics", "sync", *common, "--metrics-config-path", str(nav_jobs.config)], tmp_path)
    assert synced.returncode == 0, synced.stderr
    ran = run_lakegate(["metrics", "run", *common, "--batch", "nightly", "--metrics-set", NAV_SET], tmp_path)
    assert ran.returncode == 2, ran.stderr  # job 2 is a BLOCKER
    return lake


def test_editing_a_metric_in_the_dashboard_never_writes_the_lake(evaluated_lake: Path, tmp_path: Path) -> None:
    """An edit is evaluated for the session only; the lake stays byte-identical,
    while the batch metrics see the session's job statuses (as `metrics run` would write them)."""
    before = _digests(evaluated_lake)
    server = serve(evaluated_lake, tmp_path / "serve.log")
    try:
        dashboard = f"{server.url}/dashboard/"
        status, page = _get(dashboard)
        assert status == 200 and b"Session only, not saved" in page

        state = _json(
            "POST", dashboard + "api/sessions", {"branch": "main", "batch": "nightly", "metrics_set": NAV_SET}
        )
        assert state["origin"] == "stored"
        assert sorted(r["conflated_status"] for r in state["matrix"]["rows"]) == ["BLOCKER", "PASSED", "WARNING"]

        name = urllib.parse.quote("Time to reach final goal")  # the status check that blocks job 2
        edited = _json(
            "PUT",
            f"{dashboard}api/sessions/{state['id']}/metrics/{name}",
            {"status": {"query_string": "SELECT 1 WHERE 1 > ?", "block": 1}},
        )
        statuses = Counter(r["conflated_status"] for r in edited["matrix"]["rows"])
        assert statuses == {"PASSED": 2, "WARNING": 1}
        pie = next(m for m in edited["metrics"] if m["name"] == "Job Outcomes")["result"]["figure"]["data"][0]
        assert dict(zip(pie["labels"], pie["values"])) == statuses  # the batch metric counts the session's statuses

        _json("POST", f"{dashboard}api/sessions/{state['id']}/evaluate")
        assert _digests(evaluated_lake) == before
    finally:
        assert server.stop() == 0


def _status(url: str, method: str = "GET", headers: dict[str, str] | None = None, body: bytes | None = None) -> int:
    request = urllib.request.Request(url, data=body, method=method, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status
    except urllib.error.HTTPError as error:
        return error.code


def test_serve_checks_host_and_origin(start_server) -> None:
    """On `serve`, a Host that does not name the server (DNS rebinding) gets 421 on every
    route, a cross-site Origin on a POST 403; `--allowed-host` admits a proxy's name; the trino client works."""
    server = start_server("--allowed-host", "lake.example.com")
    for path in ("/dashboard/api/lake", "/v1/info", "/dashboard/"):
        assert _status(server.url + path, headers={"Host": f"rebound.example.net:{server.port}"}) == 421, path
    assert _status(server.url + "/dashboard/api/lake", headers={"Host": "lake.example.com"}) == 200
    assert _status(server.url + "/dashboard/api/lake", headers={"Host": f"localhost:{server.port}"}) == 200
    statement = server.url + "/v1/statement"
    headers = {"X-Trino-User": "me", "Content-Type": "text/plain"}
    assert _status(statement, "POST", {**headers, "Origin": "https://evil.example.org"}, b"SELECT 1") == 403
    assert _status(statement, "POST", {**headers, "Origin": server.url}, b"SELECT 1") == 200
    with trino.dbapi.connect(host="127.0.0.1", port=server.port, user="me", catalog="lake", schema="main") as conn:
        cursor = conn.cursor()
        cursor.execute("SELECT 1")
        assert cursor.fetchall() == [[1]]


def test_dashboard_sessions_belong_to_their_user(evaluated_lake: Path, tmp_path: Path) -> None:
    """With --users, bob opening the batch alice has open gets a session of his own: he neither sees
    nor edits hers (404, as for a session that does not exist), and no state shows server paths."""
    import bcrypt
    import requests

    passwords = {"alice": "wonderland", "bob": "builder"}
    users = tmp_path / "users.txt"
    users.write_text(
        "".join(f"{u}:{bcrypt.hashpw(p.encode(), bcrypt.gensalt(4)).decode()}\n" for u, p in passwords.items())
    )
    server = serve(evaluated_lake, tmp_path / "serve.log", "--users", str(users))
    api = f"{server.url}/dashboard/api/sessions"
    as_alice, as_bob = ("alice", passwords["alice"]), ("bob", passwords["bob"])
    opened = {"branch": "main", "batch": "nightly", "metrics_set": NAV_SET}
    try:
        alice = requests.post(api, json=opened, auth=as_alice, timeout=60).json()
        secret = {
            "name": "Alice only",
            "type": "test",
            "template": "scalar",
            "description": "d",
            "units": "",
            "query_string": "SELECT 42 AS alice_secret_42",
        }
        added = requests.post(f"{api}/{alice['id']}/metrics", json=secret, auth=as_alice, timeout=60)
        assert added.status_code == 200 and "Alice only" in added.text
        bob = requests.post(api, json=opened, auth=as_bob, timeout=60)
        assert bob.status_code == 200
        assert bob.json()["id"] != alice["id"] and "alice_secret_42" not in bob.text and "Alice only" not in bob.text
        for method, path in (
            ("GET", ""),
            ("PUT", "/metrics/Alice%20only"),
            ("DELETE", "/metrics/Alice%20only"),
            ("POST", "/evaluate"),
            ("GET", "/export"),
            ("GET", "/tables"),
            ("POST", "/query"),
        ):
            body = (
                {"query_string": "SELECT 1"} if method == "PUT" else {"sql": "SELECT 1"} if path == "/query" else None
            )
            answer = requests.request(method, f"{api}/{alice['id']}{path}", json=body, auth=as_bob, timeout=60)
            assert answer.status_code == 404 and "alice_secret_42" not in answer.text, (method, path, answer.text)
        mine = requests.get(f"{api}/{alice['id']}", auth=as_alice, timeout=60)
        assert mine.status_code == 200 and "alice_secret_42" in mine.text  # untouched by bob
        for text in (mine.text, bob.text):
            assert str(evaluated_lake) not in text and str(evaluated_lake.resolve()) not in text
    finally:
        assert server.stop() == 0
