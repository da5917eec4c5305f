"""Trino's functions/conversion.md. Conversion functions: format, format_number, parse_data_size, typeof."""

from __future__ import annotations

import re

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import write_casts as casts
from lakegate.dialect.functions.arguments import fixed, literal_str
from lakegate.dialect.functions.rendering import MAX_PAD_LENGTH
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


# === conversion ===================================================================================
def _format(call: Call) -> TType:
    if not call.args or call.types[0] is None or call.types[0].base not in ("varchar",):
        call.mismatch()
    if literal_str(call, 0) is None:
        call.fail("format() needs a literal format string in lakegate", "NOT_SUPPORTED")
    if None in call.types:
        call.mismatch()
    try:
        _format_parts(call, literal_str(call, 0), call.types[1:])
    except InvalidFormat as error:  # Trino fails when it formats a row, not over no rows
        call.node.meta["format_error"] = str(error)
    return tt.VARCHAR


class InvalidFormat(ValueError):
    """A format string java.util.Formatter refuses: Trino's INVALID_FUNCTION_ARGUMENT, raised at run time."""


_SPEC = re.compile(r"%(?:(\d+)\$)?([-#+ 0,(<]*)?(\d+)?(?:\.(\d+))?([tT][a-zA-Z]|[a-zA-Z%])")


def _format_parts(call: Call | None, fmt: str, types: list[TType]) -> list:
    """Split a Java format string into literal text and (arg index, flags, width, precision,
    conversion) items, checking each against its argument's type."""
    parts: list = []
    position = 0
    next_arg = 0
    for match in _SPEC.finditer(fmt):
        if match.start() > position:
            parts.append(fmt[position : match.start()])
        position = match.end()
        index, flags, width, precision, conversion = match.groups()
        flags = flags or ""
        column = match.start() + 1
        if conversion == "%":
            parts.append("%")
            continue
        if conversion == "n":
            parts.append("\n")
            continue

        def reject(why: str, match=match, column=column):
            if call is not None:
                call.fail(
                    f"unsupported in lakegate: format specifier '{match.group(0)}' at position {column} "
                    f"of the format string: {why}",
                    "NOT_SUPPORTED",
                )
            raise ValueError(why)

        if "-" in flags and "0" in flags:  # java.util.Formatter: IllegalFormatFlagsException
            raise InvalidFormat(f"Invalid format string: {fmt} (IllegalFormatFlags: Flags = '{flags}')")
        if conversion not in "sdfxXe":
            reject("only %s, %d, %f, %e, %x, %% and %n are translated")
        if set(flags) - set("-0,") or ("0" in flags and conversion == "s") or ("," in flags and conversion not in "df"):
            reject("only the '-', '0' and ',' (with %d / %f) flags are translated")
        if precision is not None and conversion not in "fe":
            reject("a precision is only translated for %f and %e")
        if "-" in flags and width is None:
            reject("'-' needs a width")
        if max(int(width or 0), int(precision or 0)) > MAX_PAD_LENGTH:
            reject(f"a width or precision over {MAX_PAD_LENGTH} is not translated")
        arg = int(index) - 1 if index else next_arg
        if not index:
            next_arg += 1
        if arg >= len(types):
            raise InvalidFormat(
                f"Invalid format string: {fmt} (MissingFormatArgument: Format specifier '{match.group(0)}')"
            )
        t = types[arg]
        if conversion in "dxX" and not (t.is_integral or t.is_unknown):
            reject(f"%{conversion} needs an integer argument, got {t}")
        if conversion == "f" and not (t.is_decimal or t.is_approx or t.is_unknown):
            reject(f"%f needs a decimal or floating point argument, got {t}")
        if conversion == "e" and not (t.is_approx or t.is_unknown):
            reject(f"%e is translated for double and real arguments, got {t}")
        if conversion == "e" and (flags or width):
            reject("flags and widths are not translated for %e")
        if conversion == "s" and not (
            t.base in ("varchar", "boolean", "unknown") or t.is_integral or t.is_approx or t.base == "date"
        ):
            reject(f"%s of {t} is not translated")
        parts.append((arg, flags, int(width) if width else None, int(precision) if precision else None, conversion))
    if position < len(fmt):
        tail = fmt[position:]
        if "%" in tail:
            raise InvalidFormat(f"Invalid format string: {fmt} (UnknownFormatConversion: Conversion = '%')")
        parts.append(tail)
    return parts


def _render_format(g, node, args) -> str:
    if node.meta.get("format_error"):
        return g.fail(tf.string(node.meta["format_error"]))
    fmt = args[0].name
    values = args[1:]
    pieces = []
    for part in _format_parts(None, fmt, [ttype(a) for a in values]):
        if isinstance(part, str):
            pieces.append(tf.string(part))
            continue
        arg, flags, width, precision, conversion = part
        value = values[arg]
        t = ttype(value)
        sql = g.sql(value)
        if conversion == "s":
            text = java_string(sql, t)
        elif conversion == "d":
            text = f"CAST(CAST({sql} AS BIGINT) AS VARCHAR)"
        elif conversion in "xX":
            text = f"printf('%{conversion}', CAST({sql} AS BIGINT))"
        elif conversion == "e":
            text = java_scientific(sql, 6 if precision is None else precision)
        else:
            text = java_fixed(sql, t, 6 if precision is None else precision)
        if "," in flags:
            text = group_thousands(text)
        if width:
            if "-" in flags:
                text = f"rpad({text}, CAST(greatest({width}, length({text})) AS INTEGER), ' ')"
            elif "0" in flags:
                text = (
                    f"CASE WHEN starts_with({text}, '-') THEN '-' || lpad(substr({text}, 2), "
                    f"CAST(greatest({width} - 1, length({text}) - 1) AS INTEGER), '0') ELSE "
                    f"lpad({text}, CAST(greatest({width}, length({text})) AS INTEGER), '0') END"
                )
            else:
                text = f"lpad({text}, CAST(greatest({width}, length({text})) AS INTEGER), ' ')"
        pieces.append(f"coalesce({text}, 'null')")
    return "(" + " || ".join(pieces) + ")" if pieces else "''"


def group_thousands(text: str) -> str:
    """Digits of the integer part of a number text grouped by commas (Java's ',' flag, en-US)."""
    sign = f"CASE WHEN starts_with({text}, '-') THEN '-' ELSE '' END"
    number = f"ltrim({text}, '-')"
    whole = f"split_part({number}, '.', 1)"
    fraction = f"CASE WHEN contains({number}, '.') THEN '.' || split_part({number}, '.', 2) ELSE '' END"
    reversed_whole = f"reverse({whole})"
    chunks = (
        f'array_to_string(list_transform(range(0, length({whole}), 3), lambda "_i": '
        f"substr({reversed_whole}, CAST(\"_i\" + 1 AS BIGINT), 3)), ',')"
    )
    return f"CASE WHEN {text} IS NULL THEN NULL ELSE {sign} || reverse({chunks}) || {fraction} END"


def java_string(sql: str, t: TType) -> str:
    """String.valueOf of the Java value Trino's format() passes for a SQL value."""
    if t.base == "double":
        return java_double(sql)
    if t.base == "real":
        return java_double(sql, "FLOAT")
    return f"CAST({sql} AS VARCHAR)"


def java_double(sql: str, duck: str = "DOUBLE") -> str:
    """Java's Double.toString (Float.toString for a FLOAT): plain digits with at least one decimal for
    1e-3 <= |x| < 1e7, else computerized scientific notation (1.0E10), from the shortest round-trip
    digits (a double's one digit becomes the two nearest: 4.9E-324)."""
    value = f"CAST({sql} AS {duck})"
    if duck == "DOUBLE":
        digits, exponent = casts.java_digits(value)
    else:
        text = f"CAST(abs({value}) AS VARCHAR)"
        digits = f"regexp_replace(replace(split_part({text}, 'e', 1), '.', ''), '^0+|0+$', '', 'g')"
        exponent = f"CAST(split_part(format('{{:.16e}}', CAST(abs({value}) AS DOUBLE)), 'e', 2) AS INTEGER)"
    scientific = (
        f"left({digits}, 1) || '.' || coalesce(nullif(substr({digits}, 2), ''), '0') || 'E' || "
        f"CAST({exponent} AS VARCHAR)"
    )
    plain_big = (
        f"rpad({digits}, CAST(greatest({exponent} + 1, length({digits})) AS INTEGER), '0')[1:{exponent} + 1] || '.' || "
        f"coalesce(nullif(substr({digits}, {exponent} + 2), ''), '0')"
    )
    plain_small = f"'0.' || repeat('0', -{exponent} - 1) || {digits}"
    return (
        f"CASE WHEN isnan({value}) THEN 'NaN' WHEN isinf({value}) THEN CASE WHEN {value} > 0 THEN 'Infinity' "
        f"ELSE '-Infinity' END WHEN {value} = 0 THEN CASE WHEN starts_with(CAST({value} AS VARCHAR), '-') "
        f"THEN '-0.0' ELSE '0.0' END ELSE CASE WHEN {value} < 0 THEN '-' ELSE '' END || CASE "
        f"WHEN abs({value}) >= 1e-3 AND abs({value}) < 1e7 THEN CASE WHEN {exponent} >= 0 THEN {plain_big} "
        f"ELSE {plain_small} END ELSE {scientific} END END"
    )


def _shortest_digits(value: str) -> tuple[str, str]:
    """SQL for the shortest round-trip digits (no leading or trailing zeros) of a non-zero double
    and its decimal exponent."""
    text = f"CAST(abs({value}) AS VARCHAR)"
    digits = f"regexp_replace(replace(split_part({text}, 'e', 1), '.', ''), '^0+|0+$', '', 'g')"
    exponent = f"CAST(split_part(format('{{:.16e}}', abs({value})), 'e', 2) AS INTEGER)"
    return digits, exponent


def java_scientific(sql: str, precision: int) -> str:
    """Java's %.Ne: the shortest digits rounded HALF_UP to N decimals, exponent with a sign and at
    least two digits (1.234568e+04)."""
    value = f"CAST({sql} AS DOUBLE)"
    digits, exponent = _shortest_digits(value)
    mantissa = f"CAST(left({digits}, 1) || '.' || coalesce(nullif(substr({digits}, 2), ''), '0') AS DECIMAL(38,30))"
    rounded = f"CAST({mantissa} AS DECIMAL({precision + 2},{precision}))"
    carry = f"CASE WHEN {rounded} >= 10 THEN 1 ELSE 0 END"
    shown = (
        f"CASE WHEN {rounded} >= 10 THEN CAST(CAST(1 AS DECIMAL({precision + 2},{precision})) AS VARCHAR) "
        f"ELSE CAST({rounded} AS VARCHAR) END"
    )
    if precision == 0:
        shown = f"split_part({shown}, '.', 1)"
    power = f"{exponent} + {carry}"
    suffix = f"'e' || CASE WHEN {power} < 0 THEN '-' ELSE '+' END || lpad(CAST(abs({power}) AS VARCHAR), 2, '0')"
    zero = "0" + ("." + "0" * precision if precision else "") + "e+00"
    return (
        f"CASE WHEN isnan({value}) THEN 'NaN' WHEN isinf({value}) THEN CASE WHEN {value} > 0 THEN 'Infinity' "
        f"ELSE '-Infinity' END WHEN {value} = 0 THEN CASE WHEN starts_with(CAST({value} AS VARCHAR), '-') "
        f"THEN '-{zero}' ELSE '{zero}' END ELSE CASE WHEN {value} < 0 THEN '-' ELSE '' END || {shown} || "
        f"{suffix} END"
    )


def java_fixed(sql: str, t: TType, precision: int) -> str:
    """Java's %.Nf: HALF_UP rounding of the decimal value (of the shortest digits for doubles)."""
    if precision > 30:
        raise ValueError("precision too large")
    if t.is_decimal:
        digits = t.args[0] - t.args[1] + precision
        value = f"CAST({sql} AS DECIMAL({min(38, max(digits, precision + 1))},{precision}))"
        return f"CAST({value} AS VARCHAR)" if precision else f"CAST(CAST({sql} AS DECIMAL(38,0)) AS VARCHAR)"
    value = f"CAST({sql} AS DOUBLE)"
    rounded = f"CAST(CAST(CAST({value} AS VARCHAR) AS DECIMAL(38,{precision})) AS VARCHAR)"
    rounded = f"regexp_replace({rounded}, '^(-?)[.]', '\\10.')"
    return (
        f"CASE WHEN isnan({value}) THEN 'NaN' WHEN isinf({value}) THEN CASE WHEN {value} > 0 THEN 'Infinity' "
        f"ELSE '-Infinity' END ELSE {rounded} END"
    )


#: DataSizeFunctions.Unit: the factor of each unit (powers of 1024).
_DATA_UNITS = {"B": 0, "kB": 10, "MB": 20, "GB": 30, "TB": 40, "PB": 50, "EB": 60, "ZB": 70, "YB": 80}


def _render_parse_data_size(g, node, args) -> str:
    """DataSizeFunctions: a decimal number (digits and one '.') then a unit, no spaces; the bytes
    are the exact product truncated to an integer, at most 38 digits."""
    text = g.sql(args[0])
    pattern = f"([0-9]+[.]?[0-9]*|[.][0-9]+)({'|'.join(_DATA_UNITS)})"
    number = f"regexp_extract({text}, '^[0-9.]*')"
    unit = f"substr({text}, length({number}) + 1)"
    factor = "CASE " + " ".join(f"WHEN {unit} = '{u}' THEN {2**p}" for u, p in _DATA_UNITS.items()) + " END"
    whole = f"CAST(coalesce(nullif(split_part({number}, '.', 1), ''), '0') AS HUGEINT)"
    fraction = f"split_part({number}, '.', 2)"
    fraction_bytes = (
        f"CASE WHEN {fraction} = '' THEN 0 ELSE "
        f"CAST({fraction} AS HUGEINT) * {factor} // CAST('1' || repeat('0', length({fraction})) AS HUGEINT) END"
    )
    invalid = g.fail(f"'Invalid data size: ''' || {text} || ''''")
    too_long = g.fail(
        tf.string("a data size with more than 20 fraction digits is not supported in lakegate"), "NOT_SUPPORTED"
    )
    return (
        f"CASE WHEN {text} IS NULL THEN NULL WHEN NOT regexp_full_match({text}, {tf.string(pattern)}) THEN {invalid} "
        f"WHEN length({fraction}) > 20 THEN {too_long} "
        f"ELSE CAST({whole} * {factor} + {fraction_bytes} AS DECIMAL(38,0)) END"
    )


# --- format_number (io.trino.operator.scalar.FormatNumberFunction) --------------------------------
def _java_long(sql: str) -> str:
    """Java's (long) of a double: NaN is 0, out-of-range values saturate, the rest truncate."""
    return (
        f"CASE WHEN isnan({sql}) THEN 0 WHEN {sql} >= 9.223372036854775807e18 THEN 9223372036854775807 "
        f"WHEN {sql} <= -9.223372036854775808e18 THEN -9223372036854775808 ELSE CAST(trunc({sql}) AS BIGINT) END"
    )


def _half_up_text(value: str, digits: int) -> str:
    """DecimalFormat("#.##"-like, `digits` fraction digits, HALF_UP) of the double `value` (1 <= |value|,
    or 0), rounded on its exact binary value: |value| = M * 2^-s with M < 2^53, so M * 10^digits
    shifted right by s, plus one when the bits shifted out are at least half."""
    a = f"abs({value})"
    e = f"CAST(floor(log2({a})) AS INTEGER)"
    e = (
        f"({e} - CASE WHEN pow(2.0, {e}) > {a} THEN 1 ELSE 0 END "
        f"+ CASE WHEN pow(2.0, {e} + 1) <= {a} THEN 1 ELSE 0 END)"
    )
    shift = f"(52 - {e})"
    scaled = f"(CAST({a} * pow(2.0, {shift}) AS HUGEINT) * {10**digits})"
    kept = f"({scaled} >> {shift})"
    rounded = (
        f"({kept} + CASE WHEN 2 * ({scaled} - ({kept} << {shift})) >= (CAST(1 AS HUGEINT) << {shift}) "
        "THEN 1 ELSE 0 END)"
    )
    if digits == 0:
        text = f"CAST({rounded} AS VARCHAR)"
    else:
        fraction = f"rtrim(lpad(CAST({rounded} % {10**digits} AS VARCHAR), {digits}, '0'), '0')"
        whole = f"CAST({rounded} // {10**digits} AS VARCHAR)"
        text = f"{whole} || CASE WHEN {fraction} = '' THEN '' ELSE '.' || {fraction} END"
    return f"CASE WHEN {a} = 0 THEN '0' ELSE CASE WHEN {value} < 0 THEN '-' ELSE '' END || {text} END"


def _render_format_number(g, node, args) -> str:
    """FormatNumberFunction.format: divide by 1000 (a double division each time) while |x| >= 1000,
    at most five times (K M B T Q); then "#.##" below 10 (negative values included), "#.#" below
    100, "#" otherwise, HALF_UP."""
    x = g.sql(args[0])
    count = _java_long(f"CAST({x} AS DOUBLE)") if ttype(args[0]).is_approx else f"CAST({x} AS BIGINT)"
    step = 'lambda "_v", "_i": CASE WHEN abs("_v"[1]) >= 1000 THEN ["_v"[1] / 1000, "_v"[2] + 1] ELSE "_v" END'
    scaled = f"list_reduce(range(5), {step}, [CAST({count} AS DOUBLE), 0.0])"
    f, units = f"{scaled}[1]", f"CAST({scaled}[2] AS INTEGER)"
    text = (
        f"CASE WHEN {f} < 10 THEN {_half_up_text(f, 2)} WHEN {f} < 100 THEN {_half_up_text(f, 1)} "
        f"ELSE {_half_up_text(f, 0)} END"
    )
    unit = f"['', 'K', 'M', 'B', 'T', 'Q'][{units} + 1]"
    return f"CASE WHEN ({x}) IS NULL THEN NULL ELSE {text} || {unit} END"


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "format",
        "conversion",
        "format(format, args...) -> varchar",
        _format,
        _render_format,
        notes="Java format specifiers %s, %d, %f / %.Nf and %e (HALF_UP), %x, %%, %n with '-' / '0' flags and widths; "
        "other specifiers are rejected with their position.",
    )
    register(
        "parse_data_size",
        "conversion",
        "parse_data_size(string) -> decimal(38,0)",
        fixed(tt.decimal(38, 0), "string"),
        _render_parse_data_size,
    )

    register(
        "format_number",
        "conversion",
        "format_number(number) -> varchar",
        fixed(tt.VARCHAR, "number"),
        _render_format_number,
    )
