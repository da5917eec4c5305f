"""The one error type of the dialect layer, carrying Trino's error name and the SQL position."""

from __future__ import annotations

import logging
import re

#: Trino's standard error codes (io.trino.spi.StandardErrorCode) for the names this layer raises.
ERROR_CODES = {
    "GENERIC_USER_ERROR": 0,
    "SYNTAX_ERROR": 1,
    "PERMISSION_DENIED": 4,
    "NOT_FOUND": 5,
    "FUNCTION_NOT_FOUND": 6,
    "INVALID_FUNCTION_ARGUMENT": 7,
    "DIVISION_BY_ZERO": 8,
    "INVALID_CAST_ARGUMENT": 9,
    "NOT_SUPPORTED": 13,
    "INVALID_WINDOW_FRAME": 15,
    "NUMERIC_VALUE_OUT_OF_RANGE": 19,
    "SUBQUERY_MULTIPLE_ROWS": 28,
    "QUERY_TEXT_TOO_LARGE": 35,
    "EXCEEDED_FUNCTION_MEMORY_LIMIT": 37,
    "SCHEMA_NOT_FOUND": 45,
    "TABLE_NOT_FOUND": 46,
    "COLUMN_NOT_FOUND": 47,
    "DUPLICATE_NAMED_QUERY": 53,
    "DUPLICATE_COLUMN_NAME": 54,
    "TYPE_MISMATCH": 58,
    "INVALID_LITERAL": 59,
    "MISMATCHED_COLUMN_ALIASES": 61,
    "AMBIGUOUS_NAME": 62,
    "INVALID_COLUMN_REFERENCE": 63,
    "MISSING_GROUP_BY": 64,
    "MISSING_ORDER_BY": 65,
    "MISSING_OVER": 66,
    "EXPRESSION_NOT_IN_DISTINCT": 69,
    "FUNCTION_NOT_WINDOW": 71,
    "FUNCTION_NOT_AGGREGATE": 72,
    "EXPRESSION_NOT_AGGREGATE": 73,
    "INVALID_ARGUMENTS": 76,
    "TOO_MANY_ARGUMENTS": 77,
    "INVALID_PARAMETER_USAGE": 80,
    "NULL_TREATMENT_NOT_ALLOWED": 83,
    "INVALID_ORDER_BY": 91,
    "DUPLICATE_WINDOW_NAME": 92,
    "INVALID_WINDOW_REFERENCE": 93,
    "INVALID_PARTITION_BY": 94,
    "USER_CANCELED": 3,
    "GENERIC_INTERNAL_ERROR": 65536,
    "EXCEEDED_GLOBAL_MEMORY_LIMIT": 131073,
    "HIVE_FILE_NOT_FOUND": 16777220,  # io.trino.plugin.hive.HiveErrorCode: a listed file is gone
    "HIVE_BAD_DATA": 16777223,  # io.trino.plugin.hive.HiveErrorCode: a data file cannot be read
}


class DialectError(ValueError):
    """A query is invalid or cannot be answered exactly as Trino would.

    `line` and `column` are 1-based positions in the user's original SQL text (None
    when unknown); `error_name` is a Trino StandardErrorCode name, so the server can
    report it as Trino does. `str(err)` reads like `message (line 2, column 10)`.
    """

    def __init__(
        self,
        message: str,
        *,
        line: int | None = None,
        column: int | None = None,
        error_name: str = "GENERIC_USER_ERROR",
    ):
        self.message = message
        self.line = line
        self.column = column
        self.error_name = error_name
        where = f" (line {line}, column {column})" if line is not None and column is not None else ""
        super().__init__(f"{message}{where}")

    @property
    def error_code(self) -> int:
        return ERROR_CODES.get(self.error_name, 0)


#: Run-time failures of translated SQL, recognised by DuckDB's message text (the translation raises
#: Trino's own messages with DuckDB's error()), mapped to Trino error names.
_RUNTIME = (
    ("Division by zero", "DIVISION_BY_ZERO"),
    ("Array subscript", "INVALID_FUNCTION_ARGUMENT"),
    ("SQL array indices start at 1", "INVALID_FUNCTION_ARGUMENT"),
    ("Cannot cast ", "INVALID_CAST_ARGUMENT"),
    ("out of range", "NUMERIC_VALUE_OUT_OF_RANGE"),
    ("Conversion Error", "INVALID_CAST_ARGUMENT"),
    ("Out of Range Error", "NUMERIC_VALUE_OUT_OF_RANGE"),
    ("Overflow", "NUMERIC_VALUE_OUT_OF_RANGE"),
    ("More than one row returned by a subquery", "SUBQUERY_MULTIPLE_ROWS"),
    ("Invalid Input Error", "INVALID_FUNCTION_ARGUMENT"),
)


#: DuckDB's words before the message of a Python function that failed (gateway/engine/udfs.py
#: raises Trino-named messages).
_UDF_FAILURE = re.compile(r"Python exception occurred while executing the UDF: \w+: ")

#: An absolute file path in a DuckDB message (a lake file it read): at least two folders deep.
_PATH = re.compile(r"(?<![\w.:/])/(?:[^\s/'\"]+/)+([^\s/'\"]+)")


#: DuckDB's decimal +, - and * past 38 digits (the result types match Trino's, widened to 38 at most):
#: Trino says "Decimal overflow" (io.trino.type.DecimalOperators).
_DECIMAL_OVERFLOW = re.compile(r"Overflow in (?:addition|subtract|multiplication) of DECIMAL\(")


#: DuckDB's classes of errors that refuse the translated SQL itself (not the data it reads): no Trino query
#: ever meets them, so one means lakegate wrote SQL that DuckDB will not run for this query.
_REFUSED_TRANSLATION = re.compile(
    r"(?:Binder|Catalog|Parser|Not implemented|INTERNAL|Internal|Dependency|Invalid type|Serialization"
    r"|TransactionContext|Permission|Invalid Configuration|Sequence|Constraint|Invalid) Error: "
)

_log = logging.getLogger(__name__)


def runtime_error(message: str) -> DialectError:
    """The DialectError for a DuckDB error raised while running translated SQL: Trino's error name
    and message (DuckDB's 'Invalid Input Error: ' prefix removed, absolute paths cut to their file
    name). No position: Trino reports none for run-time failures either."""
    first = message.strip().splitlines()[0] if message.strip() else message
    first = _PATH.sub(r".../\1", _UDF_FAILURE.sub("", first))
    named = re.match(r"(?:[A-Za-z ]+ Error: )?([A-Z][A-Z_]+): (.*)", first)
    if named and named.group(1) in ERROR_CODES:
        return DialectError(named.group(2), error_name=named.group(1))
    if _REFUSED_TRANSLATION.match(first):
        _log.warning("DuckDB refused a translated query: %s", first)
        return DialectError(
            "unsupported in lakegate: this query cannot be answered exactly as Trino would "
            "(its translation to the engine does not run)",
            error_name="NOT_SUPPORTED",
        )
    if _DECIMAL_OVERFLOW.search(first):
        return DialectError("Decimal overflow", error_name="NUMERIC_VALUE_OUT_OF_RANGE")
    name = next((n for marker, n in _RUNTIME if marker in first), "GENERIC_USER_ERROR")
    text = (
        first.split(": ", 1)[1]
        if first.startswith(("Invalid Input Error: ", "Conversion Error: ", "Out of Range Error: "))
        else first
    )
    return DialectError(text, error_name=name)
