"""The JSON lines of a whole validated series at once, built column by column in C code.

`SeriesLines(topic_name, fields).encode(stamps, columns)` returns the lines of the records
`{field: column[i]}` at `stamps[i]` as bytes blocks of whole lines, byte for byte as the Emitter writes
them one by one (and as `json.dumps` writes them), when every column certainly passes
`check_value` for its type: exact `int` columns in the 64-bit range, finite exact `float`
columns, exact `bool` columns, and exact `str` columns of valid Unicode text for the text
types. It returns None otherwise (another type, a NaN, a lone surrogate, `string[]` or
`metric[]` fields, an over-long line), and the Emitter then checks the series record by
record to name the first bad one.

How: the records are laid out as one flat list `[ts, sep, v0, sep, v1, ..., end]` whose
separators are `orjson.Fragment`s (written verbatim) and serialised by one `orjson.dumps`
call per block of ROWS records (small enough to stay in the CPU cache). That puts a comma
between every two items and brackets around them; the separators hold \\x01, \\x02 and
\\x03 where the line has a comma or bracket, so one `bytes.translate` deletes orjson's commas
and brackets and turns those bytes into theirs. No value's text holds any of these (numbers
cannot; text values are escaped first, and JSON escapes control characters).
orjson writes floats with the shortest round-trip digits, as `repr` does, but in another
notation below 1e-4 in magnitude (`0.00001` and `1e-7` for repr's `1e-05` and `1e-07`):
those few values are given as fragments of their `repr`.

`rows_text(rows)` does the same for records queued one by one by `Emitter.emit`: each row is a
tuple of the topic's `parts` (separator fragments) interleaved with its checked values.
"""

from __future__ import annotations

from json.encoder import encode_basestring_ascii as json_str
from typing import Any

import numpy as np
import orjson

from lakegate.lake.types import INT64_MAX, INT64_MIN, MAX_LINE_BYTES, is_utf8

TEXT_TYPES = frozenset({"string", "status", "image", "video"})
ROWS = 4096  # records per block
_PUNCTUATION = b",[]"
_STAND_INS = b"\x01\x02\x03"  # in constant text and text values until the translate
_TABLE = bytes.maketrans(_STAND_INS, _PUNCTUATION)
_HIDE = str.maketrans(_PUNCTUATION.decode(), _STAND_INS.decode())
_LONGEST_NUMBER = 24  # bytes: "-1.2345678901234567e-308", "-9223372036854775808"


def _fragment(text: str) -> orjson.Fragment:
    """Constant line text as a separator item (its punctuation hidden until the translate)."""
    return orjson.Fragment(text.translate(_HIDE).encode())


def _all_of_type(column: list[Any], kind: type) -> bool:
    """True if every item is exactly of `kind` (not a subclass: bool is not an int here)."""
    return list(map(type, column)).count(kind) == len(column)


def _float_items(column: list[float]) -> list[Any] | None:
    """The column for orjson (repr fragments for the values below 1e-4), or None if a value is not finite."""
    array = np.array(column, dtype=np.float64)
    if not np.isfinite(array).all():
        return None
    small = np.flatnonzero((np.abs(array) < 1e-4) & (array != 0.0))
    if len(small) == 0:
        return column
    items = list(column)
    for i in small.tolist():
        items[i] = orjson.Fragment(repr(items[i]).encode())
    return items


def _int_items(column: list[int], low: int, high: int) -> list[int] | None:
    """The column, if every value is an exact int in [low, high]."""
    if not _all_of_type(column, int) or not low <= min(column) or not max(column) <= high:
        return None
    return column


def _text_items(column: list[str]) -> tuple[list[orjson.Fragment], int] | None:
    """JSON strings as json.dumps writes them (ASCII, \\uXXXX escapes), and the longest one's length."""
    if not _all_of_type(column, str) or not is_utf8("".join(column)):
        return None
    texts = "\x00".join(map(json_str, column)).translate(_HIDE).split("\x00")  # \x00 is escaped in JSON text
    return [orjson.Fragment(text.encode()) for text in texts], max(map(len, texts))


class SeriesLines:
    """The line layout of one topic, ready to encode whole series of it."""

    __slots__ = ("types", "start", "row", "last", "parts", "constant_length")

    def __init__(self, topic_name: str, fields: dict[str, str]):
        self.types = tuple(fields.values())
        self.start = f'{{"$metadata": {{"topic": {json_str(topic_name)}, "timestamp": '.encode()
        texts = [
            f'}}, "$data": {{{json_str(name)}: ' if i == 0 else f", {json_str(name)}: " for i, name in enumerate(fields)
        ]
        end = "}}\n" if fields else '}, "$data": {}}\n'
        # one row: ts, then per field its separator and value, then the end and next line's start
        self.row: list[Any] = [None]
        for text in texts:
            self.row += [_fragment(text), None]
        self.row.append(_fragment(end + self.start.decode()))
        self.last = _fragment(end)
        # one record queued alone: parts[0], ts, parts[1], v0, parts[2], v1, ..., parts[-1]
        self.parts = (_fragment(self.start.decode()), *(_fragment(text) for text in texts), self.last)
        self.constant_length = len(self.start) + sum(len(t.encode()) for t in texts) + len(end)

    def encode(self, stamps: list[Any], columns: list[list[Any]]) -> list[bytes] | None:
        """The lines of the series in blocks, or None unless every value certainly passes validation.

        `stamps` and each column are lists of the same length (at least 1); columns in field order.
        """
        if _int_items(stamps, 0, INT64_MAX) is None:
            return None
        longest = self.constant_length + _LONGEST_NUMBER
        checked = [stamps]
        for field_type, column in zip(self.types, columns):
            items: list[Any] | None
            if field_type == "float":
                items = _float_items(column) if _all_of_type(column, float) else None
            elif field_type == "int":
                items = _int_items(column, INT64_MIN, INT64_MAX)
            elif field_type == "boolean":
                items = column if _all_of_type(column, bool) else None
            elif field_type in TEXT_TYPES:
                texts = _text_items(column)
                items, length = texts if texts is not None else (None, 0)
                longest += length
            else:
                return None
            if items is None:
                return None
            longest += _LONGEST_NUMBER
            checked.append(items)
        if longest > MAX_LINE_BYTES + 1:
            return None  # a line may be too long: checked record by record
        return [self._block(checked, at, min(at + ROWS, len(stamps))) for at in range(0, len(stamps), ROWS)]

    def _block(self, columns: list[list[Any]], begin: int, end: int) -> bytes:
        """The lines of records `begin` to `end` (exclusive) of checked columns (timestamps first)."""
        width = len(self.row)
        flat = self.row * (end - begin)
        for i, column in enumerate(columns):
            flat[2 * i :: width] = column[begin:end]
        flat[-1] = self.last
        return self.start + orjson.dumps(flat).translate(_TABLE, _PUNCTUATION)


def rows_text(rows: list[tuple[Any, ...]]) -> bytes:
    """The lines of rows laid out as `SeriesLines.parts` interleaved with checked values, as one block.

    orjson writes the list of rows as a list of lists: the translate deletes their brackets too.
    """
    return orjson.dumps(rows).translate(_TABLE, _PUNCTUATION)
