"""The real Trino 476 that judges lakegate's answers (tools/trino_server.py).

`trino_url` gives a test the URL of a running Trino. Outside CI it uses the one that
`python3 dev.py trino start` started and skips with that command when none runs; under CI=true it
starts one itself (once per machine, behind a file lock shared by the xdist workers), and a Trino
that cannot be fetched or started fails the test.
"""

from __future__ import annotations

import fcntl
import os

import pytest
import trino_server


@pytest.fixture(scope="session")
def trino_url() -> str:
    state = trino_server.running()
    if state is not None:
        return state["url"]
    if os.environ.get("CI") != "true":
        pytest.skip("needs a real Trino 476: python3 dev.py trino start")
    trino_server.HOME.mkdir(parents=True, exist_ok=True)
    with open(trino_server.HOME / "start.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            return trino_server.start()
        except trino_server.TrinoError as error:
            pytest.fail(f"CI needs a real Trino 476 and it could not start: {error}")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Tests marked `slow` (a minute or more of end-to-end work) run first, so that under xdist
    (`python3 dev.py test`: two workers that steal work from each other) none of them starts last
    while the other worker sits idle."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
