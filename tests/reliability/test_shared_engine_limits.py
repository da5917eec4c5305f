"""The query limits hold for everything that shares the Engine, not only `/v1/statement`: the debug
dashboard's ad hoc queries of a real `lakegate serve` (the same query workers and slots), and a real
`lakegate metrics run` (its own workers, with the default limits: 2GB, 300 s) whose config holds a
metric that builds a list without bound. The runaway query fails with Trino's memory error in the
dashboard's answer or the metric's result, the other work is done, and the memory the processes held
together stayed under the limit plus the documented margin (docs/sql-endpoint.md, "Memory").
"""

from __future__ import annotations

import json
import subprocess

import requests

from lakegate.fixtures.generate import CONFIG_PATH
from tests.gateway.conftest import CLI
from tests.reliability.conftest import MEMORY_LIMIT_MB, RSS_MARGIN_MB, MemoryWatch, capped, select_one_seconds
from tests.reliability.test_query_isolation import AT_ONCE, BOUNDED, HUGE_LIST_BOMB, LIST_BOMB

#: `lakegate metrics run`'s default --memory-limit is 2GB (docs/sql-endpoint.md).
RUN_LIMIT_MB = 2000


def _config(bomb: str) -> str:
    """The example config's topics, with one metric that counts samples and one that runs `bomb`."""
    topics = CONFIG_PATH.read_text().split("\nmetrics:", 1)[0]
    metrics = {
        "Samples": {"type": "test", "query_string": "SELECT count(*) FROM odom_linear_velocity"},
        "Runaway": {"type": "test", "query_string": bomb},
    }
    for spec in metrics.values():
        spec.update(template_type="system", template="scalar", description="d")
    return topics + "\nmetrics: " + json.dumps(metrics) + "\n"


def test_the_dashboards_queries_hold_the_servers_limits(server, tmp_path):
    process, url, lake = server
    config = tmp_path / "config.resim.yaml"
    config.write_text(_config("SELECT 1"))
    sync = [*CLI, "metrics", "sync", "--lake", str(lake), "--branch", "main", "--metrics-config-path", str(config)]
    assert subprocess.run(sync, capture_output=True, timeout=120).returncode == 0
    api = f"{url}/dashboard/api/sessions"
    session = requests.post(api, json={"branch": "main", "batch": "b1"}, timeout=60).json()
    ask = f"{api}/{session['id']}/query"
    with MemoryWatch(process.pid) as memory:
        answer = requests.post(ask, json={"sql": LIST_BOMB, "scope": "batch"}, timeout=60).json()
    assert answer["error"]["name"] in BOUNDED, answer
    assert "Traceback" not in answer["error"]["message"] and str(lake) not in answer["error"]["message"]
    assert select_one_seconds(url, lake) < AT_ONCE
    counted = requests.post(
        ask, json={"sql": "SELECT count(*) FROM odom_linear_velocity", "scope": "batch"}, timeout=60
    )
    assert counted.json()["rows"][0][0] > 0
    print(f"peak memory of the server's processes: {memory.peak:.0f} MB")
    assert memory.peak < MEMORY_LIMIT_MB + RSS_MARGIN_MB


def test_metrics_run_holds_the_same_limits(tmp_path):
    from tests.gateway.conftest import build_server_lake

    lake = build_server_lake(tmp_path)
    config = tmp_path / "config.resim.yaml"
    config.write_text(_config(HUGE_LIST_BOMB))
    command = [
        *CLI, "metrics", "run", "--lake", str(lake), "--branch", "main", "--batch", "b1",
        "--metrics-config-path", str(config), "--all-metrics", "--format", "json",
    ]  # fmt: skip
    run = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=capped)
    with MemoryWatch(run.pid) as memory:
        out, err = run.communicate(timeout=300)
    assert run.returncode == 3 and "Traceback" not in err, err  # 3: a metric errored, none blocks
    results = json.loads(out)["metrics"]
    runaway = [r for r in results if r["metric"] == "Runaway"]
    samples = [r for r in results if r["metric"] == "Samples"]
    assert len(runaway) == len(samples) == 2  # both jobs of batch b1
    for result in runaway:
        assert result["status"] == "ERROR" and "Query exceeded" in result["error"]["message"], result
    assert all(result["scalar_value"] > 0 for result in samples), samples
    print(f"peak memory of metrics run's processes: {memory.peak:.0f} MB")
    assert memory.peak < RUN_LIMIT_MB + RSS_MARGIN_MB
