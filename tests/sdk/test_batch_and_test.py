"""`lakegate.sdk.Batch` / `Test` on real lakes, against the CLI run as real subprocesses on the same files."""

from __future__ import annotations

import base64
import json
import multiprocessing
import os
import subprocess
import sys
import textwrap
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from lakegate.gateway.metrics.results_table import read_results
from lakegate.lake.config import ConfigError
from lakegate.lake.metadata import read_metadata_row
from lakegate.lake.record import job_logs_dir
from lakegate.sdk import Batch, FailedStatesError, Test
from tests.gateway.conftest import serve

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
#: A 1x1 PNG.
PNG = base64.b64decode(
    "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg=="
)


def lakegate(*args, cwd=None):
    return subprocess.run(
        [*CLI, *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        env={**os.environ, "COLUMNS": "200"},
        timeout=120,
    )


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text).lstrip())
    return path


def three_files(root: Path) -> Path:
    """A config split as SignalFlag users split it: topics, metrics (with a per-file global) and sets,
    plus a template folder outside the config folder. Returns the config folder."""
    folder = root / "metrics"
    write(
        folder / "10-topics.resim.yml",
        """
        version: 1
        topics:
          speed:
            schema: {v: float}
          frame:
            schema: {filename: image}
          goal_reached:
            event: true
            schema: {name: string, description: string, status: status, tags: "string[]"}
        """,
    )
    write(
        folder / "20-metrics.resim.yml",
        """
        version: 1
        global:
          skip-if-no-data: true
        metrics:
          Max Speed:
            type: test
            query_string: SELECT max(v) FROM speed
            template: scalar
            status:
              query_string: SELECT 1 FROM speed WHERE v > ?
              block: 3
              warn: 2
          Camera Frame:
            type: test
            query_string: SELECT filename FROM frame
            template: image
          Jobs Seen:
            type: batch
            query_string: SELECT experience_name AS x FROM metadata ORDER BY 1
            template_type: custom
            template_file: names.liquid
          Tests by Build:
            type: dashboard
            query_string: SELECT build_version, count(*) FROM metadata GROUP BY 1 ORDER BY 1
            template: table
        """,
    )
    write(
        folder / "30-sets.resim.yml",
        """
        version: 1
        metrics sets:
          Nav:
            metrics: [Max Speed, Camera Frame, Jobs Seen]
          Trends:
            metrics: [Tests by Build]
        dashboards:
          Nav Trends:
            metrics_set: Trends
            refresh: auto
            day_range: 30
        """,
    )
    write(
        root / "templates" / "names.liquid",
        '{"data": [{"type": "bar", "x": {{ x | json }}, "y": [{% for n in x %}1{% unless forloop.last %},'
        '{% endunless %}{% endfor %}]}], "layout": {}}\n',
    )
    return folder


#: name -> speeds, and whether it has a camera frame (PASSED, WARNING, BLOCKER by construction).
JOBS = {"calm": ([1.0, 1.5], True), "brisk": ([1.0, 2.5], True), "reckless": ([1.0, 3.5], False)}


def job_files(root: Path, name: str) -> Path:
    """The job laid out as SignalFlag's demo lays one out: emissions, and a logs/ folder beside them."""
    speeds, framed = JOBS[name]
    folder = root / "jobs" / name
    lines = [{"$metadata": {"topic": "speed", "timestamp": i}, "$data": {"v": v}} for i, v in enumerate(speeds)]
    if framed:
        lines.append({"$metadata": {"topic": "frame", "timestamp": 0}, "$data": {"filename": "frame.png"}})
        (folder / "logs").mkdir(parents=True)
        (folder / "logs" / "frame.png").write_bytes(PNG)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "emissions.resim.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    return folder


def statuses_by_name(lake: Path, batch: str) -> dict[str, tuple[str, str]]:
    rows = read_results(lake, "main", batch)
    names = {}
    for job_id in {r["job_id"] for r in rows if r["job_id"]}:
        names[job_id] = read_metadata_row(lake, "main", batch, job_id)["experience_name"]
    return {(names.get(r["job_id"], "batch"), r["metric_name"]): r["status"] for r in rows}


def test_three_files_with_a_template_folder_through_batch_and_test_and_through_the_cli(tmp_path):
    folder = three_files(tmp_path)
    files = sorted(folder.glob("*.resim.yml"))
    sdk_lake = tmp_path / "sdk-lake"
    with Batch(
        branch="main",
        name="nightly",
        version="1.4.2",
        metrics_set_name="Nav",
        metrics_config_path=[str(p) for p in files],
        templates_path=tmp_path / "templates",
        lake=sdk_lake,
    ) as batch:
        for name in JOBS:
            source = job_files(tmp_path / "sdk", name)
            with Test(batch, name) as test:
                for line in (source / "emissions.resim.jsonl").read_text().splitlines():
                    record = json.loads(line)
                    test.emit(record["$metadata"]["topic"], record["$data"], record["$metadata"]["timestamp"])
                if (source / "logs").is_dir():
                    test.attach_log(source / "logs" / "frame.png")
    assert batch.test_statuses == {"calm": "PASSED", "brisk": "WARNING", "reckless": "BLOCKER"}
    assert batch.status == "BLOCKER" and batch.exit_code == 0  # no fail_on_states
    sdk = statuses_by_name(sdk_lake, batch.id)
    assert sdk[("reckless", "Camera Frame")] == "NOT_RUN"  # the file's global skip-if-no-data
    assert sdk[("batch", "Jobs Seen")] == "PASSED"  # the custom template, found in templates_path

    cli_lake = tmp_path / "cli-lake"
    glob = str(folder / "*.resim.yml")
    for name in JOBS:
        source = job_files(tmp_path / "cli", name)
        ingested = lakegate(
            "ingest", source / "emissions.resim.jsonl", "--lake", cli_lake, "--branch", "main", "--batch", "nightly",
            "--job", name, "--experience-name", name, "--build-version", "1.4.2", "--metrics-config-path", glob,
        )  # fmt: skip
        assert ingested.returncode == 0, ingested.stderr
        assert ("logs: copied from" in ingested.stdout) == JOBS[name][1]  # the default logs/ beside the emissions
    run = lakegate(
        "metrics", "run", "--lake", cli_lake, "--branch", "main", "--batch", "nightly", "--metrics-set", "Nav",
        "--metrics-config-path", glob, "--templates-path", tmp_path / "templates", "--format", "json",
    )  # fmt: skip
    assert run.returncode == 2, run.stderr  # a BLOCKER: lakegate's own exit code
    jobs = {j["experience_name"]: j["job_conflated_status"] for j in json.loads(run.stdout)["jobs"]}
    assert jobs == batch.test_statuses
    assert statuses_by_name(cli_lake, "nightly") == sdk


def test_a_closed_test_is_one_job_with_its_logs_and_an_exception_makes_it_error(tmp_path):
    folder = three_files(tmp_path)
    (tmp_path / "frame.png").write_bytes(PNG)
    lake = tmp_path / "lake"
    with Batch(
        "main", version="2.0", metrics_set_name="Nav", metrics_config_path=sorted(folder.glob("*")), lake=lake
    ) as b:
        with pytest.raises(RuntimeError, match="lost the map"):
            with Test(b, "crashing") as test:
                test.emit_series("speed", {"v": [0.5, 0.7]}, [10, 20])
                test.emit("frame", {"filename": "seen.png"}, 10)
                test.attach_log(tmp_path / "frame.png", file_name="seen.png")
                test.emit_event("goal_reached", {"name": "g1", "description": "d", "status": "PASSED", "tags": []}, 15)
                raise RuntimeError("lost the map")
        crashed = test.job_id
        (tmp_path / "frame.png").unlink()  # attach_log copied it at once
    row = read_metadata_row(lake, "main", b.id, crashed)
    assert (row["experience_name"], row["build_version"], row["job_status"]) == ("crashing", "2.0", "FAILED")
    assert b.job_statuses == {crashed: "ERROR"} and test.status == "ERROR"
    logs = job_logs_dir(lake, "main", b.id, crashed)
    assert sorted(p.name for p in logs.iterdir()) == ["seen.png", "stacktrace.log"]
    assert "RuntimeError: lost the map" in (logs / "stacktrace.log").read_text()
    results = statuses_by_name(lake, b.id)
    assert results[("crashing", "Max Speed")] == "PASSED" and results[("crashing", "Camera Frame")] == "PASSED"
    answer = lakegate("query", "--lake", lake, "--format", "json", "SELECT count(*) AS n FROM speed")  # data kept
    assert answer.returncode == 0, answer.stderr
    assert json.loads(answer.stdout)["rows"] == [[2]]


def _emit_in_child(test: Test, start: int) -> None:
    for i in range(50):
        test.emit("speed", {"v": 1.0}, start + i)
    os._exit(0)  # no exit hook: the Emitter wrote each line before emit returned


def test_threads_and_forked_children_share_a_test(tmp_path):
    folder = three_files(tmp_path)
    lake = tmp_path / "lake"
    context = multiprocessing.get_context("fork")
    with Batch("main", metrics_set_name="Nav", metrics_config_path=sorted(folder.glob("*")), lake=lake) as batch:
        with Test(batch, "shared") as test:
            threads = [
                threading.Thread(target=lambda k=k: [test.emit("speed", {"v": 1.0}, k * 1000 + i) for i in range(200)])
                for k in range(4)
            ]
            children = [context.Process(target=_emit_in_child, args=(test, 10_000 + k * 100)) for k in range(3)]
            for worker in [*threads, *children]:
                worker.start()
            for worker in [*threads, *children]:
                worker.join()
            assert [c.exitcode for c in children] == [0, 0, 0]
    assert test.report is not None and test.report.rows["speed"] == 4 * 200 + 3 * 50
    assert batch.test_statuses == {"shared": "PASSED"}


@pytest.mark.slow
def test_fail_on_states_exit_codes_of_batch_and_cli(tmp_path):
    folder = three_files(tmp_path)
    lake = tmp_path / "lake"
    config = sorted(folder.glob("*"))
    with pytest.raises(FailedStatesError) as failed:
        with Batch(
            "main",
            metrics_set_name="Nav",
            metrics_config_path=config,
            templates_path=tmp_path / "templates",  # else the custom metric errs: the batch would be ERROR
            lake=lake,
            fail_on_states="BLOCKER",
        ) as b:
            with Test(b, "reckless") as test:
                test.emit("speed", {"v": 3.5}, 0)
    assert (failed.value.status, failed.value.exit_code) == ("BLOCKER", 7) and b.status == "BLOCKER"
    with Batch("main", metrics_set_name="Nav", metrics_config_path=None, lake=lake, fail_on_states=["blocker"]) as warn:
        with Test(warn, "brisk") as test:
            test.emit("speed", {"v": 2.5}, 0)
    assert (warn.status, warn.exit_code) == ("WARNING", 0)  # WARNING is not among the states

    def run(batch: str, *states: str) -> int:
        args = ["metrics", "run", "--lake", lake, "--branch", "main", "--batch", batch, "--metrics-set", "Nav"]
        return lakegate(*args, *(["--fail-on-states", ",".join(states)] if states else [])).returncode

    assert run(b.id, "BLOCKER", "ERROR", "WARNING") == 7
    assert run(b.id, "WARNING") == 0
    assert run(warn.id, "BLOCKER", "WARNING") == 8
    assert run(warn.id, "BLOCKER") == 0
    assert run(warn.id) == 0 and run(b.id) == 2  # without the option: lakegate's codes
    with Batch("main", metrics_set_name="Nav", metrics_config_path=None, lake=lake) as errored:
        Test(errored, "broken").close(status="ERROR")
    assert errored.status == "ERROR" and run(errored.id, "ERROR") == 2 and run(errored.id) == 3
    bad = lakegate("metrics", "run", "--lake", lake, "--branch", "main", "--batch", b.id, "--all-metrics",
                   "--fail-on-states", "BLOCKER,PASSED")  # fmt: skip
    assert bad.returncode == 2 and "unsupported fail-on-states value: 'PASSED'" in bad.stderr


def test_a_topic_defined_in_two_files_names_both_places(tmp_path):
    first = write(tmp_path / "a.resim.yml", "version: 1\ntopics:\n  speed:\n    schema: {v: float}\n")
    second = write(
        tmp_path / "b.resim.yml", "version: 1\ntopics:\n  other: {schema: {v: int}}\n  speed: {schema: {v: int}}\n"
    )
    message = f"{second}:4:3: duplicate topic name 'speed' found across config files (first defined at {first}:3:3)"
    with pytest.raises(ConfigError) as caught:
        Batch("main", metrics_config_path=[first, second], lake=tmp_path / "lake").__enter__()
    assert [str(p) for p in caught.value.problems] == [message]
    for command in (["metrics", "validate"], ["metrics", "sync", "--lake", tmp_path / "lake", "--branch", "main"]):
        result = lakegate(*command, "--metrics-config-path", tmp_path / "*.resim.yml")
        assert result.returncode == 1 and message in result.stdout + result.stderr
    result = lakegate("metrics", "validate", "--metrics-config-path", f"{first},{tmp_path / 'none-*.yml'}")
    assert result.returncode == 1 and "glob pattern" in result.stderr and "matched no config files" in result.stderr


def test_validate_and_config_schema_are_the_config_commands(tmp_path):
    folder = three_files(tmp_path)
    result = lakegate("metrics", "validate", "--metrics-config-path", folder / "*.yml")
    assert result.returncode == 0 and result.stdout.startswith("ok: 3 topics, 4 metrics, 2 metrics sets, 1 dashboard")
    missing = lakegate("metrics", "validate", "--metrics-config-path", folder / "*.yml", "--templates-path", folder)
    assert missing.returncode == 1 and "template file 'names.liquid' of metric 'Jobs Seen' not found" in missing.stdout
    assert lakegate("metrics", "config-schema").stdout == lakegate("config", "schema").stdout


def test_missing_log_files_warn_and_ingest_logs_option(tmp_path):
    folder = three_files(tmp_path)
    lake = tmp_path / "lake"
    source = job_files(tmp_path, "calm")
    common = ["--lake", lake, "--branch", "main", "--batch", "b", "--metrics-config-path", folder / "*.yml"]
    bare = tmp_path / "bare" / "emissions.resim.jsonl"  # the same emissions, no logs folder beside them
    bare.parent.mkdir()
    bare.write_text((source / "emissions.resim.jsonl").read_text())
    assert lakegate("ingest", bare, *common, "--job", "j").returncode == 0
    run = ["metrics", "run", *common, "--metrics-set", "Nav", "--format", "json", "--no-compact"]
    result = lakegate(*run)
    frame = next(m for m in json.loads(result.stdout)["metrics"] if m["metric"] == "Camera Frame")
    assert frame["status"] == "WARNING"
    assert (
        frame["error"]["message"]
        == "none of the files the query names is there: frame.png: no log directory to look in"
    )
    moved = tmp_path / "elsewhere"
    (source / "logs").rename(moved)
    assert lakegate("ingest", bare, *common, "--job", "j", "--logs", moved).returncode == 0
    frame = next(m for m in json.loads(lakegate(*run).stdout)["metrics"] if m["metric"] == "Camera Frame")
    assert frame["status"] == "PASSED"
    gone = lakegate("ingest", bare, *common, "--job", "j", "--logs", tmp_path / "nothing")
    assert gone.returncode == 1 and "logs folder" in gone.stderr and "does not exist" in gone.stderr


@pytest.mark.slow
def test_dashboard_by_name(tmp_path):
    folder = three_files(tmp_path)
    lake = tmp_path / "lake"
    for version in ("1.0", "1.1"):
        with Batch("main", version=version, metrics_set_name="Nav", metrics_config_path=sorted(folder.glob("*")),
                   templates_path=tmp_path / "templates", lake=lake) as batch:  # fmt: skip
            for name in ("calm", "brisk"):
                with Test(batch, name) as test:
                    test.emit("speed", {"v": 1.0}, 0)
    result = lakegate("metrics", "dashboard", "--lake", lake, "--branch", "main", "--name", "Nav Trends",
                      "--format", "json")  # fmt: skip
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout)
    table = answer["metrics"][0]
    assert [m["metric"] for m in answer["metrics"]] == ["Tests by Build"] and len(answer["batches"]) == 2
    assert table["table"]["rows"] == [["1.0", 2], ["1.1", 2]]
    unknown = lakegate("metrics", "dashboard", "--lake", lake, "--branch", "main", "--name", "Nav Trend")
    assert unknown.returncode == 1 and "no dashboard 'Nav Trend' (did you mean 'Nav Trends'?)" in unknown.stderr

    server = serve(lake, tmp_path / "serve.log")  # the same dashboard as a page of `lakegate serve`
    try:
        status, index = get(f"{server.url}/dashboard/trends/")
        assert status == 200 and '<a href="?branch=main&amp;dashboard=Nav+Trends">Nav Trends</a>' in index
        status, page = get(f"{server.url}/dashboard/trends/?branch=main&dashboard=Nav+Trends")
        assert status == 200 and "Tests by Build" in page and "last 30 days" in page
        assert "<tr><td>1.0</td><td>2</td></tr><tr><td>1.1</td><td>2</td></tr>" in page  # two tests of each build
        status, page = get(f"{server.url}/dashboard/trends/?branch=main&dashboard=Other")
        assert status == 400 and "no dashboard &#x27;Other&#x27;" in page
    finally:
        assert server.stop() == 0


def get(url: str) -> tuple[int, str]:
    try:
        with urllib.request.urlopen(url, timeout=60) as response:
            return response.status, response.read().decode()
    except urllib.error.HTTPError as error:
        return error.code, error.read().decode()
