"""The constructs table (lakegate.dialect.constructs, docs/functions.md) is true: every supported
construct's example translates, every refused one is refused with NOT_SUPPORTED naming the construct
in Trino's words, and each example is recognised as using its construct (so the case counts of the
page are counts of real uses)."""

from __future__ import annotations

import pytest
from functions_doc import used_constructs

from lakegate.dialect.constructs import CONSTRUCTS
from lakegate.dialect.errors import DialectError
from lakegate.dialect.translate import translate


@pytest.mark.parametrize("name", list(CONSTRUCTS))
def test_construct_example(name: str, fixture_lake):
    construct = CONSTRUCTS[name]
    params = [1] if "?" in construct.example else []
    assert name in used_constructs(construct.example, CONSTRUCTS)
    if not construct.refused:
        translate(construct.example, fixture_lake.schema, params=params)
        return
    with pytest.raises(DialectError) as refusal:
        translate(construct.example, fixture_lake.schema, params=params)
    assert refusal.value.error_name == "NOT_SUPPORTED"
    assert name.split(" (")[0].lower() in str(refusal.value).lower()
