"""Trino's functions/binary.md. Binary functions and operators: varbinary, its encodings, hashes and HMACs.

The hashes DuckDB has no exact equivalent of (sha512, hmac_sha512, xxhash64, murmur3,
spooky_hash_v2_32/64) are calls of Python functions that lakegate.gateway.engine.udfs registers on
every DuckDB connection the engine opens, named `UDF_PREFIX` + the Trino name; `UDFS` lists them
with their arity (varbinary arguments, varbinary result; NULL in, NULL out).
"""

from __future__ import annotations

from collections.abc import Callable

from sqlglot import exp

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.arguments import VARBINARY, binary_args, binary_in, fixed, need
from lakegate.dialect.functions.rendering import sqls, utf8_valid
from lakegate.dialect.registry import Infer, Render, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype

_TEXT_OR_BINARY = ("varchar", "varbinary", "unknown")


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
        return hmac_key_checked(message, key, f"unhex({duck}({padded(0x5C)} || {inner}))")

    return render


def hmac_key_checked(message: str, key: str, sql: str) -> str:
    """`sql`, or the error the real Trino 476 raises for an empty HMAC key (javax.crypto's
    SecretKeySpec: GENERIC_INTERNAL_ERROR 'Empty key'), not caught by try(); NULL for a NULL
    message (the call is null-propagating: the key is never looked at)."""
    empty = f"error({tf.string('GENERIC_INTERNAL_ERROR: Empty key')})"
    return (
        f"CASE WHEN {message} IS NULL THEN NULL WHEN octet_length(CAST({key} AS BLOB)) = 0 THEN {empty} ELSE {sql} END"
    )


#: Functions of bytes that never fail nor give NULL for a non-NULL argument: a call of them over
#: constants is a constant Trino's planner folds.
_PURE_BYTES = frozenset(
    "to_utf8 reverse md5 sha1 sha256 sha512 xxhash64 murmur3 spooky_hash_v2_32 spooky_hash_v2_64".split()
)
#: Nodes of a condition that is a constant which cannot fail (literals, NULL, logic and comparisons).
_SAFE_CONDITION = (
    exp.Literal,
    exp.Null,
    exp.Boolean,
    exp.Paren,
    exp.Not,
    exp.And,
    exp.Or,
    exp.Is,
    exp.Neg,
    exp.DataType,
    exp.EQ,
    exp.NEQ,
    exp.GT,
    exp.GTE,
    exp.LT,
    exp.LTE,
)


def _safe_condition(node: exp.Expression) -> bool:
    return all(
        isinstance(n, _SAFE_CONDITION) or (isinstance(n, exp.Cast) and isinstance(n.this, exp.Null))
        for n in node.walk()
    )


def _branches(node: exp.Expression) -> list[exp.Expression] | None:
    """The results a CASE or IF of safe constant conditions (and operand) may give, None otherwise
    (one without ELSE may give NULL)."""
    if isinstance(node, exp.If) and _safe_condition(node.this) and node.args.get("false") is not None:
        return [node.args["true"], node.args["false"]]
    if isinstance(node, exp.Case) and node.args.get("default") is not None:
        operand = node.this
        if (operand is None or _safe_condition(operand)) and all(_safe_condition(i.this) for i in node.args["ifs"]):
            return [*(i.args["true"] for i in node.args["ifs"]), node.args["default"]]
    return None


def _constant_bytes(node: exp.Expression) -> bool:
    """Whether `node` is a non-NULL constant that Trino's planner folds without failing."""
    while isinstance(node, exp.Paren):
        node = node.this
    if isinstance(node, exp.HexString) or (isinstance(node, exp.Literal) and node.is_string):
        return True
    if isinstance(node, exp.Anonymous) and node.name.lower() in _PURE_BYTES:
        return len(node.expressions) == 1 and _constant_bytes(node.expressions[0])
    branches = _branches(node)
    return branches is not None and all(map(_constant_bytes, branches))


def _empty_key(node: exp.Expression) -> bool:
    """Whether `node` is a constant that is X'' whatever branch is taken."""
    while isinstance(node, exp.Paren):
        node = node.this
    if isinstance(node, exp.HexString):
        return not node.this
    if isinstance(node, exp.Anonymous) and node.name.lower() == "coalesce" and node.expressions:
        return _empty_key(node.expressions[0])
    branches = _branches(node)
    return branches is not None and all(map(_empty_key, branches))


def _planning_failure(call: Call) -> None:
    """An HMAC of a constant message with a constant empty key fails while planning, as in Trino, whose
    planner folds it (the 'Empty key' error is not one it defers): even over no rows."""
    if _empty_key(call.args[1]) and _constant_bytes(call.args[0]):
        call.fail("Empty key", "GENERIC_INTERNAL_ERROR")


def _hmac_args(call: Call) -> TType:
    """Two varbinary arguments (see `_planning_failure`)."""
    if not binary_args(call, 2):
        call.mismatch()
    _planning_failure(call)
    return VARBINARY


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


#: The prefix of the DuckDB names of these functions (not callable from Trino SQL: the analyzer
#: knows only registered names).
UDF_PREFIX = "lakegate_"


#: Trino name -> (number of varbinary arguments, signature as Trino documents it).
UDFS: dict[str, tuple[int, str]] = {
    "sha512": (1, "sha512(binary) -> varbinary"),
    "hmac_sha512": (2, "hmac_sha512(binary, key) -> varbinary"),
    "xxhash64": (1, "xxhash64(binary) -> varbinary"),
    "murmur3": (1, "murmur3(binary) -> varbinary"),
    "spooky_hash_v2_32": (1, "spooky_hash_v2_32(binary) -> varbinary"),
    "spooky_hash_v2_64": (1, "spooky_hash_v2_64(binary) -> varbinary"),
}


def _udf_binary_args(count: int) -> Infer:
    def infer(call: Call) -> tt.TType:
        if len(call.args) != count or any(t is None or t.base not in ("varbinary", "unknown") for t in call.types):
            call.mismatch()
        if call.name.startswith("hmac_"):
            _planning_failure(call)
        return tt.VARBINARY

    return infer


def _render(name: str) -> Render:
    def render(g, node, args) -> str:
        values = sqls(g, args)
        sql = f"{UDF_PREFIX}{name}({', '.join(values)})"
        return hmac_key_checked(values[0], values[1], sql) if name.startswith("hmac_") else sql

    return render


def install() -> None:
    """Register the functions of this page (called by pages.py)."""
    register("to_base64", "binary", "to_base64(binary) -> varchar", binary_in(tt.VARCHAR), _render_to_base64(False))
    register(
        "to_base64url", "binary", "to_base64url(binary) -> varchar", binary_in(tt.VARCHAR), _render_to_base64(True)
    )
    register(
        "from_base64", "binary", "from_base64(string) -> varbinary", _text_in(VARBINARY), _render_from_base64(False)
    )
    register(
        "from_base64url",
        "binary",
        "from_base64url(string) -> varbinary",
        _text_in(VARBINARY),
        _render_from_base64(True),
    )
    register(
        "to_hex", "binary", "to_hex(binary) -> varchar", binary_in(tt.VARCHAR), lambda g, n, a: f"hex({g.sql(a[0])})"
    )
    register("from_hex", "binary", "from_hex(string) -> varbinary", _text_in(VARBINARY), _render_from_hex)
    register("md5", "binary", "md5(binary) -> varbinary", binary_in(VARBINARY), _hash("md5"))
    register("sha1", "binary", "sha1(binary) -> varbinary", binary_in(VARBINARY), _hash("sha1"))
    register("sha256", "binary", "sha256(binary) -> varbinary", binary_in(VARBINARY), _hash("sha256"))
    register("crc32", "binary", "crc32(binary) -> bigint", binary_in(tt.BIGINT), _render_crc32)
    for _name, _duck in (("hmac_md5", "md5"), ("hmac_sha1", "sha1"), ("hmac_sha256", "sha256")):
        register(
            _name,
            "binary",
            f"{_name}(binary, key) -> varbinary",
            _hmac_args,
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
        binary_in(tt.BIGINT),
        _render_from_big_endian(8, "BIGINT"),
    )
    register(
        "from_big_endian_32",
        "binary",
        "from_big_endian_32(binary) -> integer",
        binary_in(tt.INTEGER),
        _render_from_big_endian(4, "INTEGER"),
    )

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
        "from_ieee754_64", "binary", "from_ieee754_64(binary) -> double", binary_in(tt.DOUBLE), _render_from_ieee754(64)
    )
    register(
        "from_ieee754_32", "binary", "from_ieee754_32(binary) -> real", binary_in(tt.REAL), _render_from_ieee754(32)
    )

    register("to_base32", "binary", "to_base32(binary) -> varchar", binary_in(tt.VARCHAR), _render_to_base32)
    register("from_base32", "binary", "from_base32(string) -> varbinary", _text_in(VARBINARY), _render_from_base32)

    for _name, (_count, _signature) in UDFS.items():
        register(_name, "binary", _signature, _udf_binary_args(_count), _render(_name))
