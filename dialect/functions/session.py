"""Trino's functions/session.md. Session information: `current_groups()` here; `current_user`,
`current_catalog`, `current_schema` and `current_path` are special forms bound to the session's values
before translation (dialect/session_functions.py)."""

from __future__ import annotations

from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.arguments import fixed
from lakegate.dialect.registry import register


def install() -> None:
    """Register the functions of this page (called by pages.py)."""
    register(
        "current_groups",
        "session",
        "current_groups() -> array(varchar)",
        fixed(tt.array(tt.VARCHAR)),
        lambda g, node, args: "CAST([] AS VARCHAR[])",
        notes="Always empty: lakegate has no group provider (nor has a Trino without one).",
    )
