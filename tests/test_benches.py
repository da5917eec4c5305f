"""Every benchmark in bench/ runs at its `--smoke` size, so that none can rot: a crash fails the
suite; no timing is asserted, and a smoke run leaves bench/RESULTS.md as it was."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"
SCRIPTS = sorted(p.stem for p in BENCH.glob("*.py") if p.stem != "results")
#: Benches that compare with the real Trino 476 (the `trino_url` fixture: started under CI).
WITH_TRINO = {"vs_trino", "trino_visibility"}


def test_every_bench_is_listed():
    assert {"emit", "metrics", "server", "translate", "scale", "peer"} <= set(SCRIPTS)


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("name", SCRIPTS)
def test_bench_runs_at_smoke_size(name, request):
    results = (BENCH / "RESULTS.md").read_bytes()
    trino = ["--trino-url", request.getfixturevalue("trino_url")] if name in WITH_TRINO else []
    done = subprocess.run(
        [sys.executable, str(BENCH / f"{name}.py"), "--smoke", *trino], capture_output=True, text=True, timeout=880
    )
    assert done.returncode == 0, f"bench/{name}.py --smoke failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    assert (BENCH / "RESULTS.md").read_bytes() == results, f"bench/{name}.py --smoke changed bench/RESULTS.md"
