"""Trino's documented examples (tests/dialect/trino_doc_examples.yaml, run by
tools/trino_doc_examples.py through a real Engine and DuckDB): each answers as its page states, or is
refused with NOT_SUPPORTED in Trino's words, never with sqlglot's class names or a DuckDB error."""

from __future__ import annotations

import pytest
from trino_doc_examples import LEAKS, Outcome, normalized, outcomes


@pytest.fixture(scope="module")
def examples() -> list[Outcome]:
    return outcomes()


def _listed(found: list[Outcome]) -> str:
    return "\n".join(f"{o.page}: {o.sql}\n  doc: {o.expected}\n  got: {o.got}" for o in found)


def test_every_answer_is_the_documented_one(examples):
    wrong = [o for o in examples if o.kind == "wrong"]
    assert not wrong, _listed(wrong)
    assert sum(o.kind == "right" for o in examples) >= 250


def test_every_refusal_names_the_construct(examples):
    bad = [o for o in examples if o.kind == "leak" or o.kind == "refused" and not o.got.startswith("NOT_SUPPORTED")]
    assert not bad, _listed(bad)


def test_the_sorting_can_fail():
    assert LEAKS.search("NOT_SUPPORTED: unsupported in lakegate: syntax JSONVALUE")
    assert LEAKS.search("Binder Error: No function matches")
    assert not LEAKS.search("NOT_SUPPORTED: unsupported in lakegate: function 'json_object'")
    assert normalized("{7=1, 42=2}") == normalized("{42=2, 7=1}")
    assert normalized("[ROW(1, 'x'), ROW(2, 'y')]") == normalized("[[1, x], [2, y]]")
    assert normalized("2; 1", ordered=False) == normalized("1; 2", ordered=False)
    assert normalized("2; 1") != normalized("1; 2")
