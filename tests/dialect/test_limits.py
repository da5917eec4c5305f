"""Limits. Functions that allocate by an argument refuse oversized arguments before DuckDB allocates
anything, also for constant arguments, in a real `lakegate query` process whose address space is
capped (so a regression fails with an out-of-memory error instead of exhausting the machine).

Trino's checks and messages: trinodb/trino core/trino-main/src/main/java/io/trino/operator/scalar/
RepeatFunction.java, SequenceFunction.java, StringFunctions.java (pad); their cases are in cases/array.yaml
and cases/string.yaml.
Parsing and translation are bounded: nesting and token count are checked before parsing, and no
construct takes exponential time up to the nesting limit.
"""

from __future__ import annotations

import json
import os
import random
import re
import resource
import signal
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

import duckdb
import pytest

from lakegate.dialect import guard
from lakegate.dialect.errors import DialectError, runtime_error
from lakegate.dialect.translate import translate
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job

#: Address space of the `lakegate query` process: enough to run it, far below what the queries
#: below would allocate unchecked (4 to 24 GB).
ADDRESS_SPACE = 2 * 1024**3
CONFIG = "version: 1\ntopics:\n  sample:\n    schema: {n: int}\n"


@pytest.fixture(scope="module")
def tiny_lake(tmp_path_factory) -> Path:
    """A lake with one topic, `sample`, of two rows (n = 1, 2)."""
    root = tmp_path_factory.mktemp("tiny-lake")
    (root / "config.resim.yaml").write_text(CONFIG)
    emissions = root / "emissions.jsonl"
    emissions.write_text(
        "".join(
            json.dumps({"$metadata": {"topic": "sample", "timestamp": i}, "$data": {"n": i}}) + "\n" for i in (1, 2)
        )
    )
    ingest_job(
        root / "lake",
        "main",
        "b1",
        "j1",
        [emissions],
        config=load_config([root / "config.resim.yaml"]),
        metadata={"experience_name": "tiny"},
    )
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
        process = subprocess.Popen(
            [sys.executable, "-m", "lakegate.gateway.cli", "query", "--lake", str(lake), "--format", "json", sql],
            stdout=stdout,
            stderr=stderr,
            preexec_fn=_cap_address_space,
        )
    killer = threading.Timer(120, process.kill)
    killer.start()
    _, status, usage = os.wait4(process.pid, 0)  # wait4 gives this child's own peak memory
    killer.cancel()
    process.returncode = os.waitstatus_to_exitcode(status)
    return Run(process.returncode, out.read_text(), err.read_text(), usage.ru_maxrss / 1024)


#: Peak memory a refused query may reach: the process with its query worker peaks near 410 MB; each
#: query below needs at least 400 MB more (50,000,000 values) if the size check came after the allocation.
PEAK_MB = 500


@pytest.mark.parametrize(
    "sql, message",
    [
        (
            "SELECT cardinality(repeat(1, 1000000000))",
            "count argument of repeat function must be less than or equal to 10000",
        ),
        ("SELECT repeat('x', 1000000000)", "count argument of repeat function must be less than or equal to 10000"),
        (
            "SELECT cardinality(repeat(1, 50000000))",
            "count argument of repeat function must be less than or equal to 10000",
        ),
        ("SELECT cardinality(repeat(n, 50000000)) FROM sample", "count argument of repeat function must be less than"),
        (
            "SELECT cardinality(repeat(lpad('', 100000, 'x'), 10000))",
            "result of repeat function must not take more than",
        ),
        ("SELECT cardinality(sequence(1, 1000000000))", "result of sequence function must not have more than 10000"),
        ("SELECT cardinality(sequence(1, 50000000))", "result of sequence function must not have more than 10000"),
        ("SELECT cardinality(sequence(n, n * 50000000)) FROM sample", "result of sequence function must not have"),
        ("SELECT length(lpad('x', 1000000000, 'y'))", "Target length must be at most 1000000 in lakegate"),
        ("SELECT length(rpad('x', 2000000000, 'y'))", "Target length must be at most 1000000 in lakegate"),
    ],
)
def test_oversized_allocation_is_refused_before_allocating(tiny_lake, tmp_path, sql, message):
    run = query(tiny_lake, sql, tmp_path)
    assert run.code == 1, run.stdout + run.stderr
    assert message in run.stderr
    assert "Traceback" not in run.stderr
    assert run.peak_mb < PEAK_MB


def test_capped_process_still_answers_within_the_limits(tiny_lake, tmp_path):
    run = query(
        tiny_lake,
        "SELECT cardinality(repeat(n, 10000)), cardinality(sequence(1, 10000)), "
        "length(lpad('x', 1000000, 'y')) FROM sample ORDER BY n",
        tmp_path,
    )
    assert run.code == 0, run.stderr
    assert json.loads(run.stdout)["rows"] == [[10000, 10000, 1000000], [10000, 10000, 1000000]]


# --- parsing and translation are bounded -----------------------------------------------------------
# Trino refuses what its parser cannot nest with SYNTAX_ERROR "statement is too large (stack overflow
# while parsing)" (trinodb/trino core/trino-parser/src/main/java/io/trino/sql/parser/SqlParser.java,
# TestSqlParser.testStackOverflowStatement); lakegate refuses past guard.MAX_NESTING levels, before parsing.
#: Generous bound for one translation: catches exponential blow-up (seconds to hours), not slowness.
BOUND_S = 5
#: Constructs that nest (opening, closing); each adds one level of brackets or CASE.
NESTINGS = {
    "array": ("ARRAY[", "]"),
    "row": ("ROW(", ")"),
    "paren": ("(", ")"),
    "call": ("abs(", ")"),
    "type-named-call": ("date(", ")"),
    "decimal-call": ("decimal(", ")"),
    "cast": ("CAST(", " AS bigint)"),
    "case": ("CASE WHEN true THEN ", " END"),
    "lambda": ("transform(ARRAY[1], x -> ", ")"),
    "subquery": ("(SELECT ", ")"),
    "subscript": ("ARRAY[", "][1]"),
    "if": ("if(true, ", ", 1)"),
    "greatest": ("greatest(", ", 1)"),
    "sequence": ("cardinality(sequence(1, ", "))"),
}


def _depth(sql: str) -> int:
    """Deepest nesting of brackets and CASE in `sql` (no strings or comments in these tests)."""
    depth = deepest = 0
    for token in re.findall(r"\w+|\S", sql):
        depth += (token in "([" or token == "CASE") - (token in ")]" or token == "END")
        deepest = max(deepest, depth)
    return deepest


def _nest(opening: str, closing: str, levels: int, inner: str = "1") -> str:
    return "SELECT " + opening * levels + inner + closing * levels


def _too_slow(signum, frame):
    raise TimeoutError(f"translation took over {BOUND_S} s")


def _translate_within_bound(sql: str) -> str:
    """'ok' or the Trino error name; fails on any other exception or past BOUND_S seconds."""
    previous = signal.signal(signal.SIGALRM, _too_slow)
    signal.setitimer(signal.ITIMER_REAL, BOUND_S)
    try:
        translate(sql, {})
        return "ok"
    except DialectError as error:
        assert "Traceback" not in error.message and "<class" not in error.message
        return error.error_name
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize("name", sorted(NESTINGS))
def test_nesting_up_to_the_limit_translates_and_deeper_is_refused_before_parsing(name):
    opening, closing = NESTINGS[name]
    inner = "DATE '2024-01-01'" if name == "type-named-call" else "1"
    levels = max(n for n in range(1, guard.MAX_NESTING + 1) if _depth(_nest(opening, closing, n)) <= guard.MAX_NESTING)
    assert _translate_within_bound(_nest(opening, closing, levels, inner)) in (
        "ok",
        "NOT_SUPPORTED",
        "INVALID_FUNCTION_ARGUMENT",
        "TYPE_MISMATCH",
        "FUNCTION_NOT_FOUND",
    )
    deeper = guard.MAX_NESTING + 1
    with pytest.raises(DialectError) as refused:
        translate(_nest(opening, closing, deeper, inner), {})
    assert refused.value.error_name == "SYNTAX_ERROR"
    assert "statement is too large (stack overflow while parsing)" in refused.value.message


def test_24_deep_array_constructor_is_answered():
    # ~180 bytes of SQL that took sqlglot's parser 2^24 steps before (ARRAY[ was parsed twice per level)
    sql = "SELECT " + "ARRAY[" * 24 + "1" + "]" * 24
    assert _translate_within_bound(sql) == "ok"
    assert translate(sql, {}).columns == (("_col0", "array(" * 24 + "integer" + ")" * 24),)  # cached


def test_random_nestings_up_to_the_limit_translate_in_bounded_time():
    rng = random.Random(9)
    for _ in range(60):
        chosen = [NESTINGS[rng.choice(sorted(NESTINGS))] for _ in range(rng.randint(1, 40))]
        text = "1"
        for opening, closing in chosen:
            if _depth(opening + text + closing) > guard.MAX_NESTING:
                break
            text = opening + text + closing
        _translate_within_bound("SELECT " + text)


def test_query_text_over_the_token_budget_is_refused_before_parsing():
    error = pytest.raises(DialectError, translate, "SELECT " + ", ".join(["1"] * 200_000), {}).value
    assert error.error_name == "QUERY_TEXT_TOO_LARGE" and f"more than {guard.MAX_TOKENS} tokens" in error.message
    # the token past the budget is the comma after the 10,000th `1`
    assert (error.line, error.column) == (1, len("SELECT ") + 3 * guard.MAX_TOKENS // 2 - 1)
    assert translate("SELECT 1 IN (" + ", ".join(str(i) for i in range(5_000)) + ")", {}).columns == (
        ("_col0", "boolean"),
    )


def test_nested_calls_that_repeat_their_arguments_stay_bounded():
    # subscripts and slice() check the array before using it: the DuckDB text grows ~3-5x per level
    assert _translate_within_bound("SELECT " + "slice(ARRAY[" * 12 + "1" + "], 1, 1)" * 12) == "NOT_SUPPORTED"
    assert _translate_within_bound("SELECT " + "greatest(" * 16 + "1" + ", 1)" * 16) in ("ok", "NOT_SUPPORTED")


def test_runtime_errors_show_no_absolute_server_paths(tiny_lake):
    # a Parquet file of the lake replaced by garbage: DuckDB's message names the file by its absolute path
    broken = next(tiny_lake.rglob("*.parquet"))
    original = broken.read_bytes()
    broken.write_bytes(b"not parquet")
    try:
        with duckdb.connect() as connection:
            with pytest.raises(duckdb.Error) as caught:
                connection.execute(f"SELECT * FROM read_parquet('{broken}')").fetchall()
    finally:
        broken.write_bytes(original)
    assert str(tiny_lake) in str(caught.value)
    message = runtime_error(str(caught.value)).message
    assert str(tiny_lake) not in message and f".../{broken.name}" in message
