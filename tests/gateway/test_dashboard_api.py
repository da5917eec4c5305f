"""The dashboard's JSON API, served by a real uvicorn server on loopback over a real lake.

Expected values come from the emissions files themselves (parsed here with `json`), not from
the engine, so a wrong scope or a wrong result shows."""

from __future__ import annotations

import io
import json
import shutil
import time
import urllib.error
import urllib.parse
import urllib.request
import zipfile
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from lakegate.dialect.scope import Scope
from lakegate.gateway.cli.debug import DebugJob
from lakegate.gateway.dashboard.config_edits import FileConfig
from lakegate.gateway.dashboard.debug_session import DashboardSession
from lakegate.gateway.dashboard.routes import DashboardState, dashboard_router
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.plotly_arrays import plain_figure
from lakegate.gateway.server.app import create_app
from lakegate.lake import paths
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file, read_metadata_row

from .conftest import served_in_thread

NAV_SET = "Nav Metrics"
BRANCH, BATCH = "main", "nightly-1"


@dataclass
class Served:
    url: str  # .../dashboard/
    state: DashboardState
    lake: Path


def _emitted(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def _rows(path: Path, topic: str) -> list[dict[str, Any]]:
    return [line["$data"] for line in _emitted(path) if line["$metadata"]["topic"] == topic]


@pytest.fixture(scope="module")
def served(nav_jobs, tmp_path_factory: pytest.TempPathFactory):
    """A lake with one stored batch of the three jobs (branch main), served on a free port by the gateway."""
    lake = tmp_path_factory.mktemp("dashboard") / "lake"
    config = load_config(nav_jobs.config)
    for job in nav_jobs.jobs:
        ingest_job(
            lake,
            BRANCH,
            BATCH,
            job.job_id,
            [job.emissions_path],
            config=config,
            metadata=load_metadata_file(job.metadata_path),
        )
        shutil.copytree(job.logs_dir, paths.logs_dir(lake, BRANCH, BATCH, job.job_id))
    state = DashboardState(lake)
    app = create_app(state.engine, dashboard_router=dashboard_router(state))  # as `lakegate serve` mounts it
    with served_in_thread(app, 20) as url:
        yield Served(f"{url}/dashboard/", state, lake)
    state.close()


def _request(served: Served, method: str, path: str, body: Any = None) -> tuple[int, Any, bytes]:
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(
        served.url + path, data=data, method=method, headers={"Content-Type": "application/json"} if data else {}
    )
    try:
        with urllib.request.urlopen(request, timeout=60) as response:
            status, raw = response.status, response.read()
            kind = response.headers.get("Content-Type", "")
    except urllib.error.HTTPError as error:
        status, raw, kind = error.code, error.read(), error.headers.get("Content-Type", "")
    return status, json.loads(raw) if "json" in kind else None, raw


def api(served: Served, method: str, path: str, body: Any = None, expect: int = 200) -> Any:
    status, answer, raw = _request(served, method, "api/" + path, body)
    assert status == expect, raw[:2000]
    return answer


def _debug(served: Served, nav_jobs, tmp_path: Path, index: int = 0) -> tuple[DashboardSession, Path]:
    """A debug session on job `index` (its own batch on branch 'debug'), with its own config copy."""
    config_path = tmp_path / "config.resim.yaml"
    shutil.copy(nav_jobs.config, config_path)
    shutil.copytree(nav_jobs.config.parent / "templates", tmp_path / "templates", dirs_exist_ok=True)
    source = nav_jobs.jobs[index]
    job = DebugJob(
        served.lake, "debug", source.emissions_path, source.logs_dir, load_metadata_file(source.metadata_path)
    )
    job.ingest(load_config(config_path))
    session = DashboardSession(
        served.state.new_id(),
        served.state.evaluator,
        branch="debug",
        batch_id=job.batch_id,
        source=FileConfig([config_path]),
        metrics_set=NAV_SET,
        debug=True,
        refresh_data=job.refresh,
    )
    served.state.add(session, debug=True)
    return session, config_path


def _metric(state: dict, name: str) -> dict:
    return next(m for m in state["metrics"] if m["name"] == name)


def test_every_metric_of_the_set_renders_with_its_template(served, nav_jobs, tmp_path) -> None:
    session, config_path = _debug(served, nav_jobs, tmp_path, 0)
    state = api(served, "GET", f"sessions/{session.id}")
    config = load_config(config_path)
    assert [m["name"] for m in state["metrics"]] == config.metrics_sets[NAV_SET].metrics
    emissions = nav_jobs.jobs[0].emissions_path
    for metric in state["metrics"]:
        result = metric["result"]
        assert result["status"] == "PASSED", (metric["name"], result)
        assert metric["description"] == config.metrics[metric["name"]].description
        assert metric["query_string"] == config.metrics[metric["name"]].query_string

    speed = plain_figure(_metric(state, "Robot Speed")["result"]["figure"])
    odom = _rows(emissions, "odom_linear_velocity")
    assert len(speed["data"]) == 1 and len(speed["data"][0]["y"]) == len(odom)
    assert speed["data"][0]["y"][0] == pytest.approx((odom[0]["x"] ** 2 + odom[0]["y"] ** 2) ** 0.5)
    distance = _metric(state, "Distance to Goal")["result"]["figure"]
    goals = {row["goal_name"] for row in _rows(emissions, "goal_distance")}
    assert sorted(trace["name"] for trace in distance["data"]) == sorted(goals)

    total = sum(row["time_s"] for row in _rows(emissions, "time_to_goal"))
    scalar = _metric(state, "Time to reach final goal")
    assert float(scalar["result"]["text"].removesuffix(" s")) == pytest.approx(total, rel=1e-5)
    assert scalar["units"] == "s" and scalar["status"]["block"] == 3

    table = _metric(state, "AMCL Covariance Calibration")["result"]["table"]
    samples = _rows(emissions, "covariance_accuracy")
    assert table["columns"] == ["Metric", "Value"]
    assert table["rows"][0] == ["Total Samples", str(len(samples))]

    timeline = _metric(state, "Goal Status")["result"]["figure"]
    states = {row["state"] for row in _rows(emissions, "goal_status")}
    assert sorted(trace["name"] for trace in timeline["data"]) == sorted(states)
    histogram = plain_figure(_metric(state, "Speed Distribution")["result"]["figure"])
    assert len(histogram["data"][0]["x"]) == len(_rows(emissions, "robot_speed"))
    pie = _metric(state, "Job Outcomes")["result"]["figure"]["data"][0]
    assert pie["labels"] == ["PASSED"] and pie["values"] == [1]  # the session wrote its job's status first
    bar = _metric(state, "Maximum Localization Error")["result"]["figure"]["data"][0]
    assert bar["y"] == [pytest.approx(max(r["position_diff_m"] for r in _rows(emissions, "pose_difference")))]

    image = _metric(state, "Stereo Camera Feed")["result"]
    names = [row["filename"] for row in _rows(emissions, "camera_gif")]
    assert image["images"] == names
    status, _, raw = _request(served, "GET", f"api/sessions/{session.id}/logs/{state['job_id']}/{names[0]}")
    assert status == 200 and raw == (nav_jobs.jobs[0].logs_dir / names[0]).read_bytes()


def test_statuses_follow_the_data(served, nav_jobs, tmp_path) -> None:
    session, _ = _debug(served, nav_jobs, tmp_path, 2)  # the BLOCKER job: fewer than 3 goals reached
    state = api(served, "GET", f"sessions/{session.id}")
    assert len(_rows(nav_jobs.jobs[2].emissions_path, "time_to_goal")) < 3
    assert _metric(state, "Time to reach final goal")["result"]["status"] == "BLOCKER"
    assert state["jobs"][0]["conflated_status"] == "BLOCKER" and state["status"] == "BLOCKER"
    row = read_metadata_row(served.lake, "debug", session.batch_id, state["job_id"])
    assert row["job_conflated_status"] is None  # the session's statuses are never written


def test_edit_a_query_see_errors_with_position_and_revert(served, nav_jobs, tmp_path) -> None:
    session, _ = _debug(served, nav_jobs, tmp_path)
    name = urllib.parse.quote("Time to reach final goal")
    state = api(served, "PUT", f"sessions/{session.id}/metrics/{name}", {"query_string": "SELECT 12.5"})
    metric = _metric(state, "Time to reach final goal")
    assert metric["result"]["text"] == "12.5 s" and metric["origin"] == "edited" and metric["location"] is None
    assert state["config"]["edited"] == ["Time to reach final goal"]

    state = api(
        served,
        "PUT",
        f"sessions/{session.id}/metrics/{name}",
        {"query_string": "SELECT sum(time_s)\n  FROM time_to_goals"},
    )
    result = _metric(state, "Time to reach final goal")["result"]
    assert result["status"] == "ERROR"
    assert result["error"]["query"] == "query"
    assert (result["error"]["line"], result["error"]["column"]) == (2, 8)
    assert "time_to_goals" in result["error"]["message"]
    assert state["jobs"][0]["metrics_status"] == "ERROR"

    line = urllib.parse.quote("Robot Speed")
    state = api(served, "PUT", f"sessions/{session.id}/metrics/{line}", {"query_string": "SELECT 1, 2"})
    result = _metric(state, "Robot Speed")["result"]
    assert (
        result["status"] == "ERROR"
        and "line" in result["error"]["message"]
        and "3 columns" in result["error"]["message"]
    )

    state = api(served, "DELETE", f"sessions/{session.id}/metrics/{name}")
    metric = _metric(state, "Time to reach final goal")
    assert metric["origin"] == "config" and metric["result"]["status"] == "PASSED"
    assert metric["location"].endswith(":62:3")  # back to the config file's text and place
    api(served, "DELETE", f"sessions/{session.id}/metrics/{name}", expect=400)  # nothing left to revert


def test_add_metric_with_status_and_refusals(served, nav_jobs, tmp_path) -> None:
    session, _ = _debug(served, nav_jobs, tmp_path)
    goal_states = len(_rows(nav_jobs.jobs[0].emissions_path, "goal_status"))
    spec = {
        "name": "Goal status changes",
        "type": "test",
        "template": "scalar",
        "description": "How many",
        "units": "",
        "query_string": "SELECT COUNT(*) FROM goal_status",
        "status": {
            "query_string": "SELECT 1 FROM goal_status HAVING COUNT(*) > ?",
            "block": str(goal_states + 10),
            "warn": str(goal_states - 1),
        },
    }
    state = api(served, "POST", f"sessions/{session.id}/metrics", spec)
    added = _metric(state, "Goal status changes")
    assert state["metrics"][-1]["name"] == "Goal status changes"
    assert added["origin"] == "added" and added["result"]["text"] == str(goal_states)
    assert added["result"]["status"] == "WARNING"  # above warn, below block
    assert added["status"] == {
        "query_string": spec["status"]["query_string"],
        "block": goal_states + 10,
        "warn": goal_states - 1,
    }

    bad = api(
        served,
        "POST",
        f"sessions/{session.id}/metrics",
        {**spec, "name": "Other", "status": {**spec["status"], "query_string": "SELECT 1 FROM goal_status"}},
        expect=400,
    )
    assert "exactly one ?" in bad["detail"]["message"]
    duplicate = api(served, "POST", f"sessions/{session.id}/metrics", spec, expect=400)
    assert "already exists" in duplicate["detail"]["message"]
    bad_template = api(
        served, "POST", f"sessions/{session.id}/metrics", {**spec, "name": "T", "template": "donut"}, expect=400
    )
    assert "donut" in bad_template["detail"]["message"]
    assert [m["name"] for m in api(served, "GET", f"sessions/{session.id}")["metrics"]].count("Other") == 0


def test_export_loads_back_with_order_and_comments_kept(served, nav_jobs, tmp_path) -> None:
    session, config_path = _debug(served, nav_jobs, tmp_path)
    original = config_path.read_text()
    speed = 'SELECT \'Speed\', timestamp / 1E9 AS "Time (s)", x AS "Speed (m/s)"\nFROM odom_linear_velocity'
    api(served, "PUT", f"sessions/{session.id}/metrics/{urllib.parse.quote('Robot Speed')}", {"query_string": speed})
    api(
        served,
        "POST",
        f"sessions/{session.id}/metrics",
        {
            "name": "Event count",
            "type": "batch",
            "template": "scalar",
            "description": "Events",
            "query_string": "SELECT COUNT(*) FROM events",
        },
    )
    status, _, raw = _request(served, "GET", f"api/sessions/{session.id}/export")
    assert status == 200
    archive = zipfile.ZipFile(io.BytesIO(raw))
    assert archive.namelist() == ["config.resim.yaml", "templates/goal_times.liquid"]  # the custom template too
    exported = tmp_path / "exported" / "config.resim.yaml"
    exported.parent.mkdir()
    exported.write_bytes(archive.read("config.resim.yaml"))
    text = exported.read_text()

    config = load_config(exported)
    before = load_config(config_path)
    assert list(config.metrics) == [*before.metrics, "Event count"]
    assert config.metrics_sets[NAV_SET].metrics == [*before.metrics_sets[NAV_SET].metrics, "Event count"]
    assert config.metrics["Robot Speed"].query_string.strip() == speed
    assert config.metrics["Event count"].type == "batch"
    for name, metric in before.metrics.items():
        if name != "Robot Speed":
            assert config.metrics[name].query_string == metric.query_string
    assert text.splitlines()[:3] == original.splitlines()[:3]  # the leading comment
    unchanged = original.split("  Time to reach final goal:")[1].split("metrics sets:")[0]
    assert unchanged in text  # untouched metrics are byte for byte the same
    assert config_path.read_text() == original  # the file on disk is never written


def test_config_changes_on_disk_show_on_reload_with_session_edits_on_top(served, nav_jobs, tmp_path) -> None:
    session, config_path = _debug(served, nav_jobs, tmp_path)
    api(
        served,
        "PUT",
        f"sessions/{session.id}/metrics/{urllib.parse.quote('Average Speed')}",
        {"query_string": "SELECT 2.5"},
    )
    time.sleep(0.01)
    config_path.write_text(
        config_path.read_text()
        .replace("description: Share of jobs by conflated status.", "description: Shares.")
        .replace('    units: "m/s"\n', '    units: "km/h"\n')
    )
    state = api(served, "GET", f"sessions/{session.id}")
    assert _metric(state, "Job Outcomes")["description"] == "Shares."
    average = _metric(state, "Average Speed")
    assert average["origin"] == "edited" and average["result"]["text"] == "2.5 km/h"

    config_path.write_text(config_path.read_text().replace("version: 1", "version: [", 1))
    state = api(served, "GET", f"sessions/{session.id}")
    assert state["config"]["problems"] and "config.resim.yaml" in state["config"]["problems"][0]
    assert _metric(state, "Average Speed")["result"]["text"] == "2.5 km/h"  # the last good config stays


def test_data_explorer_tables_and_queries(served, nav_jobs, tmp_path) -> None:
    session, _ = _debug(served, nav_jobs, tmp_path, 1)
    job_id = api(served, "GET", f"sessions/{session.id}")["job_id"]
    counts = Counter(line["$metadata"]["topic"] for line in _emitted(nav_jobs.jobs[1].emissions_path))
    tables = {
        t["name"]: t for t in api(served, "GET", f"sessions/{session.id}/tables?scope=job&job={job_id}")["tables"]
    }
    for topic, count in counts.items():
        assert tables[topic]["rows"] == count, topic
    assert tables["metadata"]["rows"] == 1
    assert [c["name"] for c in tables["goal_distance"]["columns"]][:3] == ["timestamp", "goal_name", "distance_m"]
    branch_tables = {
        t["name"]: t["rows"] for t in api(served, "GET", f"sessions/{session.id}/tables?scope=branch")["tables"]
    }
    assert branch_tables["metadata"] >= 1

    odom, states = counts["odom_linear_velocity"], counts["goal_status"]
    assert odom * states > 1000
    answer = api(
        served,
        "POST",
        f"sessions/{session.id}/query",
        {
            "sql": "SELECT o.timestamp, s.state FROM odom_linear_velocity o CROSS JOIN goal_status s",
            "scope": "job",
            "job": job_id,
        },
    )
    assert answer["total"] == odom * states and len(answer["rows"]) == 1000
    assert answer["columns"] == [{"name": "timestamp", "type": "bigint"}, {"name": "state", "type": "varchar"}]
    answer = api(
        served,
        "POST",
        f"sessions/{session.id}/query",
        {"sql": "SELECT 7 / 2 AS q, typeof(7 / 2) AS t", "scope": "batch"},
    )
    assert answer["rows"] == [[3, "integer"]]  # Trino semantics: integer division
    error = api(
        served,
        "POST",
        f"sessions/{session.id}/query",
        {"sql": "SELECT *\nFROM odom\nWHERE x > 1", "scope": "job", "job": job_id},
    )["error"]
    assert (error["line"], error["column"]) == (2, 6) and "odom" in error["message"]
    api(served, "POST", f"sessions/{session.id}/query", {"sql": "SELECT 1", "scope": "job", "job": "nope"}, expect=400)


def test_events_in_time_order_with_their_metrics(served, nav_jobs, tmp_path) -> None:
    session, _ = _debug(served, nav_jobs, tmp_path, 0)
    job_id = api(served, "GET", f"sessions/{session.id}")["job_id"]
    events = api(served, "GET", f"sessions/{session.id}/events?job={job_id}")["events"]
    emitted = [
        line for line in _emitted(nav_jobs.jobs[0].emissions_path) if line["$metadata"]["topic"] == "goal_reached"
    ]
    assert [e["timestamp"] for e in events] == sorted(line["$metadata"]["timestamp"] for line in emitted)
    assert [e["name"] for e in events] == [
        line["$data"]["name"] for line in sorted(emitted, key=lambda line: line["$metadata"]["timestamp"])
    ]
    images = [m for m in events[0]["metrics"] if m["type"] == "image"]
    assert images and all(isinstance(m["value"], list) for m in images)
    status, _, _ = _request(served, "GET", f"api/sessions/{session.id}/logs/{job_id}/{images[0]['value'][0]}")
    assert status == 200


def test_batch_view_evaluates_then_shows_stored_results(served, nav_jobs) -> None:
    listing = api(served, "GET", "lake")
    main = next(b for b in listing["branches"] if b["name"] == BRANCH)
    assert main["batches"] == [{"id": BATCH, "jobs": sorted(j.job_id for j in nav_jobs.jobs)}]

    state = api(served, "POST", "sessions", {"branch": BRANCH, "batch": BATCH})
    assert not state["debug"] and state["origin"] == "evaluated" and state["metrics_set"] == NAV_SET
    by_job = {row["job_id"]: row for row in state["matrix"]["rows"]}
    assert [by_job[j.job_id]["conflated_status"] for j in nav_jobs.jobs] == ["PASSED", "WARNING", "BLOCKER"]
    assert state["matrix"]["metrics"] == [m["name"] for m in state["metrics"] if m["type"] == "test"]
    for job in nav_jobs.jobs:  # never written: the batch metrics see the session's statuses instead
        assert read_metadata_row(served.lake, BRANCH, BATCH, job.job_id)["job_conflated_status"] is None
    pie = _metric(state, "Job Outcomes")["result"]["figure"]["data"][0]
    assert dict(zip(pie["labels"], pie["values"])) == {"PASSED": 1, "WARNING": 1, "BLOCKER": 1}
    other = api(served, "GET", f"sessions/{state['id']}?job={nav_jobs.jobs[2].job_id}")
    assert other["job_id"] == nav_jobs.jobs[2].job_id
    assert _metric(other, "Time to reach final goal")["result"]["status"] == "BLOCKER"

    registry = BranchConfigs(served.lake, BRANCH)  # evaluate and store the batch, as `lakegate metrics run` does
    with MetricsEngine(served.lake) as engine:
        engine.evaluate_batch(
            BRANCH,
            BATCH,
            registry.current().metrics_in_set(NAV_SET),
            metrics_set=NAV_SET,
            config_version=registry.current_version(),
        )
    served.state.sessions.clear()
    stored = api(served, "POST", "sessions", {"branch": BRANCH, "batch": BATCH, "metrics_set": NAV_SET})
    assert stored["origin"] == "stored"
    assert [r["conflated_status"] for r in stored["matrix"]["rows"]] == [
        r["conflated_status"] for r in state["matrix"]["rows"]
    ]
    assert [_metric(stored, m["name"])["result"]["text"] for m in state["metrics"]] == [
        m["result"]["text"] for m in state["metrics"]
    ]

    api(served, "POST", "sessions", {"branch": BRANCH, "batch": "nope"}, expect=400)
    api(served, "POST", "sessions", {"branch": "nope", "batch": BATCH}, expect=400)


def test_refuses_unknown_sessions_and_files_outside_the_logs(served, nav_jobs, tmp_path) -> None:
    session, _ = _debug(served, nav_jobs, tmp_path)
    job_id = api(served, "GET", f"sessions/{session.id}")["job_id"]
    api(served, "GET", "sessions/nope", expect=404)
    for name in ("..%2F..%2Fmetadata.yaml", "%2Fetc%2Fpasswd", "missing.png"):
        status, _, _ = _request(served, "GET", f"api/sessions/{session.id}/logs/{job_id}/{name}")
        assert status == 404, name


def test_page_and_static_files(served) -> None:
    status, _, page = _request(served, "GET", "")
    assert status == 200 and b"Export Config" in page and b"static/plotly.min.js" in page
    for name, marker in (
        ("dashboard.js", b"makeEditor"),
        ("dashboard.css", b".metric"),
        ("plotly.min.js", b"plotly.js v"),
    ):
        status, _, body = _request(served, "GET", f"static/{name}")
        assert status == 200 and marker in body[: 2000 if name == "plotly.min.js" else None], name
    status, _, _ = _request(served, "GET", "static/../debug_session.py")
    assert status == 404


def test_scope_statuses_overlay_metadata_without_writing(served, nav_jobs) -> None:
    """The session's job statuses reach batch metrics through the scope (`Scope.statuses`): `metadata`
    keeps its columns and order, shows the given statuses for the listed jobs, its own for the others."""
    backend = served.state.engine.backend
    plain = backend.execute("SELECT * FROM metadata ORDER BY job_id", branch=BRANCH, scope=Scope(BATCH))
    first, second = sorted(j.job_id for j in nav_jobs.jobs)[:2]
    scope = Scope(BATCH, statuses=((first, "WARNING", "ERROR"),))
    overlaid = backend.execute("SELECT * FROM metadata ORDER BY job_id", branch=BRANCH, scope=scope)
    assert overlaid.columns == plain.columns
    names = [name for name, _ in plain.columns]
    rows = {row[names.index("job_id")]: dict(zip(names, row)) for row in overlaid.rows()}
    stored = {row[names.index("job_id")]: dict(zip(names, row)) for row in plain.rows()}
    assert (rows[first]["job_metrics_status"], rows[first]["job_conflated_status"]) == ("WARNING", "ERROR")
    assert rows[second] == stored[second]
    statuses = ("job_metrics_status", "job_conflated_status")
    assert {k: v for k, v in rows[first].items() if k not in statuses} == {
        k: v for k, v in stored[first].items() if k not in statuses
    }
    assert (
        read_metadata_row(served.lake, BRANCH, BATCH, first)["job_conflated_status"]
        == stored[first]["job_conflated_status"]
    )
