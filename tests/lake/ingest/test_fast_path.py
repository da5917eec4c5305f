"""The ingestion's fast path and the exact `check_value` decide every value of a table the same."""

from __future__ import annotations

import json
import math

import numpy as np
import pyarrow as pa

from lakegate.lake.config import load_config
from lakegate.lake.ingest import check_line, ingest_job, scan
from lakegate.lake.types import FieldError, check_value
from tests.lake.ingest.lines import bits, query

# -- the fast path and check_value agree ----------------------------------------------------

VALUES = {
    "int": [
        "0",
        "-0",
        "1",
        "-1",
        "9223372036854775807",
        "-9223372036854775808",
        "9223372036854775808",
        "-9223372036854775809",
        "1.0",
        "1e3",
        "1E2",
        "1.5",
        "true",
        "false",
        "null",
        '"1"',
        "[1]",
        '{"a": 1}',
        "NaN",
        "Infinity",
        "00",
        "-",
        "+1",
    ],
    "float": [
        "0",
        "1",
        "-1",
        "0.1",
        "-0.0",
        "1e308",
        "1e309",
        "-1e309",
        "1e-400",
        "4.9e-324",
        "2.2250738585072014e-308",
        "123456789012345678901234567890",
        "9007199254740993",
        "0.30000000000000004",
        "1.7976931348623157e308",
        "1.5e+10",
        "1E-5",
        "true",
        "null",
        '"1.5"',
        "NaN",
        "-Infinity",
        "[1.0]",
        ".5",
        "1.",
        "01.5",
    ],
    "boolean": ["true", "false", "0", "1", '"true"', "null", "[true]", "True"],
    "string": [
        '""',
        '"x"',
        '"\u00fcn\u00ef"',
        '"\\u00fc"',
        '"\\ud83d\\ude80"',
        '"\\ud800"',
        '"a\\"b"',
        '"tab\\t"',
        '"\\u0000"',
        "5",
        "true",
        "null",
        '["x"]',
        '{"a": "b"}',
        '"raw\ttab"',
        '"\\x"',
        "'single'",
    ],
    "status": ['"PASSED"', "1", "null"],
    "image": ['"a.png"', "[]"],
    "string[]": [
        "[]",
        '["a"]',
        '["a", "b"]',
        "[1]",
        '["a", null]',
        "null",
        '"a"',
        '[["a"]]',
        "[true]",
        '["\\ud800"]',
        '["a",]',
        "[ ]",
    ],
}


def expected_decision(field_type, literal):
    """What the rules say: standard JSON only, then check_value, then what Parquet can hold."""

    def refuse(token):
        raise ValueError(token)

    try:
        value = json.loads(literal, parse_constant=refuse)
        stored = check_value(field_type, value)
    except (ValueError, FieldError):
        return False, None
    try:
        json.dumps(stored, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError:
        return False, None
    return True, stored


def fast_paths(plans, raw):
    """Run one line through both fast paths: whole lines, and `$data` objects of lines in the Emitter's layout."""
    block = scan.Block("test", 1, raw + b"\n", np.array([0, len(raw) + 1]), 0)
    lines = pa.Array.from_buffers(pa.large_binary(), 1, [None, pa.py_buffer(block.offsets), pa.py_buffer(block.data)])
    codes, after = scan.Hinter(plans).codes_of(block, lines)
    plan = plans[codes[0]]
    layout, timestamps, start, close = scan._emitter_layout(block, np.array([0]), after, plan.topic.event)
    assert layout[0], "the cases are written in the Emitter's layout"
    payloads = scan._payloads(bytearray(block.data), start, close)
    return {
        "lines": scan._fast_lines(plan, pa.py_buffer(block.data), np.array([1])),
        "payloads": scan._fast_payloads(plan, payloads, np.array([1]), timestamps),
    }


def test_fast_path_and_exact_checks_agree_on_a_table_of_values(tmp_path):
    names = {t: "t_" + t.replace("[]", "_list") for t in VALUES}
    config_path = tmp_path / "c.yaml"
    config_path.write_text(
        "version: 1\ntopics:\n" + "".join(f"  {names[t]}:\n    schema: {{v: {json.dumps(t)}}}\n" for t in VALUES)
    )
    config = load_config(config_path)
    cases = [(t, literal) for t, literals in VALUES.items() for literal in literals]
    texts = [
        f'{{"$metadata": {{"topic": "{names[t]}", "timestamp": {n}}}, "$data": {{"v": {literal}}}}}'
        for n, (t, literal) in enumerate(cases)
    ]
    path = tmp_path / "cases.jsonl"
    path.write_bytes("".join(t + "\n" for t in texts).encode("utf-8", "surrogatepass"))
    plans = scan.topic_plans(config)
    for (field_type, literal), text in zip(cases, texts):
        accept, stored = expected_decision(field_type, literal)
        raw = text.encode("utf-8", "surrogatepass")
        # the exact check
        try:
            checked = check_line(raw, config.topics)
        except ValueError:
            checked = None
        assert (checked is not None) == accept, (field_type, literal)
        if accept:
            assert checked[2] == [stored]
        # each fast path alone, on this one line: the same decision and the same value
        for route, (table, refused) in fast_paths(plans, raw).items():
            assert (not len(refused)) == accept, (route, "decided otherwise", field_type, literal)
            if accept:
                value = table.column("v")[0].as_py()
                assert value == stored and type(value) is type(stored), (route, field_type, literal, value, stored)
                if field_type == "float":
                    assert bits(value) == bits(stored)
    # and end to end
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config, skip_bad_lines=True)
    accepted = {(t, lit) for t, lit in cases if expected_decision(t, lit)[0]}
    assert report.bad_lines == len(cases) - len(accepted)
    for field_type in VALUES:
        rows = query(tmp_path / "lake", f"SELECT timestamp, v FROM {names[field_type]} ORDER BY timestamp")
        want = [
            (n, expected_decision(t, lit)[1])
            for n, (t, lit) in enumerate(cases)
            if t == field_type and (t, lit) in accepted
        ]
        assert [r[0] for r in rows] == [w[0] for w in want]
        for (_, got), (_, value) in zip(rows, want):
            assert got == value and (field_type != "float" or bits(got) == bits(value))
    assert any(math.isclose(v, 1.2345678901234568e29) for (v,) in query(tmp_path / "lake", "SELECT v FROM t_float"))
