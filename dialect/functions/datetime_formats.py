"""Trino's functions/datetime.md. The formatting and parsing functions of datetime.md: the MySQL date functions
(date_format, date_parse) and the Java date functions (format_datetime, parse_datetime, over Joda-Time
patterns).
"""

from __future__ import annotations

import re

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import zones
from lakegate.dialect.functions.arguments import literal_str, need
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype

#: MySQL date_format specifiers Trino supports, as DuckDB strftime specifiers.
MYSQL_FORMAT = {
    "a": "%a",
    "b": "%b",
    "c": "%-m",
    "d": "%d",
    "e": "%-d",
    "f": "%f",
    "H": "%H",
    "h": "%I",
    "I": "%I",
    "i": "%M",
    "j": "%j",
    "k": "%-H",
    "l": "%-I",
    "M": "%B",
    "m": "%m",
    "p": "%p",
    "r": "%I:%M:%S %p",
    "S": "%S",
    "s": "%S",
    "T": "%H:%M:%S",
    "W": "%A",
    "Y": "%Y",
    "y": "%y",
    "%": "%%",
}


def mysql_to_strftime(fmt: str) -> str:
    """Translate a MySQL-style format (Trino's date_format / date_parse) to strftime; ValueError
    naming the first specifier that has no exact equivalent."""
    out = []
    i = 0
    while i < len(fmt):
        ch = fmt[i]
        if ch == "%" and i + 1 < len(fmt):
            spec = fmt[i + 1]
            if spec not in MYSQL_FORMAT:
                raise ValueError(f"%{spec}")
            out.append(MYSQL_FORMAT[spec])
            i += 2
            continue
        out.append("%%" if ch == "%" else ch)
        i += 1
    return "".join(out)


def _date_format(call: Call) -> TType:
    need(call, "temporal", "string")
    fmt = literal_str(call, 1)
    if fmt is None:
        call.fail("date_format needs a literal format in lakegate", "NOT_SUPPORTED")
    try:
        mysql_to_strftime(fmt)
    except ValueError as error:
        call.fail(f"unsupported in lakegate: date_format specifier '{error}'", "NOT_SUPPORTED")
    return tt.VARCHAR


def _render_date_format(g, node, args) -> str:
    value = tf.wall_time(g, args[0])
    if "%f" in re.findall(r"%.", args[1].name):  # Trino prints the milliseconds as six digits ('.111000')
        value = f"date_trunc('millisecond', {value})"
    return f"strftime({value}, {tf.string(mysql_to_strftime(args[1].name))})"


def _date_parse(call: Call) -> TType:
    need(call, "string", "string")
    fmt = literal_str(call, 1)
    if fmt is None:
        call.fail("date_parse needs a literal format in lakegate", "NOT_SUPPORTED")
    try:
        mysql_to_strftime(fmt)
    except ValueError as error:
        call.fail(f"unsupported in lakegate: date_parse specifier '{error}'", "NOT_SUPPORTED")
    return tt.timestamp(3)


def _render_date_parse(g, node, args) -> str:
    """Fields the format leaves out default to 1970-01-01 and %y reads 70..69 as 1970..2069
    (DateTimeFunctions: Joda's defaults, PIVOT_YEAR = 2020); strptime would use 1900 and 1969."""
    fmt, value = args[1].name, g.sql(args[0])
    years = re.findall(r"%.", fmt)
    if "%Y" not in years and "%y" not in years:
        fmt, value = "%Y " + fmt, f"('1970 ' || {value})"
    sql = f"CAST(strptime({value}, {tf.string(mysql_to_strftime(fmt))}) AS TIMESTAMP)"
    if "%y" in years:
        sql = f"CASE WHEN year({sql}) = 1969 THEN {sql} + INTERVAL 100 YEAR ELSE {sql} END"
    return sql


# --- format_datetime (Joda-Time DateTimeFormat patterns, DateTimeFunctions.formatDatetime) --------
#: Joda pattern letter -> (DuckDB SQL of the field over "_t" as an integer, or None for text fields).
_JODA_NUMBERS = {
    "C": 'year("_t") // 100',
    "Y": 'year("_t")',
    "y": 'year("_t")',
    "x": 'isoyear("_t")',
    "w": 'week("_t")',
    "e": 'isodow("_t")',
    "D": 'dayofyear("_t")',
    "M": 'month("_t")',
    "d": 'day("_t")',
    "K": 'hour("_t") % 12',
    "h": '(hour("_t") + 11) % 12 + 1',
    "H": 'hour("_t")',
    "k": '(hour("_t") + 23) % 24 + 1',
    "m": 'minute("_t")',
    "s": 'second("_t")',
}


def _joda_tokens(pattern: str) -> list[tuple[str, str]]:
    """Joda's DateTimeFormat.parsePatternTo: runs of one letter ('letter', run), quoted text and
    other characters ('text', text); '' is a quote."""
    tokens, i = [], 0
    while i < len(pattern):
        ch = pattern[i]
        if ch.isascii() and ch.isalpha():
            j = i
            while j < len(pattern) and pattern[j] == ch:
                j += 1
            tokens.append(("letter", pattern[i:j]))
            i = j
        elif ch == "'":
            j, text = i + 1, []
            while j < len(pattern):
                if pattern[j] == "'":
                    if pattern[j + 1 : j + 2] == "'":
                        text.append("'")
                        j += 2
                        continue
                    break
                text.append(pattern[j])
                j += 1
            tokens.append(("text", "".join(text) if j > i + 1 else "'"))
            i = j + 1
        else:
            tokens.append(("text", ch))
            i += 1
    return tokens


def joda_field(call: Call, run: str) -> str:
    """The SQL of one pattern letter run (Joda's number fields zero-padded to the run's length, a
    two-letter year its last two digits; text fields in English)."""
    letter, count = run[0], len(run)
    if letter in "yYx" and count == 2:
        return f"lpad(CAST({_JODA_NUMBERS[letter]} % 100 AS VARCHAR), 2, '0')"
    if letter == "M" and count >= 3:
        return f"strftime(\"_t\", '{'%B' if count >= 4 else '%b'}')"
    if letter == "E":
        return f"strftime(\"_t\", '{'%A' if count >= 4 else '%a'}')"
    if letter == "a":
        return "strftime(\"_t\", '%p')"
    if letter == "G":
        return "'AD'"
    if letter == "S":
        digits = "strftime(\"_t\", '%f')"
        return f"left({digits}, {count})" if count <= 6 else f"rpad({digits}, {count}, '0')"
    if letter in _JODA_NUMBERS:
        number = f"CAST({_JODA_NUMBERS[letter]} AS VARCHAR)"
        return f"lpad({number}, CAST(greatest(length({number}), {count}) AS INTEGER), '0')"  # lpad also cuts
    if letter in "zZ":
        call.fail(f"format_datetime with the time zone field '{run}' is not supported in lakegate", "NOT_SUPPORTED")
    call.fail(f"Illegal pattern component: {run}", "INVALID_FUNCTION_ARGUMENT")


def _format_datetime(call: Call) -> TType:
    value, _ = need(call, "temporal", "string")
    if value.base == "date":
        call.mismatch()
    pattern = literal_str(call, 1)
    if pattern is None:
        call.fail("format_datetime with a non-literal format is not supported in lakegate", "NOT_SUPPORTED")
    pieces = [tf.string(text) if kind == "text" else joda_field(call, text) for kind, text in _joda_tokens(pattern)]
    call.node.meta["joda"] = " || ".join(pieces) or "''"
    return tt.VARCHAR


def render_format_datetime(g, node, args) -> str:
    value = g.sql(args[0])
    if ttype(args[0]).base == "timestamp_tz":
        value = f"timezone('UTC', {value})"
    return f'list_transform([CAST({value} AS TIMESTAMP)], lambda "_t": {node.meta["joda"]})[1]'


# --- parse_datetime (DateTimeFunctions.parseDatetime: Joda-Time DateTimeFormat.forPattern(format)
# .parseDateTime in the session zone, UTC) ---------------------------------------------------------
#: Pattern letter -> (field, the most digits Joda's DateTimeFormat.parsePatternTo lets it read),
#: for the number fields lakegate parses (yyyy appendYear(n, 9) is signed; the others unsigned).
_JODA_PARSED = {
    "y": ("year", 9),
    "M": ("month", 2),
    "d": ("day", 2),
    "H": ("hour", 2),
    "m": ("minute", 2),
    "s": ("second", 2),
    "S": ("fraction", 9),
}

_JODA_LETTERS = "GCYxweEyDMdaKhHkmsSzZ"


def _joda_parser(call: Call, pattern: str) -> tuple[str, list[str]] | str:
    """The full-match regex and its groups' fields for `pattern`, or Joda's error message for an
    invalid one. Joda reads a number greedily and never backtracks, so a number field next to
    another or to literal digits is refused (a regex could split the digits otherwise)."""
    if not pattern:
        return "Invalid pattern specification"
    regex, fields, previous = [], [], None
    for kind, text in _joda_tokens(pattern):
        if kind == "text":
            if previous == "letter" and text[:1].isdigit():
                call.fail(
                    "parse_datetime with digits right after a number field is not supported in lakegate",
                    "NOT_SUPPORTED",
                )
            literal = re.escape(text)
            regex.append(f"(?i:{literal})" if any(c.isalpha() for c in text) else literal)
        elif text[0] not in _JODA_LETTERS:
            return f"Illegal pattern component: {text}"
        elif text[0] not in _JODA_PARSED or (text[0] == "y" and len(text) == 2) or (text[0] == "M" and len(text) > 2):
            call.fail(f"parse_datetime with the pattern field '{text}' is not supported in lakegate", "NOT_SUPPORTED")
        elif previous == "letter":
            call.fail("parse_datetime with adjacent number fields is not supported in lakegate", "NOT_SUPPORTED")
        else:
            field, digits = _JODA_PARSED[text[0]]
            regex.append(f"({'[-+]?' if field == 'year' else ''}[0-9]{{1,{max(digits, len(text))}}})")
            fields.append(field)
        previous = kind
    return "".join(regex), fields


def _parse_datetime(call: Call) -> TType:
    need(call, "string", "string")
    pattern = literal_str(call, 1)
    if pattern is None and not call.types[1].is_unknown:
        call.fail("parse_datetime with a non-literal format is not supported in lakegate", "NOT_SUPPORTED")
    call.node.meta["joda_parser"] = None if pattern is None else _joda_parser(call, pattern)
    return tt.timestamp(3, True, call.analyzer.time_zone)  # Joda's chronology of the session zone


def _render_parse_datetime(g, node, args) -> str:
    """Joda's parseDateTime in the session zone: the whole text must match (literals ignore case);
    fields missing from the pattern are 1970-01-01 00:00:00.000; a fraction is cut to milliseconds;
    then each field must be in range, and the wall time must exist in the zone (Joda fails in a
    daylight-saving gap). Years outside 1..9999 are refused."""
    text, parser = g.sql(args[0]), node.meta["joda_parser"]
    if parser is None:
        return "CAST(NULL AS TIMESTAMPTZ)"
    if isinstance(parser, str):
        return f"CASE WHEN ({text}) IS NULL THEN NULL ELSE {g.fail(tf.string(parser))} END"
    regex, fields = tf.string(parser[0]), parser[1]

    def field(name: str, default: str) -> str:
        if name not in fields:
            return default
        return f"TRY_CAST(regexp_extract({text}, {regex}, {fields.index(name) + 1}) AS INTEGER)"

    year, month, day = field("year", "1970"), field("month", "1"), field("day", "1")
    hour, minute, second = field("hour", "0"), field("minute", "0"), field("second", "0")
    fraction = f"regexp_extract({text}, {regex}, {fields.index('fraction') + 1})" if "fraction" in fields else "''"
    millis = f"CAST(rpad(left({fraction}, 3), 3, '0') AS INTEGER)"
    year_ok = f"{year} BETWEEN 1 AND 9999"
    days = (
        f"day(last_day(make_date(CASE WHEN {year_ok} THEN {year} ELSE 2000 END, least(greatest({month}, 1), 12), 1)))"
    )
    in_range = (
        f"{month} BETWEEN 1 AND 12 AND {day} BETWEEN 1 AND {days} "
        f"AND {hour} BETWEEN 0 AND 23 AND {minute} BETWEEN 0 AND 59 AND {second} BETWEEN 0 AND 59"
    )
    # DuckDB folds constant arguments even in a CASE branch not taken: out-of-range fields become 1
    year, month, day = (f"CASE WHEN {year_ok} AND {in_range} THEN {f} ELSE 1 END" for f in (year, month, day))
    stamp = f"make_timestamp({year}, {month}, {day}, {hour}, {minute}, {second}) + to_milliseconds({millis})"
    zone = tt.zone_of(ttype(node))
    instant = zones.instant(stamp, zone)
    quoted = f"'\"' || {text} || '\"'"
    malformed, out_of_range = g.fail(f"'Invalid format: ' || {quoted}"), g.fail(f"'Cannot parse ' || {quoted}")
    refused = g.fail(
        tf.string("parse_datetime of a year outside 1..9999 is not supported in lakegate"), "NOT_SUPPORTED"
    )
    return (
        f"CASE WHEN ({text}) IS NULL THEN NULL WHEN NOT regexp_full_match({text}, {regex}) THEN {malformed} "
        f"WHEN NOT ({year_ok}) THEN {refused} WHEN NOT ({in_range}) THEN {out_of_range} "
        f"WHEN {zones.local(instant, zone)} <> {stamp} THEN {out_of_range} ELSE {instant} END"
    )


def install() -> None:
    """Register the functions of this page (called by pages.py)."""
    register(
        "date_format",
        "datetime",
        "date_format(timestamp, format) -> varchar",
        _date_format,
        _render_date_format,
        notes="MySQL-style specifiers with an exact strftime equivalent; others are rejected.",
    )
    register("date_parse", "datetime", "date_parse(string, format) -> timestamp(3)", _date_parse, _render_date_parse)

    register(
        "format_datetime",
        "datetime",
        "format_datetime(timestamp, format) -> varchar",
        _format_datetime,
        render_format_datetime,
        notes="A literal Joda-Time pattern; the time zone fields z and Z are refused.",
    )

    register(
        "parse_datetime",
        "datetime",
        "parse_datetime(string, format) -> timestamp(3) with time zone",
        _parse_datetime,
        _render_parse_datetime,
        notes=(
            "A literal Joda-Time pattern of the number fields yyyy M d H m s S and literals; other fields are refused."
        ),
    )
