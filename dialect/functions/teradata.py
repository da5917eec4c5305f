"""Trino's functions/teradata.md. Teradata functions: to_char, to_date, to_timestamp (plugin/trino-teradata-
functions).
"""

from __future__ import annotations

import re

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.arguments import literal_str, need
from lakegate.dialect.functions.datetime_formats import joda_field, render_format_datetime
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call

# --- Teradata to_char / to_date / to_timestamp (plugin/trino-teradata-functions: DateFormatParser,
# TeradataDateFunctions) -------------------------------------------------------------------------
#: Teradata format token -> (the Joda pattern DateFormatParser builds, the parse regex, the field).
_TERADATA = {
    "yyyy": ("yyyy", "([0-9]{1,4})", "year"),
    "yy": ("yy", "([0-9]{2})", "year2"),
    "mm": ("MM", "([0-9]{1,2})", "month"),
    "dd": ("dd", "([0-9]{1,2})", "day"),
    "hh24": ("HH", "([0-9]{1,2})", "hour"),
    "hh": ("KK", "([0-9]{1,2})", "hour"),
    "mi": ("mm", "([0-9]{1,2})", "minute"),
    "ss": ("ss", "([0-9]{1,2})", "second"),
}

_TERADATA_TEXT = "-/,.;: "


def _teradata_tokens(call: Call) -> list[tuple[str, str]]:
    """The literal format's tokens: ('field', token) longest first, ('text', characters)."""
    fmt = literal_str(call, 1)
    if fmt is None:
        call.fail(f"{call.name} with a non-literal format is not supported in lakegate", "NOT_SUPPORTED")
    tokens, i = [], 0
    while i < len(fmt):
        token = next((t for t in sorted(_TERADATA, key=len, reverse=True) if fmt.startswith(t, i)), None)
        if token is not None:
            tokens.append(("field", token))
            i += len(token)
        elif fmt[i] in _TERADATA_TEXT:
            tokens.append(("text", fmt[i]))
            i += 1
        else:
            call.fail(f"Failed to tokenize string [{fmt[i]}] at offset [{i}]", "INVALID_FUNCTION_ARGUMENT")
    return tokens


def _to_char(call: Call) -> TType:
    value, _ = need(call, "temporal", "string")
    if value.base == "date":
        call.mismatch()
    pieces = [
        tf.string(text) if kind == "text" else joda_field(call, _TERADATA[text][0])
        for kind, text in _teradata_tokens(call)
    ]
    call.node.meta["joda"] = " || ".join(pieces) or "''"
    return tt.VARCHAR


def _teradata_parse(call: Call) -> TType:
    """to_date / to_timestamp: Joda parses each field greedily and never backtracks, so two number
    fields with nothing between them are refused (a regular expression could split them otherwise)."""
    need(call, "string", "string")
    tokens = _teradata_tokens(call)
    if any(a[0] == b[0] == "field" for a, b in zip(tokens, tokens[1:])):
        call.fail(f"{call.name} with adjacent number fields is not supported in lakegate", "NOT_SUPPORTED")
    call.node.meta["teradata"] = tokens
    return tt.DATE if call.name == "to_date" else tt.timestamp(3)


def _render_teradata_parse(g, node, args) -> str:
    """DateTimeFormatter.parseMillis in UTC: the whole text must match; fields missing from the
    format are 1970-01-01 00:00:00; yy is 2000-2099 (appendTwoDigitYear(2050)); to_date keeps the
    day MILLISECONDS.toDays gives (towards 1970 for a time of day before 1970)."""
    text = g.sql(args[0])
    tokens = node.meta["teradata"]
    pattern = "".join(re.escape(t) if kind == "text" else _TERADATA[t][1] for kind, t in tokens)
    fields = {_TERADATA[t][2]: i + 1 for i, (kind, t) in enumerate((k, t) for k, t in tokens if k == "field")}

    def field(name: str, default: str) -> str:
        if name not in fields:
            return default
        return f"CAST(regexp_extract({text}, {tf.string(pattern)}, {fields[name]}) AS INTEGER)"

    year = (
        field("year", "1970") if "year" in fields else f"2000 + {field('year2', '70')}" if "year2" in fields else "1970"
    )
    month, day = field("month", "1"), field("day", "1")
    hour, minute, second = field("hour", "0"), field("minute", "0"), field("second", "0")
    halfday = any(t == "hh" for _, t in tokens)
    checks = (
        f"{month} BETWEEN 1 AND 12 "
        f"AND {day} BETWEEN 1 AND day(last_day(make_date({year}, least(greatest({month}, 1), 12), 1))) "
        f"AND {hour} BETWEEN 0 AND {11 if halfday else 23} AND {minute} BETWEEN 0 AND 59 AND {second} BETWEEN 0 AND 59"
    )
    # DuckDB folds constant arguments even in a CASE branch not taken: out-of-range fields become 1
    month, day = (f"CASE WHEN {checks} THEN {f} ELSE 1 END" for f in (month, day))
    stamp = f"make_timestamp({year}, {month}, {day}, {hour}, {minute}, {second})"
    if node.name.lower() == "to_date":
        early_time = (
            f"make_date({year}, {month}, {day}) < DATE '1970-01-01' AND ({hour} > 0 OR {minute} > 0 OR {second} > 0)"
        )
        value = f"make_date({year}, {month}, {day}) + CASE WHEN {early_time} THEN 1 ELSE 0 END"
    else:
        value = stamp
    invalid = g.fail(f"'Invalid format: \"' || {text} || '\"'")
    return (
        f"CASE WHEN {text} IS NULL OR ({g.sql(args[1])}) IS NULL THEN NULL "
        f"WHEN NOT regexp_full_match({text}, {tf.string(pattern)}) THEN {invalid} "
        f"WHEN NOT ({checks}) THEN {g.fail(tf.string('Cannot parse ') + ' || ' + text)} ELSE {value} END"
    )


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "to_char",
        "datetime",
        "to_char(timestamp, format) -> varchar (Teradata)",
        _to_char,
        render_format_datetime,
        notes="A literal Teradata format (yyyy yy mm dd hh hh24 mi ss and - / , . ; : space).",
    )
    for _name, _result in (("to_date", "date"), ("to_timestamp", "timestamp(3)")):
        register(
            _name,
            "datetime",
            f"{_name}(string, format) -> {_result} (Teradata)",
            _teradata_parse,
            _render_teradata_parse,
            notes="A literal Teradata format; number fields with nothing between them are refused.",
        )
