"""The one error type of the dialect layer, carrying Trino's error name and the SQL position."""
from __future__ import annotations

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
    "INVALID_PARAMETER_USAGE": 23,
    "SCHEMA_NOT_FOUND": 45,
    "TABLE_NOT_FOUND": 46,
    "COLUMN_NOT_FOUND": 47,
    "AMBIGUOUS_NAME": 48,
    "TYPE_MISMATCH": 58,
}


class DialectError(ValueError):
    """A query is invalid or cannot be answered exactly as Trino would.

    `line` and `column` are 1-based positions in the user's original SQL text (None
    when unknown); `error_name` is a Trino StandardErrorCode name, so the server can
    report it as Trino does. `str(err)` reads like `message (line 2, column 10)`.
    """

    def __init__(self, message: str, *, line: int | None = None, column: int | None = None,
                 error_name: str = "GENERIC_USER_ERROR"):
        self.message = message
        self.line = line
        self.column = column
        self.error_name = error_name
        where = f" (line {line}, column {column})" if line is not None and column is not None else ""
        super().__init__(f"{message}{where}")

    @property
    def error_code(self) -> int:
        return ERROR_CODES.get(self.error_name, 0)
