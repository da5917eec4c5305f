"""Dashboard and report metrics over many batches: `lakegate metrics dashboard`, `lakegate metrics
report` and the trends page of `lakegate serve`, on a real lake of three batches of three builds.

The expected values are computed here from the emissions files the generator wrote (never through
lakegate): the mean time to reach the final goal per build, over the jobs that reached all 3 goals.
"""

from __future__ import annotations

import datetime as dt
import json
import re
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from lakegate.fixtures.generate import CONFIG_PATH, generate_batch
from lakegate.gateway.metrics.plotly_arrays import plain_figure
from lakegate.gateway.metrics.trends import Window, batch_link
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file

from .conftest import serve
from .test_dashboard_browser import ARGS, CHROMIUM, _artifacts, _require_browser
from .test_metrics_command import lakegate

DASHBOARD_CONFIG = CONFIG_PATH.with_name("dashboard.resim.yaml")
NOW = dt.datetime.now(dt.UTC).replace(microsecond=0)
#: batch -> (build version, how many days ago it ran)
BATCHES = {"nightly-1": ("1.4.0", 40), "nightly-2": ("1.4.1", 10), "nightly-3": ("1.10.0", 1)}
REPORT_CONFIG = """\
version: 1
metrics:
  Jobs per Build:
    type: report
    description: jobs of the batches given, per build
    query_string: |
      SELECT m.build_version AS "Build", COUNT(*) AS "Jobs", COUNT(DISTINCT o.job_id) AS "With odometry"
      FROM metadata m LEFT JOIN (SELECT DISTINCT batch_id, job_id FROM odom_linear_velocity) o
        ON o.batch_id = m.batch_id AND o.job_id = m.job_id
      GROUP BY m.build_version ORDER BY 1
    template: table
  Too Few Jobs:
    type: report
    description: blocks when the batches given hold fewer jobs than the threshold
    query_string: SELECT COUNT(*) FROM metadata
    template: scalar
    status:
      query_string: SELECT 1 FROM metadata HAVING COUNT(*) < ?
      block: 7
      warn: 10
  Speed of this job:
    type: test
    query_string: SELECT 1
    template: scalar
"""


@pytest.fixture(scope="module")
def trends_lake(tmp_path_factory):
    """Branch `main` with three batches of three jobs, one build each, and the fixture config plus
    the dashboard config stored; returns (lake, {batch: [emissions paths]})."""
    root = tmp_path_factory.mktemp("trends")
    lake = root / "lake"
    registry = BranchConfigs(lake, "main")
    config = registry.load(registry.store([CONFIG_PATH, DASHBOARD_CONFIG]))
    emissions = {}
    for seed, (batch, (build, days)) in enumerate(BATCHES.items()):
        made = NOW - dt.timedelta(days=days, hours=1)
        jobs = generate_batch(root / batch, jobs=3, seed=seed, samples_per_goal=6, build_version=build, build_time=made)
        for job in jobs:
            metadata = load_metadata_file(job.metadata_path)
            ingest_job(
                lake,
                "main",
                batch,
                job.job_id,
                [job.emissions_path],
                config=config,
                metadata=metadata,
                logs=job.logs_dir,
            )
        emissions[batch] = [job.emissions_path for job in jobs]
    return lake, emissions


def expected_means(emissions: dict[str, list[Path]], batches: list[str]) -> dict[str, float]:
    """Build -> mean over its jobs with 3 goals of the sum of their time_to_goal rows, from the files."""
    totals: dict[str, list[float]] = {}
    for batch in batches:
        for path in emissions[batch]:
            times = [
                line["$data"]["time_s"]
                for line in map(json.loads, path.read_text().splitlines())
                if line["$metadata"]["topic"] == "time_to_goal"
            ]
            if len(times) == 3:
                totals.setdefault(BATCHES[batch][0], []).append(sum(times))
    return {build: sum(values) / len(values) for build, values in totals.items()}


def dashboard_json(lake: Path, *args: str) -> dict:
    result = lakegate("metrics", "dashboard", "--lake", lake, "--branch", "main", "--format", "json", *args)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def metric(output: dict, name: str) -> dict:
    return next(m for m in output["metrics"] if m["metric"] == name)


def test_dashboard_metrics_run_over_every_batch_and_show_the_trend_by_build(trends_lake):
    lake, emissions = trends_lake
    output = dashboard_json(lake)
    assert [b["batch_id"] for b in output["batches"]] == list(BATCHES)  # by time
    assert [b["build_versions"] for b in output["batches"]] == [[build] for build, _ in BATCHES.values()]
    trend = metric(output, "Time to Final Goal by Build")
    assert trend["status"] == "PASSED" and trend["type"] == "dashboard"
    expected = expected_means(emissions, list(BATCHES))
    assert len(expected) >= 2  # some builds have jobs with 3 goals: a real trend
    line = plain_figure(trend["figure"])["data"][0]
    builds = [build for build, _ in BATCHES.values() if build in expected]  # ORDER BY MIN(m.time)
    assert line["x"] == builds
    assert line["y"] == pytest.approx([expected[build] for build in builds], rel=1e-12)
    table = metric(output, "Batches by Build")["table"]
    assert table["columns"][:3] == ["link_path", "Build", "Jobs"]
    assert [row[:3] for row in table["rows"]] == [[b, build, 3] for b, (build, _) in BATCHES.items()]


@pytest.mark.parametrize(
    "window, batches",
    [
        ("2", ["nightly-2", "nightly-3"]),
        ("1", ["nightly-3"]),
        ("30d", ["nightly-2", "nightly-3"]),
        ("5d", ["nightly-3"]),
        ("99999999999999999999d", ["nightly-1", "nightly-2", "nightly-3"]),  # more days than a datetime holds
    ],
)
def test_a_window_keeps_the_last_batches_or_days(trends_lake, window, batches):
    lake, emissions = trends_lake
    output = dashboard_json(lake, "--window", window)
    assert [b["batch_id"] for b in output["batches"]] == batches
    line = plain_figure(metric(output, "Time to Final Goal by Build")["figure"])["data"][0]
    expected = expected_means(emissions, batches)
    assert dict(zip(line["x"], line["y"])) == pytest.approx(expected, rel=1e-12)
    assert [row[0] for row in metric(output, "Batches by Build")["table"]["rows"]] == batches


def test_the_table_output_and_the_offline_page_with_links(trends_lake, tmp_path):
    lake, _ = trends_lake
    page = tmp_path / "out" / "trends.html"
    result = lakegate("metrics", "dashboard", "--lake", lake, "--branch", "main", "--window", "2", "--report", page)
    assert result.returncode == 0, result.stderr
    assert "PASSED  Time to Final Goal by Build  1 series, 2 points" in result.stdout
    assert "dashboard of branch 'main': PASSED (2 metrics over 2 batches, the last 2 batches: nightly-2, nightly-3" in (
        result.stdout
    )
    text = page.read_text()
    assert "Plotly.newPlot" in text and "<script src=" not in text  # plotly.js inline: works offline
    for batch in ("nightly-2", "nightly-3"):
        assert f'<a href="http://127.0.0.1:8080/dashboard/?branch=main&amp;batch={batch}">{batch}</a>' in text
    assert "nightly-1" not in text
    other = tmp_path / "other.html"
    result = lakegate(
        "metrics",
        "dashboard",
        "--lake",
        lake,
        "--branch",
        "main",
        "--report",
        other,
        "--link-base",
        "https://lg.example/",
    )
    assert result.returncode == 0, result.stderr
    assert '<a href="https://lg.example/dashboard/?branch=main&amp;batch=nightly-1">' in other.read_text()


def test_report_metrics_run_over_the_batches_given(trends_lake, tmp_path):
    lake, _ = trends_lake
    extra = tmp_path / "report.resim.yaml"
    extra.write_text(REPORT_CONFIG)
    args = ["metrics", "report", "--lake", lake, "--branch", "main", "--metrics-config-path", CONFIG_PATH]
    args += ["--metrics-config-path", extra]
    result = lakegate(*args, "--batches", "nightly-3,nightly-1", "--format", "json")
    assert result.returncode == 2, result.stderr  # 6 jobs < 7: BLOCKER
    output = json.loads(result.stdout)
    assert [b["batch_id"] for b in output["batches"]] == ["nightly-3", "nightly-1"]
    assert [m["metric"] for m in output["metrics"]] == ["Jobs per Build", "Too Few Jobs"]  # report metrics only
    assert metric(output, "Jobs per Build")["table"]["rows"] == [["1.10.0", 3, 3], ["1.4.0", 3, 3]]
    assert metric(output, "Too Few Jobs")["status"] == "BLOCKER" and metric(output, "Too Few Jobs")["scalar_value"] == 6
    result = lakegate(*args, "--batches", "nightly-1,nightly-2,nightly-3", "--format", "json")
    assert result.returncode == 0, result.stderr  # 9 jobs: not below 7, but below 10: WARNING
    assert metric(json.loads(result.stdout), "Too Few Jobs")["status"] == "WARNING"
    page = tmp_path / "report.html"
    result = lakegate(*args, "--batches", "nightly-2", "--report", page)
    assert result.returncode == 2 and re.search(r"^BLOCKER +Too Few Jobs +3$", result.stdout, re.MULTILINE)
    assert "Report of branch main: BLOCKER" in page.read_text()


def test_mistakes_are_one_clear_line(trends_lake, tmp_path):
    lake, _ = trends_lake
    base = ["metrics", "report", "--lake", lake, "--branch", "main"]
    extra = tmp_path / "report.resim.yaml"
    extra.write_text(REPORT_CONFIG)
    configs = ["--metrics-config-path", CONFIG_PATH, "--metrics-config-path", extra]
    result = lakegate(*base, *configs, "--batches", "nightly-1,nope")
    assert result.returncode == 1
    assert result.stderr.startswith("lakegate: no batch 'nope' on branch 'main' (batches: 'nightly-1', 'nightly-2'")
    result = lakegate(*base, "--metrics-config-path", CONFIG_PATH, "--batches", "nightly-1")  # no report metrics
    assert result.returncode == 1 and result.stderr == "lakegate: the config has no 'type: report' metrics\n"
    result = lakegate("metrics", "dashboard", "--lake", lake, "--branch", "main", "--window", "0")
    assert (
        result.returncode == 2 and "--window: expected a window like '30d'" in result.stderr
    )  # argparse's usage error
    result = lakegate("metrics", "dashboard", "--lake", lake, "--branch", "main", "--metrics-set", "Nav Metrics")
    assert (
        result.returncode == 1
        and result.stderr == "lakegate: metrics set 'Nav Metrics' has no 'type: dashboard' metrics\n"
    )
    result = lakegate("metrics", "dashboard", "--lake", lake, "--branch", "nope")
    assert result.returncode == 1 and result.stderr.startswith("lakegate: no branch 'nope' in ")


def test_a_batch_run_reports_dashboard_metrics_not_run_naming_the_command(trends_lake, tmp_path):
    lake, _ = trends_lake
    config = tmp_path / "both.resim.yaml"
    config.write_text(
        CONFIG_PATH.read_text().replace("      - Job Outcomes\n", "      - Job Outcomes\n      - Batches by Build\n")
    )
    args = ["metrics", "run", "--lake", lake, "--branch", "main", "--batch", "nightly-1", "--format", "json"]
    result = lakegate(
        *args,
        "--metrics-set",
        "Nav Metrics",
        "--metrics-config-path",
        config,
        "--metrics-config-path",
        DASHBOARD_CONFIG,
    )
    output = json.loads(result.stdout)
    found = metric(output, "Batches by Build")
    assert found["status"] == "NOT_RUN"
    assert found["error"]["message"] == "a dashboard metric runs over many batches: lakegate metrics dashboard"


def _get(url: str) -> tuple[int, str]:
    try:
        with urllib.request.urlopen(url, timeout=60) as response:
            return response.status, response.read().decode()
    except urllib.error.HTTPError as error:
        return error.code, error.read().decode()


@pytest.fixture(scope="module")
def trends_server(trends_lake, tmp_path_factory):
    lake, _ = trends_lake
    server = serve(lake, tmp_path_factory.mktemp("trends-server") / "stderr.log")
    yield server
    assert server.stop() == 0


def test_the_served_trends_page_of_a_branch(trends_lake, trends_server):
    _, emissions = trends_lake
    status, index = _get(f"{trends_server.url}/dashboard/trends/")
    assert status == 200 and '<a href="?branch=main">main</a>' in index
    status, dashboard = _get(f"{trends_server.url}/dashboard/")
    assert status == 200 and '<a id="trends" class="button" href="trends/"' in dashboard
    status, page = _get(f"{trends_server.url}/dashboard/trends/?branch=main&window=2")
    assert status == 200
    assert "<title>Dashboard of branch main: PASSED</title>" in page
    assert '<script src="/dashboard/static/plotly.min.js"></script>' in page  # not inlined in every response
    assert '<a href="/dashboard/?branch=main&amp;batch=nightly-2">nightly-2</a>' in page
    assert "nightly-1" not in page
    expected = expected_means(emissions, ["nightly-2", "nightly-3"])
    data = plain_figure(json.loads(page.split('Plotly.newPlot("lg-figure-2", ', 1)[1].split(", {", 1)[0]))
    assert dict(zip(data[0]["x"], data[0]["y"])) == pytest.approx(expected, rel=1e-12)
    status, page = _get(f"{trends_server.url}/dashboard/trends/?branch=main&window=soon")
    assert status == 400 and "expected a window like" in page
    status, page = _get(f"{trends_server.url}/dashboard/trends/?branch=nope")
    assert status == 400 and "no branch &#x27;nope&#x27; in the lake" in page
    request = urllib.request.Request(
        f"{trends_server.url}/dashboard/trends/?branch=main", headers={"Host": "evil.example"}
    )
    with pytest.raises(urllib.error.HTTPError) as caught:  # the Host check of every page (DNS rebinding)
        urllib.request.urlopen(request, timeout=30)
    assert caught.value.code == 421


def test_the_trends_page_in_a_real_browser(trends_server, tmp_path):
    sync_api = _require_browser()
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_page()
            errors: list[str] = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.goto(f"{trends_server.url}/dashboard/trends/")
            page.click('a:text-is("main")')
            page.wait_for_selector("#lg-figure-2 .main-svg", timeout=30_000)  # Plotly drew the trend
            assert page.locator("#lg-figure-2 .scatterlayer .trace").count() == 1
            page.screenshot(path=str(_artifacts(tmp_path) / "trends.png"), full_page=True)
            page.click('td a:text-is("nightly-2")')  # a link_path cell opens the batch in the dashboard
            page.wait_for_function("document.querySelector('#pick-batch')?.value === 'nightly-2'", timeout=60_000)
            assert not errors
        finally:
            browser.close()


def test_link_paths_name_a_batch_or_a_job_and_windows_read_as_documented():
    assert batch_link("feature/x", "b1/j2", "http://h:1/") == "http://h:1/dashboard/?branch=feature%2Fx&batch=b1&job=j2"
    assert batch_link("main", "b 1") == "/dashboard/?branch=main&batch=b+1"
    assert batch_link("main", None) is None and batch_link("main", "") is None
    assert Window.parse("30d") == Window(days=30) and str(Window.parse(" 10 ")) == "last 10 batches"
    for bad in ("0", "-3", "30 days", "d", ""):
        with pytest.raises(ValueError, match="expected a window like '30d'"):
            Window.parse(bad)


LINKED_BARS = """\
version: 1
metrics:
  Jobs per Batch:
    type: dashboard
    description: bars of [x, y, link_path] and [series, x, y, link_path]
    query_string: |
      SELECT batch_id AS "Batch", COUNT(*) AS "Jobs", batch_id AS link_path
      FROM metadata GROUP BY batch_id ORDER BY batch_id
    template: bar
  Jobs per Build and Batch:
    type: dashboard
    query_string: |
      SELECT build_version AS "Build", batch_id AS "Batch", COUNT(*) AS "Jobs", batch_id AS link_path
      FROM metadata GROUP BY 1, 2 ORDER BY 2
    template: bar
metrics sets:
  Linked:
    metrics: [Jobs per Batch, Jobs per Build and Batch]
"""


def test_a_bar_with_link_path_opens_its_batch_in_a_real_browser(trends_lake, tmp_path):
    """ReSim's optional link_path column of bar (and line) results: every bar links to its batch."""
    lake, _ = trends_lake
    config = tmp_path / "linked.resim.yaml"
    config.write_text(LINKED_BARS)
    page_file = tmp_path / "linked.html"
    args = ["metrics", "dashboard", "--lake", lake, "--branch", "main", "--metrics-set", "Linked"]
    result = lakegate(*args, "--metrics-config-path", config, "--report", page_file, "--link-base", "http://lg.test/")
    assert result.returncode == 0, result.stderr
    lines = [" ".join(line.split()) for line in result.stdout.splitlines()]
    assert "PASSED Jobs per Batch 1 series, 3 bars" in lines
    assert "PASSED Jobs per Build and Batch 3 series, 3 bars" in lines
    sync_api = _require_browser()
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_page()
            page.route(
                "http://lg.test/**", lambda route: route.fulfill(body="the batch page", content_type="text/plain")
            )
            page.goto(page_file.as_uri())
            page.wait_for_selector("#lg-figure-2 .main-svg", timeout=30_000)
            bars = page.locator("#lg-figure-2 .bars .point path")
            assert bars.count() == 3
            with page.expect_navigation(timeout=30_000):
                bars.nth(1).click(force=True)
            assert page.url == "http://lg.test/dashboard/?branch=main&batch=nightly-2"
        finally:
            browser.close()
