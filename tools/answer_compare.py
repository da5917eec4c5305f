"""How two answers in the Trino client-protocol JSON encoding compare, as the conformance runner and
the differential run against the real Trino both judge them: type names without case, quotes and
spaces after commas; values strictly (a bool is not a number, "1" is not 1), doubles to a tolerance
when one is given; rows in order when the query fixes the order, otherwise as a multiset.
"""

from __future__ import annotations

import json
import math
import re

import sqlglot


def normalize_type(text: str) -> str:
    """Type names compare without case, quotes and spaces after commas (`decimal(6, 2)` is
    `decimal(6,2)`)."""
    return re.sub(r"\s*,\s*", ",", text.strip().lower().replace('"', ""))


def same(expected, actual, tolerance: float | None) -> bool:
    """Whether two encoded values (or rows, or lists of rows) are equal."""
    if isinstance(expected, bool) or isinstance(actual, bool):
        return type(expected) is type(actual) and expected == actual
    if isinstance(expected, (int, float)) and isinstance(actual, (int, float)):
        if tolerance is not None:
            return math.isclose(expected, actual, rel_tol=tolerance, abs_tol=tolerance)
        return expected == actual
    if isinstance(expected, list) and isinstance(actual, list):
        return len(expected) == len(actual) and all(same(e, a, tolerance) for e, a in zip(expected, actual))
    if isinstance(expected, dict) and isinstance(actual, dict):
        return expected.keys() == actual.keys() and all(same(expected[k], actual[k], tolerance) for k in expected)
    return expected == actual and type(expected) is type(actual)


def sort_key(row) -> str:
    """A key that sorts equal rows together (numbers as floats, so that 1 and 1.0 sort alike)."""

    def norm(v):
        if isinstance(v, bool) or v is None or isinstance(v, str):
            return v
        if isinstance(v, (int, float)):
            return float(v)
        if isinstance(v, list):
            return [norm(x) for x in v]
        if isinstance(v, dict):
            return {k: norm(x) for k, x in v.items()}
        return repr(v)

    return json.dumps(norm(row), sort_keys=True, ensure_ascii=False)


def has_order_by(sql: str) -> bool:
    """Whether the Trino query has a top-level ORDER BY (which fixes the order of its rows); False for
    a query sqlglot cannot read (its rows then compare as a multiset)."""
    try:
        tree = sqlglot.parse_one(sql.strip().rstrip(";"), read="trino")
    except sqlglot.errors.SqlglotError:
        return False
    return bool(tree and tree.args.get("order"))


def rows_match(expected, actual, *, ordered: bool, tolerance: float | None = None) -> bool:
    """Whether two lists of encoded rows are equal, in order or as multisets."""
    expected, actual = [list(row) for row in expected], [list(row) for row in actual]
    if not ordered:
        expected, actual = sorted(expected, key=sort_key), sorted(actual, key=sort_key)
    return same(expected, actual, tolerance)


def types_match(expected, actual) -> bool:
    """Whether two lists of (name, type) columns have the same type names, in order."""
    return [normalize_type(t) for _, t in expected] == [normalize_type(t) for _, t in actual]
