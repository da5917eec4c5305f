"""The lake's catalog name, in a module of its own so that `lakegate serve --help` shows it without
importing the engine."""

from __future__ import annotations

#: The lake's catalog name (Trino clients address tables as catalog.schema.table).
CATALOG = "lake"
