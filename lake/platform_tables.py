"""The tables ReSim's platform generates for every job, read from the job's own files.

`container_performance` (each container's CPU and memory over the run) comes from the job's
`resource_metrics.resim.jsonl` and `test_length_seconds` (the length of the run) from its
`test_length_metric.resim.jsonl`: emissions files (JSON lines as the Emitter writes them) whose
lines carry these topics. Their fields are those ReSim publishes for the two tables
(docs/resim-compat.md, "Platform tables", cites the source). Every branch has both tables, empty
when no job brought the files, so a metric over them runs instead of failing on a missing table.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from lakegate.lake.config import Topic

CONTAINER_PERFORMANCE = "container_performance"
TEST_LENGTH_SECONDS = "test_length_seconds"

#: The platform tables as topics (field -> config type), in ReSim's published column order.
TOPICS: dict[str, Topic] = {
    CONTAINER_PERFORMANCE: Topic(
        CONTAINER_PERFORMANCE,
        {
            "timestamp_seconds": "float",
            "container_name": "string",
            "cpu_usage_core_seconds_per_sec": "float",
            "cpu_throttling_seconds": "float",
            "memory_usage_gib": "float",
            "memory_limit_failures": "float",
        },
    ),
    TEST_LENGTH_SECONDS: Topic(TEST_LENGTH_SECONDS, {"test_length": "float"}),
}

#: The file of a job that each platform table is read from.
FILES = {
    "resource_metrics.resim.jsonl": CONTAINER_PERFORMANCE,
    "test_length_metric.resim.jsonl": TEST_LENGTH_SECONDS,
}

#: Columns of the platform tables that other topics do not have (one value per job, from `metadata`).
EXTRA_JOB_COLUMNS = (("org_id", "varchar"),)


def files_beside(emissions: Sequence[Path]) -> list[Path]:
    """The platform files in the folders of the given emissions files that are not among them."""
    given = {path.resolve() for path in emissions}
    found = []
    for folder in dict.fromkeys(path.resolve().parent for path in emissions):
        for name in FILES:
            candidate = folder / name
            if candidate.is_file() and candidate not in given:
                found.append(candidate)
                given.add(candidate)
    return found
