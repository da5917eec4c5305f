"""Charts store their numbers as Plotly typed arrays (gateway/metrics/plotly_arrays.py) when every one is a
finite number: the values read back exactly, plotly.py reads the figure as it is, NULL, NaN and numbers
past int32 stay lists, and the comparison of builds reads the values of either form."""

from __future__ import annotations

import math

import numpy as np
import orjson
import plotly.graph_objects as go
import plotly.io as pio
import pyarrow as pa
import pytest

from lakegate.gateway.metrics.compare import series_values
from lakegate.gateway.metrics.plotly_arrays import is_typed, plain, plain_figure, typed_array
from lakegate.gateway.metrics.result_columns import table_rows
from lakegate.gateway.metrics.results_table import _json
from lakegate.gateway.metrics.templates import render

LINE = [("series", "varchar"), ("t", "double"), ("v", "double")]


def line_table(xs: list, ys: list, series: list | None = None) -> pa.Table:
    return pa.table({"series": series or ["s"] * len(xs), "t": pa.array(xs, pa.float64()), "v": ys})


def test_a_line_of_finite_numbers_stores_typed_arrays_that_read_back_exactly():
    rng = np.random.default_rng(7)
    xs, ys = rng.random(1000).tolist(), (rng.standard_normal(1000) * 1e6).tolist()
    figure = render("Speed", "line", LINE, line_table(xs, ys)).figure
    trace = figure["data"][0]
    assert trace["x"]["dtype"] == trace["y"]["dtype"] == "f8"
    assert plain(trace["x"]) == xs and plain(trace["y"]) == ys  # every bit of every float
    stored = _json(figure)
    as_lists = orjson.dumps(plain_figure(figure)).decode()
    assert len(stored) < 0.75 * len(as_lists)
    assert plain_figure(orjson.loads(stored)) == orjson.loads(as_lists)
    read = pio.from_json(stored)  # plotly.py takes the stored figure as it is
    assert read.data[0].x == trace["x"] and plain(read.data[0].y) == ys
    go.Figure(figure)  # valid against Plotly's schema


def test_series_split_the_typed_arrays_by_row():
    table = line_table([0.0, 1.0, 2.0, 3.0], [10.0, 20.0, 30.0, 40.0], ["a", "b", "a", "b"])
    traces = render("Speed", "line", LINE, table).figure["data"]
    assert [(t["name"], plain(t["x"]), plain(t["y"])) for t in traces] == [
        ("a", [0.0, 2.0], [10.0, 30.0]),
        ("b", [1.0, 3.0], [20.0, 40.0]),
    ]


@pytest.mark.parametrize(
    ("values", "typed"),
    [
        ([1.5, None, 2.5], False),  # a NULL is a gap: null in a list
        ([1.5, math.nan, 2.5], False),  # NaN is not drawn: null in a list
        ([1.5, math.inf], False),
        ([1.5, -0.0, 2.5e300], True),
    ],
)
def test_only_finite_numbers_make_a_typed_array(values, typed):
    figure = render("Speed", "line", LINE, line_table([0.0, 1.0, 2.0][: len(values)], values)).figure
    assert is_typed(figure["data"][0]["y"]) is typed
    drawn = [v if v is not None and math.isfinite(v) else None for v in values]
    assert plain(figure["data"][0]["y"]) == drawn


@pytest.mark.parametrize(
    ("values", "form"),
    [([1, -(2**31), 2**31 - 1], "i4"), ([1, 2**31], None), ([0, -(2**62)], None)],
)
def test_integers_are_int32_typed_arrays_when_each_fits(values, form):
    columns = [("value", "bigint")]
    figure = render("Goals", "histogram", columns, pa.table({"value": pa.array(values, pa.int64())})).figure
    x = figure["data"][0]["x"]
    assert (x["dtype"] if is_typed(x) else None) == form
    assert plain(x) == values and all(type(v) is int for v in plain(x))


def test_rows_and_arrow_make_the_same_typed_figure():
    table = line_table([0.0, 0.5, 1.0], [3.0, 2.0, 1.0])
    from_arrow = render("Speed", "line", LINE, table).figure
    assert is_typed(from_arrow["data"][0]["y"])
    assert orjson.dumps(from_arrow) == orjson.dumps(render("Speed", "line", LINE, table_rows(table)).figure)


def test_typed_arrays_of_every_plotly_dtype_read_back_as_plotly_py_writes_them():
    figure = go.Figure(
        [
            go.Scatter(x=np.array([1, 2, 3], np.int8), y=np.array([1.5, 2.5, 3.5], np.float32)),
            go.Heatmap(z=np.arange(6, dtype=np.uint16).reshape(2, 3)),
        ]
    )
    data = orjson.loads(pio.to_json(figure))["data"]
    assert all(is_typed(v) for v in (data[0]["x"], data[0]["y"], data[1]["z"]))
    assert plain(data[0]["x"]) == [1, 2, 3] and plain(data[0]["y"]) == [1.5, 2.5, 3.5]
    assert plain(data[1]["z"]) == [[0, 1, 2], [3, 4, 5]]


def test_typed_array_leaves_64_bit_integers_to_lists():
    assert typed_array(np.array([2**40])) is None
    assert plain(typed_array(np.array([2**31 - 1]))) == [2**31 - 1]


def test_the_comparison_of_builds_reads_typed_arrays():
    rng = np.random.default_rng(3)
    ys = rng.random(50).tolist()
    line = orjson.loads(_json(render("Speed", "line", LINE, line_table(list(map(float, range(50))), ys)).figure))
    assert series_values("line", line) == ys
    values = rng.random(40).tolist()
    histogram = render("Speeds", "histogram", [("v", "double")], pa.table({"v": values})).figure
    assert series_values("histogram", orjson.loads(_json(histogram))) == values
