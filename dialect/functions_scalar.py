"""Scalar functions of issue 14 family 5: VARBINARY and its encodings and hashes, strings, numbers
and dates that translate exactly. Registered into `registry.SUPPORTED` when
lakegate.dialect.translate imports this module; the Trino overloads of functions registered by
lakegate.dialect.functions (length(varbinary), ...) are added with `overload`.

Sources are trinodb/trino core/trino-main/src/main/java/io/trino/operator/scalar/*.java, cited per
function; each function has conformance cases in tests/dialect/cases/cov_*.yaml.
"""

from __future__ import annotations

import re
import re._parser as re_parser
from collections.abc import Callable

from sqlglot import exp

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import zones
from lakegate.dialect.analyze import Call, ttype
from lakegate.dialect.functions import (
    capturing_groups,
    checked,
    fixed,
    literal_str,
    need,
    pad_checks,
    regexp_call,
    sqls,
)
from lakegate.dialect.registry import SUPPORTED, Render, overload, register
from lakegate.dialect.trino_types import TType

VARBINARY = tt.VARBINARY


def _binary_args(call: Call, count: int) -> bool:
    """Whether the call has `count` arguments, the first varbinary and none of another type than
    varbinary or NULL."""
    types = call.types
    return (
        len(types) == count
        and types[0] is not None
        and types[0].base == "varbinary"
        and all(t is not None and t.base in ("varbinary", "unknown") for t in types)
    )


#: Well-formed UTF-8 (RFC 3629) over upper-case hex digits, two a byte: no overlong forms,
#: surrogates or code points past U+10FFFF.
_UTF8_HEX = (
    "(?:[0-7][0-9A-F]|(?:C[2-9A-F]|D[0-9A-F])[89AB][0-9A-F]|E0[AB][0-9A-F][89AB][0-9A-F]"
    "|(?:E[1-9A-CEF])[89AB][0-9A-F][89AB][0-9A-F]|ED[89][0-9A-F][89AB][0-9A-F]"
    "|F0[9AB][0-9A-F](?:[89AB][0-9A-F]){2}|F[1-3](?:[89AB][0-9A-F]){3}|F48[0-9A-F](?:[89AB][0-9A-F]){2})*"
)


def utf8_valid(hex_sql: str) -> str:
    """Whether the bytes spelled by the upper-case hex text `hex_sql` are well-formed UTF-8 (checked
    without decoding: DuckDB's try() refuses arguments that can raise Trino's errors)."""
    return f"regexp_full_match({hex_sql}, {tf.string(_UTF8_HEX)})"


# === varbinary (io.trino.operator.scalar.VarbinaryFunctions, HmacFunctions) =====================
_KINDS_BINARY = ("varbinary", "unknown")
_TEXT_OR_BINARY = ("varchar", "varbinary", "unknown")


def _binary_in(result: TType) -> Callable[[Call], TType]:
    """One varbinary argument; the result type."""

    def infer(call: Call) -> TType:
        if len(call.args) != 1 or call.types[0] is None or call.types[0].base not in _KINDS_BINARY:
            call.mismatch()
        return result

    return infer


def _text_in(result: TType) -> Callable[[Call], TType]:
    """One varchar or varbinary argument (Trino has both overloads); the result type."""

    def infer(call: Call) -> TType:
        if len(call.args) != 1 or call.types[0] is None or call.types[0].base not in _TEXT_OR_BINARY:
            call.mismatch()
        return result

    return infer


def _text(g, node) -> str:
    """The argument as text: a varbinary argument is read as UTF-8 (invalid UTF-8 gives a text no
    decoder accepts, so the caller's validity check fails as Trino's decoder does)."""
    sql = g.sql(node)
    if ttype(node).base != "varbinary":
        return sql
    return f"CASE WHEN ({sql}) IS NULL THEN NULL WHEN {utf8_valid(f'hex({sql})')} THEN decode({sql}) ELSE '!' END"


def _decoded(g, text: str, valid: str, value: str, message: str) -> str:
    """`value` when the text matches the regular expression `valid`, else Trino's
    INVALID_FUNCTION_ARGUMENT."""
    return (
        f"CASE WHEN {text} IS NULL THEN NULL WHEN NOT regexp_full_match({text}, {tf.string(valid)}) "
        f"THEN {g.fail(tf.string(message))} ELSE {value} END"
    )


#: java.util.Base64's basic decoder: whole 4-character units, and a last unit of 2 or 3 characters,
#: padded with '=' to 4 or not padded at all.
_BASE64 = "([A-Za-z0-9+/]{4})*([A-Za-z0-9+/]{2}(==)?|[A-Za-z0-9+/]{3}=?)?"
_BASE64URL = _BASE64.replace("+/", "_-")


def _render_from_base64(url: bool) -> Render:
    def render(g, node, args) -> str:
        text = _text(g, args[0])
        standard = f"translate({text}, '-_', '+/')" if url else text
        padded = f"rpad({standard}, CAST(ceil(length({text}) / 4) * 4 AS INTEGER), '=')"
        return _decoded(
            g, text, _BASE64URL if url else _BASE64, f"from_base64({padded})", "Illegal base64 character or length"
        )

    return render


def _render_to_base64(url: bool) -> Render:
    def render(g, node, args) -> str:
        sql = f"to_base64({g.sql(args[0])})"
        return f"translate({sql}, '+/', '-_')" if url else sql

    return render


def _render_from_hex(g, node, args) -> str:
    text = _text(g, args[0])
    return (
        f"CASE WHEN {text} IS NULL THEN NULL WHEN length({text}) % 2 = 1 THEN "
        f"{g.fail(tf.string('invalid input length ') + f' || length({text})')} "
        f"WHEN NOT regexp_full_match({text}, '[0-9A-Fa-f]*') THEN {g.fail(tf.string('invalid hex digit'))} "
        f"ELSE unhex({text}) END"
    )


def _bytes(sql: str) -> str:
    """The bytes of a varbinary as a list of integers 0..255."""
    return f"list_transform(regexp_extract_all(hex({sql}), '..'), lambda \"_h\": CAST('0x' || \"_h\" AS INTEGER))"


def _hash(duck: str) -> Render:
    """DuckDB's hash function `duck` gives lower-case hex text; Trino gives the digest's bytes."""
    return lambda g, node, args: f"unhex({duck}({g.sql(args[0])}))"


def _crc_table() -> str:
    """The byte table of CRC-32 (java.util.zip.CRC32: reflected polynomial 0xEDB88320) as a DuckDB list."""
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
        table.append(c)
    return "[" + ", ".join(map(str, table)) + "]"


_CRC32_TABLE = _crc_table()


def _render_crc32(g, node, args) -> str:
    """java.util.zip.CRC32, table-driven over the bytes."""
    step = f'lambda "_c", "_b": xor({_CRC32_TABLE}[(xor("_c", "_b") & 255) + 1], "_c" >> 8)'
    crc = f"list_reduce({_bytes(g.sql(args[0]))}, {step}, CAST(4294967295 AS BIGINT))"
    return f"CAST(xor({crc}, 4294967295) AS BIGINT)"


def _render_hmac(duck: str) -> Render:
    """HMAC (RFC 2104) over DuckDB's `duck` hash, 64-byte blocks: H((K ^ opad) || H((K ^ ipad) || m)),
    a key longer than a block hashed first (javax.crypto.Mac, as HmacFunctions uses it)."""

    def render(g, node, args) -> str:
        message, key = sqls(g, args)
        block_key = f"rpad(hex(CASE WHEN octet_length({key}) > 64 THEN unhex({duck}({key})) ELSE {key} END), 128, '0')"

        def padded(pad: int) -> str:
            xored = (
                f"list_transform(range(0, 64), lambda \"_i\": lpad(hex(xor(CAST('0x' || "
                f"substr({block_key}, 2 * \"_i\" + 1, 2) AS INTEGER), {pad})), 2, '0'))"
            )
            return f"unhex(array_to_string({xored}, ''))"

        inner = f"unhex({duck}({padded(0x36)} || {message}))"
        return hmac_key_checked(key, f"unhex({duck}({padded(0x5C)} || {inner}))")

    return render


def hmac_key_checked(key: str, sql: str) -> str:
    """`sql`, or the error the real Trino 476 raises for an empty HMAC key (javax.crypto's
    SecretKeySpec: GENERIC_INTERNAL_ERROR 'Empty key'), not caught by try()."""
    empty = f"error({tf.string('GENERIC_INTERNAL_ERROR: Empty key')})"
    return f"CASE WHEN octet_length(CAST({key} AS BLOB)) = 0 THEN {empty} ELSE {sql} END"


def _render_from_big_endian(size: int, duck: str) -> Render:
    def render(g, node, args) -> str:
        value = g.sql(args[0])
        unsigned = f"CAST('0x' || hex({value}) AS HUGEINT)"
        signed = f"{unsigned} - CASE WHEN {unsigned} >= {2 ** (size * 8 - 1)} THEN {2 ** (size * 8)} ELSE 0 END"
        message = tf.string(f"expected {size}-byte input, but got instead: ") + f" || octet_length({value})"
        return f"CASE WHEN octet_length({value}) <> {size} THEN {g.fail(message)} ELSE CAST({signed} AS {duck}) END"

    return render


def _render_to_big_endian(size: int, duck: str) -> Render:
    digits = size * 2
    # hex() of a negative integer gives its 64-bit two's complement; of a positive one, no leading zeros
    return lambda g, node, args: f"unhex(right(lpad(hex(CAST({g.sql(args[0])} AS {duck})), 16, '0'), {digits}))"


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


def _render_reverse_binary(g, node, args) -> str:
    return f"unhex(array_to_string(list_reverse(regexp_extract_all(hex({g.sql(args[0])}), '..')), ''))"


def _concat_binary(call: Call) -> TType | None:
    if not any(t is not None and t.base == "varbinary" for t in call.types):
        return None
    if len(call.args) < 2:
        call.fail("There must be two or more concatenation arguments", "INVALID_FUNCTION_ARGUMENT")
    if not all(t is not None and t.base in _KINDS_BINARY for t in call.types):
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
    _binary_in(tt.VARCHAR),
    _render_from_utf8,
    notes="Bytes that are not UTF-8 fail (NOT_SUPPORTED) instead of decoding to U+FFFD.",
)
register("to_base64", "binary", "to_base64(binary) -> varchar", _binary_in(tt.VARCHAR), _render_to_base64(False))
register("to_base64url", "binary", "to_base64url(binary) -> varchar", _binary_in(tt.VARCHAR), _render_to_base64(True))
register("from_base64", "binary", "from_base64(string) -> varbinary", _text_in(VARBINARY), _render_from_base64(False))
register(
    "from_base64url", "binary", "from_base64url(string) -> varbinary", _text_in(VARBINARY), _render_from_base64(True)
)
register("to_hex", "binary", "to_hex(binary) -> varchar", _binary_in(tt.VARCHAR), lambda g, n, a: f"hex({g.sql(a[0])})")
register("from_hex", "binary", "from_hex(string) -> varbinary", _text_in(VARBINARY), _render_from_hex)
register("md5", "binary", "md5(binary) -> varbinary", _binary_in(VARBINARY), _hash("md5"))
register("sha1", "binary", "sha1(binary) -> varbinary", _binary_in(VARBINARY), _hash("sha1"))
register("sha256", "binary", "sha256(binary) -> varbinary", _binary_in(VARBINARY), _hash("sha256"))
register("crc32", "binary", "crc32(binary) -> bigint", _binary_in(tt.BIGINT), _render_crc32)
for _name, _duck in (("hmac_md5", "md5"), ("hmac_sha1", "sha1"), ("hmac_sha256", "sha256")):
    register(
        _name,
        "binary",
        f"{_name}(binary, key) -> varbinary",
        lambda c: VARBINARY if _binary_args(c, 2) else c.mismatch(),
        _render_hmac(_duck),
    )
register(
    "to_big_endian_64",
    "binary",
    "to_big_endian_64(bigint) -> varbinary",
    fixed(VARBINARY, "integral"),
    _render_to_big_endian(8, "BIGINT"),
)
register(
    "to_big_endian_32",
    "binary",
    "to_big_endian_32(integer) -> varbinary",
    lambda c: (
        VARBINARY if need(c, "integral")[0].base in ("tinyint", "smallint", "integer", "unknown") else c.mismatch()
    ),
    _render_to_big_endian(4, "INTEGER"),
)
register(
    "from_big_endian_64",
    "binary",
    "from_big_endian_64(binary) -> bigint",
    _binary_in(tt.BIGINT),
    _render_from_big_endian(8, "BIGINT"),
)
register(
    "from_big_endian_32",
    "binary",
    "from_big_endian_32(binary) -> integer",
    _binary_in(tt.INTEGER),
    _render_from_big_endian(4, "INTEGER"),
)
#: IEEE 754 binary formats: (bytes, exponent bits, fraction bits, Java's canonical NaN bits, DuckDB type).
_IEEE = {32: (4, 8, 23, 0x7FC00000, "FLOAT"), 64: (8, 11, 52, 0x7FF8000000000000, "DOUBLE")}


def _render_to_ieee754(size: int) -> Render:
    """Float.floatToIntBits / Double.doubleToLongBits, big-endian: the sign, the biased exponent and
    the fraction, computed by exact power-of-two scaling (subnormals scaled in two steps)."""
    nbytes, exponent_bits, fraction_bits, nan, _ = _IEEE[size]
    bias = 2 ** (exponent_bits - 1) - 1
    top = 2**exponent_bits - 1

    def render(g, node, args) -> str:
        x = f"CAST({g.sql(args[0])} AS DOUBLE)"
        a = f"abs({x})"
        guess = f"CAST(floor(log2({a})) AS INTEGER)"
        exponent = (
            f"({guess} - CASE WHEN pow(2.0, {guess}) > {a} THEN 1 ELSE 0 END "
            f"+ CASE WHEN pow(2.0, {guess} + 1) <= {a} THEN 1 ELSE 0 END)"
        )
        normal = (
            f"(CAST({exponent} + {bias} AS HUGEINT) << {fraction_bits}) + "
            f"CAST(({a} / pow(2.0, {exponent}) - 1) * pow(2.0, {fraction_bits}) AS HUGEINT)"
        )
        subnormal = f"CAST({a} * pow(2.0, {bias - 1}) * pow(2.0, {fraction_bits}) AS HUGEINT)"
        magnitude = (
            f"CASE WHEN isinf({x}) THEN {top << fraction_bits} WHEN {a} = 0 THEN 0 "
            f"WHEN {a} < pow(2.0, {1 - bias}) THEN {subnormal} ELSE {normal} END"
        )
        sign = f"CASE WHEN signbit({x}) THEN {1 << (size - 1)} ELSE 0 END"
        bits = f"CASE WHEN isnan({x}) THEN {nan} ELSE {magnitude} + {sign} END"
        return f"unhex(lpad(hex(CAST({bits} AS UBIGINT)), {nbytes * 2}, '0'))"

    return render


def _render_from_ieee754(size: int) -> Render:
    """Float.intBitsToFloat / Double.longBitsToDouble of exactly size / 8 big-endian bytes."""
    nbytes, exponent_bits, fraction_bits, _, duck = _IEEE[size]
    bias = 2 ** (exponent_bits - 1) - 1
    top = 2**exponent_bits - 1

    def render(g, node, args) -> str:
        value = g.sql(args[0])
        bits = f"CAST('0x' || hex({value}) AS UBIGINT)"
        exponent = f"CAST(({bits} >> {fraction_bits}) & {top} AS INTEGER)"
        fraction = f"CAST({bits} & {2**fraction_bits - 1} AS DOUBLE)"
        magnitude = (
            f"CASE WHEN {exponent} = {top} THEN CASE WHEN {fraction} = 0 THEN CAST('Infinity' AS DOUBLE) "
            f"ELSE CAST('NaN' AS DOUBLE) END "
            f"WHEN {exponent} = 0 THEN {fraction} * pow(2.0, {1 - bias}) * pow(2.0, -{fraction_bits}) "
            f"ELSE ({fraction} + {2**fraction_bits}) * pow(2.0, {exponent} - {bias + fraction_bits}) END"
        )
        signed = f"CASE WHEN ({bits} >> {size - 1}) = 1 THEN -({magnitude}) ELSE {magnitude} END"
        message = tf.string(f"Input floating-point value must be exactly {nbytes} bytes long")
        return f"CASE WHEN octet_length({value}) <> {nbytes} THEN {g.fail(message)} ELSE CAST({signed} AS {duck}) END"

    return render


register(
    "to_ieee754_64",
    "binary",
    "to_ieee754_64(double) -> varbinary",
    fixed(VARBINARY, "number"),
    _render_to_ieee754(64),
)
register(
    "to_ieee754_32",
    "binary",
    "to_ieee754_32(real) -> varbinary",
    lambda c: VARBINARY if need(c, "number")[0].base in ("real", "unknown") else c.mismatch(),
    _render_to_ieee754(32),
)
register(
    "from_ieee754_64", "binary", "from_ieee754_64(binary) -> double", _binary_in(tt.DOUBLE), _render_from_ieee754(64)
)
register("from_ieee754_32", "binary", "from_ieee754_32(binary) -> real", _binary_in(tt.REAL), _render_from_ieee754(32))
#: Guava's BaseEncoding.base32() (RFC 4648): 5 bits a character, padded with '=' to 8 characters.
_BASE32 = "ABCDEFGHIJKLMNOPQRSTUVWXYZ234567"


def _render_to_base32(g, node, args) -> str:
    value = g.sql(args[0])
    nibbles = f"regexp_extract_all(hex({value}), '.')"
    bits = (
        f"array_to_string(list_transform({nibbles}, "
        "lambda \"_h\": lpad(bin(CAST('0x' || \"_h\" AS INTEGER)), 4, '0')), '')"
    )
    padded = f"rpad({bits}, CAST(ceil(length({bits}) / 5) * 5 AS INTEGER), '0')"
    chars = (
        f'list_transform(range(0, length({padded}) // 5), lambda "_i": '
        f"substr('{_BASE32}', CAST('0b' || substr({padded}, 5 * \"_i\" + 1, 5) AS INTEGER) + 1, 1))"
    )
    text = f"array_to_string({chars}, '')"
    return (
        f"CASE WHEN {value} IS NULL THEN NULL ELSE rpad({text}, CAST(ceil(length({text}) / 8) * 8 AS INTEGER), '=') END"
    )


def _render_from_base32(g, node, args) -> str:
    """BaseEncoding.base32().decode: trailing '=' dropped, then A-Z and 2-7 only, in a length that
    ends on a whole byte (0, 2, 4, 5 or 7 characters past a multiple of 8)."""
    text = _text(g, args[0])
    trimmed = f"rtrim({text}, '=')"
    bits = (
        f"array_to_string(list_transform(regexp_extract_all({trimmed}, '.'), lambda \"_c\": "
        f"lpad(bin(strpos('{_BASE32}', \"_c\") - 1), 5, '0')), '')"
    )
    whole = f"left({bits}, CAST(length({bits}) // 8 * 8 AS INTEGER))"
    hexed = (
        f'array_to_string(list_transform(range(0, length({whole}) // 4), lambda "_i": '
        f"upper(to_base(CAST('0b' || substr({whole}, 4 * \"_i\" + 1, 4) AS INTEGER), 16))), '')"
    )
    length = g.fail(f"'Invalid input length ' || length({trimmed})")
    bad = g.fail(tf.string("Unrecognized character"))
    return (
        f"CASE WHEN {text} IS NULL THEN NULL WHEN length({trimmed}) % 8 IN (1, 3, 6) THEN {length} "
        f"WHEN NOT regexp_full_match({trimmed}, '[A-Z2-7]*') THEN {bad} ELSE unhex({hexed}) END"
    )


register("to_base32", "binary", "to_base32(binary) -> varchar", _binary_in(tt.VARCHAR), _render_to_base32)
register("from_base32", "binary", "from_base32(string) -> varbinary", _text_in(VARBINARY), _render_from_base32)


def _pad_binary(call: Call) -> TType | None:
    types = call.types
    if not (types and types[0] is not None and types[0].base == "varbinary"):
        return None
    if len(types) != 3 or not (types[1] is not None and (types[1].is_integral or types[1].is_unknown)):
        call.mismatch()
    if types[2] is None or types[2].base not in _KINDS_BINARY:
        call.mismatch()
    return VARBINARY


def _render_pad_binary(g, node, args) -> str:
    """VarbinaryFunctions.leftPad / rightPad: `size` bytes, the padding repeated from its start, the
    value cut to `size` bytes when longer (on the hex text, two digits a byte)."""
    value, size, pad = sqls(g, args)
    checks = pad_checks(value, size, pad, f"octet_length({pad}) = 0", "Padding bytes must not be empty")
    width = checked(g, f"CAST(2 * ({size}) AS INTEGER)", checks)
    return f"unhex({node.name.lower()}(hex({value}), {width}, hex({pad})))"


overload(
    "length",
    lambda c: tt.BIGINT if _binary_args(c, 1) else None,
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
overload(
    "reverse",
    lambda c: VARBINARY if _binary_args(c, 1) else None,
    _render_reverse_binary,
    "reverse(binary) -> varbinary",
)


# === math (io.trino.operator.scalar.MathFunctions, BitwiseFunctions, WilsonInterval,
# ArrayVectorFunctions, DataSizeFunctions) ======================================================
_WIDTH = {"tinyint": 8, "smallint": 16, "integer": 32, "bigint": 64}
_U64 = 2**64 - 1


def _shift(call: Call) -> TType:
    value, _ = need(call, "integral", "integer")  # BitwiseFunctions: the shift is an integer
    return tt.BIGINT if value.is_unknown else value


def _signed(sql: str, width: int) -> str:
    """The low `width` bits of the non-negative HUGEINT `sql` as a two's complement number."""
    low = f"(({sql}) & {2**width - 1})"
    return f"({low} - CASE WHEN {low} >= {2 ** (width - 1)} THEN {2**width} ELSE 0 END)"


def _render_shift(kind: str) -> Render:
    """BitwiseFunctions: the value's own width (tinyint 8 ... bigint 64 bits); a shift of 64 or
    more gives 0 (-1 for an arithmetic shift of a negative value); below 64, Java's `<<`, `>>>`
    and `>>` on a long (the shift taken modulo 64)."""

    def render(g, node, args) -> str:
        value, shift = sqls(g, args)
        t = ttype(node)
        width = _WIDTH[t.base]
        s = f"(CAST({shift} AS BIGINT) & 63)"
        bits = f"(CAST({value} AS HUGEINT) & {_U64})"
        if kind == "left":
            shifted, wide = _signed(f"{bits} << {s}", width), "0"
        elif kind == "logical":
            low = f"({bits} & {2**width - 1})"
            shifted = f"CASE WHEN {s} = 0 THEN {value} ELSE {low} >> {s} END"
            wide = "0"
        else:
            shifted, wide = f"(CAST({value} AS BIGINT) >> {s})", f"CASE WHEN {value} >= 0 THEN 0 ELSE -1 END"
        return tf.cast(f"CASE WHEN {shift} >= 64 THEN {wide} ELSE {shifted} END", t)

    return render


def _render_width_bucket(g, node, args) -> str:
    """MathFunctions.widthBucket(operand, bound1, bound2, bucketCount)."""
    x, b1, b2 = (f"CAST({g.sql(a)} AS DOUBLE)" for a in args[:3])
    n = f"CAST({g.sql(args[3])} AS BIGINT)"
    lower, upper = f"least({b1}, {b2})", f"greatest({b1}, {b2})"
    checks = [
        (f"{n} <= 0", "bucketCount must be greater than 0"),
        (f"isnan({x})", "operand must not be NaN"),
        (f"NOT isfinite({b1})", "first bound must be finite"),
        (f"NOT isfinite({b2})", "second bound must be finite"),
        (f"{b1} = {b2}", "bounds cannot equal each other"),
    ]
    whens = " ".join(f"WHEN {c} THEN {g.fail(tf.string(m))}" for c, m in checks)
    bucket = (
        f"CASE WHEN {x} < {lower} THEN 0 WHEN {x} >= {upper} THEN {n} + 1 "
        f"ELSE CAST(trunc(CAST({n} AS DOUBLE) * ({x} - {lower}) / ({upper} - {lower}) + 1) AS BIGINT) END"
    )
    return (
        f"CASE WHEN {x} IS NULL OR {b1} IS NULL OR {b2} IS NULL OR {n} IS NULL THEN NULL {whens} "
        f"WHEN {b1} > {b2} THEN {n} - ({bucket}) + 1 ELSE {bucket} END"
    )


def _render_width_bucket_bins(g, node, args) -> str:
    """MathFunctions.widthBucket(operand, bins): the number of bins <= operand. Trino's binary search
    fails when it meets unsorted or non-finite bins; here any such bin fails."""
    x, bins = f"CAST({g.sql(args[0])} AS DOUBLE)", g.sql(args[1])
    unsorted = f'len(list_filter(range(1, len({bins})), lambda "_i": {bins}["_i"] > {bins}["_i" + 1])) > 0'
    infinite = f'len(list_filter({bins}, lambda "_b": NOT isfinite("_b"))) > 0'
    return (
        f"CASE WHEN {x} IS NULL OR {bins} IS NULL THEN NULL "
        f"WHEN len({bins}) = 0 THEN {g.fail(tf.string('Bins cannot be an empty array'))} "
        f"WHEN isnan({x}) THEN {g.fail(tf.string('Operand cannot be NaN'))} "
        f'WHEN list_contains(list_transform({bins}, lambda "_b": "_b" IS NULL), true) THEN '
        f"{g.fail(tf.string('NULL bins are not supported in lakegate'), 'NOT_SUPPORTED')} "
        f"WHEN {unsorted} THEN {g.fail(tf.string('Bin values are not sorted in ascending order'))} "
        f"WHEN {infinite} THEN {g.fail(tf.string('Bin value must be finite'))} "
        f'ELSE CAST(len(list_filter({bins}, lambda "_b": "_b" <= {x})) AS BIGINT) END'
    )


def _width_bucket(call: Call) -> TType:
    if len(call.args) == 2:
        x, bins = call.types
        if x is None or not (x.is_numeric or x.is_unknown) or bins is None or bins.base not in ("array", "unknown"):
            call.mismatch()
        if bins.base == "array" and not (bins.element.is_numeric or bins.element.is_unknown):
            call.mismatch()
        return tt.BIGINT
    need(call, "number", "number", "number", "integral")
    return tt.BIGINT


def _render_width_bucket_any(g, node, args) -> str:
    return (_render_width_bucket_bins if len(args) == 2 else _render_width_bucket)(g, node, args)


_DIGITS = "0123456789abcdefghijklmnopqrstuvwxyz"


def _radix_check(radix: str) -> tuple[str, str]:
    return (f"{radix} NOT BETWEEN 2 AND 36", "Radix must be between 2 and 36")


def _render_from_base(g, node, args) -> str:
    """Long.parseLong(value, radix): an optional sign, then at least one digit of the radix (either
    case); the value must fit a bigint. Digits are summed in HUGEINT, saturating past 2^64."""
    text, radix = sqls(g, args)
    digits = f"lower(regexp_replace({text}, '^[+-]', ''))"
    value = (
        f'list_reduce(string_split({digits}, \'\'), lambda "_v", "_c": CASE WHEN "_v" > {2**64} THEN "_v" '
        f'ELSE "_v" * {radix} + strpos(\'{_DIGITS}\', "_c") - 1 END, CAST(0 AS HUGEINT))'
    )
    signed = f"CASE WHEN starts_with({text}, '-') THEN -{value} ELSE {value} END"
    valid_digit = f"strpos(left('{_DIGITS}', CAST({radix} AS INTEGER)), \"_c\") > 0"
    valid = (
        f"regexp_full_match({text}, '[+-]?[0-9A-Za-z]+') AND "
        f"len(list_filter(string_split({digits}, ''), lambda \"_c\": NOT ({valid_digit}))) = 0"
    )
    bad = g.fail(f"'Not a valid base-' || {radix} || ' number: ' || {text}")
    check, message = _radix_check(radix)
    return (
        f"CASE WHEN {text} IS NULL OR {radix} IS NULL THEN NULL WHEN {check} THEN {g.fail(tf.string(message))} "
        f"WHEN NOT ({valid}) THEN {bad} "
        f"WHEN ({signed}) NOT BETWEEN {-(2**63)} AND {2**63 - 1} THEN {bad} "
        f"ELSE CAST({signed} AS BIGINT) END"
    )


def _render_to_base(g, node, args) -> str:
    """Long.toString(value, radix): lower-case digits, '-' for negative values."""
    value, radix = (f"CAST({g.sql(a)} AS BIGINT)" for a in args)
    check, message = _radix_check(radix)
    minimum = -(2**63)
    radix_sql = radix
    radix = f"CAST(least(greatest({radix}, 2), 36) AS INTEGER)"  # DuckDB's to_base takes an INTEGER radix
    return (
        f"CASE WHEN {value} IS NULL OR {radix_sql} IS NULL THEN NULL WHEN {check} THEN {g.fail(tf.string(message))} "
        f"WHEN {value} = {minimum} THEN '-' || lower(to_base(CAST(-({value} // {radix}) AS BIGINT), {radix}) || "
        f"to_base(CAST(-({value} % {radix}) AS BIGINT), {radix})) "
        f"WHEN {value} < 0 THEN '-' || lower(to_base(CAST(-{value} AS BIGINT), {radix})) "
        f"ELSE lower(to_base({value}, {radix})) END"
    )


def _render_wilson(bound: int) -> Render:
    """WilsonInterval.wilsonInterval, the same double operations in the same order."""

    def render(g, node, args) -> str:
        successes, trials = (f"CAST({g.sql(a)} AS BIGINT)" for a in args[:2])
        z = f"CAST({g.sql(args[2])} AS DOUBLE)"
        p, n = f"(CAST({successes} AS DOUBLE) / CAST({trials} AS DOUBLE))", f"CAST({trials} AS DOUBLE)"
        value = (
            f"({p} + ({z} * {z}) / (2 * {n}) + {bound} * {z} * sqrt(({p} * (1 - {p})) / {n} + "
            f"({z} * {z}) / (4 * {n} * {n}))) / (1 + ({z} * {z}) / {n})"
        )
        checks = [
            (f"{successes} < 0", "number of successes must not be negative"),
            (f"{trials} <= 0", "number of trials must be positive"),
            (f"{successes} > {trials}", "number of successes must not be larger than number of trials"),
            (f"{z} < 0", "z-score must not be negative"),
        ]
        whens = " ".join(f"WHEN {c} THEN {g.fail(tf.string(m))}" for c, m in checks)
        return f"CASE WHEN {successes} IS NULL OR {trials} IS NULL OR {z} IS NULL THEN NULL {whens} ELSE {value} END"

    return render


def _vectors(call: Call) -> TType:
    if len(call.args) != 2:
        call.mismatch()
    if call.name.startswith("cosine_") and all(t is not None and t.base == "map" for t in call.types):
        call.fail(f"unsupported in lakegate: {call.name} of maps (sparse vectors) is not translated", "NOT_SUPPORTED")
    for t in call.types:
        if t is None or not (t.is_unknown or (t.base == "array" and (t.element.is_numeric or t.element.is_unknown))):
            call.mismatch()
    return tt.DOUBLE


def _fold(pairs: str, step: str) -> str:
    """A left-to-right double sum over the element pairs ("_p"[1], "_p"[2]), as Java's loop adds."""
    return (
        f'list_reduce(list_transform({pairs}, lambda "_p": {step}), lambda "_s", "_x": "_s" + "_x", CAST(0 AS DOUBLE))'
    )


def _render_vector(kind: str) -> Render:
    """ArrayVectorFunctions: the arrays must have the same length; NULL elements are refused."""

    def render(g, node, args) -> str:
        a, b = (f"CAST({g.sql(x)} AS DOUBLE[])" for x in args)
        pairs = f'list_transform(range(1, len({a}) + 1), lambda "_i": [{a}["_i"], {b}["_i"]])'
        dot = _fold(pairs, '"_p"[1] * "_p"[2]')
        if kind == "dot":
            value = dot
        elif kind == "euclidean":
            squared = '("_p"[1] - "_p"[2]) * ("_p"[1] - "_p"[2])'
            value = f"sqrt({_fold(pairs, squared)})"
        else:
            first, second = _fold(pairs, '"_p"[1] * "_p"[1]'), _fold(pairs, '"_p"[2] * "_p"[2]')
            similarity = (
                f"CASE WHEN {first} = 0 OR {second} = 0 THEN {g.fail(tf.string('Vector magnitude cannot be zero'))} "
                f"ELSE {dot} / sqrt({first} * {second}) END"
            )
            value = similarity if kind == "cosine" else f"1.0 - ({similarity})"
        has_null = f'list_contains(list_transform(list_concat({a}, {b}), lambda "_x": "_x" IS NULL), true)'
        return (
            f"CASE WHEN {a} IS NULL OR {b} IS NULL THEN NULL "
            f"WHEN len({a}) <> len({b}) THEN {g.fail(tf.string('The arguments must have the same length'))} "
            f"WHEN {has_null} THEN {g.fail(tf.string('NULL elements are not supported in lakegate'), 'NOT_SUPPORTED')} "
            f"ELSE {value} END"
        )

    return render


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


for _name, _kind in (
    ("bitwise_left_shift", "left"),
    ("bitwise_right_shift", "logical"),
    ("bitwise_right_shift_arithmetic", "arithmetic"),
):
    register(_name, "math", f"{_name}(value, shift) -> same as value", _shift, _render_shift(_kind))
register(
    "width_bucket",
    "math",
    "width_bucket(x, bound1, bound2, n) -> bigint; width_bucket(x, bins) -> bigint",
    _width_bucket,
    _render_width_bucket_any,
    notes="With bins, any unsorted or non-finite bin fails (Trino fails only on those its binary search meets).",
)
register(
    "from_base", "math", "from_base(string, radix) -> bigint", fixed(tt.BIGINT, "string", "integral"), _render_from_base
)
register(
    "to_base",
    "math",
    "to_base(x, radix) -> varchar(64)",
    fixed(tt.varchar(64), "integral", "integral"),
    _render_to_base,
)
register(
    "wilson_interval_lower",
    "math",
    "wilson_interval_lower(successes, trials, z) -> double",
    fixed(tt.DOUBLE, "integral", "integral", "number"),
    _render_wilson(-1),
)
register(
    "wilson_interval_upper",
    "math",
    "wilson_interval_upper(successes, trials, z) -> double",
    fixed(tt.DOUBLE, "integral", "integral", "number"),
    _render_wilson(1),
)
for _name, _kind in (
    ("cosine_similarity", "cosine"),
    ("cosine_distance", "distance"),
    ("dot_product", "dot"),
    ("euclidean_distance", "euclidean"),
):
    register(
        _name,
        "math",
        f"{_name}(array(double), array(double)) -> double",
        _vectors,
        _render_vector(_kind),
        notes="Arrays only (the map forms are not translated); NULL elements fail.",
    )
register(
    "parse_data_size",
    "conversion",
    "parse_data_size(string) -> decimal(38,0)",
    fixed(tt.decimal(38, 0), "string"),
    _render_parse_data_size,
)


# === string (io.trino.operator.scalar.StringFunctions, LuhnCheckFunction) =======================
def _trim_chars(call: Call) -> TType | None:
    """trim(string, characters): the two-argument form (StringFunctions.trim / leftTrim / rightTrim
    with a code point set)."""
    if len(call.args) != 2:
        return None
    source, _ = need(call, "string", "string")
    return source if source.base == "varchar" else tt.VARCHAR


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


# === date and time (io.trino.operator.scalar.DateTimeFunctions, HumanReadableSeconds,
# timestamp/ToIso8601, timestamptz/ToIso8601) =====================================================
def _render_human_readable_seconds(g, node, args) -> str:
    """HumanReadableSeconds: Math.round(|x|) seconds as weeks, days, hours, minutes and seconds,
    the zero parts left out, '0 seconds' for none; NaN and infinities fail."""
    x = f"CAST({g.sql(args[0])} AS DOUBLE)"
    whole = f"floor(abs({x}))"
    rounded = f"TRY_CAST({whole} + CASE WHEN abs({x}) - {whole} >= 0.5 THEN 1 ELSE 0 END AS BIGINT)"
    total = f"(CASE WHEN abs({x}) >= 9.223372036854775807e18 THEN 9223372036854775807 ELSE {rounded} END)"  # saturates
    parts = [
        (f"{total} // 604800", "week"),
        (f"{total} % 604800 // 86400", "day"),
        (f"{total} % 86400 // 3600", "hour"),
        (f"{total} % 3600 // 60", "minute"),
        (f"{total} % 60", "second"),
    ]
    rendered = ", ".join(
        f"CASE WHEN {n} > 0 THEN CAST({n} AS VARCHAR) || ' {unit}' || CASE WHEN {n} = 1 THEN '' ELSE 's' END END"
        for n, unit in parts
    )
    text = f"concat_ws(', ', {rendered})"
    invalid = g.fail(f"'Invalid argument found: ' || {tf.approx_text(x, tt.DOUBLE)}")
    return (
        f"CASE WHEN {x} IS NULL THEN NULL WHEN NOT isfinite({x}) THEN {invalid} "
        f"WHEN {total} = 0 THEN '0 seconds' ELSE {text} END"
    )


#: io.airlift.units.Duration: milliseconds per unit.
_DURATION_MILLIS = {
    "ns": "1.0e-6",
    "us": "1.0e-3",
    "ms": "1.0",
    "s": "1000.0",
    "m": "60000.0",
    "h": "3600000.0",
    "d": "86400000.0",
}


def _render_parse_duration(g, node, args) -> str:
    """io.airlift.units.Duration.valueOf(text).toMillis(): a decimal number, optional whitespace and a
    unit; the milliseconds are floor(value * millis-per-unit + 0.5)."""
    text = g.sql(args[0])
    pattern = (
        "[ \\t\\n\\x0B\\f\\r]*([0-9]+([.][0-9]+)?)[ \\t\\n\\x0B\\f\\r]*"
        f"({'|'.join(_DURATION_MILLIS)})[ \\t\\n\\x0B\\f\\r]*"
    )
    number = f"CAST(regexp_extract({text}, {tf.string(pattern)}, 1) AS DOUBLE)"
    unit = f"regexp_extract({text}, {tf.string(pattern)}, 3)"
    factor = "CASE " + " ".join(f"WHEN {unit} = '{u}' THEN {m}" for u, m in _DURATION_MILLIS.items()) + " END"
    millis = f"floor({number} * {factor} + 0.5)"
    invalid = g.fail(f"'duration is not a valid data duration string: ' || {text}")
    return (
        f"CASE WHEN {text} IS NULL THEN NULL WHEN NOT regexp_full_match({text}, {tf.string(pattern)}) THEN {invalid} "
        f"WHEN {millis} > 9223372036854775807 THEN {g.fail(tf.string('duration is too large'))} "
        f"ELSE to_milliseconds(CAST({millis} AS BIGINT)) END"
    )


#: The ISO 8601 date-times lakegate reads: a calendar date, optionally 'T' and hours[:minutes[:seconds
#: [.fraction]]], and no offset (the session zone, UTC) or 'Z'.
_ISO_DATETIME = (
    "([0-9]{4})-([0-9]{2})-([0-9]{2})(?:T([0-9]{2})(?::([0-9]{2})(?::([0-9]{2})(?:[.,]([0-9]{1,3}))?)?)?)?Z?"
)


def _from_iso8601_timestamp(call: Call) -> TType:
    """timestamp(3) with time zone: UTC for a text ending in Z, else the session zone (Joda reads a
    text without offset in it). The zone must be known from the query: a text that is not a literal
    is answered in a UTC session only (there both forms give UTC)."""
    need(call, "string")
    text, zone = literal_str(call, 0), call.analyzer.time_zone
    offset = re.search(r"T[0-9:.,]+([+-][0-9]{2}(?::?[0-9]{2})?)$", text.strip()) if text is not None else None
    if offset is not None:  # a literal's offset is the value's zone (Joda's withOffsetParsed)
        try:
            zone = zones.canonical(offset.group(1))
        except ValueError:
            call.fail(f'Invalid format: "{text}"', "INVALID_FUNCTION_ARGUMENT")
        call.node.meta["iso_text"] = text.strip()[: offset.start(1)]
    elif text is not None and text.rstrip().endswith("Z"):
        zone = zones.UTC
    elif text is None and zone != zones.UTC:
        call.fail(
            "unsupported in lakegate: from_iso8601_timestamp of a value that is not a literal outside a UTC "
            "session (a value with Z is in UTC, one without an offset in the session zone)",
            "NOT_SUPPORTED",
        )
    return tt.timestamp(3, True, zone)


def _render_from_iso8601_timestamp(g, node, args) -> str:
    """DateTimeFunctions.fromISO8601Timestamp (Joda's ISODateTimeFormat.dateTimeParser) for the
    common forms; other forms and offsets other than Z are refused: Trino keeps the offset as the
    value's zone, which lakegate's values carry when a literal names it (then read without it)."""
    text = tf.string(node.meta["iso_text"]) if "iso_text" in node.meta else g.sql(args[0])
    pattern = tf.string(_ISO_DATETIME)

    def part(index: int, default: str = "0") -> str:
        return f"CAST(coalesce(nullif(regexp_extract({text}, {pattern}, {index}), ''), '{default}') AS INTEGER)"

    millis = f"CAST(rpad(coalesce(nullif(regexp_extract({text}, {pattern}, 7), ''), '0'), 3, '0') AS INTEGER)"
    value = f"make_timestamp({part(1)}, {part(2)}, {part(3)}, {part(4)}, {part(5)}, {part(6)} + {millis} / 1000.0)"
    unsupported = g.fail(
        f"'from_iso8601_timestamp of ' || {text} || ' is not supported in lakegate "
        "(only yyyy-MM-dd[THH[:mm[:ss[.SSS]]]] with Z or no offset)'",
        "NOT_SUPPORTED",
    )
    out_of_range = g.fail(f"'Cannot parse \"' || {text} || '\": a field value is out of range'")
    valid = (
        f"{part(2)} BETWEEN 1 AND 12 AND {part(3)} BETWEEN 1 AND day(last_day(make_date({part(1)}, {part(2)}, 1))) "
        f"AND {part(4)} <= 23 AND {part(5)} <= 59 AND {part(6)} <= 59"
    )
    return (
        f"CASE WHEN {text} IS NULL THEN NULL WHEN NOT regexp_full_match({text}, {pattern}) THEN {unsupported} "
        f"WHEN NOT ({part(2)} BETWEEN 1 AND 12) OR NOT ({valid}) THEN {out_of_range} "
        f"ELSE {zones.instant(value, tt.zone_of(ttype(node)))} END"
    )


register(
    "to_milliseconds",
    "datetime",
    "to_milliseconds(interval) -> bigint",
    lambda c: tt.BIGINT if need(c, "any")[0].base in ("interval_ds", "unknown") else c.mismatch(),
    lambda g, node, args: f"CAST(epoch_ms({g.sql(args[0])}) AS BIGINT)",
)
register(
    "human_readable_seconds",
    "datetime",
    "human_readable_seconds(double) -> varchar",
    fixed(tt.VARCHAR, "number"),
    _render_human_readable_seconds,
)
register(
    "parse_duration",
    "datetime",
    "parse_duration(string) -> interval day to second",
    fixed(tt.INTERVAL_DS, "string"),
    _render_parse_duration,
)
register(
    "from_iso8601_timestamp",
    "datetime",
    "from_iso8601_timestamp(string) -> timestamp(3) with time zone",
    _from_iso8601_timestamp,
    _render_from_iso8601_timestamp,
    notes="yyyy-MM-dd[THH[:mm[:ss[.SSS]]]] with Z (UTC), no offset (the session zone) or, in a literal, "
    "an offset (its zone).",
)


# === regular expressions (io.trino.operator.scalar.JoniRegexpFunctions) =========================
def _regexp_position(call: Call) -> TType:
    regexp_call(call, tt.INTEGER, (2, 3, 4), "string", "string", "integer", "integer")
    if "\\G" in (literal_str(call, 1) or ""):
        call.fail("regexp_position with \\G is not supported in lakegate", "NOT_SUPPORTED")
    return tt.INTEGER


def _search(text: str, pattern: str, start: str) -> str:
    """[begin, next start] of the leftmost match at or after code point `start` ([-1, -1] if none):
    the match begins after the shortest prefix the pattern can follow. From a start past 1 the
    character before it is kept, unmatched, so that \\b and ^ see the text around the start as
    Joni's search from an offset does; the next search starts after the match, or one character on
    after an empty match (JoniRegexpFunctions.getNextStart)."""
    rest = f"substr({text}, greatest({start} - 1, 1))"
    before = f"CASE WHEN {start} > 1 THEN '(?s:.)' ELSE '' END"
    anchored = f"'^' || {before} || '((?s:.*?))(' || {pattern} || ')'"
    begin = f"{start} + length(regexp_extract({rest}, {anchored}, 1))"
    found = f"[{begin}, {begin} + greatest(length(regexp_extract({rest}, {anchored}, 2)), 1)]"
    return f"CASE WHEN regexp_matches({rest}, {anchored}) THEN {found} ELSE [-1, -1] END"


def _render_regexp_position(g, node, args) -> str:
    """JoniRegexpFunctions.regexpPosition: the code point position of the occurrence-th match
    searching from `start`, each search resuming where the last match ended; -1 when there is none."""
    text, pattern = sqls(g, args[:2])
    start = f"CAST({g.sql(args[2])} AS BIGINT)" if len(args) >= 3 else "1"
    occurrence = f"CAST({g.sql(args[3])} AS BIGINT)" if len(args) == 4 else "1"
    resume = '"_at"[2]'
    step = f'lambda "_at", "_n": CASE WHEN "_at"[1] < 0 THEN "_at" ELSE {_search(text, pattern, resume)} END'
    # each match takes at least one step forward, so more occurrences than length + 1 cannot exist
    position = f"list_reduce(range({occurrence}), {step}, [0, {start}])[1]"
    checks = [
        (f"{start} < 1", "start position cannot be smaller than 1"),
        (f"{occurrence} < 1", "occurrence cannot be smaller than 1"),
    ]
    whens = " ".join(f"WHEN {c} THEN {g.fail(tf.string(m))}" for c, m in checks)
    nulls = " OR ".join(f"({g.sql(a)}) IS NULL" for a in args)
    return (
        f"CASE WHEN {nulls} THEN NULL {whens} WHEN {start} > length({text}) OR {occurrence} > length({text}) + 1 "
        f"THEN -1 ELSE CAST({position} AS INTEGER) END"
    )


register(
    "regexp_position",
    "regexp",
    "regexp_position(string, pattern[, start[, occurrence]]) -> integer",
    _regexp_position,
    _render_regexp_position,
)


# === URL (io.trino.operator.scalar.UrlFunctions over java.net.URI) ==============================
#: What java.net.URI reads, for the ASCII URLs lakegate answers: every character is a URI character
#: (no space, quote, <, >, \, ^, `, {, |, } or control), '%' starts a two-digit escape, one '#' at
#: most. '[' / ']' (IPv6 hosts) and non-ASCII characters are refused.
_URI_CHARS = "(?:[A-Za-z0-9_.!~*'();/?:@&=+$,#-]|%[0-9A-Fa-f]{2})*"
#: RFC 3986 appendix B: 1 scheme, 2 authority, 3 path, 4 query, 5 fragment.
_URI_PARTS = "^(?:([^:/?#]+):)?(?://([^/?#]*))?([^?#]*)(?:[?]([^#]*))?(?:#(.*))?$"
_LABEL = "[A-Za-z0-9](?:[A-Za-z0-9-]*[A-Za-z0-9])?"
_TOP_LABEL = "[A-Za-z](?:[A-Za-z0-9-]*[A-Za-z0-9])?"
_BYTE = "0*(?:25[0-5]|2[0-4][0-9]|1[0-9][0-9]|[1-9]?[0-9])"
#: A server-based authority (URI.Parser.parseServer): [userinfo@]host[:port], the host an IPv4
#: address or a hostname whose last label starts with a letter when there are several; any other
#: authority is registry-based, and has no host or port.
_SERVER = (
    "^(?:(?:[A-Za-z0-9_.!~*'();:&=+$,-]|%[0-9A-Fa-f]{2})*@)?"
    f"((?:{_BYTE}[.]){{3}}{_BYTE}|(?:{_LABEL}|(?:{_LABEL}[.])+{_TOP_LABEL})[.]?)(?::([0-9]*))?$"
)


def _escapes_utf8(sql: str) -> str:
    """Whether every run of %XX escapes in `sql` spells well-formed UTF-8 (each run decodes alone,
    as URLDecoder and URI.decode do)."""
    runs = f"regexp_extract_all({sql}, '(?:%[0-9A-Fa-f]{{2}})+')"
    run_hex = "upper(replace(\"_r\", '%', ''))"
    return f'len(list_filter({runs}, lambda "_r": NOT {utf8_valid(run_hex)})) = 0'


class _Url:
    """The parts of a URL as java.net.URI gives them, as DuckDB SQL over the URL's SQL."""

    def __init__(self, g, sql: str):
        self.g, self.sql = g, sql

    def part(self, index: int) -> str:
        return f"regexp_extract({self.sql}, {tf.string(_URI_PARTS)}, {index})"

    def has(self, index: int) -> str:
        """Whether the part is present (an empty query or fragment is present, unlike a missing one)."""
        marker = {2: "^(?:[^:/?#]+:)?//", 4: "^[^#]*[?]", 5: "#"}[index]
        return f"regexp_matches({self.sql}, {tf.string(marker)})"

    def opaque(self) -> str:
        """scheme:rest with rest not starting with '/': no authority, path or query (URI.getPath() null)."""
        return f"({self.part(1)} <> '' AND NOT starts_with({self.part(3)}, '/') AND NOT {self.has(2)})"

    def invalid(self) -> str:
        """What java.net.URI refuses (URISyntaxException): the URL functions then give NULL."""
        scheme = self.part(1)
        return (
            f"(NOT regexp_full_match({self.sql}, {tf.string(_URI_CHARS)}) "
            f"OR starts_with({self.sql}, ':') "
            f"OR ({scheme} <> '' AND NOT regexp_full_match({scheme}, '[A-Za-z][A-Za-z0-9+.-]*')) "
            f"OR ({scheme} <> '' AND regexp_full_match({self.sql}, '[^:/?#]+:(#.*)?')) "
            f"OR regexp_full_match({self.sql}, '(?:[^:/?#]+:)?//'))"
        )

    def guarded(self, value: str) -> str:
        """`value`, NULL for a URL java.net.URI refuses; non-ASCII and IPv6 URLs are refused."""
        message = tf.string("URLs with non-ASCII characters or IPv6 hosts are not supported in lakegate")
        return (
            f"CASE WHEN {self.sql} IS NULL THEN NULL "
            f"WHEN regexp_matches({self.sql}, '[^\\x00-\\x7F]|[\\[\\]]') THEN {self.g.fail(message, 'NOT_SUPPORTED')} "
            f"WHEN {self.invalid()} THEN NULL ELSE {value} END"
        )

    def server(self, index: int) -> str:
        """Group `index` of the server-based authority (1 host, 2 port), '' when registry-based."""
        return f"regexp_extract({self.part(2)}, {tf.string(_SERVER)}, {index})"

    def decoded(self, sql: str) -> str:
        """java.net.URI's decoding of escapes (URI.decode); invalid UTF-8 is refused."""
        message = tf.string("URL escapes that are not UTF-8 are not supported in lakegate")
        return f"CASE WHEN {_escapes_utf8(sql)} THEN url_decode({sql}) ELSE {self.g.fail(message, 'NOT_SUPPORTED')} END"


def _render_url_part(part: str) -> Render:
    def render(g, node, args) -> str:
        url = _Url(g, g.sql(args[0]))
        if part == "protocol":
            value = url.part(1)
        elif part == "host":
            value = f"CASE WHEN {url.opaque()} THEN '' ELSE {url.server(1)} END"
        elif part == "port":
            port = url.server(2)
            value = (
                f"CASE WHEN {url.opaque()} OR {port} = '' OR length({port}) > 10 "
                f"OR CAST({port} AS BIGINT) > 2147483647 THEN NULL ELSE CAST({port} AS BIGINT) END"
            )
        elif part == "path":
            value = f"CASE WHEN {url.opaque()} THEN '' ELSE {url.decoded(url.part(3))} END"
        elif part == "query":
            value = f"CASE WHEN {url.opaque()} THEN '' ELSE {url.decoded(url.part(4))} END"
        else:
            value = url.decoded(url.part(5))
        return url.guarded(value)

    return render


def _url_decoder(g, sql: str) -> str:
    """java.net.URLDecoder.decode: '+' is a space, %XX escapes are UTF-8 bytes; a bad escape fails,
    invalid UTF-8 is refused."""
    bad = g.fail(f"'URLDecoder: Illegal hex characters in escape (%) pattern: ' || {sql}")
    message = tf.string("URL escapes that are not UTF-8 are not supported in lakegate")
    plain = f"replace({sql}, '+', ' ')"
    decoded = f"CASE WHEN {_escapes_utf8(plain)} THEN url_decode({plain}) ELSE {g.fail(message, 'NOT_SUPPORTED')} END"
    return (
        f"CASE WHEN {sql} IS NULL THEN NULL WHEN regexp_matches({sql}, '%(?:[^0-9A-Fa-f]|.[^0-9A-Fa-f]|.?$)') "
        f"THEN {bad} ELSE {decoded} END"
    )


def _render_url_parameter(g, node, args) -> str:
    """UrlFunctions.urlExtractParameter: the raw query split on '&', each argument on its first '=';
    the first whose name is `name` gives its URLDecoder-decoded value ('' without '='); NULL if none."""
    url, name = _Url(g, g.sql(args[0])), g.sql(args[1])
    pairs = f"string_split({url.part(4)}, '&')"
    first = f'list_filter({pairs}, lambda "_a": split_part("_a", \'=\', 1) = {name})[1]'
    raw_value = f"CASE WHEN strpos({first}, '=') = 0 THEN '' ELSE substr({first}, strpos({first}, '=') + 1) END"
    value = (
        f"CASE WHEN {url.opaque()} OR NOT {url.has(4)} OR {first} IS NULL THEN NULL "
        f"ELSE {_url_decoder(g, raw_value)} END"
    )
    return f"CASE WHEN {name} IS NULL THEN NULL ELSE {url.guarded(value)} END"


#: Guava's UrlEscapers.urlFormParameterEscaper: letters, digits and "-_.*" stay, a space is '+',
#: every other byte of the UTF-8 text is %XX (upper case).
def _render_url_encode(g, node, args) -> str:
    text = g.sql(args[0])
    byte = '"_h"'
    char = f"chr(CAST('0x' || {byte} AS INTEGER))"
    kept = f"regexp_full_match({char}, '[A-Za-z0-9*._-]')"
    escaped = f"CASE WHEN {byte} = '20' THEN '+' WHEN {kept} THEN {char} ELSE '%' || {byte} END"
    return (
        f"CASE WHEN {text} IS NULL THEN NULL ELSE array_to_string(list_transform("
        f"regexp_extract_all(hex(encode({text})), '..'), lambda {byte}: {escaped}), '') END"
    )


def _text_same(*kinds: str) -> Callable[[Call], TType]:
    """The first argument's varchar(x) type (unbounded varchar for NULL)."""

    def infer(call: Call) -> TType:
        t = need(call, *kinds)[0]
        return t if t.base == "varchar" else tt.VARCHAR

    return infer


for _part in ("protocol", "host", "path", "query", "fragment"):
    register(
        f"url_extract_{_part}",
        "url",
        f"url_extract_{_part}(url) -> varchar",
        _text_same("string"),
        _render_url_part(_part),
        notes="NULL for a URL java.net.URI refuses, '' for a missing part; non-ASCII and IPv6 URLs are refused.",
    )
register(
    "url_extract_port",
    "url",
    "url_extract_port(url) -> bigint",
    fixed(tt.BIGINT, "string"),
    _render_url_part("port"),
    notes="Non-ASCII and IPv6 URLs are refused.",
)
register(
    "url_extract_parameter",
    "url",
    "url_extract_parameter(url, name) -> varchar",
    _text_same("string", "string"),
    _render_url_parameter,
    notes="Non-ASCII and IPv6 URLs are refused.",
)


def _url_encode(call: Call) -> TType:
    """varchar(min(2147483647, 12 x)) for varchar(x) (UrlFunctions.urlEncode's constraint)."""
    t = need(call, "string")[0]
    length = tt.varchar_length(t) if t.base == "varchar" else None
    return tt.VARCHAR if length is None else tt.varchar(min(2147483647, 12 * length))


register(
    "url_encode",
    "url",
    "url_encode(value) -> varchar",
    _url_encode,
    _render_url_encode,
)
register(
    "url_decode",
    "url",
    "url_decode(value) -> varchar",
    _text_same("string"),
    lambda g, node, args: _url_decoder(g, g.sql(args[0])),
    notes="Escapes that decode to invalid UTF-8 are refused.",
)


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


def _joda_field(call: Call, run: str) -> str:
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
    pieces = [tf.string(text) if kind == "text" else _joda_field(call, text) for kind, text in _joda_tokens(pattern)]
    call.node.meta["joda"] = " || ".join(pieces) or "''"
    return tt.VARCHAR


def _render_format_datetime(g, node, args) -> str:
    value = g.sql(args[0])
    if ttype(args[0]).base == "timestamp_tz":
        value = f"timezone('UTC', {value})"
    return f'list_transform([CAST({value} AS TIMESTAMP)], lambda "_t": {node.meta["joda"]})[1]'


register(
    "format_datetime",
    "datetime",
    "format_datetime(timestamp, format) -> varchar",
    _format_datetime,
    _render_format_datetime,
    notes="A literal Joda-Time pattern; the time zone fields z and Z are refused.",
)


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
        tf.string(text) if kind == "text" else _joda_field(call, _TERADATA[text][0])
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


register(
    "to_char",
    "datetime",
    "to_char(timestamp, format) -> varchar (Teradata)",
    _to_char,
    _render_format_datetime,
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


register(
    "format_number",
    "conversion",
    "format_number(number) -> varchar",
    fixed(tt.VARCHAR, "number"),
    _render_format_number,
)


# === issue 14 family 5, second part ===============================================================
# --- normalize(string, form) (StringFunctions.normalize; AstBuilder.visitNormalize passes the form
# keyword NFC | NFD | NFKC | NFKD as the string it is written as) ----------------------------------
_NORMAL_FORMS = ("NFD", "NFC", "NFKD", "NFKC")


def _normalize_form(call: Call) -> TType | None:
    if len(call.args) != 2:
        return None
    need(call, "string", "string")
    form = literal_str(call, 1)
    if form is None and not call.types[1].is_unknown:
        call.fail("normalize with a non-literal form is not supported in lakegate", "NOT_SUPPORTED")
    if form in _NORMAL_FORMS and form != "NFC":
        call.fail(f"normalize with the form {form} is not supported in lakegate (only NFC)", "NOT_SUPPORTED")
    call.node.meta["normal_form"] = form
    return tt.VARCHAR


def _render_normalize_form(g, node, args) -> str:
    """NFC is DuckDB's nfc_normalize; another form is Normalizer.Form.valueOf's error at run time
    (a NULL argument gives NULL first)."""
    value, form = g.sql(args[0]), node.meta["normal_form"]
    if form is None:
        return "CAST(NULL AS VARCHAR)"
    if form == "NFC":
        return f"nfc_normalize({value})"
    message = tf.string("Normalization form must be one of [NFD, NFC, NFKD, NFKC]")
    return f"CASE WHEN ({value}) IS NULL THEN NULL ELSE {g.fail(message)} END"


overload("normalize", _normalize_form, _render_normalize_form, "normalize(string, form) -> varchar")


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


register(
    "parse_datetime",
    "datetime",
    "parse_datetime(string, format) -> timestamp(3) with time zone",
    _parse_datetime,
    _render_parse_datetime,
    notes="A literal Joda-Time pattern of the number fields yyyy M d H m s S and literals; other fields are refused.",
)


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


register(
    "soundex",
    "string",
    "soundex(string) -> varchar(4)",
    fixed(tt.varchar(4), "string"),
    _render_soundex,
    notes="ASCII text; non-ASCII text is refused.",
)


# --- regexp_replace(string, pattern, function) (JoniRegexpReplaceLambdaFunction) ----------------
def _regexp_replace_lambda(call: Call) -> TType | None:
    """The lambda gets each match's capturing groups as array(varchar). Patterns that can match the
    empty string (Joni then steps one code point on) or have a group that may not take part (Joni
    passes NULL, DuckDB '') are refused."""
    if len(call.args) != 3 or not isinstance(call.args[2], exp.Lambda):
        return None
    call.types[2] = call.lam(2, [tt.array(tt.VARCHAR)])  # the lambda's result stands for it in the checks
    regexp_call(call, tt.VARCHAR, (3,), "string", "string", "string")
    pattern = literal_str(call, 1)
    if pattern is None:
        call.fail("regexp_replace with a lambda needs a literal pattern in lakegate", "NOT_SUPPORTED")
    try:
        empty = re_parser.parse(pattern).getwidth()[0] == 0
    except re.error:
        call.fail(
            f"regexp_replace with a lambda and the pattern '{pattern}' is not supported in lakegate", "NOT_SUPPORTED"
        )
    groups = capturing_groups(pattern)
    if empty or any(optional for _, optional, _ in groups):
        reason = "may match the empty string" if empty else "has a capturing group that may not take part in a match"
        call.fail(f"regexp_replace with a lambda whose pattern {reason} is not supported in lakegate", "NOT_SUPPORTED")
    call.node.meta["group_count"] = len(groups)
    return tt.VARCHAR


def _render_regexp_replace_lambda(g, node, args) -> str:
    """The text between the matches (string_split_regex), each match's groups (regexp_extract_all)
    through the lambda in between; a NULL replacement makes the result NULL."""
    value, pattern = g.sql(args[0]), g.sql(args[1])
    groups = ", ".join(
        f'regexp_extract_all({value}, {pattern}, {k})["_i"]' for k in range(1, node.meta["group_count"] + 1)
    )
    matches = f"len(regexp_extract_all({value}, {pattern}))"
    arrays = f'list_transform(range(1, {matches} + 1), lambda "_i": CAST([{groups}] AS VARCHAR[]))'
    pieces = f"string_split_regex({value}, {pattern})"
    between = f'list_transform(range(1, len("_r") + 1), lambda "_j": "_r"["_j"] || {pieces}["_j" + 1])'
    joined = (
        f'CASE WHEN len(list_filter("_r", lambda "_x": "_x" IS NULL)) > 0 THEN NULL '
        f"ELSE {pieces}[1] || array_to_string({between}, '') END"
    )
    replaced = f"list_transform({arrays}, {g.lambda_(args[2])})"
    return f'CASE WHEN ({value}) IS NULL THEN NULL ELSE list_transform([{replaced}], lambda "_r": {joined})[1] END'


overload(
    "regexp_replace",
    _regexp_replace_lambda,
    _render_regexp_replace_lambda,
    "regexp_replace(string, pattern, function(array(varchar), varchar)) -> varchar",
)
