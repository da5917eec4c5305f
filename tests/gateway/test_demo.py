"""`lakegate demo`, run as a real subprocess from a folder outside the repository (so the example
config must come from the installed package), twice on the same lake."""

from __future__ import annotations

import os
import re
import subprocess
import sys

from lakegate.gateway.cli.demo import BATCH, BRANCH
from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.gateway.metrics.results import read_results
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


def test_demo_from_anywhere_with_no_arguments_then_again(tmp_path):
    out = demo(cwd=tmp_path)
    lake = tmp_path / "lake-demo"
    report = lake / "report.html"
    assert f"report: {report}" in out and f"lake:   {lake}" in out
    for name in ("Warehouse Loop", "Robot Speed", "Passed Jobs by Tag Group", "Total Samples: "):
        assert name in out
    assert re.search(
        r"batch 'nav-regression-1' on branch 'main': BLOCKER \(6 jobs: 2 PASSED, 2 WARNING, 2 BLOCKER;", out
    )

    backend = DuckDBBackend(lake)
    try:
        statuses = backend.execute(
            "SELECT job_conflated_status, COUNT(*) FROM metadata GROUP BY 1 ORDER BY 1", branch=BRANCH
        ).rows()
    finally:
        backend.close()
    assert statuses == [("BLOCKER", 2), ("PASSED", 2), ("WARNING", 2)]

    html = report.read_text()
    for kind in ("scatter", "bar", "histogram", "pie"):  # line, bar and state timeline, histogram, pie
        assert f'"type":"{kind}"' in html
    assert '"orientation":"h"' in html  # the state timeline's segments
    assert 'class="lg-table"' in html and 'class="lg-scalar"' in html  # table, scalar
    assert "data:image/gif;base64" in html and "data:image/png;base64" in html  # camera feed, event images
    assert "Goal 1 Reached at " in html  # events
    assert "<script src=" not in html and "Plotly.newPlot" in html  # offline: plotly.js is embedded

    results = read_results(lake, BRANCH, BATCH)
    again = demo("--lake", lake, "--no-progress", cwd=tmp_path)
    assert "2 PASSED, 2 WARNING, 2 BLOCKER" in again
    assert len(read_results(lake, BRANCH, BATCH)) == len(results) == 6 * 9 + 6  # replaced, not added
    assert len(Catalog(lake).jobs(BRANCH)) == 6
