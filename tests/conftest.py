"""The real Trino 476 that judges lakegate's answers (tools/trino_server.py).

`trino_url` gives a test the URL of a running Trino. Outside CI it uses the one that
`python3 dev.py trino start` started (waiting for one being started) and skips with that command
when none runs; under CI=true it starts one itself, or waits for the one `.ci/run` starts in the
background (once per machine: `trino_server.start` holds a file lock, shared by the xdist
workers), and a Trino that cannot be fetched or started fails the test.
"""

from __future__ import annotations

import contextlib
import itertools
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


def pytest_collection_finish(session: pytest.Session) -> None:
    """A Trino being started now (`.ci/run` starts it in the background while the suite is collected)
    is waited for here, before the first test: its fetch and start count against no test's timeout
    (a failed start is reported by `trino_url`, which tries again)."""
    if trino_server.starting():
        with contextlib.suppress(trino_server.TrinoError):
            trino_server.start()


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Tests marked `slow` (a minute or more of end-to-end work) run first, on every worker: under
    xdist (`python3 dev.py test`: workers that steal work from each other) none of them starts last
    while another worker sits idle, and they do not all queue on one worker (together they take
    longer than half the suite). A module's slow tests stay together (its module fixtures are made
    once), the cases of a parametrized one are shared out."""
    slow: dict[str, list[pytest.Item]] = {}
    for item in items:
        if item.get_closest_marker("slow") is not None:
            slow.setdefault(item.nodeid if hasattr(item, "callspec") else item.path.as_posix(), []).append(item)
    rest = [item for item in items if item.get_closest_marker("slow") is None]
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", 1))
    items[:] = [item for chunk in worker_chunks(list(slow.values()), rest, workers) for item in chunk]


def worker_chunks(slow: list[list], rest: list, workers: int) -> list[list]:
    """The run order as the consecutive chunks `--dist worksteal` first hands each of `workers` (the
    first worker gets the pending tests // workers, the next what is left // (workers - 1), ...),
    each starting with its share of the `slow` groups (dealt in turn), then filled with `rest` in order."""
    chunks, left, remaining = [], sum(map(len, slow)) + len(rest), iter(rest)
    for index in range(workers):
        size = left // (workers - index)
        left -= size
        chunk = [item for group in slow[index::workers] for item in group]
        chunks.append(chunk + list(itertools.islice(remaining, max(0, size - len(chunk)))))
    chunks[-1] += list(remaining)
    return chunks
