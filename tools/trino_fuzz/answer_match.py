"""Comparing two protocol-encoded answers: result types exactly, rows as multisets (or in order),
doubles to a relative 1e-12 (NaN equals NaN, infinities equal themselves), everything else exactly.
"""

from __future__ import annotations

import json
import math
import re
import struct
from typing import Any

from trino_fuzz.sides import Outcome

REL = 1e-12
_SPECIAL = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


def _floating(t: str) -> bool:
    return t in ("double", "real")


def _children(t: str) -> list[str]:
    """The element types of array/map/row type `t` (row: field types), else []."""
    match = re.fullmatch(r"(array|map|row)\((.*)\)", t)
    if not match:
        return []
    parts, depth, current = [], 0, ""
    for char in match.group(2):
        depth += {"(": 1, ")": -1}.get(char, 0)
        if char == "," and depth == 0:
            parts.append(current.strip())
            current = ""
        else:
            current += char
    parts.append(current.strip())
    if match.group(1) == "row":  # "name type" or "type"
        parts = [
            p.split(" ", 1)[1] if re.match(r'^("[^"]*"|\w+) \w', p) and not p.startswith("timestamp") else p
            for p in parts
        ]
    return parts


def _key(value: Any, t: str) -> Any:
    """A sortable, hashable form of a value, doubles rounded so that near-equal ones sort together."""
    if value is None:
        return (0,)
    if _floating(t):
        number = _SPECIAL.get(value, value) if isinstance(value, str) else float(value)
        if math.isnan(number):
            return (1, "nan")
        return (2, float(f"{number:.9g}"))
    if t == "json":  # numbers rounded as doubles are
        try:
            return (5, json.dumps(json.loads(value, parse_float=lambda text: float(f"{float(text):.9g}"))))
        except ValueError:
            return (5, repr(value))
    kids = _children(t)
    if t.startswith("array(") and isinstance(value, list):
        return (3, tuple(_key(v, kids[0]) for v in value))
    if t.startswith("row(") and isinstance(value, list):
        return (3, tuple(_key(v, k) for v, k in zip(value, kids)))
    if t.startswith("map(") and isinstance(value, dict):
        return (4, tuple(sorted((k, _key(v, kids[1])) for k, v in value.items())))
    return (5, repr(value))


def _same_json(a: Any, b: Any) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return isinstance(a, (int, float)) and isinstance(b, (int, float)) and _same(a, b, "double")
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same_json(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return list(a) == list(b) and all(_same_json(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


def _same(a: Any, b: Any, t: str) -> bool:
    if a is None or b is None:
        return a is None and b is None
    if t == "json" and a != b:
        try:
            return _same_json(json.loads(a), json.loads(b))
        except ValueError:
            return False
    if _floating(t):
        x = _SPECIAL.get(a, a) if isinstance(a, str) else float(a)
        y = _SPECIAL.get(b, b) if isinstance(b, str) else float(b)
        if t == "real" and math.isfinite(x) and math.isfinite(y):  # a float's digits: exactly the same float
            return struct.pack("f", x) == struct.pack("f", y)
        if math.isnan(x) or math.isnan(y):
            return math.isnan(x) and math.isnan(y)
        if math.isinf(x) or math.isinf(y):
            return x == y
        return x == y or abs(x - y) <= REL * max(abs(x), abs(y))
    kids = _children(t)
    if t.startswith(("array(", "row(")) and isinstance(a, list) and isinstance(b, list):
        types = [kids[0]] * len(a) if t.startswith("array(") else kids
        return len(a) == len(b) and all(_same(x, y, k) for x, y, k in zip(a, b, types))
    if t.startswith("map(") and isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k], kids[1]) for k in a)
    return a == b


def type_name(t: str) -> str:
    """A protocol type name, spelled one way: Trino writes `decimal(5, 2)` where lakegate writes
    `decimal(5,2)` (clients read the typeSignature, which is the same)."""
    return re.sub(r"decimal\((\d+), (\d+)\)", r"decimal(\1,\2)", t)


def differ(lakegate: Outcome, trino: Outcome, ordered: bool) -> str | None:
    """Why two successful answers differ, or None when they are the same."""
    if [type_name(t) for t in lakegate.types] != [type_name(t) for t in trino.types]:
        return f"result types differ: lakegate {lakegate.types}, Trino {trino.types}"
    if len(lakegate.rows) != len(trino.rows):
        return f"row counts differ: lakegate {len(lakegate.rows)}, Trino {len(trino.rows)}"
    types = trino.types
    same = lambda a, b: all(_same(x, y, t) for x, y, t in zip(a, b, types))  # noqa: E731
    if ordered:
        for index, (a, b) in enumerate(zip(lakegate.rows, trino.rows)):
            if not same(a, b):
                return f"rows differ at position {index}: lakegate {a}, Trino {b}"
        return None
    # as multisets: rows whose rounded keys are equal are matched by value, in any order (doubles
    # that round alike, such as 1.75e18 and 1.7500000005e18, sort in no fixed order)
    key = lambda row: tuple(_key(v, t) for v, t in zip(row, types))  # noqa: E731
    groups: dict[tuple, list[list[Any]]] = {}
    for row in trino.rows:
        groups.setdefault(key(row), []).append(row)
    for row in sorted(lakegate.rows, key=key):
        group = groups.get(key(row), [])
        match = next((i for i, other in enumerate(group) if same(row, other)), None)
        if match is None:
            return f"rows differ: lakegate's row {row} is not in Trino's answer"
        del group[match]
    return None
