"""Plotly's typed arrays: a long column of numbers in a figure as `{"dtype": "f8", "bdata": "<base64>"}`.

plotly.js (2.28 and later) reads such an object wherever a figure takes an array of numbers, and
plotly.py (6 and later) writes NumPy arrays so. The templates store a chart's numbers this way when
every one is a finite number (`typed_array`): the figure JSON is about half the size, and no
Python object is made per point. A reader of a stored figure that needs the values takes `plain`.
"""

from __future__ import annotations

import base64
from typing import Any

import numpy as np

#: plotly.js's names of the element types of a typed array, and NumPy's (little-endian).
DTYPES = {"i1": "<i1", "u1": "<u1", "i2": "<i2", "u2": "<u2", "i4": "<i4", "u4": "<u4", "f4": "<f4", "f8": "<f8"}
_INT32 = np.iinfo(np.int32)


def typed_array(values: np.ndarray) -> dict[str, str] | None:
    """A 1-d array of numbers as a typed array: float64 as `f8`, integers as `i4` when every one fits
    (None otherwise, as plotly.py leaves them: plotly.js has no 64-bit integers)."""
    if values.dtype.kind == "f":
        return {"dtype": "f8", "bdata": base64.b64encode(values.astype("<f8", copy=False)).decode("ascii")}
    if values.dtype.kind in "iu" and (not len(values) or (values.min() >= _INT32.min and values.max() <= _INT32.max)):
        return {"dtype": "i4", "bdata": base64.b64encode(values.astype("<i4", copy=False)).decode("ascii")}
    return None


def is_typed(value: Any) -> bool:
    """Whether `value` is a typed array."""
    return isinstance(value, dict) and value.get("dtype") in DTYPES and isinstance(value.get("bdata"), str)


def plain(value: Any) -> Any:
    """The numbers of a typed array as a list (nested by its `shape`, as plotly.py writes a 2-d array);
    any other value as it is."""
    if not is_typed(value):
        return value
    array = np.frombuffer(base64.b64decode(value["bdata"]), DTYPES[value["dtype"]])
    shape = value.get("shape")
    if shape:
        array = array.reshape([int(part) for part in str(shape).split(",") if part.strip()])
    return array.tolist()


def plain_figure(figure: Any) -> Any:
    """A figure (or any part of one) with every typed array made a list, for readers of its values."""
    if is_typed(figure):
        return plain(figure)
    if isinstance(figure, dict):
        return {key: plain_figure(value) for key, value in figure.items()}
    if isinstance(figure, list):
        return [plain_figure(value) for value in figure]
    return figure
