"""Trino's functions/url.md. URL functions (io.trino.operator.scalar.UrlFunctions over java.net.URI)."""

from __future__ import annotations

from collections.abc import Callable

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.arguments import fixed, need
from lakegate.dialect.functions.rendering import utf8_valid
from lakegate.dialect.registry import Render, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call

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


def _url_encode(call: Call) -> TType:
    """varchar(min(2147483647, 12 x)) for varchar(x) (UrlFunctions.urlEncode's constraint)."""
    t = need(call, "string")[0]
    length = tt.varchar_length(t) if t.base == "varchar" else None
    return tt.VARCHAR if length is None else tt.varchar(min(2147483647, 12 * length))


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

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
