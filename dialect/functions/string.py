"""Trino's functions/string.md. String functions and operators, with their char(n) and varbinary overloads.

A char(n) value is its text padded to n characters (dialect/chars.py); Trino keeps it without
trailing spaces, so each char(n) overload is written from the Trino function applied to that
trimmed value (StringFunctions.java, checked by TestStringFunctions).
"""

from __future__ import annotations

from collections.abc import Callable

from sqlglot import exp

from lakegate.dialect import chars
from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions import letter_case
from lakegate.dialect.functions.arguments import (
    KINDS_BINARY,
    VARBINARY,
    binary_args,
    binary_in,
    fixed,
    literal_str,
    need,
)
from lakegate.dialect.functions.rendering import MAX_PAD_LENGTH, call_as, checked, null_if_any_null, sqls, utf8_valid
from lakegate.dialect.registry import SUPPORTED, Render, overload, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


# === string =======================================================================================
def _string_same(call: Call) -> TType:
    (t,) = need(call, "string")
    return _varchar_result(t)


def _varchar_result(t: TType) -> TType:
    """The varchar(x) a `varchar(x) -> varchar(x)` function returns: a NULL literal binds x = 0."""
    if t.is_unknown:
        return tt.varchar(0)
    return t if t.base == "varchar" else tt.VARCHAR


def _concat(call: Call) -> TType:
    if not call.args or None in call.types:
        call.mismatch()
    if len(call.types) == 2 and any(t.is_unknown for t in call.types):
        t = tt.concat_with_null(call.types)
        if t is None:
            call.fail(tt.AMBIGUOUS, "AMBIGUOUS_FUNCTION_CALL")
        call.node.meta["array"] = True
        return t
    if any(t.base == "array" for t in call.types):
        element = None
        for t in call.types:
            inner = t.element if t.base == "array" else t
            element = inner if element is None else tt.common_super_type(element, inner)
            if element is None:
                call.mismatch()
        call.node.meta["array"] = True
        return tt.array(element)
    for t in call.types:
        if t.base not in ("varchar", "unknown"):
            call.mismatch()
    return tt.VARCHAR


def _render_concat(g, node, args) -> str:
    if not node.meta.get("array"):
        return "(" + " || ".join(g.sql(a) for a in args) + ")"
    t = ttype(node)
    if any(ttype(a).is_unknown for a in args):  # concat(x, NULL) as array(x): always NULL
        return f"CAST(NULL AS {tt.duckdb_type(t) or 'INTEGER[]'})"  # array(unknown): any list type
    pieces = []
    for a in args:
        pieces.append(g.coerce(a, t) if ttype(a).base == "array" else f"[{g.coerce(a, t.element)}]")
    # NULL when any argument, array or element, is NULL (io.trino.operator.scalar.ArrayConcatFunction,
    # ArrayToElementConcatFunction, ElementToArrayConcatFunction take no nullable arguments)
    return null_if_any_null(g, args, "flatten([" + ", ".join(pieces) + "])")


def _replace(call: Call) -> TType:
    types = need(call, "string", "string", "string", optional=1)
    length = tt.varchar_length(types[0]) if types[0].base == "varchar" else None
    if len(types) == 2 or length is None:
        return types[0] if len(types) == 2 and types[0].base == "varchar" else tt.VARCHAR
    to_length = tt.varchar_length(types[2]) if types[2].base == "varchar" else None
    if to_length is None:
        return tt.VARCHAR
    return tt.varchar(length + to_length * (length + 1))


def _render_replace(g, node, args) -> str:
    value, search = g.sql(args[0]), g.sql(args[1])
    target = g.sql(args[2]) if len(args) == 3 else "''"
    if isinstance(args[1], exp.Literal) and args[1].name:
        return f"replace({value}, {search}, {target})"
    empty = f"regexp_replace({value}, '', replace({target}, '\\', '\\\\'), 'g')"
    return f"CASE WHEN {search} = '' THEN {empty} ELSE replace({value}, {search}, {target}) END"


def _split(call: Call) -> TType:
    types = need(call, "string", "string", "integral", optional=1)
    return tt.array(types[0] if types[0].base == "varchar" else tt.VARCHAR)


def _render_split(g, node, args) -> str:
    value, delim = g.sql(args[0]), g.sql(args[1])
    sql = f"CASE WHEN ({delim}) IS NULL THEN NULL ELSE string_split({value}, {delim}) END"
    if len(args) == 3:
        limit = g.sql(args[2])
        sql = (  # NULL on NULL input, before any check (the real Trino 476 answers so)
            f"CASE WHEN ({value}) IS NULL OR ({delim}) IS NULL OR ({limit}) IS NULL THEN NULL "
            f"WHEN ({limit}) <= 0 THEN {g.fail(tf.string('Limit must be positive'))} "
            f"WHEN ({limit}) > 2147483647 THEN {g.fail(tf.string('Limit is too large'))} "
            f"WHEN len({sql}) <= ({limit}) THEN {sql} ELSE list_append({sql}[1:({limit}) - 1], "
            f'list_reduce({sql}[({limit}):], lambda "_a", "_b": "_a" || {delim} || "_b")) END'  # any delimiter
        )
    if isinstance(args[1], exp.Literal) and args[1].name:
        return sql
    return (
        f"CASE WHEN {delim} = '' THEN {g.fail(tf.string('The delimiter may not be the empty string'))} ELSE {sql} END"
    )


def _render_split_part(g, node, args) -> str:
    value, delim, index = sqls(g, args)
    parts = f"string_split({value}, {delim})"
    return (
        f"CASE WHEN ({index}) <= 0 THEN {g.fail(tf.string('Index must be greater than zero'))} "
        f"WHEN {delim} = '' THEN {g.fail(tf.string('The delimiter may not be the empty string'))} "
        f"WHEN len({parts}) < ({index}) THEN NULL ELSE {parts}[{index}] END"
    )


def _pad(call: Call) -> TType:
    need(call, "string", "integral", "string")
    return tt.VARCHAR


def pad_checks(value: str, size: str, pad: str, empty: str, message: str) -> list[tuple[str, str]]:
    """The argument checks of lpad / rpad, made only when no argument is NULL (the functions return
    NULL on NULL input before checking anything, as the real Trino 476 answers)."""
    given = f"({value}) IS NOT NULL AND ({size}) IS NOT NULL AND ({pad}) IS NOT NULL AND "
    return [
        (f"{given}(({size}) < 0 OR ({size}) > 2147483647)", "Target length must be in the range [0..2147483647]"),
        (
            f"{given}({size}) > {MAX_PAD_LENGTH}",
            f"Target length must be at most {MAX_PAD_LENGTH} in lakegate (Trino allows up to 2147483647)",
        ),
        (f"{given}{empty}", message),
    ]


def _render_pad(g, node, args) -> str:
    value, size, pad = sqls(g, args)
    width = checked(
        g, f"CAST({size} AS INTEGER)", pad_checks(value, size, pad, f"{pad} = ''", "Padding string must not be empty")
    )
    return f"{node.name.lower()}({value}, {width}, {pad})"


_PAD_NOTE = (
    f"size is at most {MAX_PAD_LENGTH:,} in lakegate (Trino: 2,147,483,647); "
    "DuckDB would build larger strings outside its memory limit."
)


def _strpos(call: Call) -> TType:
    if len(call.args) == 3:
        call.fail("strpos with an instance is not supported in lakegate", "NOT_SUPPORTED")
    need(call, "string", "string")
    return tt.BIGINT


def _substr(call: Call) -> TType:
    types = need(call, "string", "integral", "integral", optional=1)
    return types[0] if types[0].base == "varchar" else tt.VARCHAR


def _render_substr(g, node, args) -> str:
    sub = exp.Substring(this=args[0], start=args[1], length=args[2] if len(args) == 3 else None)
    sql = tf.substring_from(g, sub)
    if len(args) == 3 and not isinstance(args[2], exp.Literal):  # a NULL length is NULL (DuckDB: '')
        sql = f"CASE WHEN ({g.sql(args[2])}) IS NULL THEN NULL ELSE {sql} END"
    return sql


def _render_trim(name: str) -> Render:
    def render(g, node, args):
        chars = g.sql(args[1]) if len(args) == 2 else tf.string(tf.WHITESPACE)
        return f"{name}({g.sql(args[0])}, {chars})"

    return render


def _render_levenshtein(g, node, args) -> str:
    """Edits counted in characters (StringFunctions.levenshteinDistance); DuckDB's levenshtein counts
    bytes, so non-ASCII text runs a row-by-row dynamic programme over the characters."""
    a, b = sqls(g, args)
    by_chars = (
        f'list_reduce(string_split({a}, \'\'), lambda "_prev", "_ch": list_reduce(range(1, length({b}) + 1), '
        f'lambda "_cur", "_j": list_append("_cur", least("_prev"["_j" + 1] + 1, "_cur"["_j"] + 1, '
        f'"_prev"["_j"] + CASE WHEN "_ch" = substr({b}, "_j", 1) THEN 0 ELSE 1 END)), '
        f'["_prev"[1] + 1]), range(0, length({b}) + 1))[length({b}) + 1]'
    )
    return (
        f"CAST(CASE WHEN strlen({a}) = length({a}) AND strlen({b}) = length({b}) THEN levenshtein({a}, {b}) "
        f"ELSE {by_chars} END AS BIGINT)"
    )


def _render_hamming(g, node, args) -> str:
    """Positions counted in characters (StringFunctions.hammingDistance); DuckDB's hamming counts bytes."""
    a, b = sqls(g, args)
    same_length = "The input strings to hamming_distance function must have the same length"
    differing = f'list_filter(range(1, length({a}) + 1), lambda "_i": substr({a}, "_i", 1) <> substr({b}, "_i", 1))'
    return (  # NULL when either is NULL (the real Trino 476 answers so)
        f"CASE WHEN ({a}) IS NULL OR ({b}) IS NULL THEN NULL "
        f"WHEN length({a}) <> length({b}) THEN {g.fail(tf.string(same_length))} "
        f"ELSE CAST(len({differing}) AS BIGINT) END"
    )


def _render_substr_binary(g, node, args) -> str:
    """VarbinaryFunctions.substr: positions in bytes, 1-based, negative from the end; start 0, a
    length <= 0, a start past either end give no bytes. Works on the hex text, two digits a byte."""
    value, start = g.sql(args[0]), g.sql(args[1])
    size = f"octet_length({value})"
    hexed = f"hex({value})"
    first = f"(CASE WHEN {start} > 0 THEN {start} ELSE {start} + {size} + 1 END)"
    length = g.sql(args[2]) if len(args) == 3 else size
    return (
        f"CASE WHEN {value} IS NULL OR {start} IS NULL OR ({length}) IS NULL THEN NULL "
        f"WHEN {start} = 0 OR ({length}) <= 0 OR {start} > {size} OR {start} < -{size} THEN unhex('') "
        f"ELSE unhex(substr({hexed}, CAST(2 * {first} - 1 AS BIGINT), "
        f"CAST(2 * least({length}, {size}) AS BIGINT))) END"
    )


def _substr_binary(call: Call) -> TType | None:
    types = call.types
    if not (types and types[0] is not None and types[0].base == "varbinary"):
        return None
    if len(types) not in (2, 3) or not all(t is not None and (t.is_integral or t.is_unknown) for t in types[1:]):
        call.mismatch()
    return VARBINARY


def _concat_binary(call: Call) -> TType | None:
    if not any(t is not None and t.base == "varbinary" for t in call.types):
        return None
    if len(call.args) < 2:
        call.fail("There must be two or more concatenation arguments", "INVALID_FUNCTION_ARGUMENT")
    if len(call.args) == 2 and any(t is not None and t.is_unknown for t in call.types):
        call.fail(tt.AMBIGUOUS, "AMBIGUOUS_FUNCTION_CALL")  # the element-to-array concat fits as well
    if not all(t is not None and t.base in KINDS_BINARY for t in call.types):
        call.mismatch()
    return VARBINARY


def _render_from_utf8(g, node, args) -> str:
    value = g.sql(args[0])
    message = tf.string(
        "from_utf8 of bytes that are not UTF-8 is not supported in lakegate (Trino would replace them with U+FFFD)"
    )
    return (
        f"CASE WHEN {value} IS NULL THEN NULL WHEN NOT {utf8_valid(f'hex({value})')} THEN "
        f"{g.fail(message, 'NOT_SUPPORTED')} ELSE decode({value}) END"
    )


def _pad_binary(call: Call) -> TType | None:
    types = call.types
    if not (types and types[0] is not None and types[0].base == "varbinary"):
        return None
    if len(types) != 3 or not (types[1] is not None and (types[1].is_integral or types[1].is_unknown)):
        call.mismatch()
    if types[2] is None or types[2].base not in KINDS_BINARY:
        call.mismatch()
    return VARBINARY


def _render_pad_binary(g, node, args) -> str:
    """VarbinaryFunctions.leftPad / rightPad: `size` bytes, the padding repeated from its start, the
    value cut to `size` bytes when longer (on the hex text, two digits a byte)."""
    value, size, pad = sqls(g, args)
    checks = pad_checks(value, size, pad, f"octet_length({pad}) = 0", "Padding bytes must not be empty")
    width = checked(g, f"CAST(2 * ({size}) AS INTEGER)", checks)
    return f"unhex({node.name.lower()}(hex({value}), {width}, hex({pad})))"


# === string (io.trino.operator.scalar.StringFunctions, LuhnCheckFunction) =======================
def _trim_chars(call: Call) -> TType | None:
    """trim(string, characters): the two-argument form (StringFunctions.trim / leftTrim / rightTrim
    with a code point set)."""
    if len(call.args) != 2:
        return None
    source, _ = need(call, "string", "string")
    return _varchar_result(source)


def _strpos_instance(call: Call) -> TType | None:
    if len(call.args) != 3:
        return None
    need(call, "string", "string", "integral")
    return tt.BIGINT


def _render_strpos_instance(g, node, args) -> str:
    """StringFunctions.stringPosition: the position of the n-th (overlapping) match, counted from the
    end when n is negative; 0 when there is none, 1 for an empty substring, n = 0 fails."""
    text, sub, instance = sqls(g, args)
    starts = (
        f'list_filter(range(1, length({text}) - length({sub}) + 2), lambda "_i": '
        f'substr({text}, "_i", length({sub})) = {sub})'
    )
    message = tf.string("'instance' must be a positive or negative number.")
    return (
        f"CASE WHEN {text} IS NULL OR {sub} IS NULL OR {instance} IS NULL THEN NULL "
        f"WHEN {instance} = 0 THEN {g.fail(message)} WHEN length({sub}) = 0 THEN CAST(1 AS BIGINT) "
        f"ELSE CAST(coalesce(CASE WHEN {instance} > 0 THEN {starts}[{instance}] "
        f"ELSE {starts}[len({starts}) + {instance} + 1] END, 0) AS BIGINT) END"
    )


def _render_luhn_check(g, node, args) -> str:
    """LuhnCheckFunction: false for '', a non-digit fails; every second digit from the right doubled
    (minus 9 past 9), the sum divisible by 10."""
    text = g.sql(args[0])
    digit = f'CAST(substr(reverse({text}), "_i", 1) AS INTEGER)'
    term = (
        f'CASE WHEN "_i" % 2 = 0 THEN CASE WHEN {digit} * 2 > 9 THEN {digit} * 2 - 9 ELSE {digit} * 2 END '
        f"ELSE {digit} END"
    )
    total = f'list_sum(list_transform(range(1, length({text}) + 1), lambda "_i": {term}))'
    return (
        f"CASE WHEN {text} IS NULL THEN NULL WHEN {text} = '' THEN false "
        f"WHEN NOT regexp_full_match({text}, '[0-9]*') THEN {g.fail(tf.string('Input contains non-digit character'))} "
        f"ELSE {total} % 10 = 0 END"
    )


def _char2hexint(g, node, args) -> str:
    """Teradata char2hexint: the UTF-16BE code units of the string in upper-case hex (one code unit
    for characters of the Basic Multilingual Plane; others are refused)."""
    text = g.sql(args[0])
    units = (
        f"list_transform(string_split({text}, ''), lambda \"_c\": lpad(upper(to_base(unicode(\"_c\"), 16)), 4, '0'))"
    )
    beyond = f'len(list_filter(string_split({text}, \'\'), lambda "_c": unicode("_c") > 65535)) > 0'
    message = tf.string("char2hexint of characters beyond U+FFFF is not supported in lakegate")
    return f"CASE WHEN {beyond} THEN {g.fail(message, 'NOT_SUPPORTED')} ELSE array_to_string({units}, '') END"


# --- normalize(string, form) (StringFunctions.normalize; AstBuilder.visitNormalize passes the form
# keyword NFC | NFD | NFKC | NFKD as the string it is written as) ----------------------------------
_NORMAL_FORMS = ("NFD", "NFC", "NFKD", "NFKC")


def _normalize_form(call: Call) -> TType | None:
    if len(call.args) != 2:
        return None
    need(call, "string", "string")
    form = literal_str(call, 1)  # the parser passes only the keyword NFC, NFD, NFKC or NFKD, as written
    if form in _NORMAL_FORMS and form != "NFC":
        call.fail(f"normalize with the form {form} is not supported in lakegate (only NFC)", "NOT_SUPPORTED")
    call.node.meta["normal_form"] = form
    return tt.VARCHAR


def _render_normalize_form(g, node, args) -> str:
    """NFC is DuckDB's nfc_normalize; a keyword in lower case is Normalizer.Form.valueOf's error at
    run time (a NULL argument gives NULL first)."""
    value, form = g.sql(args[0]), node.meta["normal_form"]
    if form == "NFC":
        return f"nfc_normalize({value})"
    message = tf.string("Normalization form must be one of [NFD, NFC, NFKD, NFKC]")
    return f"CASE WHEN ({value}) IS NULL THEN NULL ELSE {g.fail(message)} END"


# --- soundex (io.trino.util.Soundex, commons-codec's Soundex.US_ENGLISH) -------------------------
_SOUNDEX_CODES = ("ABCDEFGHIJKLMNOPQRSTUVWXYZ", "01230120022455012623010202")


def _render_soundex(g, node, args) -> str:
    """Soundex.soundex over ASCII text: the letters upper-cased, the first kept; H and W after it
    ignored completely; then each code that is not 0 (a vowel, which separates) and differs from the
    one before, up to three, padded with 0; '' without letters. Non-ASCII text (Unicode letters and
    upper-casing, or the error of an unmapped letter) is refused."""
    value = g.sql(args[0])
    letters = f"upper(regexp_replace({value}, '[^A-Za-z]', '', 'g'))"
    kept = f"left({letters}, 1) || regexp_replace(substr({letters}, 2), '[HW]', '', 'g')"
    code = 'substr("_c", "_i", 1)'
    picked = (
        f'list_filter(range(2, length("_c") + 1), lambda "_i": {code} <> \'0\' AND {code} <> substr("_c", "_i" - 1, 1))'
    )
    digits = f"array_to_string(list_transform({picked}, lambda \"_i\": {code}), '')"
    codes = f'translate("_s", {tf.string(_SOUNDEX_CODES[0])}, {tf.string(_SOUNDEX_CODES[1])})'
    encoded = f'list_transform([{codes}], lambda "_c": left("_s", 1) || rpad(left({digits}, 3), 3, \'0\'))[1]'
    non_ascii = g.fail(tf.string("soundex of non-ASCII text is not supported in lakegate"), "NOT_SUPPORTED")
    return (
        f"CASE WHEN ({value}) IS NULL THEN NULL WHEN regexp_matches({value}, '[^\\x00-\\x7F]') THEN {non_ascii} "
        f"WHEN {letters} = '' THEN '' ELSE list_transform([{kept}], lambda \"_s\": {encoded})[1] END"
    )


_TEXT = ("char", "varchar", "unknown")


def _char_call(result: Callable[[TType], TType], *rest: tuple[str, ...], optional: int = 0):
    """Accept calls whose first argument is char(x) and whose other arguments have the given bases;
    the result type from x's type. The call is marked as translated for char (analyze._check_char_use)."""

    def accepts(call: Call) -> TType | None:
        types = call.types
        if not types or types[0] is None or types[0].base != "char":
            return None
        if not len(rest) - optional <= len(types) - 1 <= len(rest):
            return None
        if any(t is None or t.base not in bases for t, bases in zip(types[1:], rest)):
            return None
        call.node.meta["char"] = True
        return result(types[0])

    return accepts


_INTEGRAL = ("tinyint", "smallint", "integer", "bigint", "unknown")


def _varchar_of(t: TType) -> TType:
    return tt.varchar(t.args[0])


def _trimmed(sql: str) -> str:
    """Trino's stored value of a char: its padded text without the trailing spaces (Chars.trimTrailingSpaces)."""
    return f"rtrim({sql}, ' ')"


def _trim(kind: str) -> Render:
    """trim, ltrim and rtrim of a char (StringFunctions.charTrim, charLeftTrim, charRightTrim): the
    function applied to the stored value; with characters to remove, trailing spaces trimmed after."""

    def render(g, node, args):
        value = _trimmed(g.sql(args[0]))
        if len(args) == 1:
            return f"{kind}({value}, {tf.string(tf.WHITESPACE)})"
        trimmed = f"{kind}({value}, {g.sql(args[1])})"
        return trimmed if kind == "ltrim" else _trimmed(trimmed)

    return render


def _char_substr(g, node, args) -> str:
    """substr(char(x), start[, length]): the varchar substr of the padded value (StringFunctions.charSubstring)."""
    return tf.substring_from(g, exp.Substring(this=args[0], start=args[1], length=args[2] if len(args) == 3 else None))


def _char_concat(g, node, args) -> str:
    """concat(char(x), char(y)): the left value padded to x, then the right one (StringFunctions.concat);
    the padded right one reads the same once the result is padded to x + y."""
    left, right = (g.coerce(a, tt.as_char(ttype(a))) for a in args)
    return f"({left} || {right})"


def _concat_type(call: Call) -> TType | None:
    types = call.types
    if len(types) != 2 or "char" not in (t.base for t in types if t is not None):
        return None
    if any(t is None or t.base not in _TEXT for t in types):
        return None
    if any(t.is_unknown for t in types):
        call.fail(tt.AMBIGUOUS, "AMBIGUOUS_FUNCTION_CALL")  # the element-to-array concat fits as well
    t = chars.concat_type(types[0], types[1])
    if t is None:
        call.fail(f"concat of {types[0]} and {types[1]} (longer than char(65536))", "NOT_SUPPORTED")
    call.node.meta["char"] = True
    return t


def _codepoint(call: Call) -> TType:
    """codepoint takes varchar(1) only: a longer or unbounded varchar is FUNCTION_NOT_FOUND in Trino."""
    (t,) = need(call, "string")
    if t.base == "varchar" and (not t.args or t.args[0] > 1):
        call.mismatch()
    return tt.INTEGER


def _render_case(name: str):
    """upper or lower as Java maps each code point (letter_case)."""
    return lambda g, node, args: letter_case.render(name, g.sql(args[0]))


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "length",
        "string",
        "length(string) -> bigint",
        fixed(tt.BIGINT, "string"),
        lambda g, node, args: f"CAST(length({g.sql(args[0])}) AS BIGINT)",
    )
    register("lower", "string", "lower(string) -> varchar", _string_same, _render_case("lower"))
    register("upper", "string", "upper(string) -> varchar", _string_same, _render_case("upper"))
    register("trim", "string", "trim(string) -> varchar", _string_same, _render_trim("trim"))
    register("ltrim", "string", "ltrim(string) -> varchar", _string_same, _render_trim("ltrim"))
    register("rtrim", "string", "rtrim(string) -> varchar", _string_same, _render_trim("rtrim"))
    register(
        "substr",
        "string",
        "substr(string, start[, length]) -> varchar",
        _substr,
        _render_substr,
        aliases=("substring",),
    )
    register("replace", "string", "replace(string, search[, replace]) -> varchar", _replace, _render_replace)
    register(
        "strpos",
        "string",
        "strpos(string, substring) -> bigint",
        _strpos,
        lambda g, node, args: f"CAST(strpos({g.sql(args[0])}, {g.sql(args[1])}) AS BIGINT)",
    )
    register(
        "starts_with",
        "string",
        "starts_with(string, prefix) -> boolean",
        fixed(tt.BOOLEAN, "string", "string"),
        call_as("starts_with"),
    )
    register(
        "concat",
        "string",
        "concat(string1, ..., stringN) -> varchar; concat(array1, ..., arrayN) -> array",
        _concat,
        _render_concat,
        notes="NULL when any argument is NULL, as in Trino (DuckDB's concat skips NULLs).",
    )
    register(
        "concat_ws",
        "string",
        "concat_ws(separator, string1, ...) -> varchar",
        lambda c: (
            tt.VARCHAR
            if len(c.args) >= 2 and all(t is not None and t.base in ("varchar", "unknown") for t in c.types)
            else c.mismatch()
        ),
        call_as("concat_ws"),
    )
    register("lpad", "string", "lpad(string, size, padstring) -> varchar", _pad, _render_pad, notes=_PAD_NOTE)
    register("rpad", "string", "rpad(string, size, padstring) -> varchar", _pad, _render_pad, notes=_PAD_NOTE)
    register("split", "string", "split(string, delimiter[, limit]) -> array(varchar)", _split, _render_split)
    register(
        "split_part",
        "string",
        "split_part(string, delimiter, index) -> varchar",
        lambda c: (
            need(c, "string", "string", "integral")[0]
            if c.types and c.types[0] is not None and c.types[0].base == "varchar"
            else fixed(tt.VARCHAR, "string", "string", "integral")(c)
        ),
        _render_split_part,
        notes="NULL when the index is beyond the last field, as in Trino (DuckDB gives '').",
    )
    register(
        "chr",
        "string",
        "chr(n) -> varchar(1)",
        fixed(tt.varchar(1), "integral"),
        lambda g, node, args: f"chr(CAST({g.sql(args[0])} AS INTEGER))",
    )
    register(
        "codepoint",
        "string",
        "codepoint(varchar(1)) -> integer",
        _codepoint,
        lambda g, node, args: (
            f"CASE WHEN length({g.sql(args[0])}) <> 1 THEN "
            f"{g.fail(tf.string('Input string must be a single character string'))} "
            f"ELSE CAST(unicode({g.sql(args[0])}) AS INTEGER) END"
        ),
    )

    register(
        "levenshtein_distance",
        "string",
        "levenshtein_distance(string1, string2) -> bigint",
        fixed(tt.BIGINT, "string", "string"),
        _render_levenshtein,
        notes="Counts characters, as Trino does.",
    )
    register(
        "hamming_distance",
        "string",
        "hamming_distance(string1, string2) -> bigint",
        fixed(tt.BIGINT, "string", "string"),
        _render_hamming,
        notes="Counts characters, as Trino does.",
    )
    register(
        "translate",
        "string",
        "translate(source, from, to) -> varchar",
        fixed(tt.VARCHAR, "string", "string", "string"),
        call_as("translate"),
    )

    register(
        "to_utf8",
        "string",
        "to_utf8(string) -> varbinary",
        fixed(VARBINARY, "string"),
        lambda g, n, a: f"encode({g.sql(a[0])})",
    )
    register(
        "from_utf8",
        "string",
        "from_utf8(binary) -> varchar",
        binary_in(tt.VARCHAR),
        _render_from_utf8,
        notes="Bytes that are not UTF-8 fail (NOT_SUPPORTED) instead of decoding to U+FFFD.",
    )

    overload(
        "length",
        lambda c: tt.BIGINT if binary_args(c, 1) else None,
        lambda g, node, args: f"CAST(octet_length({g.sql(args[0])}) AS BIGINT)",
        "length(binary) -> bigint",
    )
    overload(
        "concat",
        _concat_binary,
        lambda g, node, args: "(" + " || ".join(g.sql(a) for a in args) + ")",
        "concat(binary1, ..., binaryN) -> varbinary",
    )
    for _name in ("lpad", "rpad"):
        overload(_name, _pad_binary, _render_pad_binary, f"{_name}(binary, size, padbinary) -> varbinary")
    for _name in ("substr", "substring"):
        overload(_name, _substr_binary, _render_substr_binary, "substr(binary, start[, length]) -> varbinary")

    for _name in ("trim", "ltrim", "rtrim"):
        overload(
            _name,
            _trim_chars,
            SUPPORTED[_name].render,
            f"{_name}(string, characters) -> varchar",
        )
    overload("strpos", _strpos_instance, _render_strpos_instance, "strpos(string, substring, instance) -> bigint")
    register("luhn_check", "string", "luhn_check(string) -> boolean", fixed(tt.BOOLEAN, "string"), _render_luhn_check)
    register(
        "normalize",
        "string",
        "normalize(string) -> varchar",
        fixed(tt.VARCHAR, "string"),
        lambda g, node, args: f"nfc_normalize({g.sql(args[0])})",
        notes="The form NFC (the default); NFD, NFKC and NFKD are refused.",
    )
    register(
        "index",
        "string",
        "index(string, substring) -> bigint (Teradata)",
        fixed(tt.BIGINT, "string", "string"),
        lambda g, node, args: "CAST(strpos({}, {}) AS BIGINT)".format(*sqls(g, args)),
    )
    register(
        "char2hexint",
        "string",
        "char2hexint(string) -> varchar (Teradata)",
        fixed(tt.VARCHAR, "string"),
        _char2hexint,
    )

    overload("normalize", _normalize_form, _render_normalize_form, "normalize(string, form) -> varchar")

    register(
        "soundex",
        "string",
        "soundex(string) -> varchar(4)",
        fixed(tt.varchar(4), "string"),
        _render_soundex,
        notes="ASCII text; non-ASCII text is refused.",
    )

    overload(
        "length",
        _char_call(lambda t: tt.BIGINT),
        lambda g, node, args: f"CAST(length({g.sql(args[0])}) AS BIGINT)",
        "length(char(x)) -> bigint (x: StringFunctions.charLength)",
    )
    for _name in ("lower", "upper"):
        overload(
            _name,
            _char_call(lambda t: t),
            _render_case(_name),
            f"{_name}(char(x)) -> char(x)",
        )
    for _name in ("trim", "ltrim", "rtrim"):
        overload(
            _name,
            _char_call(_varchar_of, _TEXT, optional=1),
            _trim(_name),
            f"{_name}(char(x)[, characters]) -> varchar(x) (trailing spaces are not part of a char value)",
        )
    for _name in ("substr", "substring"):
        overload(
            _name,
            _char_call(_varchar_of, _INTEGRAL, _INTEGRAL, optional=1),
            _char_substr,
            f"{_name}(char(x), start[, length]) -> varchar(x) (of the padded value: StringFunctions.charSubstring)",
        )
    overload(
        "concat",
        _concat_type,
        _char_concat,
        "concat(char(x), char(y)) -> char(x + y) (two arguments; varchar and NULL coerced to char)",
    )
    overload(
        "lpad",
        _char_call(lambda t: tt.VARCHAR, _INTEGRAL, ("varchar", "unknown")),
        SUPPORTED["lpad"].render,
        "lpad(char(x), size, padstring) -> varchar (of the padded value: StringFunctions.leftPad, trinodb/trino#16907)",
    )
