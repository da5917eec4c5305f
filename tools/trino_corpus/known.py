"""The corpus queries where lakegate still answers otherwise than the real Trino 476 (`different`) or
answers where Trino raises (`trino raises`), each with what Trino does: allowed by the differential
run until fixed (a new one fails it). Keyed by the query's SQL."""

from __future__ import annotations

KNOWN: dict[str, str] = {
    "SELECT greatest(ARRAY[REAL '5'], ARRAY[REAL '4'], ARRAY[REAL '3'], ARRAY[CAST(NaN() as REAL)])": (
        "greatest of arrays holding NaN: Trino orders nested NaN below the other values, [5.0] (a NaN family of the "
        "fidelity work)"
    ),
    "SELECT (SELECT t.a FROM (VALUES BIGINT '1', BIGINT '2') t(a) WHERE t.a = t2.b LIMIT 1) "
    "FROM (VALUES 1e0, 2e0) t2(b)": (
        "a correlated subquery with LIMIT 1 whose correlation needs a cast: NOT_SUPPORTED "
        "(Given correlated subquery is not supported)"
    ),
    "SELECT (SELECT t.a FROM (VALUES BIGINT '1', BIGINT '2', BIGINT '3') t(a) WHERE t.a = t2.b LIMIT 2) "
    "FROM (VALUES 1e0, 2e0) t2(b)": (
        "a correlated subquery with LIMIT whose correlation needs a cast: NOT_SUPPORTED "
        "(Given correlated subquery is not supported)"
    ),
}
