"""`lakegate metrics debug` as a real process: bad input refused in one line, the dashboard served,
config changes on disk picked up, the scratch lake removed on Ctrl+C."""

from __future__ import annotations

import io
import json
import re
import shutil
import signal
import urllib.error
import urllib.parse
import urllib.request
import zipfile
from pathlib import Path

import pyarrow.parquet as pq
import trino

from lakegate.lake import paths
from lakegate.lake.config import load_config

NAV_SET = "Nav Metrics"


def _one_line_error(result, *words: str) -> str:
    assert result.returncode == 1, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert lines[0].startswith("lakegate: ")
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


def _args(emissions: Path, config: Path, metrics_set: str = NAV_SET) -> list[str]:
    return [
        "metrics",
        "debug",
        "--no-browser",
        "--emissions-file",
        str(emissions),
        "--metrics-config-path",
        str(config),
        "--metrics-set",
        metrics_set,
    ]


def test_missing_emissions_file(tmp_path: Path, nav_jobs, run_lakegate) -> None:
    result = run_lakegate(_args(tmp_path / "nope.jsonl", nav_jobs.config), tmp_path)
    _one_line_error(result, "emissions file", "nope.jsonl", "does not exist")


def test_malformed_emissions_file(tmp_path: Path, nav_jobs, run_lakegate) -> None:
    lines = nav_jobs.jobs[0].emissions_path.read_text().splitlines()
    bad = tmp_path / "emissions.resim.jsonl"
    bad.write_text(
        "\n".join(
            lines[:3]
            + [
                '{"$metadata": {"topic": "odom_linear_velocity", "timestamp": 5}, '
                '"$data": {"x": "left", "y": 1.0, "z": 0.0}}',
                "not json",
            ]
            + lines[3:]
        )
        + "\n"
    )
    result = run_lakegate(_args(bad, nav_jobs.config), tmp_path)
    line = _one_line_error(result, "bad emissions file", f"{bad}:4:", "and 1 more bad line")
    assert "'x'" in line or "x:" in line or " x " in line  # names the bad field


def test_invalid_config(tmp_path: Path, nav_jobs, run_lakegate) -> None:
    config = tmp_path / "config.resim.yaml"
    config.write_text(nav_jobs.config.read_text().replace("    template: line\n", "    template: lines\n", 1))
    line_number = config.read_text().splitlines().index("    template: lines") + 1
    result = run_lakegate(_args(nav_jobs.jobs[0].emissions_path, config), tmp_path)
    _one_line_error(result, "invalid config", f"{config}:{line_number}:", "lines")


def test_unparsable_config(tmp_path: Path, nav_jobs, run_lakegate) -> None:
    config = tmp_path / "config.resim.yaml"
    config.write_text("version: 1\ntopics: [\n")
    result = run_lakegate(_args(nav_jobs.jobs[0].emissions_path, config), tmp_path)
    _one_line_error(result, "invalid config", str(config), "YAML")


def test_unknown_metrics_set(tmp_path: Path, nav_jobs, run_lakegate) -> None:
    result = run_lakegate(_args(nav_jobs.jobs[0].emissions_path, nav_jobs.config, "Nav Metrix"), tmp_path)
    _one_line_error(result, "'Nav Metrix'", "'Nav Metrics'")


def test_missing_config_file(tmp_path: Path, nav_jobs, run_lakegate) -> None:
    result = run_lakegate(_args(nav_jobs.jobs[0].emissions_path, tmp_path / "missing.resim.yaml"), tmp_path)
    _one_line_error(result, "config file", "missing.resim.yaml", "does not exist")


def _get(url: str) -> bytes:
    with urllib.request.urlopen(url, timeout=30) as response:
        assert response.status == 200
        return response.read()


def test_serves_the_dashboard_and_picks_up_config_changes(tmp_path: Path, nav_jobs, debug_processes) -> None:
    config = tmp_path / "config.resim.yaml"
    config.write_text(nav_jobs.config.read_text())
    shutil.copytree(nav_jobs.config.parent / "templates", tmp_path / "templates")  # its custom template
    job = nav_jobs.jobs[2]  # fewer than 3 goals reached: "Time to reach final goal" blocks
    server = debug_processes(
        ["--emissions-file", str(job.emissions_path), "--metrics-config-path", str(config), "--metrics-set", NAV_SET],
        tmp_path,
    )
    match = re.fullmatch(r"http://127\.0\.0\.1:(\d+)/dashboard/\?session=([\w-]+)", server.url)
    assert match, server.url
    scratch = Path(re.search(r"in a scratch lake (\S+)", "\n".join(server.lines)).group(1))
    assert scratch.is_dir()

    page = _get(server.url).decode()
    assert "static/dashboard.js" in page and "static/plotly.min.js" in page
    base = server.url.split("?")[0]
    plotly = _get(base + "static/plotly.min.js")
    assert len(plotly) > 1_000_000 and b"plotly" in plotly[:2000].lower()
    session = match.group(2)
    state = json.loads(_get(f"{base}api/sessions/{session}"))
    assert state["debug"] and state["metrics_set"] == NAV_SET
    statuses = {m["name"]: m["result"]["status"] for m in state["metrics"]}
    assert statuses["Time to reach final goal"] == "BLOCKER"
    assert state["jobs"][0]["conflated_status"] == "BLOCKER"
    assert state["jobs"][0]["experience_name"] == job.emissions_path.parent.name
    # the image metric finds its file in the logs folder beside the emissions file
    camera = next(m for m in state["metrics"] if m["template"] == "image")["result"]
    assert camera["images"] == ["camera.gif"]
    assert _get(f"{base}api/sessions/{session}/logs/{state['job_id']}/camera.gif").startswith(b"GIF8")

    # the same server answers SQL over the Trino protocol, on the debug branch
    with trino.dbapi.connect(
        host="127.0.0.1", port=int(match.group(1)), user="test", catalog="lake", schema="debug"
    ) as connection:
        cursor = connection.cursor()
        cursor.execute("SELECT count(*) FROM goal_status")
        emitted = [json.loads(line) for line in job.emissions_path.read_text().splitlines()]
        assert cursor.fetchall() == [[sum(1 for line in emitted if line["$metadata"]["topic"] == "goal_status")]]

    # a changed config file shows on the next load; the new topic means the emissions are ingested again
    text = config.read_text()
    text = text.replace("description: Robot speed over time", "description: Speed of the robot, changed on disk")
    text = text.replace("topics:\n", "topics:\n  battery:\n    schema:\n      level: float\n", 1)
    config.write_text(text)
    state = json.loads(_get(f"{base}api/sessions/{session}"))
    robot = next(m for m in state["metrics"] if m["name"] == "Robot Speed")
    assert robot["description"] == "Speed of the robot, changed on disk"
    tables = json.loads(_get(f"{base}api/sessions/{session}/tables?scope=job&job={state['job_id']}"))["tables"]
    assert {"name": "battery", "rows": 0} == {
        k: v for k, v in next(t for t in tables if t["name"] == "battery").items() if k in ("name", "rows")
    }

    assert server.stop() == 0
    assert not scratch.exists(), "the scratch lake is removed on exit"


def test_given_lake_is_kept(tmp_path: Path, nav_jobs, debug_processes) -> None:
    lake = tmp_path / "lake"
    server = debug_processes(
        [
            "--emissions-file",
            str(nav_jobs.jobs[0].emissions_path),
            "--metrics-config-path",
            str(nav_jobs.config),
            "--metrics-set",
            NAV_SET,
            "--lake",
            str(lake),
            "--branch",
            "feature/dbg",
        ],
        tmp_path,
    )
    assert server.stop() == 0
    metadata = list(paths.data_files(lake, "feature/dbg", paths.METADATA_TABLE))
    assert len(metadata) == 1
    row = pq.read_table(metadata[0]).to_pylist()[0]
    assert row["experience_name"] and row["job_conflated_status"] is None  # the page never writes statuses


def test_refuses_to_listen_beyond_this_machine(tmp_path: Path, nav_jobs, run_lakegate) -> None:
    result = run_lakegate(_args(nav_jobs.jobs[0].emissions_path, nav_jobs.config) + ["--host", "0.0.0.0"], tmp_path)
    _one_line_error(result, "refusing", "0.0.0.0", "127.0.0.1")


def test_help_lists_every_option(tmp_path: Path, run_lakegate) -> None:
    result = run_lakegate(["metrics", "debug", "--help"], tmp_path)
    assert result.returncode == 0
    for option in (
        "--emissions-file",
        "--metrics-config-path",
        "--metrics-set",
        "--port",
        "--lake",
        "--host",
        "--no-browser",
        "--logs-dir",
        "--metadata",
        "--all-metrics",
    ):
        assert option in result.stdout


def _status(url: str, method: str = "GET", headers: dict[str, str] | None = None, body: bytes | None = None) -> int:
    request = urllib.request.Request(url, data=body, method=method, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status
    except urllib.error.HTTPError as error:
        return error.code


def test_without_a_logs_folder_only_the_referenced_files_are_served(tmp_path: Path, nav_jobs, debug_processes) -> None:
    """With no `logs/` beside the emissions file, the job's logs are only the files
    the emissions name in image fields (a key next to it is never served); NUL in a name is a 404."""
    job = nav_jobs.jobs[0]
    folder = tmp_path / "run"
    folder.mkdir()
    shutil.copy(job.emissions_path, folder / "emissions.resim.jsonl")
    for image in job.logs_dir.iterdir():
        shutil.copy(image, folder / image.name)
    (folder / ".ssh").mkdir()
    (folder / ".ssh" / "id_rsa").write_text("-----BEGIN OPENSSH PRIVATE KEY-----\n")
    (folder / "notes.txt").write_text("private")
    server = debug_processes(
        [
            "--emissions-file",
            str(folder / "emissions.resim.jsonl"),
            "--metrics-config-path",
            str(nav_jobs.config),
            "--metrics-set",
            NAV_SET,
        ],
        tmp_path,
    )
    base, session = server.url.split("?session=")
    base = base.rstrip("/") + "/"
    state = json.loads(_get(f"{base}api/sessions/{session}"))
    logs = f"{base}api/sessions/{session}/logs/{state['job_id']}/"
    camera = next(m for m in state["metrics"] if m["template"] == "image")["result"]
    assert camera["images"] == ["camera.gif"] and _get(logs + "camera.gif").startswith(b"GIF8")
    for name in (".ssh/id_rsa", ".ssh%2Fid_rsa", "notes.txt", "emissions.resim.jsonl", "camera.gif%00.png", "%00"):
        assert _status(logs + name) == 404, name
    assert _status(f"{base}api/sessions/{session}/logs/j%00b/camera.gif") in (400, 404)
    listing = _get(f"{base}api/lake").decode()
    assert session not in listing and state["batch_id"] in listing  # the session id is only in the printed URL
    request = urllib.request.Request(
        f"{base}api/sessions",
        method="POST",
        headers={"Content-Type": "application/json"},
        data=json.dumps({"branch": "debug", "batch": state["batch_id"]}).encode(),
    )
    try:
        urllib.request.urlopen(request, timeout=30)
        raise AssertionError("the debug batch was opened without its session id")
    except urllib.error.HTTPError as error:
        assert error.code == 400 and session not in error.read().decode()
    assert server.stop() == 0


def test_host_and_origin_are_checked(tmp_path: Path, nav_jobs, debug_processes) -> None:
    """DNS rebinding (a foreign Host) gets 421, a cross-site POST (foreign Origin) 403;
    loopback names, the same origin and the trino client (Host 127.0.0.1:PORT) work."""
    server = debug_processes(
        [
            "--emissions-file",
            str(nav_jobs.jobs[0].emissions_path),
            "--metrics-config-path",
            str(nav_jobs.config),
            "--metrics-set",
            NAV_SET,
        ],
        tmp_path,
    )
    base, session = server.url.split("?session=")
    port = int(re.search(r":(\d+)/", base).group(1))
    api = f"{base}api/sessions/{session}"
    assert _status(api, headers={"Host": f"rebound.example.com:{port}"}) == 421
    assert _status(api, headers={"Host": f"127.0.0.1:{port + 1}"}) == 421
    assert _status(api, headers={"Host": f"localhost:{port}"}) == 200
    evaluate = (f"{api}/evaluate", "POST")
    assert _status(*evaluate, headers={"Origin": "http://evil.example.com"}) == 403
    assert _status(*evaluate, headers={"Origin": "null"}) == 403
    assert _status(*evaluate, headers={"Origin": f"http://localhost:{port}"}) == 200
    assert _status(*evaluate) == 200  # no Origin: not a browser's cross-site request
    with trino.dbapi.connect(host="127.0.0.1", port=port, user="test", catalog="lake", schema="debug") as connection:
        cursor = connection.cursor()
        cursor.execute("SELECT 1")
        assert cursor.fetchall() == [[1]]
    assert server.stop() == 0


CUSTOM_METRIC = """\
  Custom View:
    type: test
    description: A custom template.
    query_string: SELECT 1
    template_type: custom
    template_file: {template}
"""


def _with_custom_metric(text: str, template: str) -> str:
    text = text.replace("metrics:\n", "metrics:\n" + CUSTOM_METRIC.format(template=template), 1)
    return text.replace("      - Robot Speed\n", "      - Robot Speed\n      - Custom View\n", 1)


def test_export_keeps_to_the_config_folder(tmp_path: Path, nav_jobs, debug_processes) -> None:
    """A template_file outside the config's folder is never exported (a clear 400
    naming the metric and where it is), one inside it is; the download's file name is escaped."""
    folder = tmp_path / "config"
    (folder / "templates").mkdir(parents=True)
    (folder / "templates" / "view.liquid").write_text("{{ value }}")
    config = folder / 'we"ird é.resim.yaml'
    config.write_text(_with_custom_metric(nav_jobs.config.read_text(), "../../../../../../../../etc/passwd"))
    server = debug_processes(
        [
            "--emissions-file",
            str(nav_jobs.jobs[0].emissions_path),
            "--metrics-config-path",
            str(config),
            "--metrics-set",
            NAV_SET,
        ],
        tmp_path,
    )
    base, session = server.url.split("?session=")
    export = f"{base}api/sessions/{session}/export"
    try:
        urllib.request.urlopen(export, timeout=30)
        raise AssertionError("a template file outside the config's folder was exported")
    except urllib.error.HTTPError as error:
        assert error.code == 400
        message = json.loads(error.read())["detail"]["message"]
    line = config.read_text().splitlines().index("  Custom View:") + 1
    assert (
        "'Custom View'" in message and f"{config.name}:{line}:" in message and "outside the config's folder" in message
    )
    assert str(tmp_path) not in message

    config.write_text(_with_custom_metric(nav_jobs.config.read_text(), "templates/view.liquid"))
    _get(f"{base}api/sessions/{session}")  # reloading the page picks up the changed file
    with urllib.request.urlopen(export, timeout=30) as response:
        disposition = response.headers["Content-Disposition"]
        archive = zipfile.ZipFile(io.BytesIO(response.read()))
    assert disposition == "attachment; filename=\"we_ird__-export.zip\"; filename*=UTF-8''we%22ird%20%C3%A9-export.zip"
    assert sorted(archive.namelist()) == sorted([config.name, "templates/view.liquid"])
    config.write_text(_with_custom_metric(nav_jobs.config.read_text(), "view.liquid"))  # found in templates/
    _get(f"{base}api/sessions/{session}")
    with urllib.request.urlopen(export, timeout=30) as response:
        archive = zipfile.ZipFile(io.BytesIO(response.read()))
    assert sorted(archive.namelist()) == sorted([config.name, "templates/view.liquid"])

    assert server.stop() == 0


def test_exported_edits_load_back_with_the_same_values(tmp_path: Path, nav_jobs, debug_processes) -> None:
    """The page edits YAML with ruamel (YAML 1.2) and the loader reads YAML 1.2 with the same library:
    units "on" stays a string (YAML 1.1 reads a boolean) and "1:30" stays a string (YAML 1.1: 90).
    Thresholds are numbers (a quoted one is refused, as SignalFlag's validator refuses it)."""
    config = tmp_path / "config.resim.yaml"
    config.write_text(nav_jobs.config.read_text())
    server = debug_processes(
        [
            "--emissions-file",
            str(nav_jobs.jobs[0].emissions_path),
            "--metrics-config-path",
            str(config),
            "--metrics-set",
            NAV_SET,
        ],
        tmp_path,
    )
    base, session = server.url.split("?session=")
    name = "Time to reach final goal"

    def edited(edit: dict) -> dict:
        request = urllib.request.Request(
            f"{base}api/sessions/{session}/metrics/{urllib.parse.quote(name)}",
            data=json.dumps(edit).encode(),
            method="PUT",
            headers={"Content-Type": "application/json"},
        )
        with urllib.request.urlopen(request, timeout=60) as response:
            return next(m for m in json.loads(response.read())["metrics"] if m["name"] == name)

    metric = edited({"units": "on", "status": {"query_string": "SELECT 1 WHERE ? < 0", "block": 90, "warn": 1.5}})
    assert metric["units"] == "on" and metric["status"]["block"] == 90
    with zipfile.ZipFile(io.BytesIO(_get(f"{base}api/sessions/{session}/export"))) as archive:
        exported = tmp_path / "exported" / config.name
        exported.parent.mkdir()
        exported.write_bytes(archive.read(config.name))
    loaded = load_config([exported]).metrics[name]
    assert (loaded.units, loaded.status.block, loaded.status.warn) == ("on", 90, 1.5)
    assert edited({"units": "1:30"})["units"] == "1:30"
    assert server.stop() == 0


def test_sigterm_stops_the_dashboard_cleanly(tmp_path: Path, nav_jobs, debug_processes) -> None:
    """SIGTERM (and Ctrl+C) once the URL is printed only asks the server to stop (no KeyboardInterrupt
    raised into whatever runs, e.g. an import or the event loop): exit 0, no traceback, scratch removed."""
    for used in (False, True):
        server = debug_processes(
            [
                "--emissions-file",
                str(nav_jobs.jobs[0].emissions_path),
                "--metrics-config-path",
                str(nav_jobs.config),
                "--metrics-set",
                NAV_SET,
            ],
            tmp_path,
        )
        scratch = Path(re.search(r"in a scratch lake (\S+)", "\n".join(server.lines)).group(1))
        if used:  # requests leave worker threads behind, which must not keep the process alive
            _get(server.url.replace("/dashboard/?session=", "/dashboard/api/sessions/"))
        server.process.send_signal(signal.SIGTERM)
        assert server.process.wait(timeout=60) == 0
        assert not any("Traceback" in line or "Error" in line for line in server.lines), server.lines
        assert not scratch.exists()
