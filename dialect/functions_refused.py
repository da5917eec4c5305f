"""Trino functions lakegate does not translate yet, refused by name (NOT_SUPPORTED, with the reason)
rather than as unknown names (FUNCTION_NOT_FOUND is for names Trino does not have). Found by the
sweep of Trino's documented examples (tools/trino_doc_examples.py); each is in Trino's function
reference (trinodb/trino docs/src/main/sphinx/functions/).
"""

from __future__ import annotations

from lakegate.dialect import registry

REJECTED: dict[str, str] = {
    "title_case": "not translated (string.md)",
    "timezone": "not translated (datetime.md: the zone identifier of a timestamp or time with time zone)",
    "from_iso8601_timestamp_nanos": "DuckDB has no nanosecond timestamp with time zone",
}

registry.REJECTED.update(REJECTED)
