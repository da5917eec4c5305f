"""Templates read a query's Arrow table column by column (gateway/metrics/result_columns.py) and give
the same figure, byte for byte, as from the rows `QueryResult.rows` makes of it: random tables of
every kind of column a chart meets (NaN, infinities, -0.0, NULLs, labels that print alike, decimals,
timestamps), rendered by every system template both ways."""

from __future__ import annotations

import datetime as dt
from decimal import Decimal

import orjson
import pyarrow as pa
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lakegate.gateway.metrics.plotly_arrays import plain
from lakegate.gateway.metrics.result_columns import result_table, table_rows
from lakegate.gateway.metrics.templates import TemplateError, render
from lakegate.lake.template_kinds import TEMPLATES

#: Arrow type, its Trino type name, and values of it (None is NULL).
FLOATS = st.one_of(
    st.none(),
    st.sampled_from([0.0, -0.0, 1.0000001, 1.0000002, float("nan"), float("inf"), float("-inf"), 1e-7, 2.5e15]),
    st.floats(allow_nan=True, allow_infinity=True, width=64),
)
KINDS = {
    "double": (pa.float64(), "double", FLOATS),
    "real": (pa.float32(), "real", st.one_of(st.none(), st.floats(width=32, allow_nan=True))),
    "bigint": (pa.int64(), "bigint", st.one_of(st.none(), st.integers(-(2**63), 2**63 - 1))),
    "integer": (pa.int32(), "integer", st.one_of(st.none(), st.integers(-5, 5))),
    "varchar": (pa.string(), "varchar", st.one_of(st.none(), st.sampled_from(["a", "b", "PASSED", "BLOCKER", ""]))),
    "decimal": (
        pa.decimal128(10, 3),
        "decimal(10,3)",
        st.one_of(st.none(), st.decimals(-1000, 1000, places=3, allow_nan=False)),
    ),
    "timestamp": (
        pa.timestamp("us"),
        "timestamp(6)",
        st.one_of(st.none(), st.datetimes(dt.datetime(1970, 1, 1), dt.datetime(2100, 1, 1))),
    ),
    "date": (pa.date32(), "date", st.one_of(st.none(), st.dates(dt.date(1970, 1, 1), dt.date(2100, 1, 1)))),
    "boolean": (pa.bool_(), "boolean", st.one_of(st.none(), st.booleans())),
}
#: The kinds rendered from the result alone (a kind showing files also reads the job's logs).
RESULT_KINDS = [name for name, kind in TEMPLATES.items() if not kind.files]


def outcome(template: str, columns: list[tuple[str, str]], rows) -> tuple:
    """Everything a render gives, as bytes and text to compare (or the error it raised)."""
    try:
        shown = render("m", template, columns, rows, units="s")
    except TemplateError as error:
        return ("error", str(error))
    return (
        orjson.dumps(shown.figure),
        orjson.dumps(shown.table, default=str),
        repr(shown.scalar),
        shown.text,
        shown.problems,
    )


@st.composite
def results(draw) -> tuple[str, list[tuple[str, str]], pa.Table]:
    template = draw(st.sampled_from(RESULT_KINDS))
    kinds = draw(st.lists(st.sampled_from(sorted(KINDS)), min_size=1, max_size=4))
    rows = draw(st.integers(1, 12))
    names = [f"c{i}" for i in range(len(kinds))]
    if len(kinds) >= 3 and draw(st.booleans()):
        names[-1] = "link_path"
    arrays, columns = [], []
    for name, kind in zip(names, kinds):
        arrow_type, trino_type, values = KINDS[kind]
        arrays.append(pa.array(draw(st.lists(values, min_size=rows, max_size=rows)), arrow_type))
        columns.append((name, trino_type))
    table = pa.Table.from_arrays(arrays, names=names)
    if rows > 1 and draw(st.booleans()):  # as DuckDB streams them: in several batches
        cut = draw(st.integers(1, rows - 1))
        table = pa.Table.from_batches([*table.slice(0, cut).to_batches(), *table.slice(cut).to_batches()])
    return template, columns, table


@settings(max_examples=400, deadline=None)
@given(results())
def test_a_figure_from_arrow_columns_is_the_figure_from_rows(result):
    template, columns, table = result
    assert outcome(template, columns, table) == outcome(template, columns, table_rows(table))


@pytest.mark.parametrize(
    ("labels", "series"),
    [
        # labels that print alike are one series, in order of first appearance; NULL is a series of its own
        ([1.0000001, None, 1.0000002, 2.0, None], {"1": [0, 2], "NULL": [1, 4], "2": [3]}),
        (["b", "a", "b", "b"], {"b": [0, 2, 3], "a": [1]}),
        ([Decimal("1.500"), Decimal("1.500")], {"1.5": [0, 1]}),
    ],
)
def test_series_of_arrow_columns_group_by_label(labels, series):
    table = pa.table({"s": labels, "x": list(range(len(labels))), "y": [float(i) for i in range(len(labels))]})
    columns = [("s", "double"), ("x", "bigint"), ("y", "double")]
    figure = render("m", "line", columns, table).figure
    assert {trace["name"]: plain(trace["x"]) for trace in figure["data"]} == series
    assert outcome("line", columns, table) == outcome("line", columns, table_rows(table))


def test_result_table_keeps_no_rows_and_columns_as_rows_make_them():
    empty = pa.record_batch([pa.array([], pa.float64())], names=["x"])
    assert result_table([]) == [] and result_table([empty]) == []
    one = pa.record_batch([pa.array([1.5])], names=["x"])
    assert result_table([one, empty, one]).column("x").to_pylist() == [1.5, 1.5]
    other = pa.record_batch([pa.array([2], pa.int64())], names=["x"])  # batches of another schema: rows
    assert result_table([one, other]) == [(1.5,), (2,)]
