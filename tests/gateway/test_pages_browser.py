"""What a new user sees on every page, in headless Chromium at 1400 x 1000: the demo's report, its
trends page, and the served landing page, dashboard and trends index of `lakegate serve` on the
demo's lake.

Each test looks at the drawn page: colours of legend swatches and badges, boxes of labels, selects and
buttons, the size of images and what a click shows. Screenshots of each page go to the test's tmp_path,
or to $LAKEGATE_TEST_ARTIFACTS (CI artifacts). Without Chromium the tests skip (fail under CI=true).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest

from lakegate.gateway.metrics.figures_html import MIN_IMAGE_WIDTH, report_html
from lakegate.gateway.metrics.plotly_arrays import is_typed, plain_figure
from lakegate.gateway.metrics.templates import STATUS_COLOURS, Rendered, format_number, render

from .test_dashboard_browser import ARGS, CHROMIUM, _artifacts, _require_browser

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
VIEWPORT = {"width": 1400, "height": 1000}

#: (name -> swatch colour) of each legend of bars, pie slices or timeline states in the plots under `root`.
LEGENDS_JS = """root => [...root.querySelectorAll('.js-plotly-plot')].map(plot =>
    Object.fromEntries([...plot.querySelectorAll('.legend .traces')]
        .filter(entry => entry.querySelector('.legendpoints path'))
        .map(entry => [entry.querySelector('.legendtext').textContent,
                       getComputedStyle(entry.querySelector('.legendpoints path')).fill])))"""
#: Whether the y-axis title of each plot under `root` overlaps one of its tick labels.
Y_TITLE_OVERLAPS_JS = """root => [...root.querySelectorAll('.js-plotly-plot')].map(plot => {
    const title = plot.querySelector('.g-ytitle text').getBoundingClientRect();
    return [...plot.querySelectorAll('.yaxislayer-above .ytick text')].some(tick => {
        const box = tick.getBoundingClientRect();
        return box.right > title.left && box.left < title.right && box.bottom > title.top && box.top < title.bottom;
    });
})"""


def _rgb(hex_colour: str) -> str:
    red, green, blue = (int(hex_colour[i : i + 2], 16) for i in (1, 3, 5))
    return f"rgb({red}, {green}, {blue})"


@pytest.fixture(scope="module")
def demo_lake(tmp_path_factory) -> Path:
    """The demo's lake (with report.html, trends.html and compare.html), made by `lakegate demo`."""
    lake = tmp_path_factory.mktemp("pages") / "lake-demo"
    done = subprocess.run(
        [*CLI, "demo", "--lake", str(lake), "--no-progress"], capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    return lake


@pytest.fixture(scope="module")
def served(demo_lake, tmp_path_factory):
    """`lakegate serve` of the demo lake: (its start-up line, its URL); stopped after the tests."""
    log = tmp_path_factory.mktemp("serve") / "serve.log"
    process = subprocess.Popen(
        [*CLI, "serve", "--lake", str(demo_lake), "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=log.open("w"),
        text=True,
    )
    try:
        line = process.stdout.readline()
        found = re.search(r" at (http://127\.0\.0\.1:\d+) ", line)
        assert found, f"{line}{log.read_text()}"
        yield line, found.group(1)
    finally:
        process.terminate()
        process.wait(timeout=30)


@pytest.fixture(scope="module")
def browser():
    sync_api = _require_browser()
    with sync_api.sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            yield chromium
        finally:
            chromium.close()


@pytest.fixture
def page(browser):
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    page.set_default_timeout(60_000)
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    yield page
    context.close()
    assert errors == []


def _check_timelines(cards, where: str) -> dict[str, str]:
    """Every state timeline of `cards` gives each state its own colour, the same in each chart, and keeps
    its axis title clear of the systems' names; returns state -> colour."""
    assert cards.count() > 0, where
    colours: dict[str, str] = {}
    for i in range(cards.count()):
        card = cards.nth(i)
        card.scroll_into_view_if_needed()
        [legend] = card.evaluate(LEGENDS_JS)
        assert len(legend) > 1 and len(set(legend.values())) == len(legend), (where, legend)  # no two alike
        for state, colour in legend.items():
            assert colours.setdefault(state, colour) == colour, (where, state)  # the same state, the same colour
        assert card.evaluate(Y_TITLE_OVERLAPS_JS) == [False], where
    return colours


def _report_timelines(page):
    return page.locator("article.lg-metric", has=page.locator("h3", has_text=re.compile("^Goal Status")))


def _check_images(page, images, where: str) -> None:
    """Images are drawn at least MIN_IMAGE_WIDTH wide (the demo's are 32 to 64 px), and a click shows the
    original at its own size over the page; another click closes it."""
    assert images.count() > 0, where
    for i in range(images.count()):
        image = images.nth(i)
        image.scroll_into_view_if_needed()
        page.wait_for_function("img => img.complete && img.naturalWidth > 0", arg=image.element_handle())
        natural, shown = image.evaluate("img => [img.naturalWidth, img.getBoundingClientRect().width]")
        assert natural < MIN_IMAGE_WIDTH <= shown + 0.5, (where, natural, shown)
    first = images.first
    natural = first.evaluate("img => img.naturalWidth")
    first.click()
    original = page.locator(".lg-original img")
    original.wait_for()
    assert original.evaluate("img => img.getBoundingClientRect().width") == natural
    assert f"{natural} x" in page.locator(".lg-original figcaption").inner_text()
    page.locator(".lg-original").click()
    assert page.locator(".lg-original").count() == 0


def test_the_report(page, demo_lake, tmp_path):
    page.goto((demo_lake / "report.html").as_uri())
    page.wait_for_selector(".js-plotly-plot .main-svg")
    page.screenshot(path=str(_artifacts(tmp_path) / "report.png"))

    # a table of contents: every section, each job's metrics and events; and back to the top from each section
    toc = page.locator("nav.lg-toc")
    sections = page.locator("main > section")
    assert toc.locator("ol > li").count() == sections.count() == 2 + 8  # overview, batch metrics, 8 jobs
    assert "Goal 1 Reached at" in toc.inner_text() and "Goal Status" in toc.inner_text()
    toc.locator("ol > li").nth(5).locator("a").first.click()
    page.wait_for_function("() => window.scrollY > 1000")
    assert abs(sections.nth(5).evaluate("s => s.getBoundingClientRect().top")) < 2
    sections.nth(5).locator("a.lg-up").click()
    page.wait_for_function("() => window.scrollY === 0")
    assert sections.locator("h2 a.lg-up[href='#top']").count() == sections.count()

    # one colour per state, the same in every job's Goal Status; the axis title clear of the labels
    assert _report_timelines(page).count() == 8
    colours = _check_timelines(_report_timelines(page), "report")
    assert set(colours) == {"WAITING", "NAVIGATING", "REACHED", "ABORTED"}

    # the pie of job statuses in the badges' colours
    badge = {s: page.locator(".lg-badge", has_text=re.compile(f"^{s}$")).first for s in ("PASSED", "BLOCKER")}
    badge_colours = {s: b.evaluate("b => getComputedStyle(b).backgroundColor") for s, b in badge.items()}
    assert badge_colours == {s: _rgb(STATUS_COLOURS[s]) for s in badge}
    outcomes = page.locator("article.lg-metric", has=page.locator("h3", has_text=re.compile("^Job Outcomes")))
    pie = outcomes.evaluate(LEGENDS_JS)[0]
    assert pie == {s: _rgb(STATUS_COLOURS[s]) for s in ("BLOCKER", "PASSED", "WARNING")}

    # images scaled, a click shows the original
    _check_images(page, page.locator(".lg-images img"), "report")
    page.screenshot(path=str(_artifacts(tmp_path) / "report-timeline.png"))


def test_the_served_dashboard(page, served, demo_lake, tmp_path):
    line, url = served
    assert f"dashboard {url}/dashboard/" in line  # the start-up line names the dashboard
    page.goto(f"{url}/dashboard/")
    page.wait_for_selector("body[data-ready=true]")
    page.wait_for_selector(".js-plotly-plot .main-svg")
    page.screenshot(path=str(_artifacts(tmp_path) / "dashboard.png"))

    # the header's buttons on one row, none wrapped; no select cuts its text
    boxes = page.locator("header.top .actions > *").evaluate_all(
        "nodes => nodes.map(n => [n.getBoundingClientRect().top, n.getBoundingClientRect().height,"
        " parseFloat(getComputedStyle(n).lineHeight) || 20])"
    )
    assert len({round(top) for top, _, _ in boxes}) == 1, boxes
    assert all(height < 2 * line_height for _, height, line_height in boxes), boxes
    cut = page.locator("header.top select").evaluate_all(
        """selects => selects.filter(select => {
            const context = document.createElement('canvas').getContext('2d');
            context.font = getComputedStyle(select).font;
            const text = select.options[select.selectedIndex].text;
            return context.measureText(text).width + 24 > select.clientWidth;  // 24: padding and the arrow
        }).map(select => select.id)"""
    )
    assert cut == []
    assert "Warehouse Loop" in page.locator("#pick-job option:checked").inner_text()

    # scalar cards in rows of their own, each as tall as its content
    scalars = page.locator("article.metric[data-template=scalar]")
    assert scalars.count() >= 2
    rows = page.locator(".metrics > article.metric").evaluate_all(
        "cards => cards.map(c => [c.dataset.template, Math.round(c.getBoundingClientRect().top),"
        " c.getBoundingClientRect().height, [...c.children].reduce((h, e) => h + e.getBoundingClientRect().height, 0)])"
    )
    scalar_rows = {top for template, top, _, _ in rows if template == "scalar"}
    assert all(template == "scalar" for template, top, _, _ in rows if top in scalar_rows)
    assert all(height < content + 80 for template, _, height, content in rows if template == "scalar"), rows

    # one number format: the page's is the report's (format_number), a table's cells show it
    values = [12345.25, 1234568.5, 0.1 + 0.2, 1 / 3, 1e-5, 1.5e15, 42.98434, -0.000123456, 99999.95, 2.0, 7]
    assert page.evaluate("values => values.map(lakegate.formatNumber)", values) == [format_number(v) for v in values]
    cells = page.locator("article.metric[data-template=table] table.data td.num").all_inner_texts()
    assert cells and all(len(re.sub(r"\D", "", text).lstrip("0")) <= 6 for text in cells if "." in text)

    # state colours as in the report; the pie of statuses in the badges' colours
    colours = _check_timelines(page.locator("article.metric[data-template=state_timeline]"), "dashboard")
    report = page.context.new_page()
    report.goto((demo_lake / "report.html").as_uri())
    report.wait_for_selector(".js-plotly-plot .main-svg")
    assert {s: c for s, c in _check_timelines(_report_timelines(report), "report").items() if s in colours} == colours
    report.close()
    badge = page.locator("#summary .badge").first
    assert badge.inner_text() == "BLOCKER"
    assert badge.evaluate("b => getComputedStyle(b).backgroundColor") == _rgb(STATUS_COLOURS["BLOCKER"])
    outcomes = page.locator('article.metric[data-metric="Job Outcomes"]')
    assert outcomes.evaluate(LEGENDS_JS)[0] == {s: _rgb(STATUS_COLOURS[s]) for s in ("BLOCKER", "PASSED", "WARNING")}

    # images scaled as in the report, a click shows the original file
    _check_images(page, page.locator("#test-metrics .lg-images img"), "dashboard")


def test_the_landing_page(page, served, tmp_path):
    _, url = served
    page.goto(f"{url}/")
    page.screenshot(path=str(_artifacts(tmp_path) / "landing.png"), full_page=True)
    assert page.title() == "lakegate"
    port = url.rsplit(":", 1)[1]
    connect = page.locator("#connect").inner_text()
    assert f"trino://me@127.0.0.1:{port}/lake/main" in connect
    assert f"jdbc:trino://127.0.0.1:{port}/lake/main" in connect
    branch = page.locator('article.lg-branch[data-branch="main"]')
    rows = branch.locator("tbody tr")
    assert [rows.nth(i).locator("td").first.inner_text() for i in range(rows.count())] == [
        "nav-regression-1",
        "nightly-1.4.1",
        "nightly-1.4.0",
    ]  # the newest first
    latest = rows.first.locator(".lg-statuses .lg-badge")
    assert latest.all_inner_texts() == ["PASSED", "WARNING", "BLOCKER"]
    assert latest.evaluate_all("badges => badges.map(b => getComputedStyle(b).backgroundColor)") == [
        _rgb(STATUS_COLOURS[s]) for s in ("PASSED", "WARNING", "BLOCKER")
    ]
    rows.nth(1).locator("td a").first.click()  # a batch opens in the dashboard
    page.wait_for_selector("body[data-ready=true]")
    assert page.locator("#pick-batch").input_value() == "nightly-1.4.1"
    page.go_back()
    page.locator(".lg-top nav a", has_text="Trends").click()
    page.wait_for_selector("ul.lg-list")
    assert page.url == f"{url}/dashboard/trends/"


def test_the_trends_pages_look_like_the_others(page, served, demo_lake, tmp_path):
    _, url = served
    page.goto(f"{url}/dashboard/trends/")
    page.screenshot(path=str(_artifacts(tmp_path) / "trends-index.png"))
    index_style = page.evaluate(
        "() => [getComputedStyle(document.body).fontFamily, getComputedStyle(document.querySelector('.lg-top'))"
        ".backgroundColor, getComputedStyle(document.querySelector('main')).maxWidth]"
    )
    assert "system-ui" in index_style[0] and index_style[1] == "rgb(251, 252, 253)" and index_style[2] == "1200px"
    page.locator("ul.lg-list a", has_text="main").first.click()
    page.wait_for_selector(".js-plotly-plot .main-svg")
    page.screenshot(path=str(_artifacts(tmp_path) / "trends.png"))
    assert page.evaluate("() => getComputedStyle(document.body).fontFamily") == index_style[0]
    assert page.locator(".lg-top nav a").all_inner_texts() == ["Home", "Dashboard", "Trends"]
    page.goto(f"{url}/dashboard/trends/?branch=nope")  # an error page, in the same style
    assert page.locator("h1").inner_text() == "Cannot show the trends"
    assert page.evaluate("() => getComputedStyle(document.body).fontFamily") == index_style[0]
    page.goto((demo_lake / "trends.html").as_uri())  # the demo's own trends page, offline
    assert page.evaluate("() => getComputedStyle(document.body).fontFamily") == index_style[0]


def test_the_comparison_page(page, served, tmp_path):
    _, url = served
    page.goto(f"{url}/dashboard/compare/?branch=main&batch=nav-regression-1")
    page.wait_for_selector(".js-plotly-plot .main-svg")
    page.screenshot(path=str(_artifacts(tmp_path) / "compare.png"))
    assert page.locator("h1").inner_text() == "Compare nightly-1.4.1 -> nav-regression-1 on branch main"
    contents = page.locator("nav.lg-toc > ol > li")
    assert contents.locator("> a").all_inner_texts() == ["Summary", "Experiences", "Changed metrics", "Base and new"]
    assert contents.first.locator(".lg-toc-items a").count() == 0  # a section of one item named as itself
    assert "Time to reach final goal (Parking Lot)" in contents.last.inner_text()
    assert page.locator(".lg-top nav a").all_inner_texts() == ["Home", "Dashboard", "Trends"]
    button = page.locator("#compare-go")
    assert button.evaluate("b => getComputedStyle(b).borderRadius") == "4px"  # styled as the dashboard's


#: The page coordinates of point `index` of the first trace of the chart `id` (Plotly's own axis maps).
POINT_JS = """([id, index]) => {
    const chart = document.getElementById(id), box = chart.getBoundingClientRect();
    const x = chart._fullLayout.xaxis, y = chart._fullLayout.yaxis, point = chart.calcdata[0][index];
    return [box.left + x._offset + x.c2p(point.x), box.top + y._offset + y.c2p(point.y)];
}"""
HOVERED_JS = """([id, index]) => {
    const hovered = document.getElementById(id)._hoverdata;
    return Boolean(hovered && hovered.length && hovered[0].pointNumber === index);
}"""


def test_two_clicks_on_the_trends_chart_open_their_comparison(page, served, tmp_path):
    """A build's point stands for its latest batch; the earlier of the two picked is the base."""
    _, url = served
    page.goto(f"{url}/dashboard/trends/?branch=main")
    chart = page.locator("article.lg-metric", has_text="Time to Final Goal by Build").locator("[id^=lg-figure-]")
    chart.locator(".main-svg").first.wait_for()
    assert page.locator("#compare-base").input_value() == "nightly-1.4.1"  # the form stays, the way without a chart
    chart_id = chart.get_attribute("id")
    builds = page.evaluate(f"() => document.getElementById('{chart_id}').data[0].x")
    assert builds == ["1.4.0", "1.4.1", "1.4.2"]
    chart.scroll_into_view_if_needed()

    def click_point(index: int) -> None:
        """As a user's pointer: Plotly's click reports the point it last hovered, so wait for that hover."""
        at = page.evaluate(POINT_JS, [chart_id, index])
        page.mouse.move(*at)
        page.wait_for_function(HOVERED_JS, arg=[chart_id, index])
        page.mouse.click(*at)

    click_point(2)  # 1.4.2: the demo's batch nav-regression-1
    picked = "Picked nav-regression-1 (build 1.4.2): click a point of another batch to compare the two."
    assert page.locator("#compare-pick").inner_text() == picked  # above the charts, and under the chart clicked
    assert page.locator(f"#{chart_id} + #compare-picked").inner_text() == picked
    click_point(0)  # 1.4.0: nightly-1.4.0
    page.wait_for_url("**/dashboard/compare/?*")
    assert page.url == f"{url}/dashboard/compare/?branch=main&base=nightly-1.4.0&batch=nav-regression-1"
    page.wait_for_selector(".js-plotly-plot .main-svg")
    assert page.locator("h1").inner_text() == "Compare nightly-1.4.0 -> nav-regression-1 on branch main"
    page.screenshot(path=str(_artifacts(tmp_path) / "compare-from-clicks.png"))


#: What Plotly drew of every chart of a page: the paths of its traces and the text of its axes' ticks.
DRAWN_JS = """() => [...document.querySelectorAll('.js-plotly-plot')].map(plot => [
    [...plot.querySelectorAll('.scatterlayer path, .barlayer path')].map(path => path.getAttribute('d')),
    [...plot.querySelectorAll('.xtick text, .ytick text')].map(tick => tick.textContent)])"""


def test_charts_of_typed_arrays_draw_what_their_lists_draw(page, tmp_path):
    """A stored figure's numbers are Plotly typed arrays (docs/lake-format.md): the page draws the same
    lines and bars as from the same numbers written as lists."""
    rng = np.random.default_rng(5)
    line = pa.table({"s": ["a"] * 3000 + ["b"] * 2000, "t": np.arange(5000) / 7, "v": rng.standard_normal(5000)})
    histogram = pa.table({"v": rng.gamma(2.0, 1.5, 8000), "n": rng.integers(-50, 50, 8000)})
    shown = [
        render("Speed", "line", [("s", "varchar"), ("t", "double"), ("v", "double")], line),
        render("Speeds", "histogram", [("v", "double")], histogram.select(["v"])),
        render("Steps", "histogram", [("n", "bigint")], histogram.select(["n"])),
    ]
    assert all(is_typed(trace["x"]) for rendered in shown for trace in rendered.figure["data"])
    drawn = []
    for name, figure_of in (("typed", lambda r: r.figure), ("lists", lambda r: plain_figure(r.figure))):
        metrics = [(r.template, Rendered(template=r.template, figure=figure_of(r)), {}) for r in shown]
        (tmp_path / f"{name}.html").write_text(report_html(name, [("charts", metrics)]))
        page.goto((tmp_path / f"{name}.html").as_uri())
        page.wait_for_function("() => document.querySelectorAll('.js-plotly-plot .main-svg').length >= 3")
        drawn.append(page.evaluate(DRAWN_JS))
    assert drawn[0] == drawn[1]
    assert len(drawn[0]) == 3 and all(paths and ticks for paths, ticks in drawn[0])
