"""The conformance cases whose expected answers were taken from the real Trino 476 (their note starts
with "Trino 476"), asked of the real Trino again: the case files keep saying what Trino says. The
lakegate side of the same cases runs in test_conformance.py."""

from __future__ import annotations

import datetime as dt
import math
from decimal import Decimal
from urllib.parse import urlsplit

import numpy as np
import pytest
import trino
from functions_doc import Case, load_cases

JUDGED = [case for case in load_cases() if (case.note or "").startswith("Trino 476")]


def normalize_type(text: str) -> str:
    """`decimal(5, 3)` and `decimal(5,3)` alike, as the case files write them."""
    return text.strip().lower().replace(", ", ",").replace('"', "")


def _encoded(value, trino_type: str):
    """A value of the trino client in the case files' encoding (real: as the double of the float)."""
    if isinstance(value, float):
        if math.isnan(value):
            return "NaN"
        if math.isinf(value):
            return "Infinity" if value > 0 else "-Infinity"
        return float(np.float32(value)) if trino_type == "real" else value
    if isinstance(value, Decimal):
        return format(value, "f")
    if isinstance(value, (dt.date, dt.datetime)):
        return value.isoformat()
    return value


@pytest.mark.parametrize("case", JUDGED, ids=lambda case: case.id)
def test_case_files_say_what_trino_says(case: Case, trino_url):
    parts = urlsplit(trino_url)
    cursor = trino.dbapi.connect(host=parts.hostname, port=parts.port, user="lakegate-judged-cases").cursor()
    if case.errors:
        with pytest.raises(trino.exceptions.TrinoQueryError) as error:
            cursor.execute(case.sql)
            cursor.fetchall()
        assert error.value.error_name in case.errors
        assert (case.message or "").lower() in error.value.message.lower()
        return
    cursor.execute(case.sql)
    rows = cursor.fetchall()
    columns = [(d[0], d[1]) for d in cursor.description]
    assert [(n, normalize_type(t)) for n, t in columns] == [(n, normalize_type(t)) for n, t in case.columns]
    got = [[_encoded(v, normalize_type(t)) for v, (_, t) in zip(row, columns)] for row in rows]
    expected = [list(row) for row in case.rows]
    if case.ordered is False or (case.ordered is None and "ORDER BY" not in case.sql.upper()):
        got, expected = sorted(got, key=repr), sorted(expected, key=repr)
    assert got == expected
