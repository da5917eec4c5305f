"""The plain-translation baseline: every result case of cases/*.yaml is also run through
`sqlglot.transpile(read="trino", write="duckdb")` and DuckDB, without lakegate's analysis. Where that
baseline gives Trino's rows exactly (values compared in the client-protocol encoding of the
expected types, as the conformance runner does), lakegate must answer too: a refusal there is a
construct lifted cheaply by a plain translation. Where lakegate answers, the conformance
suite already checks the answer, so only refusals are compared here.
"""

from __future__ import annotations

import duckdb
import pytest
import sqlglot
from answer_compare import sort_key
from functions_doc import Case, load_cases

from lakegate.dialect.errors import DialectError
from lakegate.dialect.translate import translate
from tests.dialect.test_conformance import is_ordered, parse_type, same, to_protocol

RESULT_CASES = [case for case in load_cases() if not case.errors]

#: Cases the baseline answers that lakegate still refuses, each with the open work it waits for. An
#: entry that starts to pass fails the suite (strict xfail), so this list only shrinks.
NOT_YET: dict[str, str] = {}


def baseline_rows(case: Case, lake) -> list | None:
    """The rows plain sqlglot + DuckDB return, encoded for the case's expected types; None when the
    baseline fails or returns a different number of columns."""
    try:
        duck_sql = sqlglot.transpile(case.sql.strip().rstrip(";"), read="trino", write="duckdb")[0]
    except sqlglot.errors.SqlglotError:
        return None
    types = [parse_type(t) for _, t in case.columns]
    with lake.transaction() as con:
        try:
            cursor = con.execute(duck_sql)
            raw = cursor.fetchall()
        except duckdb.Error:
            return None
        if len(cursor.description) != len(types):
            return None
    return [[to_protocol(v, t) for v, t in zip(row, types)] for row in raw]


def baseline_is_right(case: Case, lake) -> bool:
    rows = baseline_rows(case, lake)
    if rows is None:
        return False
    expected = [list(row) for row in case.rows]
    if not is_ordered(case):
        rows, expected = sorted(rows, key=sort_key), sorted(expected, key=sort_key)
    return same(expected, rows, case.tolerance)


def _marked(case: Case):
    reason = NOT_YET.get(case.id)
    return pytest.param(case, id=case.id, marks=pytest.mark.xfail(reason=reason, strict=True) if reason else ())


@pytest.mark.parametrize("case", [_marked(case) for case in RESULT_CASES])
def test_no_refusal_where_plain_translation_is_right(case: Case, fixture_lake):
    try:
        translate(case.sql, fixture_lake.schema, time_zone=case.time_zone)
    except DialectError as e:
        if baseline_is_right(case, fixture_lake):
            pytest.fail(
                f"lakegate refuses ({e.error_name}: {e}) what plain sqlglot + DuckDB answers "
                f"exactly\nTrino SQL: {case.sql.strip()}",
                pytrace=False,
            )


def test_baseline_runner_detects_right_and_wrong(fixture_lake):
    """The runner itself: a plain translation that is exact is recognised, a wrong one is not."""
    right = Case("probe", "right", "SELECT 1 + 1", columns=(("_col0", "integer"),), rows=((2,),))
    wrong = Case("probe", "wrong", "SELECT 7 / 2", columns=(("_col0", "integer"),), rows=((3,),))
    assert baseline_is_right(right, fixture_lake)
    assert not baseline_is_right(wrong, fixture_lake)
