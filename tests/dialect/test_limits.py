"""Functions that allocate by an argument refuse oversized arguments before DuckDB allocates
anything, also for constant arguments, in a real `lakegate query` process whose address space is
capped (so a regression fails with an out-of-memory error instead of exhausting the machine).

Trino's checks and messages: trinodb/trino core/trino-main/src/main/java/io/trino/operator/scalar/
RepeatFunction.java, SequenceFunction.java, StringFunctions.java (pad); see cases/limits.yaml.
"""
from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

import pytest

from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job

#: Address space of the `lakegate query` process: enough to run it, far below what the queries
#: below would allocate unchecked (4 to 24 GB).
ADDRESS_SPACE = 2 * 1024 ** 3
CONFIG = "version: 1\ntopics:\n  sample:\n    schema: {n: int}\n"


@pytest.fixture(scope="module")
def tiny_lake(tmp_path_factory) -> Path:
    """A lake with one topic, `sample`, of two rows (n = 1, 2)."""
    root = tmp_path_factory.mktemp("tiny-lake")
    (root / "config.resim.yaml").write_text(CONFIG)
    emissions = root / "emissions.jsonl"
    emissions.write_text("".join(json.dumps({"$metadata": {"topic": "sample", "timestamp": i}, "$data": {"n": i}})
                                 + "\n" for i in (1, 2)))
    ingest_job(root / "lake", "main", "b1", "j1", [emissions], config=load_config([root / "config.resim.yaml"]),
               metadata={"experience_name": "tiny"})
    return root / "lake"


@dataclass
class Run:
    """One finished `lakegate query` process."""

    code: int
    stdout: str
    stderr: str
    peak_mb: float  # its peak resident memory


def _cap_address_space() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


def query(lake: Path, sql: str, tmp_path: Path) -> Run:
    """`lakegate query --lake LAKE --format json SQL` in a process with a capped address space
    (killed after 120 s)."""
    out, err = tmp_path / "stdout", tmp_path / "stderr"
    with open(out, "w") as stdout, open(err, "w") as stderr:
        process = subprocess.Popen([sys.executable, "-m", "lakegate.gateway.cli", "query", "--lake", str(lake),
                                    "--format", "json", sql], stdout=stdout, stderr=stderr,
                                   preexec_fn=_cap_address_space)
    killer = threading.Timer(120, process.kill)
    killer.start()
    _, status, usage = os.wait4(process.pid, 0)  # wait4 gives this child's own peak memory
    killer.cancel()
    process.returncode = os.waitstatus_to_exitcode(status)
    return Run(process.returncode, out.read_text(), err.read_text(), usage.ru_maxrss / 1024)


#: Peak memory a refused query may reach: the process alone takes about 150 MB; each query below
#: needs at least 400 MB more if the size check came after the allocation.
PEAK_MB = 400


@pytest.mark.parametrize("sql, message", [
    ("SELECT cardinality(repeat(1, 1000000000))", "count argument of repeat function must be less than or equal to 10000"),
    ("SELECT repeat('x', 1000000000)", "count argument of repeat function must be less than or equal to 10000"),
    ("SELECT cardinality(repeat(1, 50000000))", "count argument of repeat function must be less than or equal to 10000"),
    ("SELECT cardinality(repeat(n, 50000000)) FROM sample", "count argument of repeat function must be less than"),
    ("SELECT cardinality(repeat(lpad('', 100000, 'x'), 10000))", "result of repeat function must not take more than"),
    ("SELECT cardinality(sequence(1, 1000000000))", "result of sequence function must not have more than 10000"),
    ("SELECT cardinality(sequence(1, 50000000))", "result of sequence function must not have more than 10000"),
    ("SELECT cardinality(sequence(n, n * 50000000)) FROM sample", "result of sequence function must not have"),
    ("SELECT length(lpad('x', 1000000000, 'y'))", "Target length must be at most 1000000 in lakegate"),
    ("SELECT length(rpad('x', 2000000000, 'y'))", "Target length must be at most 1000000 in lakegate"),
])
def test_oversized_allocation_is_refused_before_allocating(tiny_lake, tmp_path, sql, message):
    run = query(tiny_lake, sql, tmp_path)
    assert run.code == 1, run.stdout + run.stderr
    assert message in run.stderr
    assert "Traceback" not in run.stderr
    assert run.peak_mb < PEAK_MB


def test_capped_process_still_answers_within_the_limits(tiny_lake, tmp_path):
    run = query(tiny_lake, "SELECT cardinality(repeat(n, 10000)), cardinality(sequence(1, 10000)), "
                           "length(lpad('x', 1000000, 'y')) FROM sample ORDER BY n", tmp_path)
    assert run.code == 0, run.stderr
    assert json.loads(run.stdout)["rows"] == [[10000, 10000, 1000000], [10000, 10000, 1000000]]
