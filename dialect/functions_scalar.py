"""Scalar functions of issue 14 family 5: VARBINARY and its encodings and hashes, strings, numbers
and dates that translate exactly. Registered into `functions.SUPPORTED` when `functions` is
imported; the Trino overloads of functions registered there (length(varbinary), ...) are added with
`overload`.

Sources are trinodb/trino core/trino-main/src/main/java/io/trino/operator/scalar/*.java, cited per
function; each function has conformance cases in tests/dialect/cases/cov_*.yaml.
"""

from __future__ import annotations

from collections.abc import Callable

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.analyze import Call, ttype
from lakegate.dialect.functions import SUPPORTED, Render, fixed, need, register, sqls
from lakegate.dialect.trino_types import TType

VARBINARY = tt.VARBINARY


def overload(name: str, accepts: Callable[[Call], TType | None], render: Render, signature: str) -> None:
    """Add a Trino overload to the registered function `name`: `accepts` types the calls it takes
    (None for the others, which keep the registered rule) and `render` writes them."""
    base = SUPPORTED[name]

    def infer(call: Call) -> TType:
        result = accepts(call)
        if result is None:
            return base.infer(call)
        call.node.meta["overload"] = render
        return result

    def render_either(g, node, args) -> str:
        return node.meta.get("overload", base.render)(g, node, args)

    register(name, base.family, f"{base.signature}; {signature}", infer, render_either, base.kind, base.notes)


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


# === varbinary (io.trino.operator.scalar.VarbinaryFunctions, HmacFunctions) =====================
_KINDS_BINARY = ("varbinary", "unknown")
_TEXT_OR_BINARY = ("varchar", "varbinary", "unknown")


def _binary_in(*result: TType) -> Callable[[Call], TType]:
    """One varbinary argument; the result type."""

    def infer(call: Call) -> TType:
        if len(call.args) != 1 or call.types[0] is None or call.types[0].base not in _KINDS_BINARY:
            call.mismatch()
        return result[0]

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
    return f"CASE WHEN ({sql}) IS NULL THEN NULL ELSE coalesce(try(decode({sql})), '!') END"


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
        return f"unhex({duck}({padded(0x5C)} || {inner}))"

    return render


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
        f"CASE WHEN {value} IS NULL THEN NULL WHEN try(decode({value})) IS NULL THEN "
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
for _name in ("substr", "substring"):
    overload(_name, _substr_binary, _render_substr_binary, "substr(binary, start[, length]) -> varbinary")
overload(
    "reverse",
    lambda c: VARBINARY if _binary_args(c, 1) else None,
    _render_reverse_binary,
    "reverse(binary) -> varbinary",
)
