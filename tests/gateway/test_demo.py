"""`lakegate demo`, run as a real subprocess from a folder outside the repository (so the example
config must come from the installed package), twice on the same lake."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from lakegate.gateway.cli.demo import BATCH, BRANCH
from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.gateway.metrics.plotly_arrays import plain_figure
from lakegate.gateway.metrics.results_table import read_results
from lakegate.lake.catalog import Catalog

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]


def demo(*args, cwd):
    result = subprocess.run(
        [*CLI, "demo", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        env={**os.environ, "COLUMNS": "200"},
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    return result.stdout


@pytest.mark.slow
def test_demo_from_anywhere_with_no_arguments_then_again(tmp_path):
    out = demo(cwd=tmp_path)
    lake = tmp_path / "lake-demo"
    report = lake / "report.html"
    assert f"report:  {report}" in out and f"lake:    {lake}" in out
    for name in ("Warehouse Loop", "Robot Speed", "Passed Jobs by Tag Group", "Total Samples: "):
        assert name in out
    assert re.search(
        r"batch 'nav-regression-1' on branch 'main': BLOCKER \(8 jobs: 4 PASSED, 2 WARNING, 2 BLOCKER;", out
    )

    backend = DuckDBBackend(lake)
    try:
        statuses = backend.execute(
            "SELECT job_conflated_status, COUNT(*) FROM metadata WHERE batch_id = ? GROUP BY 1 ORDER BY 1",
            branch=BRANCH,
            params=[BATCH],
        ).rows()
        unevaluated = backend.execute(
            "SELECT count(*) FROM metadata WHERE job_conflated_status IS NULL", branch=BRANCH
        ).rows()
    finally:
        backend.close()
    assert unevaluated == [(0,)]  # the earlier builds' batches are evaluated too: no NULL status to explain
    assert statuses == [("BLOCKER", 2), ("PASSED", 4), ("WARNING", 2)]  # the cycle of 6, two reruns PASSED

    html = report.read_text()
    for kind in ("scatter", "bar", "histogram", "pie"):  # line, bar and state timeline, histogram, pie
        assert f'"type":"{kind}"' in html
    assert '"orientation":"h"' in html  # the state timeline's segments
    assert 'class="lg-table"' in html and 'class="lg-scalar"' in html  # table, scalar
    assert "data:image/gif;base64" in html and "data:image/png;base64" in html  # camera feed, event images
    assert "Goal 1 Reached at " in html  # events
    assert "<script src=" not in html and "Plotly.newPlot" in html  # offline: plotly.js is embedded

    check_trends(out, lake)
    check_comparison(out, lake)
    check_next_hints(out, tmp_path)
    check_readme_commands(tmp_path)

    results = read_results(lake, BRANCH, BATCH)
    again = demo("--lake", lake, "--no-progress", cwd=tmp_path)
    assert "4 PASSED, 2 WARNING, 2 BLOCKER" in again
    assert len(read_results(lake, BRANCH, BATCH)) == len(results) == 8 * 9 + 6  # replaced, not added
    assert len(Catalog(lake).jobs(BRANCH)) == 8 + 3 + 6  # the batch and the two earlier builds' batches


def check_next_hints(out: str, cwd: Path) -> None:
    """Every command the demo suggests runs as printed, in a shell in the folder it ran from (serve until
    its start-up line)."""
    hints = [line.strip() for line in out.split("\nnext:\n", 1)[1].splitlines() if line.strip()]
    assert len(hints) >= 6 and all(" -m lakegate.gateway.cli " in hint for hint in hints)  # how this test ran it
    for hint in hints:
        if " serve " in hint:
            server = subprocess.Popen(  # `exec`: the shell becomes the server, so terminate() stops the server
                "exec " + hint.replace("--lake", "--port 0 --lake"),
                shell=True,
                cwd=cwd,
                stdout=subprocess.PIPE,
                text=True,
            )
            try:
                assert "lakegate: serving" in server.stdout.readline()
            finally:
                server.terminate()  # right after start-up: its query workers may still be starting under load
                server.wait(timeout=120)
            continue
        done = subprocess.run(hint, shell=True, cwd=cwd, capture_output=True, text=True, timeout=120)
        # exit codes of a gate: 2 a metric blocks (metrics run), 4 a new failure (compare --fail-on)
        assert done.returncode in (0, 2, 4), f"{hint}: {done.stderr}"
        assert done.stdout.strip() and "usage:" not in done.stderr and "lakegate:" not in done.stderr, hint


def check_readme_commands(cwd: Path) -> None:
    """README's commands to explore the demo's lake run on it (`.venv/bin/lakegate` as this test runs
    lakegate), in the folder the demo ran in; the report metric's page is written."""
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    block = readme.split("Then explore the lake", 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    commands = [c.strip() for c in block.replace("\\\n", " ").split(".venv/bin/lakegate ") if c.strip()]
    assert len(commands) == 4 and commands[-1].startswith("metrics report --lake lake-demo")
    for command in commands:
        done = subprocess.run(
            f"{' '.join(CLI)} {command}", shell=True, cwd=cwd, capture_output=True, text=True, timeout=120
        )
        assert done.returncode in (0, 2), f"{command}: {done.stderr}"  # 2: a metric of the batch blocks
        assert "NULL" not in done.stdout and "lakegate:" not in done.stderr, command
    assert "Job Outcomes by Build" in (cwd / "lake-demo" / "builds.html").read_text()


def check_comparison(out: str, lake: Path) -> None:
    """The demo's comparison of builds 1.4.1 and 1.4.2 shows the regression, the fix and the flaky
    experience built into it (gateway/cli/demo.py), in the terminal and through `lakegate compare`."""
    assert f"compare: {lake / 'compare.html'}" in out
    assert "flaky: Narrow Aisle" in out and "new failures: Parking Lot" in out
    done = subprocess.run(
        [*CLI, "compare", "--lake", lake, "--branch", BRANCH, "--base-build", "1.4.1", "--build", "1.4.2"]
        + ["--format", "json", "--fail-on", "new-failures"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 4, done.stderr  # Parking Lot passed on 1.4.1 and blocks on 1.4.2
    tags = {e["experience"]: e["tag"] for e in json.loads(done.stdout)["experiences"]}
    assert tags == {
        "Parking Lot": "new failure",
        "Narrow Aisle": "flaky",
        "Loading Dock": "fixed",
        "Office Corridor": "still failing",
        "Open Field": "still failing",
        "Warehouse Loop": "same",
    }
    html = (lake / "compare.html").read_text()
    assert "<script src=" not in html and "Plotly.newPlot" in html


def check_trends(out: str, lake: Path) -> None:
    """The demo's dashboard metric: mean time to the final goal per build, over the jobs that reached
    3 goals, computed here from the generated emissions files (the builds in the order they ran)."""
    assert f"trends:  {lake / 'trends.html'}" in out
    assert (
        "dashboard of branch 'main': PASSED (2 metrics over 3 batches, every batch: nightly-1.4.0, "
        "nightly-1.4.1, nav-regression-1;" in out
    )
    totals: dict[str, list[float]] = {}
    for emissions in sorted((lake / "_demo_inputs").glob("**/emissions.resim.jsonl")):
        metadata = yaml.safe_load((emissions.parent / "metadata.yaml").read_text())
        times = [
            line["$data"]["time_s"]
            for line in map(json.loads, emissions.read_text().splitlines())
            if line["$metadata"]["topic"] == "time_to_goal"
        ]
        if len(times) == 3:
            totals.setdefault(metadata["build_version"], []).append(sum(times))
    html = (lake / "trends.html").read_text()
    data = plain_figure(json.loads(html.split('Plotly.newPlot("lg-figure-2", ', 1)[1].split(", {", 1)[0]))
    assert data[0]["x"] == ["1.4.0", "1.4.1", "1.4.2"]
    assert data[0]["y"] == pytest.approx([sum(totals[b]) / len(totals[b]) for b in data[0]["x"]], rel=1e-12)
    for batch in ("nightly-1.4.0", "nightly-1.4.1", BATCH):  # the link_path column links to the served batch page
        assert f'<a href="http://127.0.0.1:8080/dashboard/?branch=main&amp;batch={batch}">{batch}</a>' in html
