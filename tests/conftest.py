"""The real Trino 476 that judges lakegate's answers (tools/trino_server.py).

`trino_url` gives a test the URL of a running Trino. Outside CI it uses the one that
`python3 dev.py trino start` started (waiting for one being started) and skips with that command
when none runs; under CI=true it starts one itself, or waits for the one `.ci/run` starts in the
background (once per machine: `trino_server.start` holds a file lock, shared by the xdist
workers), and a Trino that cannot be fetched or started fails the test.
"""

from __future__ import annotations

import os

import pytest
import trino_server


@pytest.fixture(scope="session")
def trino_url() -> str:
    if not trino_server.starting():  # else one is starting: it answers before its hive catalog is ready
        state = trino_server.running()
        if state is not None:
            return state["url"]
        if os.environ.get("CI") != "true":
            pytest.skip("needs a real Trino 476: python3 dev.py trino start")
    try:
        return trino_server.start()  # or waits for the one being started, and takes it
    except trino_server.TrinoError as error:
        pytest.fail(f"CI needs a real Trino 476 and it could not start: {error}")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Tests marked `slow` (a minute or more of end-to-end work) run first, so that under xdist
    (`python3 dev.py test`: two workers that steal work from each other) none of them starts last
    while the other worker sits idle."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
