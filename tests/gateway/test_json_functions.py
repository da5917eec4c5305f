"""The JSON functions that read text as Trino's streaming Jackson parser does
(gateway/engine/json_stream.py, json_functions.py); every expected answer is the real Trino 476's
(tests/dialect/cases/json.yaml holds them as conformance cases)."""

from __future__ import annotations

import duckdb
import pytest

from lakegate.gateway.engine import json_functions as jf
from lakegate.gateway.engine import udfs
from lakegate.gateway.engine.json_stream import MalformedJson, Parser


@pytest.mark.parametrize(
    ("text", "path", "answer"),
    [
        ("[1,]", '["0"]', "1"),
        ("[1,]", '["1"]', None),
        ("[1] x", "[]", None),
        ('{"a": 1, ', '["a"]', "1"),
        ('{"b": [1,], "a": 2}', '["a"]', None),
        ("[1, 01]", '["0"]', "1"),
        ("[01]", '["0"]', None),
        ("[1.50, x", '["0"]', "1.50"),
        ("1 x", "[]", "1"),
        ("1x", "[]", None),
        ("[true$]", '["0"]', "true"),
        ("[true_]", '["0"]', None),
        ('["a\\nb", x', '["0"]', "a\nb"),
        ('["\\ud800", x', '["0"]', "?"),
        ('{"0": 5}', '["0"]', "5"),
        ("[5, 6]", '["+1"]', "6"),
        ("[5, 6]", '["-1"]', None),
        ("", "[]", None),
    ],
)
def test_json_extract_scalar_stops_at_the_value(text, path, answer):
    assert jf.json_extract_scalar(text, path) == answer


def test_json_extract_writes_as_jacksons_generator():
    assert jf.json_extract('{"a": {"z": 1.50, "y": [1e3, "s\\u00e9"]}, x', '["a"]') == '{"z":1.5,"y":[1000.0,"sé"]}'
    assert jf.json_extract('["\\u0001\\t😀"]', '["0"]') == '"\\u0001\\t\\uD83D\\uDE00"'
    assert jf.json_extract("[-0, 1e400] x", "[]") == '[0,"Infinity"]'
    assert jf.json_extract('{"a": [1,]}', '["a"]') is None


def test_array_functions_read_as_far_as_they_need():
    assert jf.json_array_length("[1, [2, 3], {}] {") == 3
    assert jf.json_array_length("[1, 2,]") is None
    assert jf.json_size('{"a": "abc', '["a"]') == 0  # the string is never read
    assert jf.json_size('{"a": 1, "b": 2} x', "[]") == 2
    assert jf.json_array_get("[1, 2, x", 1) == "2"
    assert jf.json_array_get("[1, 2, x", -1) is None
    assert jf.json_array_get('[{"b": 1, "b": 2}]', 0) == '{"b":2}'
    assert jf.json_array_contains_bigint("[1, 2, x", 1) is True
    assert jf.json_array_contains_bigint("[1, 2, x", 5) is None
    assert jf.json_array_contains_varchar('["a", "b"] x', "c") is False
    with pytest.raises(RuntimeError, match="GENERIC_INTERNAL_ERROR: string is null"):
        jf.json_array_get("[null, 2] x", -2)


def test_a_string_is_checked_when_the_next_token_is_read():
    parser = Parser('["a\\q", 1]')
    assert parser.next_token() == "[" and parser.next_token() == "string"
    with pytest.raises(MalformedJson):
        parser.next_token()


def test_registered_functions_answer_null_for_null():
    connection = duckdb.connect()
    udfs.install(connection)
    row = connection.execute(
        "SELECT lakegate_json_extract_scalar(NULL, '[]'), lakegate_json_array_get('[1,', 0), "
        "lakegate_json_array_contains_double('[1.5,', 1.5)"
    ).fetchone()
    assert row == (None, "1", True)
