"""Valid Trino syntax that sqlglot's Trino parser does not read: when parsing fails, a query that
uses one of these is refused with NOT_SUPPORTED naming the construct in Trino's words, not with a
SYNTAX_ERROR that would call valid Trino invalid (docs/src/main/sphinx/functions/string.md overlay,
language/types.md numeric literals, functions/conditional.md CASE).
"""

from __future__ import annotations

import re

#: The refusal of json_table (functions/json.md), parsed by sqlglot or not.
JSON_TABLE = "table function 'json_table' is not translated (json_value, json_query and json_exists are)"

#: (pattern over the query text, the construct as Trino's documentation names it)
_CONSTRUCTS = (
    (re.compile(r"\bjson_table\s*\(", re.IGNORECASE), JSON_TABLE),  # AS name, PLAN, PASSING, ... do not parse
    (  # trinodb/trino pull request 30026 (merged 2026-06-23) added it, long after Trino 476
        re.compile(r"\boverlay\s*\(.*\bPLACING\b", re.IGNORECASE | re.DOTALL),
        "overlay(string PLACING ...), which Trino added after 476 (the release lakegate answers as)",
    ),
    (re.compile(r"\b\d+(?:_\d+)+\b"), "numeric literal with _ digit separators (10_000)"),
    (
        re.compile(r"\bWHEN\s+(?:[<>=!]|(?:NOT\s+)?(?:BETWEEN|IN|LIKE)\b|IS\b)", re.IGNORECASE),
        "CASE operand WHEN with a predicate (WHEN > x, WHEN IS NULL, ...)",
    ),
)


def unparsed_construct(sql: str) -> str | None:
    """The Trino construct sqlglot cannot parse that `sql` uses, if any."""
    return next((name for pattern, name in _CONSTRUCTS if pattern.search(sql)), None)
