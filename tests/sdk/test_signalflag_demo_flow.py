"""SignalFlag's own SDK demo flow (`signalflag/demo/run.py` of signalflag 1.8.0), adapted to a local lake.

The demo reads a data bundle (`manifest.json`: batches "a" and "b", each with a name, a version and
jobs; a job has a directory, an emissions file and artifacts), then for each side opens a `Batch`
with the demo's config and templates, replays every job into a `Test` through the typed emit methods
(events through `emit_event`), attaches its artifacts, closes every test in a `finally`, and leaves the
batch; the config's `dashboards:` entry trends the two builds. Here the bundle is generated (the real
one is downloaded from S3), the client and project are gone, and `lake=` names the lake. The config
is written for this test in the style of the demo's (system templates, a status check, an image, a
custom template, a dashboard), not copied from it.
"""

from __future__ import annotations

import base64
import json
import subprocess
import sys
import textwrap
from pathlib import Path

from lakegate.gateway.metrics.results_table import read_results
from lakegate.lake.record import job_logs_dir
from lakegate.sdk import Batch, Test

PNG = base64.b64decode(
    "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg=="
)
CONFIG = """
version: 1
topics:
  odom_linear_velocity:
    schema: {x: float, y: float, z: float}
  time_to_goal:
    schema: {goal_name: string, time_s: float}
  goal_count:
    schema: {count: int}
  camera_frame:
    schema: {camera_name: string, filename: image}
  goal_reached:
    event: true
    schema: {name: string, description: string, status: status, tags: "string[]"}
metrics:
  Robot Speed:
    type: test
    query_string: |
      SELECT 'Speed' AS group_name, timestamp / 1E9 AS "Time (s)", SQRT(POWER(x, 2) + POWER(y, 2)) AS "Speed (m/s)"
      FROM odom_linear_velocity
    template_type: system
    template: line
    template_settings:
      xaxis: {label: Session time (s)}
      yaxis: {label: Speed (m/s), min: 0}
      series:
        - {group_name: Speed, color: "#AE84DE"}
      legend: {show: false}
  Speed Distribution:
    type: test
    query_string: SELECT SQRT(POWER(x, 2) + POWER(y, 2)) AS "Speed (m/s)" FROM odom_linear_velocity
    template_type: system
    template: histogram
    template_settings:
      display: {bins: 7}
  Goals Missed:
    type: test
    query_string: SELECT MAX(count) - (SELECT COUNT(*) FROM time_to_goal) FROM goal_count
    status:
      query_string: SELECT 1 FROM goal_count WHERE count - (SELECT COUNT(*) FROM time_to_goal) >= ?
      block: 1
    template_type: system
    template: scalar
  Camera Frame:
    type: test
    query_string: SELECT filename FROM camera_frame
    skip_if_no_data: true
    template_type: system
    template: image
  Time by Experience:
    type: batch
    query_string: |
      SELECT 'Total' AS group_name, m.experience_name, SUM(t.time_s)
      FROM time_to_goal t JOIN metadata m ON t.job_id = m.job_id GROUP BY 2 ORDER BY 2
    template_type: custom
    template_file: bars.liquid
  Outcomes by Build Version:
    type: dashboard
    query_string: |
      SELECT job_conflated_status, build_version, COUNT(*) FROM metadata GROUP BY 1, 2 ORDER BY 2, 1
    template_type: system
    template: table
metrics sets:
  Demo Metrics:
    metrics: [Robot Speed, Speed Distribution, Goals Missed, Camera Frame, Time by Experience]
  Demo Trends:
    metrics: [Outcomes by Build Version]
dashboards:
  SDK Demo Trends:
    metrics_set: Demo Trends
    refresh: auto
    day_range: 30
"""
BARS = '{"data": [{"type": "bar", "x": {{ experience_name | json }}, "y": {{ _col2 | json }}}], "layout": {}}\n'


def make_bundle(root: Path) -> dict:
    """A bundle in the demo's layout: two sides of two builds; one job per side misses a goal."""
    manifest: dict = {"batches": {}}
    for side, version in (("a", "1.0.0"), ("b", "1.1.0")):
        jobs = []
        for index, experience in enumerate(("Lobby", "Ward 3")):
            directory = f"{side}/{index}"
            folder = root / directory
            folder.mkdir(parents=True)
            reached = 2 if (side, index) != ("a", 1) else 1
            lines = [("goal_count", {"count": 2}, 0, False)]
            lines += [("odom_linear_velocity", {"x": 0.1 * t, "y": 0.0, "z": 0.0}, t * 10**9, False) for t in range(5)]
            for goal in range(reached):
                lines.append(
                    ("time_to_goal", {"goal_name": f"g{goal}", "time_s": 10.0 + goal}, (goal + 1) * 10**9, False)
                )
                event = {"name": f"g{goal}", "description": "reached", "status": "PASSED", "tags": ["nav"]}
                lines.append(("goal_reached", event, (goal + 1) * 10**9, True))
            lines.append(("camera_frame", {"camera_name": "front", "filename": "front.png"}, 0, False))
            (folder / "emissions.resim.jsonl").write_text(
                "".join(
                    json.dumps(
                        {"$metadata": {"topic": t, "timestamp": ts, **({"event": True} if e else {})}, "$data": d}
                    )
                    + "\n"
                    for t, d, ts, e in lines
                )
            )
            (folder / "front.png").write_bytes(PNG)
            (folder / "run.log").write_text("navigation log\n")
            jobs.append(
                {
                    "directory": directory,
                    "experience_name": experience,
                    "emissions": "emissions.resim.jsonl",
                    "artifacts": [
                        {"file": "front.png", "log_type": None},
                        {"file": "run.log", "log_type": "SYSTEM_LOG"},
                    ],
                }
            )
        manifest["batches"][side] = {"name": f"SDK Demo {side.upper()}", "version": version, "jobs": jobs}
    (root / "manifest.json").write_text(json.dumps(manifest))
    return manifest


def replay_job(batch: Batch, root: Path, job: dict) -> Test:
    """The demo's `replay_job`: emissions through the typed methods, artifacts as logs; not closed."""
    job_dir = root / job["directory"]
    test = Test(batch, job["experience_name"])
    for artifact in job["artifacts"]:
        test.attach_log(str(job_dir / artifact["file"]), artifact["log_type"])
    for line in (job_dir / job["emissions"]).read_text().splitlines():
        record = json.loads(line)
        metadata = record["$metadata"]
        if metadata.get("event"):
            test.emit_event(metadata["topic"], record["$data"], metadata["timestamp"])
        else:
            test.emit(metadata["topic"], record["$data"], metadata["timestamp"])
    return test


def test_signalflag_demo_flow_on_a_local_lake(tmp_path):
    data = tmp_path / "bundle"
    manifest = make_bundle(data)
    config = tmp_path / "demo" / "config.resim.yml"
    config.parent.mkdir()
    config.write_text(textwrap.dedent(CONFIG).lstrip())
    (tmp_path / "demo" / "templates").mkdir()
    (tmp_path / "demo" / "templates" / "bars.liquid").write_text(BARS)
    lake = tmp_path / "lake"

    batches = {}
    for side in ("a", "b"):
        details = manifest["batches"][side]
        with Batch(
            branch="sdk-demo",
            name=details["name"],
            version=details["version"],
            metrics_set_name="Demo Metrics",
            metrics_config_path=str(config),
            templates_path=str(tmp_path / "demo" / "templates"),
            lake=lake,
        ) as batch:
            tests = []
            try:
                for job in details["jobs"]:
                    tests.append(replay_job(batch, data, job))
            finally:
                for test in tests:
                    test.close()
        batches[side] = batch

    assert batches["a"].test_statuses == {"Lobby": "PASSED", "Ward 3": "BLOCKER"}
    assert batches["b"].test_statuses == {"Lobby": "PASSED", "Ward 3": "PASSED"}
    for side, batch in batches.items():
        rows = read_results(lake, "sdk-demo", batch.id)
        assert {r["metric_name"]: r["status"] for r in rows if r["job_id"] is None} == {"Time by Experience": "PASSED"}
        frames = [r for r in rows if r["metric_name"] == "Camera Frame"]
        assert [r["status"] for r in frames] == ["PASSED", "PASSED"], side
        speed = next(r for r in rows if r["metric_name"] == "Robot Speed")  # template_settings honoured
        figure, details = json.loads(speed["figure_json"]), json.loads(speed["details_json"])
        assert figure["layout"]["xaxis"]["title"]["text"] == "Session time (s)"
        assert (figure["layout"]["yaxis"]["title"]["text"], figure["layout"]["yaxis"]["range"]) == (
            "Speed (m/s)",
            [0, None],
        )
        assert figure["data"][0]["line"]["color"] == "#AE84DE"
        assert "template_settings not used by lakegate: legend" in details["problems"]
        histogram = next(r for r in rows if r["metric_name"] == "Speed Distribution")
        assert json.loads(histogram["figure_json"])["data"][0]["nbinsx"] == 7
        for job_id in batch.job_statuses:
            logs = job_logs_dir(lake, "sdk-demo", batch.id, job_id)
            assert sorted(p.name for p in logs.iterdir()) == ["front.png", "run.log"]
    events = subprocess.run(
        [sys.executable, "-m", "lakegate.gateway.cli", "query", "--lake", lake, "--branch", "sdk-demo",
         "--format", "json", "SELECT count(*) FROM events"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert events.returncode == 0, events.stderr
    assert json.loads(events.stdout)["rows"] == [[7]]  # 2 + 1 goals in batch A, 2 + 2 in batch B

    trends = subprocess.run(
        [sys.executable, "-m", "lakegate.gateway.cli", "metrics", "dashboard", "--lake", lake, "--branch",
         "sdk-demo", "--name", "SDK Demo Trends", "--format", "json"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert trends.returncode == 0, trends.stderr
    table = json.loads(trends.stdout)["metrics"][0]["table"]
    assert table["rows"] == [["BLOCKER", "1.0.0", 1], ["PASSED", "1.0.0", 1], ["PASSED", "1.1.0", 2]]
