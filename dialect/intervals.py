"""Trino's interval literals with a span of fields, `INTERVAL '1 2:03:04.5' DAY TO SECOND` and
`INTERVAL '1-2' YEAR TO MONTH`, read as the real Trino 476 reads them: a sign, then the fields from the
first unit on, each later one optional ('2' HOUR TO SECOND is two hours), a field past its range carried
('42 30' DAY TO HOUR is 43 days 6 hours), a fraction on seconds only, kept to milliseconds (truncated)."""

from __future__ import annotations

import re

#: Each span's fields, in order, as the literal's text writes them.
_DAY_TIME_SPANS = {
    ("DAY", "HOUR"): r"(\d+)(?: (\d+))?",
    ("DAY", "MINUTE"): r"(\d+)(?: (\d+)(?::(\d+))?)?",
    ("DAY", "SECOND"): r"(\d+)(?: (\d+)(?::(\d+)(?::(\d+)(?:\.(\d+))?)?)?)?",
    ("HOUR", "MINUTE"): r"(\d+)(?::(\d+))?",
    ("HOUR", "SECOND"): r"(\d+)(?::(\d+)(?::(\d+)(?:\.(\d+))?)?)?",
    ("MINUTE", "SECOND"): r"(\d+)(?::(\d+)(?:\.(\d+))?)?",
}
_MILLIS = {"DAY": 86_400_000, "HOUR": 3_600_000, "MINUTE": 60_000, "SECOND": 1000}
_ORDER = ("DAY", "HOUR", "MINUTE", "SECOND")


def span_value(text: str, first: str, last: str) -> tuple[str, int] | None:
    """("months", n) or ("millis", n) of the literal `text` of span `first` TO `last`, or None when
    lakegate does not read it (Trino may answer or refuse it)."""
    match = re.fullmatch(r"([+-]?)(.*)", text)
    sign = -1 if match.group(1) == "-" else 1
    body = match.group(2)
    if (first, last) == ("YEAR", "MONTH"):
        fields = re.fullmatch(r"(\d+)(?:-(\d+))?", body)
        if fields is None:
            return None
        return "months", sign * (int(fields.group(1)) * 12 + int(fields.group(2) or 0))
    pattern = _DAY_TIME_SPANS.get((first, last))
    fields = re.fullmatch(pattern, body) if pattern else None
    if fields is None:
        return None
    units = _ORDER[_ORDER.index(first) : _ORDER.index(last) + 1]
    values = fields.groups()
    millis = sum(int(value or 0) * _MILLIS[unit] for unit, value in zip(units, values))
    if last == "SECOND" and values[len(units)] is not None:
        millis += int(values[len(units)][:3].ljust(3, "0"))
    return "millis", sign * millis


def duckdb_interval(kind: str, amount: int) -> str:
    """DuckDB SQL of an interval of `amount` months or milliseconds (days kept as days, as the
    single-field literals are)."""
    if kind == "months":
        return f"INTERVAL '{amount}' MONTH"
    days, millis = divmod(abs(amount), _MILLIS["DAY"])
    sign = "-" if amount < 0 else ""
    return f"(INTERVAL '{sign}{days}' DAY + INTERVAL '{sign}{millis}' MILLISECOND)"


#: The fields of each interval type (DateTimeFunctions: dayFromInterval, yearFromInterval, ...).
FIELDS = {
    "interval_ds": ("day", "hour", "minute", "second", "millisecond"),
    "interval_ym": ("year", "month"),
}
_FIELD_SQL = {
    "day": "{m} // 86400000",
    "hour": "{m} % 86400000 // 3600000",
    "minute": "{m} % 3600000 // 60000",
    "second": "{m} % 60000 // 1000",
    "millisecond": "{m} % 1000",
    "year": "{m} // 12",
    "month": "{m} % 12",
}


def field(sql: str, base: str, name: str) -> str:
    """DuckDB SQL of one field of an interval (`name` of FIELDS[base]) as Trino computes it: of the
    whole value in milliseconds or months, truncating toward zero (a negative interval's fields are
    negative)."""
    if base == "interval_ym":
        amount = f"CAST(date_part('year', {sql}) * 12 + date_part('month', {sql}) AS BIGINT)"
    else:
        amount = f"CAST(epoch_ms({sql}) AS BIGINT)"
    return f"CAST({_FIELD_SQL[name].format(m=f'({amount})')} AS BIGINT)"
