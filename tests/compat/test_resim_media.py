"""A field robot's config in ReSim's style runs as is: event metrics with a `unit` key, video and
artifact templates over the job's logs, `unit` for `units`, an unknown key (a warning, refused by
--strict); and `skip_if_no_data` and units work for every template kind. Real CLI subprocesses."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import pytest

from lakegate.gateway.metrics.templates import format_number
from lakegate.lake import paths
from tests.compat.test_resim_configs import CONFIGS, lakegate

CONFIG = CONFIGS / "field_robot.resim.yaml"
MP4 = b"\x00\x00\x00\x18ftypmp42\x00\x00\x00\x00mp42isom" + bytes(100)  # an ISO media file's first box
WEBM = b"\x1a\x45\xdf\xa3\x9f\x42\x86\x81\x01" + bytes(50)  # an EBML header
LOGS = {"front.mp4": MP4, "rear.webm": WEBM, "run/nav.log": b"nav ok\n" * 300, "run/planner.log": b"plan\n"}
# drive rows: (speed, clip, log_file); two clips are not in the logs
DRIVE = [
    (0.5, "front.mp4", "run/nav.log"),
    (1.25, "", "run/nav.log"),
    (2.0, "rear.webm", "run/planner.log"),
    (1.0, "lost_1.mp4", "run/nav.log"),
    (0.75, "lost_2.mp4", "run/planner.log"),
]
GOAL_METRICS = [
    {"name": "Time to goal", "type": "scalar", "value": 12.5, "unit": "s"},
    {"name": "Path length", "type": "scalar", "value": 30.25, "unit": "m", "source": "odometry"},
    {"name": "Verdict", "type": "text", "value": "reached"},
]


def emissions(path: Path) -> Path:
    lines = [
        {"$metadata": {"topic": "drive", "timestamp": i}, "$data": {"speed": s, "clip": c, "log_file": f}}
        for i, (s, c, f) in enumerate(DRIVE)
    ]
    lines.append(
        {
            "$metadata": {"topic": "goal_reached", "timestamp": 9, "event": True},
            "$data": {"name": "Goal 1", "status": "PASSED", "metrics": GOAL_METRICS},
        }
    )
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


@pytest.fixture(scope="module")
def lake(tmp_path_factory):
    root = tmp_path_factory.mktemp("media")
    lake = root / "lake"
    ingested = lakegate(
        "ingest", "--lake", lake, "--branch", "main", "--batch", "b1", "--job", "j1",
        "--metrics-config-path", CONFIG, "--no-progress", emissions(root / "j1.jsonl"),
    )  # fmt: skip
    assert f"{CONFIG}:27:5: warning: unknown key 'owner' in metric 'Camera Replay': ignored" in ingested.stderr
    logs = paths.logs_dir(lake, "main", "b1", "j1")
    for name, data in LOGS.items():
        (logs / name).parent.mkdir(parents=True, exist_ok=True)
        (logs / name).write_bytes(data)
    return lake


def run(lake: Path, *config_args, report: Path | None = None, check=True):
    args = ["metrics", "run", "--lake", lake, "--branch", "main", "--batch", "b1", "--format", "json"]
    args += [*config_args, "--no-progress"] + (["--report", report] if report else [])
    return lakegate(*args, check=check)


def test_the_field_config_runs_as_is_with_videos_artifacts_and_event_units(lake, tmp_path):
    report = tmp_path / "report.html"
    result = run(lake, "--metrics-config-path", CONFIG, "--metrics-set", "Field", report=report)
    by = {m["metric"]: m for m in json.loads(result.stdout)["metrics"]}
    missing = [clip for _, clip, _ in DRIVE if clip.startswith("lost")]
    replay = by["Camera Replay"]
    assert (replay["status"], replay["value"]) == ("PASSED", f"2 videos, {len(missing)} problems")
    [problem] = replay["problems"]  # one line for every missing clip, with the count
    assert problem.startswith(f"{len(missing)} files: missing from the job's logs") and "lost_1.mp4" in problem
    assert (by["Run Logs"]["status"], by["Run Logs"]["value"]) == ("PASSED", "2 files")
    assert (by["Top Speed"]["scalar_value"], by["Top Speed"]["units"]) == (max(s for s, _, _ in DRIVE), "m/s")
    assert by["Goal Times"]["status"] == "PASSED"

    page = report.read_text()
    players = re.findall(r'<video controls preload="metadata" src="data:(video/[a-z0-9]+);base64,([^"]+)"', page)
    assert [(mime, base64.b64decode(data)) for mime, data in players] == [("video/mp4", MP4), ("video/webm", WEBM)]
    links = re.findall(r'<a href="data:application/octet-stream;base64,([^"]+)" download="([^"]+)">', page)
    assert [(base64.b64decode(data), name) for data, name in links] == [
        (LOGS["run/nav.log"], "nav.log"),
        (LOGS["run/planner.log"], "planner.log"),
    ]
    assert "<td>2.1 KiB</td>" in page and "<td>5 B</td>" in page  # 2100 and 5 bytes
    # the event metrics' unit keys, read back by SQL from the `extra` JSON of each metric object
    rows = sorted((m["name"], str(m["value"]), m.get("unit")) for m in GOAL_METRICS)
    for name, value, unit in rows:
        assert f"<td>{name}</td><td>{value}</td><td>{'NULL' if unit is None else unit}</td>" in page


def test_strict_refuses_the_unknown_key_that_resim_accepts(lake):
    result = run(lake, "--metrics-config-path", CONFIG, "--metrics-set", "Field", "--strict", check=False)
    assert result.returncode != 0 and result.stdout == ""
    assert "unknown key 'owner' in metric 'Camera Replay' (ReSim accepts this; refused because of --strict)" in (
        result.stderr
    )


#: One query per template kind with the columns its template needs; each returns no rows.
SHAPES = {
    "line": "SELECT 'a', timestamp, speed",
    "bar": "SELECT 'a', log_file, speed",
    "table": "SELECT speed",
    "scalar": "SELECT speed",
    "image": "SELECT clip",
    "state_timeline": "SELECT 'a', timestamp, log_file",
    "histogram": "SELECT speed",
    "pie": "SELECT log_file, speed",
    "video": "SELECT clip",
    "artifact": "SELECT log_file",
    "custom": "SELECT timestamp, speed",
}
LIQUID = '{"data": [{"type": "scatter", "x": {{ timestamp | json }}, "y": {{ speed | json }}}], "layout": {}}'


def kinds_config(folder: Path, where: str, skip: bool) -> Path:
    """A config with the field topics and one metric per template kind, each with `unit`."""
    (folder / "xy.liquid").write_text(LIQUID)
    topics = CONFIG.read_text().split("\nmetrics:\n")[0]
    metrics = []
    for kind, select in SHAPES.items():
        template = "template_type: custom, template_file: xy.liquid" if kind == "custom" else f"template: {kind}"
        skipping = ", skip_if_no_data: true" if skip else ""
        metrics.append(
            f'  K {kind}: {{type: test, query_string: "{select} FROM drive {where}", '
            f"{template}, unit: u{kind}{skipping}}}"
        )
    path = folder / "kinds.resim.yaml"
    path.write_text(topics + "\nmetrics:\n" + "\n".join(metrics) + "\n")
    return path


def test_skip_if_no_data_and_units_for_every_template_kind(lake, tmp_path):
    skipping = kinds_config(tmp_path, "WHERE speed < 0", skip=True)
    result = run(lake, "--metrics-config-path", skipping, "--all-metrics")
    by = {m["metric"]: m for m in json.loads(result.stdout)["metrics"]}
    assert {name: m["status"] for name, m in by.items()} == {f"K {kind}": "NOT_RUN" for kind in SHAPES}
    assert all("skip_if_no_data" in m["error"]["message"] for m in by.values())

    (tmp_path / "with_data").mkdir()
    showing = kinds_config(tmp_path / "with_data", "WHERE speed > 0 ORDER BY speed DESC", skip=True)
    report = tmp_path / "kinds.html"
    result = run(lake, "--metrics-config-path", showing, "--all-metrics", report=report)
    by = {m["metric"]: m for m in json.loads(result.stdout)["metrics"]}
    assert {name: m["status"] for name, m in by.items()} == {f"K {kind}": "PASSED" for kind in SHAPES}
    assert {name: m["units"] for name, m in by.items()} == {f"K {kind}": f"u{kind}" for kind in SHAPES}
    page = report.read_text()
    assert f"{format_number(max(s for s, _, _ in DRIVE))} uscalar" in page  # after the scalar's value
    for kind in SHAPES.keys() - {"scalar"}:  # beside every other kind
        assert f'<p class="lg-meta">Units: u{kind}</p>' in page, kind
