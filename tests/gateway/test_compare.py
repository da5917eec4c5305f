"""`lakegate compare` and `lakegate flakes` on batches whose differences are known by construction.

Every job emits `value` samples drawn with a fixed seed from a normal distribution whose mean is
chosen per experience and side, and a sequence of `mode` states. Each experience is built to land on
one tag: a shifted distribution, a status that fails now, one that is fixed, one still failing, an
experience that fails one run in three (flaky), one gone and one new. The expected tags, means,
changes and p-values are computed here from the raw values written (numpy, and SciPy called
directly), never through lakegate.
"""

from __future__ import annotations

import datetime as dt
import json
import re
import urllib.error
import urllib.request
import uuid
from pathlib import Path

import numpy as np
import pytest
import trino
from scipy import stats

from lakegate.gateway.cli.main import main
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.emitter import Emitter
from lakegate.lake.ingest import ingest_job

from .conftest import serve
from .test_dashboard_browser import ARGS, CHROMIUM, _artifacts, _require_browser
from .test_metrics_command import lakegate
from .test_trino_backend import same, start_server, stop_server

CONFIG = """\
version: 1
topics:
  sample:
    schema:
      value: float
  mode:
    schema:
      state: string
metrics:
  Mean Value:
    type: test
    query_string: SELECT AVG(value) FROM sample
    template: scalar
    units: m
    status:
      query_string: SELECT 1 FROM sample HAVING AVG(value) > ?
      block: 10
      warn: 5
  Value Distribution:
    type: test
    query_string: SELECT value FROM sample
    template: histogram
  Value Over Time:
    type: test
    query_string: SELECT 'value', timestamp, value FROM sample ORDER BY timestamp
    template: line
  Mode:
    type: test
    query_string: SELECT 'Robot', timestamp, state FROM mode ORDER BY timestamp
    template: state_timeline
  Old Metric:
    type: test
    query_string: SELECT 1
    template: scalar
  Fresh Metric:
    type: test
    query_string: SELECT 2
    template: scalar
  Batch Mean:
    type: batch
    query_string: SELECT AVG(value) FROM sample
    template: scalar
  Mean by Build:
    type: dashboard
    query_string: |
      SELECT 'mean', m.build_version, AVG(s.value)
      FROM sample s JOIN metadata m ON s.batch_id = m.batch_id AND s.job_id = m.job_id
      GROUP BY m.build_version ORDER BY MIN(m.time)
    template: line
metrics sets:
  Base Set:
    metrics: [Mean Value, Value Distribution, Value Over Time, Mode, Old Metric, Batch Mean]
  New Set:
    metrics: [Mean Value, Value Distribution, Value Over Time, Mode, Fresh Metric, Batch Mean]
"""
SAMPLES = 150
#: experience -> (base runs, new runs): each run is (mean of its values, extra STOP states); None: absent.
PLAN = {
    "Steady": ([(1.0, 0)], [(1.0, 0)]),
    "Shifted": ([(1.0, 0)], [(3.0, 15)]),  # same status, values shifted by 2, more STOP segments
    "Regressed": ([(2.0, 0)], [(7.0, 0)]),  # PASSED -> WARNING: a new failure
    "Repaired": ([(12.0, 0)], [(2.0, 0)]),  # BLOCKER -> PASSED: fixed
    "Broken": ([(12.0, 0)], [(6.0, 0)]),  # BLOCKER -> WARNING: still failing
    "Wobbly": ([(2.0, 0)], [(2.0, 0), (6.0, 0), (2.0, 0)]),  # fails one run in three: flaky
    "Dropped": ([(1.0, 0)], None),
    "Added": (None, [(1.0, 0)]),
}
#: A second new batch of the new build: only Wobbly fails, on one run of three (a flaky new failure only).
FLAKY_ONLY = {name: (runs[0], runs[0]) for name, runs in PLAN.items() if name in ("Steady", "Wobbly")}
FLAKY_ONLY["Wobbly"] = ([(2.0, 0)], [(2.0, 0), (2.0, 0), (6.0, 0)])
BUILDS = {"base": "1.0", "new": "1.1", "flaky-only": "1.1"}
START = dt.datetime(2026, 1, 1, tzinfo=dt.UTC)


def expected_status(mean: float) -> str:
    return "BLOCKER" if mean > 10 else "WARNING" if mean > 5 else "PASSED"


def states(extra_stops: int) -> list[str]:
    """The run's mode states: IDLE, RUN, IDLE, RUN ... and `extra_stops` STOP states in between."""
    found = ["IDLE", "RUN"] * 20
    for i in range(extra_stops):
        found.insert(1 + 3 * i, "STOP")
    return found


def segments(sequence: list[str]) -> list[str]:
    """One state name per segment: consecutive equal states are one segment."""
    return [s for i, s in enumerate(sequence) if i == 0 or sequence[i - 1] != s]


def make_lake(root: Path, batches: list[tuple[str, str, dict[str, list[tuple[float, int]]], str]]):
    """A lake of `batches` ((batch, build, experience -> runs as (mean, extra STOP states), metrics set)),
    evaluated; returns (lake, per batch: experience -> list of runs (values, states, status))."""
    (root / "config.resim.yaml").write_text(CONFIG)
    lake = root / "lake"
    registry = BranchConfigs(lake, "main")
    config = registry.load(registry.store([root / "config.resim.yaml"]))
    truth: dict[str, dict[str, list]] = {}
    minute = 0
    for batch, build, plan, _ in batches:
        truth[batch] = {}
        for experience, runs in plan.items():
            for run, (mean, stops) in enumerate(runs):
                rng = np.random.default_rng([ord(c) for c in f"{batch}/{experience}/{run}"])
                values = rng.normal(mean, 1.0, SAMPLES).tolist()
                sequence = states(stops)
                job = f"{experience.lower()}-{run}"
                path = root / batch / job / "emissions.resim.jsonl"
                path.parent.mkdir(parents=True)
                with Emitter(root / "config.resim.yaml", path) as emitter:
                    emitter.emit_series("sample", {"value": values}, timestamps=[i * 10**6 for i in range(SAMPLES)])
                    emitter.emit_series(
                        "mode", {"state": sequence}, timestamps=[i * 10**8 for i in range(len(sequence))]
                    )
                minute += 1
                metadata = {
                    "experience_name": experience,
                    "build_version": build,
                    "time": (START + dt.timedelta(minutes=minute)).isoformat(),
                }
                ingest_job(lake, "main", batch, job, [path], config=config, metadata=metadata)
                truth[batch].setdefault(experience, []).append(
                    {"values": values, "states": sequence, "status": expected_status(float(np.mean(values)))}
                )
    with MetricsEngine(lake) as engine:
        for batch, _, _, metrics_set in batches:
            engine.evaluate_batch("main", batch, config.metrics_in_set(metrics_set), metrics_set=metrics_set)
    return lake, truth


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The lake of the base, the new and the flaky-only batch, and what each run was made of."""
    batches = [
        ("base", BUILDS["base"], {e: runs[0] for e, runs in PLAN.items() if runs[0]}, "Base Set"),
        ("new", BUILDS["new"], {e: runs[1] for e, runs in PLAN.items() if runs[1]}, "New Set"),
        ("flaky-only", BUILDS["flaky-only"], {e: runs[1] for e, runs in FLAKY_ONLY.items()}, "New Set"),
    ]
    return make_lake(tmp_path_factory.mktemp("compare"), batches)


SEVERITY = {"PASSED": 1, "WARNING": 2, "BLOCKER": 3}


def worst(runs: list[dict]) -> str:
    return max((r["status"] for r in runs), key=SEVERITY.__getitem__)


def expected_tag(base: list[dict] | None, new: list[dict] | None, flaky: set[str], experience: str) -> str:
    if base is None:
        return "new"
    if new is None:
        return "gone"
    before, after = worst(base) != "PASSED", worst(new) != "PASSED"
    if not before and after:
        return "flaky" if experience in flaky else "new failure"
    return {(True, False): "fixed", (True, True): "still failing"}.get((before, after), "same")


def flaky_by_construction(truth: dict) -> set[str]:
    """Experiences whose runs of one build (here: of the new build, over both its batches) changed status."""
    found = set()
    for experience in {e for runs in truth.values() for e in runs}:
        for build in set(BUILDS.values()):
            runs = [r for b, e in truth.items() if BUILDS[b] == build for r in e.get(experience, [])]
            if any(a["status"] != b["status"] for a, b in zip(runs, runs[1:])):
                found.add(experience)
    return found


def compare(lake: Path, *args: str) -> tuple[int, dict]:
    done = lakegate("compare", "--lake", lake, "--branch", "main", "--format", "json", *args)
    assert done.returncode in (0, 4), done.stderr
    return done.returncode, json.loads(done.stdout)


def test_every_tag_value_and_p_value_matches_an_independent_computation(built):
    lake, truth = built
    code, answer = compare(lake, "--base", "base", "--batch", "new")
    assert code == 0  # no --fail-on
    flaky = flaky_by_construction(truth)
    assert flaky == {"Wobbly"}
    base, new = truth["base"], truth["new"]
    experiences = set(base) | set(new)
    assert {e["experience"]: e["tag"] for e in answer["experiences"]} == {
        e: expected_tag(base.get(e), new.get(e), flaky, e) for e in experiences
    }
    tags = {e["experience"]: e["tag"] for e in answer["experiences"]}
    assert tags["Regressed"] == "new failure" and tags["Repaired"] == "fixed" and tags["Broken"] == "still failing"
    assert tags["Wobbly"] == "flaky" and tags["Dropped"] == "gone" and tags["Added"] == "new"
    assert answer["flaky_experiences"] == ["Wobbly"]
    order = ["new failure", "flaky", "still failing", "gone", "new", "fixed", "same"]
    ranks = [order.index(e["tag"]) for e in answer["experiences"]]
    assert ranks == sorted(ranks)  # by severity
    for job in answer["experiences"]:
        b, n = base.get(job["experience"]), new.get(job["experience"])
        assert job["base_runs"] == (len(b) if b else None) and job["new_runs"] == (len(n) if n else None)
        assert job["base_status"] == (worst(b) if b else None) and job["new_status"] == (worst(n) if n else None)

    metrics = {(m["experience"], m["metric"]): m for m in answer["metrics"]}
    for experience in experiences:
        b, n = base.get(experience), new.get(experience)
        mean = metrics[(experience, "Mean Value")]
        assert mean["tag"] == expected_tag(b, n, flaky, experience)
        base_mean = None if b is None else float(np.mean([np.mean(r["values"]) for r in b]))
        new_mean = None if n is None else float(np.mean([np.mean(r["values"]) for r in n]))
        for got, wanted in ((mean["base_value"], base_mean), (mean["new_value"], new_mean)):
            assert got is None if wanted is None else got == pytest.approx(wanted, rel=1e-12)
        if b and n:
            assert mean["change"] == pytest.approx(new_mean - base_mean, rel=1e-9)
            assert mean["relative_change"] == pytest.approx((new_mean - base_mean) / abs(base_mean), rel=1e-9)
            pooled = [np.concatenate([r["values"] for r in side]) for side in (b, n)]
            ks = stats.ks_2samp(*pooled)
            for metric in ("Value Distribution", "Value Over Time"):
                test = metrics[(experience, metric)]["series_test"]
                assert test["test"] == "Kolmogorov-Smirnov"
                assert test["p_value"] == pytest.approx(ks.pvalue, rel=1e-9)
                assert test["statistic"] == pytest.approx(ks.statistic, rel=1e-9)
                assert (test["base_count"], test["new_count"]) == (len(pooled[0]), len(pooled[1]))
                assert metrics[(experience, metric)]["significant"] == (ks.pvalue < 0.05)
            counted = [[s for r in side for s in segments(r["states"])] for side in (b, n)]
            names = sorted(set(counted[0]) | set(counted[1]))
            chi = stats.chi2_contingency([[side.count(s) for s in names] for side in counted])
            mode = metrics[(experience, "Mode")]["series_test"]
            assert mode["test"] == "chi-square" and mode["p_value"] == pytest.approx(chi.pvalue, rel=1e-9)
        else:
            assert mean["change"] is None and metrics[(experience, "Mode")]["series_test"] is None
    # by construction: the shift of 2 standard deviations and the extra STOP states are significant
    assert metrics[("Shifted", "Value Distribution")]["significant"] is True
    assert metrics[("Shifted", "Mode")]["significant"] is True
    assert metrics[("Steady", "Mode")]["series_test"]["p_value"] == 1.0  # the same states
    # metrics only on one side
    for experience in base.keys() & new.keys():
        assert metrics[(experience, "Old Metric")]["tag"] == "gone"
        assert metrics[(experience, "Fresh Metric")]["tag"] == "new"
    batch_mean = metrics[(None, "Batch Mean")]
    everything = [np.concatenate([r["values"] for runs in side.values() for r in runs]) for side in (base, new)]
    assert batch_mean["base_value"] == pytest.approx(float(np.mean(everything[0])), rel=1e-12)
    assert batch_mean["new_value"] == pytest.approx(float(np.mean(everything[1])), rel=1e-12)
    assert batch_mean["change"] == pytest.approx(float(np.mean(everything[1]) - np.mean(everything[0])), rel=1e-9)


@pytest.mark.slow
def test_fail_on_new_failures_exit_codes(built):
    lake, _ = built
    assert compare(lake, "--base", "base", "--batch", "new", "--fail-on", "new-failures")[0] == 4  # Regressed
    assert compare(lake, "--base", "base", "--batch", "base", "--fail-on", "new-failures")[0] == 0  # known failures
    # only the flaky experience fails now: not a new failure unless --strict
    code, answer = compare(lake, "--base", "base", "--batch", "flaky-only", "--fail-on", "new-failures")
    assert code == 0 and {e["experience"]: e["tag"] for e in answer["experiences"]}["Wobbly"] == "flaky"
    assert compare(lake, "--base", "base", "--batch", "flaky-only", "--fail-on", "new-failures", "--strict")[0] == 4
    # builds: the latest batch of each
    code, answer = compare(lake, "--base-build", "1.0", "--build", "1.1")
    assert (answer["base"]["batch_id"], answer["new"]["batch_id"]) == ("base", "flaky-only")
    unknown = lakegate("compare", "--lake", lake, "--branch", "main", "--base", "base", "--batch", "nope")
    assert unknown.returncode == 1
    assert unknown.stderr == "lakegate: no batch 'nope' on branch 'main' (batches: base, new, flaky-only)\n"
    build = lakegate("compare", "--lake", lake, "--branch", "main", "--base-build", "9", "--batch", "new")
    assert build.returncode == 1 and "no batch of build '9' on branch 'main' (builds: 1.0, 1.1)" in build.stderr


def test_table_is_ordered_by_severity_and_report_is_one_offline_page(built, tmp_path):
    lake, _ = built
    report = tmp_path / "compare.html"
    done = lakegate(
        "compare", "--lake", lake, "--branch", "main", "--base", "base", "--batch", "new", "--report", report
    )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].split() == ["TAG", "EXPERIENCE", "BASE", "NEW", "RUNS"]
    assert lines[1].split()[:4] == ["NEW", "FAILURE", "Regressed", "PASSED"]
    assert lines[2].split()[:2] == ["FLAKY", "Wobbly"]
    assert "new failures: Regressed" in done.stdout and f"report: {report}" in done.stdout
    html = report.read_text()
    assert "<script src=" not in html and "Plotly.newPlot" in html
    assert html.index("Summary") < html.index("Changed metrics") < html.index("Base and new")
    shifted = html.index("Value Distribution (Shifted)")
    figure = json.loads(html[shifted:].split("Plotly.newPlot(", 1)[1].split(", ", 1)[1].split(', {"', 1)[0])
    assert [trace["name"] for trace in figure] == ["base", "new"]  # one figure, both sides


def test_flakes_scores_match_the_runs(built):
    lake, truth = built
    done = lakegate("flakes", "--lake", lake, "--branch", "main", "--format", "json", "--all")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["batches"] == ["base", "new", "flaky-only"]
    found = {(f["build"], f["experience"]): f for f in answer["flakes"]}
    for build in set(BUILDS.values()):
        for experience in {e for runs in truth.values() for e in runs}:
            runs = [r for b, e in truth.items() if BUILDS[b] == build for r in e.get(experience, [])]
            if not runs:
                assert (build, experience) not in found
                continue
            flake = found[(build, experience)]
            flips = sum(a["status"] != b["status"] for a, b in zip(runs, runs[1:]))
            assert (flake["runs"], flake["status_flips"]) == (len(runs), flips)
            assert flake["flip_rate"] == pytest.approx(flips / (len(runs) - 1) if len(runs) > 1 else 0.0)
            means = [float(np.mean(r["values"])) for r in runs]
            if len(means) > 1:
                cv = float(np.std(means, ddof=1) / abs(np.mean(means)))
                assert flake["max_cv"] == pytest.approx(cv, rel=1e-9) and flake["max_cv_metric"] == "Mean Value"
            else:
                assert flake["max_cv"] is None
            assert flake["flaky"] == (flips > 0 or (len(means) > 1 and cv > 0.2))
    table = lakegate("flakes", "--lake", lake, "--branch", "main")
    assert table.stdout.splitlines()[1].split()[:2] == ["FLAKY", "Wobbly"]


def test_compare_through_a_trino_backend_matches_the_embedded_engine(built, tmp_path):
    """The same comparison with its SQL forwarded to a Trino-protocol server (a `lakegate serve` of the
    lake, as tests/gateway/test_trino_backend.py does) answers as the embedded engine."""
    lake, _ = built
    embedded = compare(lake, "--base", "base", "--batch", "new")[1]
    process, url = start_server(lake, tmp_path / "serve.log")
    try:
        args = ["--trino-url", url, "--trino-catalog", "lake", "--trino-schema-map", "*={branch}"]
        forwarded = compare(lake, "--base", "base", "--batch", "new", "--backend", "trino", *args)[1]
    finally:
        stop_server(process)
    assert embedded.pop("seconds") >= 0 and forwarded.pop("seconds") >= 0
    assert same(forwarded, embedded)


def _get(url: str) -> tuple[int, str]:
    try:
        with urllib.request.urlopen(url, timeout=60) as answer:
            return answer.status, answer.read().decode()
    except urllib.error.HTTPError as error:
        return error.code, error.read().decode()


@pytest.mark.slow
def test_the_served_compare_page_in_a_real_browser(built, tmp_path):
    """From a batch page ("compare with the previous build"), then two batches picked on the compare
    page, then on the trends page: Chromium draws the same comparison as `lakegate compare`."""
    lake, _ = built
    sync_api = _require_browser()
    server = serve(lake, tmp_path / "serve.log")
    try:
        status, page = _get(f"{server.url}/dashboard/compare/?branch=main&batch=nope")
        assert status == 400 and "no batch &#x27;nope&#x27; on branch &#x27;main&#x27;" in page
        status, page = _get(f"{server.url}/dashboard/compare/?branch=main&batch=base")
        assert status == 400 and "is the first batch of branch" in page
        expected = compare(lake, "--base", "base", "--batch", "new")[1]["counts"]["experiences"]
        with sync_api.sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
            try:
                page = browser.new_page(viewport={"width": 1400, "height": 1000})
                page.set_default_timeout(30_000)
                errors: list[str] = []
                page.on("pageerror", lambda error: errors.append(str(error)))
                page.goto(f"{server.url}/dashboard/?branch=main&batch=new")
                page.wait_for_selector("body[data-ready=true]")
                page.click("#compare-previous")
                page.wait_for_url("**/dashboard/compare/?*")
                assert page.title() == "Compare base -> new on branch main"
                summary = page.locator("article.lg-metric").first.locator("table")
                shown = {
                    row.locator("td").nth(0).inner_text(): row.locator("td").nth(1).inner_text()
                    for row in summary.locator("tbody tr").all()
                }
                assert {tag: shown[tag] for tag in expected} == {tag: str(n) for tag, n in expected.items()}
                shifted = page.locator("article.lg-metric", has_text="Value Distribution (Shifted)")
                shifted.locator(".main-svg").first.wait_for()  # Plotly drew it: base and new in one figure
                assert shifted.locator(".barlayer .trace").count() == 2
                page.screenshot(path=str(_artifacts(tmp_path) / "compare.png"), full_page=True)
                page.select_option("#compare-base", "new")
                page.select_option("#compare-batch", "flaky-only")
                page.click("#compare-go")
                page.wait_for_url("**base=new&batch=flaky-only")
                assert page.title() == "Compare new -> flaky-only on branch main"
                page.goto(f"{server.url}/dashboard/trends/?branch=main")
                page.wait_for_selector("#lg-figure-2 .main-svg")
                assert page.locator("#compare-base").input_value() == "new"  # the last two batches by default
                assert page.locator("#compare-batch").input_value() == "flaky-only"
                page.select_option("#compare-base", "base")
                page.select_option("#compare-batch", "new")
                page.click("#compare-go")
                page.wait_for_url("**base=base&batch=new")
                assert page.locator("h1").inner_text() == "Compare base -> new on branch main"
                assert not errors
            finally:
                browser.close()
    finally:
        server.stop()


#: Builds of the trend: Drifting's mean stays near 1 for three builds, then jumps to 5 (an alert).
TREND = {"1.0": 1.0, "1.1": 1.2, "1.2": 0.9, "1.3": 5.0}


@pytest.fixture(scope="module")
def trend_lake(tmp_path_factory):
    batches = [
        (f"nightly-{build}", build, {"Drifting": [(mean, 0)], "Steady": [(1.0, 0)]}, "New Set")
        for build, mean in TREND.items()
    ]
    return make_lake(tmp_path_factory.mktemp("trend"), batches)


@pytest.mark.slow
def test_trend_alerts_in_metrics_dashboard_and_on_the_trends_page(trend_lake, tmp_path):
    lake, truth = trend_lake
    run = ["metrics", "dashboard", "--lake", lake, "--branch", "main", "--format", "json"]
    done = lakegate(*run, "--alert-k", "3", "--alert-builds", "3")
    assert done.returncode == 0, done.stderr  # no --fail-on
    checks = {c["metric"]: c for c in json.loads(done.stdout)["trend_checks"]}
    builds = list(TREND)
    for metric, per_build in {
        "Mean Value": {
            b: np.mean([np.mean(r["values"]) for runs in truth[f"nightly-{b}"].values() for r in runs]) for b in builds
        },
        "Batch Mean": {
            b: np.mean([v for runs in truth[f"nightly-{b}"].values() for r in runs for v in r["values"]])
            for b in builds
        },
    }.items():
        earlier = [float(per_build[b]) for b in builds[:-1]]
        mean, sd = float(np.mean(earlier)), float(np.std(earlier, ddof=1))
        check = checks[metric]
        assert check["build"] == "1.3" and check["history_builds"] == builds[:-1]
        assert check["value"] == pytest.approx(float(per_build["1.3"]), rel=1e-12)
        assert (check["mean"], check["sd"]) == (pytest.approx(mean, rel=1e-12), pytest.approx(sd, rel=1e-9))
        assert check["alert"] == (abs(float(per_build["1.3"]) - mean) > 3 * sd)
    assert checks["Mean Value"]["alert"] is True  # Drifting's jump of about 4 standard deviations of its history
    assert lakegate(*run, "--fail-on", "regression").returncode == 5
    assert lakegate(*run, "--fail-on", "regression", "--alert-k", "1000").returncode == 0
    assert lakegate(*run, "--fail-on", "regression", "--alert-builds", "1").returncode == 0  # 2 builds needed
    table = lakegate("metrics", "dashboard", "--lake", lake, "--branch", "main", "--report", tmp_path / "t.html")
    assert "ALERT Mean Value: build 1.3" in table.stdout
    assert "Trend alerts" in (tmp_path / "t.html").read_text()
    server = serve(lake, tmp_path / "serve.log")
    try:
        status, page = _get(f"{server.url}/dashboard/trends/?branch=main")
        assert status == 200 and '<li class="lg-alert">Mean Value: build 1.3' in page
        status, page = _get(f"{server.url}/dashboard/trends/?branch=main&k=1000")
        assert status == 200 and "lg-alert" not in page.split("Trend alerts", 1)[1][:200]
    finally:
        server.stop()


def test_compare_fail_on_regression_exit_codes(trend_lake, capsys):
    """Exit 5 when a trend alert marks a metric of the new batch's build, over the batches up to it
    (the command run in this process: four runs of it, each cheap)."""
    lake, truth = trend_lake
    builds = list(TREND)
    per_build = {
        b: float(np.mean([np.mean(r["values"]) for runs in truth[f"nightly-{b}"].values() for r in runs]))
        for b in builds
    }

    def compare_exit(*args: str) -> tuple[int, dict]:
        code = main(["compare", "--lake", str(lake), "--branch", "main", "--format", "json", *args])
        out, err = capsys.readouterr()
        assert code in (0, 4, 5), err
        return code, json.loads(out)

    code, answer = compare_exit("--base-build", "1.2", "--build", "1.3", "--fail-on", "regression")
    check = next(c for c in answer["trend_checks"] if c["metric"] == "Mean Value")
    earlier = [per_build[b] for b in builds[:-1]]
    assert (check["build"], check["history_builds"], check["alert"]) == ("1.3", builds[:-1], True)
    assert check["value"] == pytest.approx(per_build["1.3"], rel=1e-12)
    assert abs(per_build["1.3"] - np.mean(earlier)) > 3 * np.std(earlier, ddof=1)  # Drifting's jump, by construction
    assert code == 5
    # 1.2 against 1.1: its value lies within the history of 1.0 and 1.1, and later batches are not looked at
    code, answer = compare_exit("--base", "nightly-1.1", "--batch", "nightly-1.2", "--fail-on", "regression")
    checks = {c["metric"]: (c["build"], c["alert"]) for c in answer["trend_checks"]}
    assert checks == {m: ("1.2", False) for m in ("Mean Value", "Batch Mean", "Fresh Metric")} and code == 0
    assert abs(per_build["1.2"] - np.mean(earlier[:2])) <= 3 * np.std(earlier[:2], ddof=1)
    insensitive = compare_exit(
        "--base", "nightly-1.2", "--batch", "nightly-1.3", "--fail-on", "regression", "--alert-k", "1000"
    )
    assert insensitive[0] == 0
    # both asked for: a new failure (4) wins over a regression (5)
    failed = any(
        expected_status(float(np.mean(truth["nightly-1.2"][e][0]["values"]))) == "PASSED"
        and expected_status(float(np.mean(truth["nightly-1.3"][e][0]["values"]))) != "PASSED"
        for e in truth["nightly-1.3"]
    )
    with pytest.raises(SystemExit) as usage:  # a malformed command line: argparse's 2, naming the choices
        main(["compare", "--lake", str(lake), "--branch", "main", "--base", "a", "--batch", "b", "--fail-on", "slower"])
    assert usage.value.code == 2 and "--fail-on: invalid choice: 'slower'" in capsys.readouterr().err
    both = ("--fail-on", "regression", "--fail-on", "new-failures")
    assert compare_exit("--base", "nightly-1.2", "--batch", "nightly-1.3", *both)[0] == (4 if failed else 5)


@pytest.mark.slow
def test_compare_on_the_real_trino_matches_the_embedded_engine(built, trino_url):
    """The lake registered in the real Trino 476 (`lakegate trino-ddl`, hive catalog over the lake's
    folder): `compare` and `flakes` forwarded there answer as on the embedded engine."""
    lake, _ = built
    prefix = f"compare_{uuid.uuid4().hex[:8]}_"
    ddl = lakegate("trino-ddl", "--lake", lake, "--location", f"local://{lake.resolve()}", "--schema-prefix", prefix)
    assert ddl.returncode == 0, ddl.stderr
    schema = f"{prefix}main"
    host, port = trino_url.removeprefix("http://").split(":")
    cursor = trino.dbapi.connect(host=host, port=int(port), user="compare").cursor()
    try:
        for statement in re.sub(r"^--.*$", "", ddl.stdout, flags=re.M).split(";"):
            if statement.strip():
                cursor.execute(statement)
                cursor.fetchall()
        remote = ["--backend", "trino", "--trino-url", trino_url, "--trino-schema-map", f"main={schema}"]
        for command in (["compare", "--base", "base", "--batch", "new"], ["flakes", "--all"]):
            answers = [
                lakegate(*command, "--lake", lake, "--branch", "main", "--format", "json", *extra)
                for extra in ([], remote)
            ]
            assert [a.returncode for a in answers] == [0, 0], answers[1].stderr
            embedded, forwarded = (json.loads(a.stdout) for a in answers)
            embedded.pop("seconds", None), forwarded.pop("seconds", None)
            assert same(forwarded, embedded)
    finally:
        cursor.execute(f"SHOW TABLES FROM hive.{schema}")
        for (table,) in cursor.fetchall():
            cursor.execute(f'DROP TABLE hive.{schema}."{table}"')
            cursor.fetchall()
        cursor.execute(f"DROP SCHEMA hive.{schema}")
        cursor.fetchall()
