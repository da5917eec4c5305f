"""No engine text in any error: every function of docs/functions.md called with arguments of the wrong
kind (constants of other types, columns, NULL, lambdas; drawn by hypothesis) through a real Engine
over a real lake, and once more through a real `lakegate serve` (what a client reads: the message
of the QueryResults document), and every message checked for DuckDB's and sqlglot's own wording.

A call starts from one of the function's shapes that lakegate accepts (tools/trino_fuzz/functions.py
finds them from the registry); its arguments are constants or columns of the right type, and one of
them (or an extra one) is then swapped for an argument of another kind. Whatever the outcome, an
error must be a DialectError with one of Trino's error names and a message in Trino's terms.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import requests
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from trino_fuzz.functions import Shape, discover

from lakegate.dialect.errors import ERROR_CODES, DialectError
from lakegate.gateway.engine.engine import Engine

ALL_TYPES_BRANCH = "feature/all-types"  # the branch of the test lake with a column of every type (conftest.py)
FUNCTIONS_DOC = Path(__file__).parents[2] / "docs" / "functions.md"

#: Words that only DuckDB's or sqlglot's own messages (and Python's) use, never Trino's.
ENGINE_WORDING = re.compile(
    r"Binder Error|Catalog Error|Parser Error|Conversion Error|Invalid Input Error|Out of Range Error"
    r"|Not implemented Error|INTERNAL Error|Internal Error|Dependency Error|Invalid type Error"
    r"|No function matches|Candidate functions|best candidate function|explicit type casts"
    r"|must be a constant expression|must appear in the GROUP BY clause|STRING_LITERAL|INTEGER_LITERAL"
    r"|\bINT(?:8|16|32|64|128)\b|\bUINT\d+|\bHUGEINT\b|\bVARCHAR\[\]|\bBLOB\b|\bSTRUCT\(|list_\w+\(|string_agg"
    r"|TokenType|<Token|SENTINEL|sqlglot|Required keyword|Invalid expression / Unexpected token"
    r"|Error tokenizing|Expected table name|<class '|Traceback|Python exception|\w+Error: |duckdb",
)

#: A constant of each argument type the shapes use.
CONSTANTS = {
    "bigint": "BIGINT '7'",
    "integer": "3",
    "double": "2.5E0",
    "real": "REAL '1.5'",
    "varchar": "'ab,c'",
    "boolean": "true",
    "varbinary": "X'00ff'",
    "json": "JSON '[1, {\"a\": 2}]'",
    "date": "DATE '2024-02-29'",
    "timestamp(3)": "TIMESTAMP '2024-02-29 12:34:56.789'",
    "timestamp(3) with time zone": "TIMESTAMP '2024-02-29 12:34:56.789 UTC'",
    "interval day to second": "INTERVAL '2' DAY",
    "array(bigint)": "ARRAY[BIGINT '1', NULL, 3]",
    "array(double)": "ARRAY[1.5E0, NULL]",
    "array(varchar)": "ARRAY['x', NULL, 'y']",
    "map(varchar, bigint)": "MAP(ARRAY['k'], ARRAY[BIGINT '1'])",
}
#: Columns of `sample s` and `metadata m` on the all-types branch, by type.
COLUMNS = {
    "bigint": ["s.n", 's."timestamp"'],
    "double": ["s.x"],
    "varchar": ["s.s", "s.st", "m.experience_name"],
    "boolean": ["s.flag"],
    "timestamp(3)": ['m."time"'],
    "array(varchar)": ["s.tags", "m.experience_tag_names"],
}
#: Arguments of every other kind: constants of each type, NULLs, columns, lambdas, rows.
WRONG = [
    *CONSTANTS.values(),
    *(column for columns in COLUMNS.values() for column in columns),
    "NULL",
    "CAST(NULL AS bigint)",
    "CAST(NULL AS array(varchar))",
    "s.metrics",
    "ROW(1, 'a')",
    "x -> x",
    "x -> true",
    "(x, y) -> x",
    "(a, b, c) -> a",
    "-1",
    "0",
    "9223372036854775807",
    "''",
]


def _documented_functions() -> list[str]:
    """The supported functions of docs/functions.md."""
    return re.findall(r"^\| `(\w+)` \| supported", FUNCTIONS_DOC.read_text(), flags=re.MULTILINE)


FUNCTIONS = _documented_functions()


@pytest.fixture(scope="module")
def shapes() -> dict[str, list[Shape]]:
    found: dict[str, list[Shape]] = {}
    for shape in discover(limit_per_function=6):
        found.setdefault(shape.name, []).append(shape)
    return found


@pytest.fixture(scope="module")
def engine(server_lake) -> Engine:
    engine = Engine.open(server_lake)
    yield engine
    engine.close()


def _lambda(kind: str) -> str:
    """A lambda for a `lambda:<params>:<body>` kind of a shape."""
    count = int(kind.split(":")[1])
    params = ["x", "y", "z"][:count]
    head = params[0] if count == 1 else f"({', '.join(params)})"
    return f"{head} -> {'true' if kind.endswith(':boolean') else params[-1]}"


@st.composite
def calls(draw, name: str, shapes: list[Shape]) -> str:
    """A call of `name` with one argument of the wrong kind (or one too many or too few)."""
    if shapes:
        shape = draw(st.sampled_from(shapes))
        args = []
        for kind in shape.args:
            if kind.startswith("lambda:"):
                args.append(_lambda(kind))
            elif kind in COLUMNS and draw(st.booleans()):
                args.append(draw(st.sampled_from(COLUMNS[kind])))
            else:
                args.append(CONSTANTS.get(kind, "NULL"))
        kind = "window" if shape.kind == "window" else "call"
    else:
        args = [draw(st.sampled_from(WRONG)) for _ in range(draw(st.integers(0, 2)))]
        kind = "call"
    change = draw(st.sampled_from(["swap", "swap", "swap", "add", "drop"]))
    if change == "swap" and args:
        args[draw(st.integers(0, len(args) - 1))] = draw(st.sampled_from(WRONG))
    elif change == "add":
        args.insert(draw(st.integers(0, len(args))), draw(st.sampled_from(WRONG)))
    elif args:
        del args[draw(st.integers(0, len(args) - 1))]
    text = f"{name}({', '.join(args)})"
    return f"{text} OVER (ORDER BY s.n)" if kind == "window" else text


def _outcome(engine: Engine, sql: str) -> str | None:
    """None when the query answers; else the message the client would see."""
    session = engine.session(branch=ALL_TYPES_BRANCH)
    try:
        engine.execute(sql, session).rows()
    except DialectError as error:
        assert error.error_name in ERROR_CODES or error.error_name.startswith("EXCEEDED_"), (sql, error.error_name)
        return str(error)
    return None


def _served_outcome(server, sql: str) -> str | None:
    """None when `lakegate serve` answers the query; else the error message its client reads."""
    headers = {"X-Trino-User": "wording", "X-Trino-Catalog": "lake", "X-Trino-Schema": ALL_TYPES_BRANCH}
    document = requests.post(f"{server.url}/v1/statement", data=sql.encode(), headers=headers, timeout=60).json()
    while "nextUri" in document:
        document = requests.get(document["nextUri"], timeout=60).json()
    error = document.get("error")
    if error is None:
        return None
    assert error["errorName"] in ERROR_CODES or error["errorName"].startswith("EXCEEDED_"), (sql, error)
    return error["message"]


def _wrong_calls(name: str, shapes, outcome, examples: int) -> None:
    """Check `examples` calls of `name` with a wrong argument (drawn by hypothesis, always the same)."""

    @settings(
        max_examples=examples,
        deadline=None,
        database=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    )
    @given(call=calls(name, shapes.get(name, [])))
    def check(call: str) -> None:
        sql = f"SELECT {call} FROM sample s JOIN metadata m ON s.job_id = m.job_id LIMIT 3"
        message = outcome(sql)
        assert message is None or not ENGINE_WORDING.search(message), f"{sql}\n-> {message}"

    check()


@pytest.mark.parametrize("name", FUNCTIONS)
def test_wrong_arguments_get_trino_errors(name: str, shapes, engine) -> None:
    _wrong_calls(name, shapes, lambda sql: _outcome(engine, sql), 6)


@pytest.mark.parametrize("name", FUNCTIONS)
def test_wrong_arguments_get_trino_errors_from_the_server(name: str, shapes, lake_server) -> None:
    _wrong_calls(name, shapes, lambda sql: _served_outcome(lake_server, sql), 2)


def test_the_documented_functions_are_read() -> None:
    assert len(FUNCTIONS) > 250 and {"array_join", "transform", "sum", "row_number"} <= set(FUNCTIONS)


@pytest.mark.parametrize(
    "sql",
    [
        "SELECT array_join(s.tags, s.s) FROM sample s",  # a separator of each row
        "SELECT array_join(s.tags, s.s, s.st) FROM sample s",
        "SELECT millisecond(NULL)",
        "SELECT count(x -> x) FROM sample s",
        "SELECT all_match()",
        "SELECT * FROM metadata FOR SYSTEM_TIME AS OF now()",  # Trino's syntax error, not a KeyError
        # a correlated count(*) per group: Trino answers it, and so does lakegate
        "SELECT s.job_id, count(*), (SELECT count(*) FROM metadata m WHERE m.job_id = s.job_id) "
        "FROM sample s GROUP BY 1",
    ],
)
def test_known_leaks_are_in_trino_terms(sql: str, engine, lake_server) -> None:
    for message in (_outcome(engine, sql), _served_outcome(lake_server, sql)):
        assert message is None or not ENGINE_WORDING.search(message), message
