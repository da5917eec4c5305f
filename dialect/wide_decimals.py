"""Decimal division whose dividend, rescaled to the result's scale, exceeds DuckDB's 128 bits (Trino
divides in 256: io.trino.type.DecimalOperators, Int128Math.divideRoundUp). The translation calls
`UDF_NAME`, which lakegate.gateway.engine.udfs registers on every engine connection as `divide`,
only for such rows; Python's integers give the exact quotient.
"""

from __future__ import annotations

#: The DuckDB name of `divide` (not callable from Trino SQL: the analyzer knows only registered names).
UDF_NAME = "lakegate_wide_decimal_divide"

#: The first unscaled value past decimal(38).
_LIMIT = 10**38


def divide(dividend: int, divisor: int, rescale: int, fail: bool) -> int | None:
    """round_half_up(dividend * 10^rescale / divisor), the unscaled quotient of Trino's decimal
    division; past 38 digits Trino's "Decimal overflow" (NULL when not `fail`, inside try()).
    A zero divisor gives NULL: the translation fails on it first."""
    if divisor == 0:
        return None
    quotient, remainder = divmod(abs(dividend) * 10**rescale, abs(divisor))
    if 2 * remainder >= abs(divisor):
        quotient += 1
    if quotient >= _LIMIT:
        if fail:
            raise ArithmeticError("NUMERIC_VALUE_OUT_OF_RANGE: Decimal overflow")
        return None
    return quotient if (dividend < 0) == (divisor < 0) else -quotient
