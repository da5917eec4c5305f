"""The debug dashboard in a real browser: headless Chromium (Debian's package) driven by Playwright.

Starts `lakegate metrics debug` on a generated job, loads the page and checks that every template
kind renders a non-empty chart, table, value or image; edits a query and sees the new value;
breaks it and sees the error with its line and column marked in the query; adds a metric with
the form; exports the config and loads it back; looks at the data explorer and the events.
Screenshots go to the test's tmp_path, or to $LAKEGATE_TEST_ARTIFACTS when set (CI artifacts).
Without /usr/bin/chromium the test is skipped, except under CI=true, where it must run.
"""

from __future__ import annotations

import io
import json
import os
import re
import zipfile
from pathlib import Path

import pytest

from lakegate.lake.config import load_config

CHROMIUM = Path("/usr/bin/chromium")
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
TEMPLATES = ("line", "bar", "table", "scalar", "image", "state_timeline", "histogram", "pie")
CHARTS = ("line", "bar", "state_timeline", "histogram", "pie")


def _require_browser():
    """The Playwright module, or a skip (a failure under CI) when it or Chromium is missing."""
    missing = None
    if not CHROMIUM.exists():
        missing = f"{CHROMIUM} is missing (Debian package 'chromium'; .ci/run installs it)"
    try:
        from playwright import sync_api
    except ImportError:
        missing = missing or "the 'playwright' package is missing (pip install -e '.[test]')"
    if missing:
        if os.environ.get("CI") == "true":
            pytest.fail(f"the browser test must run under CI: {missing}")
        pytest.skip(missing)
    return sync_api


def _artifacts(tmp_path: Path) -> Path:
    """Where the screenshots go: $LAKEGATE_TEST_ARTIFACTS if set, else a folder of the test's tmp_path."""
    folder = Path(os.environ.get("LAKEGATE_TEST_ARTIFACTS") or tmp_path / "artifacts")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _card(page, name: str):
    return page.locator(f'article.metric[data-metric="{name}"]')


def test_dashboard_in_a_real_browser(tmp_path: Path, nav_jobs, debug_processes) -> None:
    sync_api = _require_browser()
    artifacts = _artifacts(tmp_path)
    job = nav_jobs.jobs[0]
    server = debug_processes(
        [
            "--emissions-file",
            str(job.emissions_path),
            "--metrics-config-path",
            str(nav_jobs.config),
            "--metrics-set",
            "Nav Metrics",
            "--metadata",
            str(job.metadata_path),
        ],
        tmp_path,
    )
    emitted = [json.loads(line) for line in job.emissions_path.read_text().splitlines()]
    goal_states = sum(1 for line in emitted if line["$metadata"]["topic"] == "goal_status")
    errors: list[str] = []
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_context(viewport={"width": 1400, "height": 1000}, accept_downloads=True).new_page()
            page.set_default_timeout(15_000)
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
            page.goto(server.url)
            page.wait_for_selector("body[data-ready=true]")

            # every template kind renders something
            for kind in TEMPLATES:
                cards = page.locator(f'article.metric[data-template="{kind}"]')
                assert cards.count() > 0, kind
                for i in range(cards.count()):
                    card = cards.nth(i)
                    name = card.get_attribute("data-metric")
                    assert card.get_attribute("data-status") == "PASSED", name
                    if kind in CHARTS:
                        card.locator(".js-plotly-plot .main-svg").first.wait_for()
                        points = card.locator(".js-plotly-plot").evaluate(  # as drawn: typed arrays decoded
                            "el => el._fullData.reduce((n, t) => n + (t.x || t.values || []).length, 0)"
                        )
                        assert points > 0, name
                    elif kind == "table":
                        assert card.locator("table.data tbody tr").count() > 0, name
                    elif kind == "scalar":
                        assert re.fullmatch(r"-?[\d.]+( \S+)?", card.locator(".scalar").inner_text()), name
                    else:
                        image = card.locator(".lg-images img").first
                        image.wait_for()
                        assert image.evaluate("img => img.complete && img.naturalWidth > 0"), name
            page.screenshot(path=str(artifacts / "dashboard-metrics.png"), full_page=True)

            # edit a query in place and see the new value
            card = _card(page, "Time to reach final goal")
            card.locator("summary").click()
            card.locator("textarea").fill("SELECT 42.5")
            card.locator("button.run").click()
            page.wait_for_function(
                'document.querySelector(\'article.metric[data-metric="Time to reach final goal"] '
                ".scalar')?.textContent === '42.5 s'"
            )
            assert _card(page, "Time to reach final goal").locator(".chip.edited").count() == 1

            # break it: the error names the line and column, which are marked in the query
            card = _card(page, "Time to reach final goal")
            card.locator("textarea").fill("SELECT sum(time_s)\nFROM time_to_goalz")
            card.locator("button.run").click()
            page.wait_for_selector('article.metric[data-metric="Time to reach final goal"][data-status=ERROR]')
            card = _card(page, "Time to reach final goal")
            message = card.locator(".error").inner_text()
            assert "line 2, column 6" in message and "time_to_goalz" in message
            assert card.locator(".editor .hl-err").inner_text() == "time_to_goalz"
            assert card.locator(".badge").first.inner_text() == "ERROR"
            card.screenshot(path=str(artifacts / "dashboard-error.png"))

            # add a metric with the form
            page.click("#add-metric-open")
            form = page.locator("#add-metric")
            form.locator("input[name=name]").fill("Goal status rows")
            form.locator("select[name=template]").select_option("scalar")
            form.locator("textarea").fill("SELECT COUNT(*) FROM goal_status")
            form.locator("input[name=status_query]").fill("SELECT 1 FROM goal_status HAVING COUNT(*) > ?")
            form.locator("input[name=block]").fill("1000")
            form.locator("input[name=warn]").fill("1")
            form.locator("button[type=submit]").click()
            added = _card(page, "Goal status rows")
            added.wait_for()
            assert added.locator(".scalar").inner_text() == str(goal_states)
            assert added.get_attribute("data-status") == "WARNING"

            # export the config (a zip download) and load it back
            with page.expect_download() as download:
                page.click("#export")
            archive = zipfile.ZipFile(io.BytesIO(Path(download.value.path()).read_bytes()))
            exported = tmp_path / "exported" / "config.resim.yaml"
            exported.parent.mkdir()
            exported.write_bytes(archive.read("config.resim.yaml"))
            config = load_config(exported)
            assert (
                config.metrics["Time to reach final goal"].query_string.strip()
                == "SELECT sum(time_s)\nFROM time_to_goalz"
            )
            assert config.metrics["Goal status rows"].status.warn == 1
            assert config.metrics_sets["Nav Metrics"].metrics[-1] == "Goal status rows"

            # the data explorer: topics with row counts, an ad hoc query shown as a table
            page.click("nav.tabs button[data-tab=explorer]")
            page.wait_for_selector('#tables .table-item[data-table="goal_status"]')
            assert (
                page.locator('#tables .table-item[data-table="goal_status"] .count').inner_text()
                == f"{goal_states} rows"
            )
            page.locator('#tables .table-item[data-table="goal_status"] summary').click()
            page.locator('#tables .table-item[data-table="goal_status"] button').click()
            page.wait_for_selector("#query-result table.data")
            assert page.locator("#query-result table.data tbody tr").count() == goal_states
            assert page.locator("#query-result .result-meta").inner_text().startswith(f"{goal_states} rows")
            page.screenshot(path=str(artifacts / "dashboard-explorer.png"))

            # the events tab: the job's events in time order
            page.click("nav.tabs button[data-tab=events]")
            page.wait_for_selector("#events .event")
            goals = [line["$metadata"]["timestamp"] for line in emitted if line["$metadata"]["topic"] == "goal_reached"]
            times = page.locator("#events .event .time").all_inner_texts()
            assert times == [f"{t / 1e9:.3f} s" for t in sorted(goals)]
            page.screenshot(path=str(artifacts / "dashboard-events.png"), full_page=True)
        finally:
            browser.close()
    assert errors == []


def test_video_and_artifact_metrics_play_and_download_in_the_dashboard(tmp_path: Path, debug_processes) -> None:
    """A `video` metric shows an HTML5 player per file and an `artifact` metric a download link per
    file, both served from the job's logs (the field-robot config of tests/compat)."""
    from tests.compat.test_resim_media import CONFIG, LOGS, emissions

    sync_api = _require_browser()
    logs = tmp_path / "logs"
    for name, data in LOGS.items():
        (logs / name).parent.mkdir(parents=True, exist_ok=True)
        (logs / name).write_bytes(data)
    server = debug_processes(
        [
            "--emissions-file",
            str(emissions(tmp_path / "j1.jsonl")),
            "--logs-dir",
            str(logs),
            "--metrics-config-path",
            str(CONFIG),
            "--metrics-set",
            "Field",
        ],
        tmp_path,
    )
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_context(accept_downloads=True).new_page()
            page.set_default_timeout(15_000)
            page.goto(server.url)
            page.wait_for_selector("body[data-ready=true]")
            videos = _card(page, "Camera Replay").locator("video")
            assert videos.count() == 2
            sources = [videos.nth(i).evaluate("video => video.src") for i in range(2)]  # absolute URLs
            for source, name in zip(sources, ("front.mp4", "rear.webm")):
                assert source.endswith(name)
                served = page.request.get(source)
                assert served.status == 200 and served.body() == LOGS[name]
            links = _card(page, "Run Logs").locator("a[download]")
            names = [links.nth(i).inner_text() for i in range(links.count())]
            assert names and set(names) <= set(LOGS)
            with page.expect_download() as download:
                links.first.click()
            assert Path(download.value.path()).read_bytes() == LOGS[names[0]]
        finally:
            browser.close()
