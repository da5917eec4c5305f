"""The function registry refuses a second definition of a function: when two modules (or two merged
branches) register the same Trino name, importing the dialect fails instead of one silently winning."""

from __future__ import annotations

import duckdb
import pytest

from lakegate.dialect import registry, translate
from lakegate.dialect.functions import pages

pages.install()  # the registry, filled from the one list of function modules (translate does the same)


def test_a_function_registered_twice_is_an_error():
    spec = registry.SUPPORTED["abs"]
    with pytest.raises(ValueError, match="'abs' is already registered"):
        registry.register("abs", spec.family, spec.signature, spec.infer, spec.render)
    assert registry.SUPPORTED["abs"] is spec


def test_an_overload_must_extend_a_registered_function():
    spec = registry.SUPPORTED["abs"]
    with pytest.raises(ValueError, match="'no_such_function' is not yet registered"):
        registry.register("no_such_function", "math", "", spec.infer, spec.render, replaces=True)
    assert "no_such_function" not in registry.SUPPORTED


def test_each_overload_of_a_function_renders_its_own_calls():
    """lpad has a varbinary overload and a char one over it (both in functions/string.py): a call
    taken by neither falls through both to the varchar rule."""
    sql = "SELECT lpad(CAST('a' AS char(2)), 3, 'x'), lpad(to_utf8('a'), 3, to_utf8('b')), lpad('a', 3, 'x')"
    duckdb_sql = translate.translate(sql, {}).duckdb_sql
    assert duckdb.connect().execute(duckdb_sql).fetchall() == [("xa ", b"bba", "xxa")]
