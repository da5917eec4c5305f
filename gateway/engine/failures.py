"""What the client of a failed query sees: DuckDB's errors in Trino's terms (error names), the
time limit's error, and texts with the lake's paths hidden."""

from __future__ import annotations

import os
import re
from pathlib import Path

import duckdb

from lakegate.dialect.errors import DialectError, runtime_error


def time_limit_error(seconds: float) -> DialectError:
    """The EXCEEDED_TIME_LIMIT error of a query that ran longer than `seconds`."""
    return DialectError(
        f"Query exceeded the maximum execution time limit of {seconds:.2f}s", error_name="EXCEEDED_TIME_LIMIT"
    )


def duckdb_failure(error: BaseException) -> DialectError:
    """The DialectError (Trino error name) for an error DuckDB raised while running a query."""
    if isinstance(error, duckdb.InterruptException) or "INTERRUPT Error" in str(error):
        return DialectError("Query was canceled", error_name="USER_CANCELED")
    if isinstance(error, duckdb.OutOfMemoryException) or "Out of Memory Error" in str(error):
        return DialectError(f"Query exceeded the memory limit: {error}", error_name="EXCEEDED_GLOBAL_MEMORY_LIMIT")
    return runtime_error(str(error))


def hide_paths(text: str, *roots: Path | str | None, keep_width: bool = False) -> str:
    """`text` for a client: paths under `roots` relative to them, each root itself by its name
    (`keep_width`: a shortened path is followed by spaces, so that a drawn table keeps its shape)."""
    for root in roots:
        if root is not None:
            root = str(root).rstrip("/")
            pad = " " * (len(root) + 1) if keep_width else ""
            text = re.sub(re.escape(root + "/") + r"(\S*)", lambda match, pad=pad: match.group(1) + pad, text)
            text = re.sub(re.escape(root) + r"(?![\w.-])", os.path.basename(root), text)
    return text
