"""A query result as the metric templates read it: column by column, from Arrow or from rows.

The metrics engine hands `templates.render` the Arrow table its query returned. Plottable numbers
and the rows of each series are then found with Arrow and NumPy, so a chart of 100k points walks no
Python rows; rows (tuples of Python values, as `QueryResult.rows` makes them) are made only for the
templates that read them whole (tables, scalars, pies, state timelines, files). Every value is the
one the column's `to_pylist` gives, as the rows hold it, so a figure is the same byte for byte
whichever way the result came (tests/gateway/test_result_columns.py).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from decimal import Decimal
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

#: A rendered column of plottable values: int or float for a number, None for NULL and what cannot be drawn.
Numbers = list[int | float | None]

#: Arrow types whose values `to_pylist` gives as Python ints, and as Python floats.
_INTEGERS = (pa.int8(), pa.int16(), pa.int32(), pa.int64(), pa.uint8(), pa.uint16(), pa.uint32(), pa.uint64())
_FLOATS = (pa.float32(), pa.float64())
#: Trino types whose values are numbers of NumPy's kinds: floating, and integers.
_ARRAY_TYPES = {"double": "f", "real": "f", "tinyint": "i", "smallint": "i", "integer": "i", "bigint": "i"}


class TemplateError(ValueError):
    """The result does not fit the template; the message names the metric, the template and what it got."""


NOT_A_NUMBER = object()


def number(value: Any) -> Any:
    """int or float for a number, None for NULL, NOT_A_NUMBER for anything else (booleans too)."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)):
        return NOT_A_NUMBER
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, Decimal, np.floating)):
        return float(value)
    return NOT_A_NUMBER


def result_table(batches: Iterable[pa.RecordBatch]) -> pa.Table | list[tuple]:
    """A query's result as `templates.render` takes it: its Arrow table; [] when it has no rows or no
    columns, and its rows when its batches differ in schema (`QueryResult.rows` reads them so)."""
    read = list(batches)
    if any(batch.schema != read[0].schema for batch in read[1:]):
        return [row for batch in read for row in table_rows(pa.Table.from_batches([batch]))]
    table = pa.Table.from_batches(read) if read else None
    return table if table is not None and table.num_rows and table.num_columns else []


def table_rows(rows: pa.Table | Sequence[tuple]) -> list[tuple]:
    """The rows of an Arrow table as tuples of Python values, as `QueryResult.rows` makes them (rows
    given as rows stay as they are)."""
    if not isinstance(rows, pa.Table):
        return list(rows)
    return list(zip(*(column.to_pylist() for column in rows.columns)))


def _numpy(column: pa.ChunkedArray) -> np.ndarray:
    """A numeric column without NULLs as one NumPy array, read as its buffers lie (`to_numpy` imports pandas)."""
    dtype = np.dtype(column.type.to_pandas_dtype())
    parts = [
        np.frombuffer(chunk.buffers()[1], dtype)[chunk.offset : chunk.offset + len(chunk)]
        for chunk in column.chunks
        if len(chunk)
    ]
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def plural(count: int, word: str, plural_word: str | None = None) -> str:
    return f"{count} {word if count == 1 else (plural_word or word + 's')}"


class ResultColumns:
    """A query result being rendered by one template (`rows`: tuples of Python values, or the
    Arrow table of the query), with the checks templates share."""

    def __init__(self, metric: str, template: str, columns: list[tuple[str, str]], rows: Sequence[tuple] | pa.Table):
        self.metric = metric
        self.template = template
        self.names = [name for name, _ in columns]
        self.types = [type_name for _, type_name in columns]
        self._values: dict[int, list] = {}
        if isinstance(rows, pa.Table):
            self._table: pa.Table | None = rows
            self._rows: Sequence[tuple] | None = None
            self.count = rows.num_rows if rows.num_columns else 0
            if self.count and rows.num_columns != len(columns):
                raise self.error(f"got row 1 with {rows.num_columns} values for {len(columns)} columns")
            return
        self._table, self._rows, self.count = None, rows, len(rows)
        for row_number, row in enumerate(rows, 1):
            if len(row) != len(columns):
                raise self.error(f"got row {row_number} with {len(row)} values for {len(columns)} columns")

    @property
    def rows(self) -> Sequence[tuple]:
        """Every row, as tuples of Python values (made from the table on first use)."""
        if self._rows is None:
            self._rows = table_rows(self._table) if self.count else []
        return self._rows

    def values(self, column: int) -> list:
        """The Python values of one column, in row order."""
        found = self._values.get(column)
        if found is None:
            if self._table is not None:
                found = self._table.column(column).to_pylist() if self.count else []
            else:
                found = [row[column] for row in self._rows]
            self._values[column] = found
        return found

    def is_numeric(self, column: int) -> bool:
        """Whether the column is of an Arrow integer or floating type (every value a number or NULL)."""
        return self._table is not None and self._table.schema.field(column).type in (*_INTEGERS, *_FLOATS)

    def error(self, what: str) -> TemplateError:
        return TemplateError(f"metric {self.metric!r}: template {self.template!r} {what}")

    def need_columns(self, counts: tuple[int, ...], shape: str) -> None:
        """Fail unless the result has one of `counts` columns; `shape` names them, e.g. "[series, x, y]"."""
        if len(self.names) in counts:
            return
        if len(counts) == 1:
            wanted = f"exactly {counts[0]} column{'s' if counts[0] != 1 else ''}"
        else:
            wanted = " or ".join(map(str, counts)) + " columns"
        raise self.error(f"needs {wanted} {shape}, got {len(self.names)} ({', '.join(self.names)})")

    def numbers(self, column: int, wanted: str) -> tuple[Numbers, list[str]]:
        """The column's values as plottable numbers, NULL as None, and problems: NaN and
        infinities (JSON has neither) are not drawn. Fails naming the row on a non-number."""
        values = self.values(column)
        kind = self._table.schema.field(column).type if self._table is not None else None
        if kind in _INTEGERS:
            return values, []
        if kind in _FLOATS:  # NaN and the infinities are not drawn (NULL is None already)
            undrawn = pc.indices_nonzero(pc.invert(pc.is_finite(self._table.column(column)))).to_pylist()
            drawn, undrawable = list(values), len(undrawn)
            for index in undrawn:
                drawn[index] = None
        else:
            drawn, undrawable = self._numbers(values, column, wanted)
        problems = []
        if undrawable:
            problems.append(
                f'{plural(undrawable, "value")} of "{self.names[column]}" '
                f"{'is' if undrawable == 1 else 'are'} NaN or infinite and not drawn"
            )
        return drawn, problems

    def _numbers(self, values: list, column: int, wanted: str) -> tuple[Numbers, int]:
        """`numbers` value by value: the plottable numbers and how many could not be drawn."""
        drawn: Numbers = []
        undrawable = 0
        for row_number, value in enumerate(values, 1):
            if type(value) is not float:  # the common case first: this runs for every point
                value = number(value)
                if value is NOT_A_NUMBER:
                    raise self.bad_value(row_number, column, wanted)
            if type(value) is float and not math.isfinite(value):
                value = None
                undrawable += 1
            drawn.append(value)
        return drawn, undrawable

    def array(self, column: int) -> np.ndarray | None:
        """The column as a NumPy array when it is of a Trino floating or integer type and every value is
        a finite number (no NULL, NaN or infinity); None otherwise. Its values are the ones `numbers`
        gives, whether the result came as Arrow or as rows."""
        kind = _ARRAY_TYPES.get(self.types[column])
        if kind is None or not self.count:
            return None
        if self._table is not None:
            data = self._table.column(column)
            if data.null_count or data.type not in (_FLOATS if kind == "f" else _INTEGERS):
                return None
            found = _numpy(data)
        else:
            values = self.values(column)
            if not all(type(value) is (float if kind == "f" else int) for value in values):
                return None
            try:
                found = np.array(values, np.float64 if kind == "f" else np.int64)
            except OverflowError:
                return None
        return found if kind == "i" or np.isfinite(found).all() else None

    def codes(self, column: int) -> tuple[list, np.ndarray] | None:
        """The column's distinct values in order of first appearance (NULL as None) and each row's index
        among them; None for rows, or a column of a type Arrow does not encode (arrays, maps, rows)."""
        if self._table is None or not self.count:
            return None
        try:
            encoded = pc.dictionary_encode(self._table.column(column).combine_chunks(), null_encoding="encode")
        except pa.ArrowNotImplementedError:
            return None
        indices = encoded.indices  # int32, no NULLs (NULL is a value); read as it lies (`to_numpy` imports pandas)
        codes = np.frombuffer(indices.buffers()[1], np.int32)[indices.offset : indices.offset + len(indices)]
        return encoded.dictionary.to_pylist(), codes

    def bad_value(self, row_number: int, column: int, wanted: str) -> TemplateError:
        value = self.values(column)[row_number - 1]
        got = "NULL" if value is None else f"{value!r} ({self.types[column]})"
        return self.error(
            f'needs {wanted} in column {column + 1} "{self.names[column]}", but row {row_number} has {got}'
        )
