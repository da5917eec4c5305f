"""Trino's IPADDRESS type (io.trino.type.IpAddressType): its DuckDB representation, the text Trino reads
(Guava's InetAddresses.forString) and writes (InetAddresses.toAddrString), and its casts.

An IPADDRESS is held as a DuckDB BLOB of 16 bytes, the address's IPv6 form (an IPv4 address as
::ffff:a.b.c.d), as Trino holds it: DuckDB orders BLOBs byte by byte, which is Trino's order, and
CAST to varbinary is the BLOB itself. Text is read as Guava reads it: four decimal octets without
leading zeros, or eight groups of one to four hex digits, one `::` standing for one group or more, the
last two groups optionally a dotted IPv4 address, and after a `%` a numeric scope (dropped; a scope
naming a network interface, which Trino resolves on its server, is refused as invalid). Text is
written as Guava writes it: an IPv4-mapped address dotted, any other in lower-case hex groups without
leading zeros, the longest run of two or more zero groups (the first of equal runs) as `::`.
"""

from __future__ import annotations

import re

from lakegate.dialect.transforms import string
from lakegate.dialect.trino_types import TType

#: The twelve bytes before an IPv4 address in its IPv6 form (::ffff:0:0/96), as upper-case hex.
MAPPED_PREFIX = "00000000000000000000FFFF"

_OCTET = "(?:25[0-5]|2[0-4][0-9]|1[0-9][0-9]|[1-9]?[0-9])"
IPV4 = rf"{_OCTET}(?:\.{_OCTET}){{3}}"
_GROUP = "[0-9A-Fa-f]{1,4}"
_GROUPS = rf"(?:{_GROUP}(?::{_GROUP})*)?"
#: IPv6 text without an embedded IPv4 address or a scope: eight groups, or at most seven around one `::`.
IPV6 = rf"(?:{_GROUP}(?::{_GROUP}){{7}}|{_GROUPS}::{_GROUPS})"
#: A scope Java's Integer.parseInt reads (a number; an empty scope is dropped too).
SCOPE = "%(?:[+-]?[0-9]{1,9})?"


def parse(text: str) -> bytes | None:
    """The 16 bytes of an address text as Guava reads it, None when it is not one."""
    if re.fullmatch(IPV4, text):
        return bytes.fromhex(MAPPED_PREFIX) + bytes(int(octet) for octet in text.split("."))
    if "." not in text:
        text = re.sub(f"{SCOPE}$", "", text)
    elif (dotted := re.fullmatch(rf"(.*:)({IPV4})", text)) is not None:
        octets = [int(octet) for octet in dotted[2].split(".")]
        text = f"{dotted[1]}{octets[0] * 256 + octets[1]:x}:{octets[2] * 256 + octets[3]:x}"
    if not re.fullmatch(IPV6, text):
        return None
    head, skip, tail = text.partition("::")
    groups = [g for g in head.split(":") if g], [g for g in tail.split(":") if g]
    if skip and len(groups[0]) + len(groups[1]) > 7:
        return None
    words = groups[0] + ["0"] * (8 - len(groups[0]) - len(groups[1])) + groups[1]
    return bytes.fromhex("".join(w.rjust(4, "0") for w in words))


def constant(value: bytes) -> str:
    """An address as a DuckDB constant."""
    return f"unhex('{value.hex().upper()}')"


# --- DuckDB SQL ------------------------------------------------------------------------------------
def _let(value: str, name: str, body: str) -> str:
    return f"list_transform([{value}], lambda {name}: {body})[1]"


def _hextets(v4: str) -> str:
    """The two hex groups of a dotted IPv4 text."""
    octets = [f"CAST(string_split({v4}, '.')[{i}] AS INTEGER)" for i in range(1, 5)]
    return f"printf('%x:%x', {octets[0]} * 256 + {octets[1]}, {octets[2]} * 256 + {octets[3]})"


def parsed(text: str) -> str:
    """SQL of the BLOB a VARCHAR `text` reads as (see `parse`), NULL when it is no address."""
    t, v6 = '"_ip"', '"_v6"'
    v4_hex = " || ".join(f"printf('%02X', CAST(string_split({t}, '.')[{i}] AS INTEGER))" for i in range(1, 5))
    dotted = f"(.*:)({IPV4})"
    v6_text = (
        f"CASE WHEN NOT contains({t}, '.') THEN regexp_replace({t}, {string(SCOPE + '$')}, '') "
        f"WHEN regexp_full_match({t}, {string(dotted)}) THEN regexp_extract({t}, {string(dotted)}, 1) || "
        f"{_hextets(f'regexp_extract({t}, {string(dotted)}, 2)')} END"
    )
    head, tail = f"split_part({v6}, '::', 1)", f"split_part({v6}, '::', 2)"
    head_groups = f"CASE WHEN {head} = '' THEN []::VARCHAR[] ELSE string_split({head}, ':') END"
    tail_groups = f"CASE WHEN {tail} = '' THEN []::VARCHAR[] ELSE string_split({tail}, ':') END"
    count = f"(len({head_groups}) + len({tail_groups}))"
    words = (
        f"CASE WHEN contains({v6}, '::') THEN list_concat({head_groups}, "
        f"list_transform(range(8 - {count}), lambda \"_z\": '0'), {tail_groups}) "
        f"ELSE string_split({v6}, ':') END"
    )
    v6_hex = f"array_to_string(list_transform({words}, lambda \"_w\": lpad(\"_w\", 4, '0')), '')"
    valid = f"regexp_full_match({v6}, {string(IPV6)}) AND (NOT contains({v6}, '::') OR {count} <= 7)"
    v6_bytes = _let(v6_text, v6, f"CASE WHEN {valid} THEN unhex({v6_hex}) END")
    body = (
        f"CASE WHEN regexp_full_match({t}, {string(IPV4)}) THEN unhex('{MAPPED_PREFIX}' || {v4_hex}) "
        f"ELSE {v6_bytes} END"
    )
    return _let(text, t, body)


def text(value: str) -> str:
    """SQL of the VARCHAR Trino writes for the address BLOB `value` (see the module's docstring)."""
    h = '"_h"'
    octets = ".".join(f"' || CAST(('0x' || substr({h}, {25 + 2 * i}, 2)) AS INTEGER) || '" for i in range(4))
    dotted = f"'{octets}'"
    groups = " || ':' || ".join(f"coalesce(nullif(ltrim(substr({h}, {1 + 4 * i}, 4), '0'), ''), '0')" for i in range(8))
    s = '"_s"'
    runs = " ".join(
        f"WHEN contains({s}, '{':0' * n}:') THEN regexp_replace({s}, '{':0' * n}:', '::')" for n in range(8, 1, -1)
    )
    compressed = f"CASE {runs} ELSE {s} END"
    c = '"_c"'
    trimmed = f"CASE WHEN starts_with({c}, '::') THEN {c} ELSE substr({c}, 2) END"
    trimmed = _let(trimmed, c, f"CASE WHEN ends_with({c}, '::') THEN {c} ELSE left({c}, -1) END")
    hex_text = _let(compressed, c, trimmed)
    v6 = _let(f"lower(':' || {groups} || ':')", s, hex_text)
    body = f"CASE WHEN starts_with({h}, '{MAPPED_PREFIX}') THEN {dotted} ELSE {v6} END"
    return _let(f"hex({value})", h, body)


def from_varbinary(g, value: str) -> str:
    """SQL of CAST(varbinary AS ipaddress): 16 bytes as they are, 4 as an IPv4 address, any other length
    Trino's INVALID_CAST_ARGUMENT (IpAddressOperators.castFromVarbinaryToIpAddress)."""
    message = f"'Invalid IP address binary length: ' || octet_length({value})"
    return (
        f"CASE octet_length({value}) WHEN 16 THEN {value} WHEN 4 THEN unhex('{MAPPED_PREFIX}') || {value} "
        f"ELSE {g.fail(message, 'INVALID_CAST_ARGUMENT')} END"
    )


def from_varchar(g, value: str) -> str:
    """SQL of CAST(varchar AS ipaddress), Trino's INVALID_CAST_ARGUMENT for a text that is no address."""
    given, read = '"_in"', '"_a"'
    message = f"'Cannot cast value to IPADDRESS: ' || {given}"
    failed = f"CASE WHEN {read} IS NULL THEN {g.fail(message, 'INVALID_CAST_ARGUMENT')} ELSE {read} END"
    return f"CASE WHEN ({value}) IS NOT NULL THEN {_let(value, given, _let(parsed(given), read, failed))} END"


def cast(g, value: str, source: TType, target: TType) -> str:
    """SQL of Trino's CAST between ipaddress and varchar or varbinary (infer_casts.castable)."""
    if target.base == "varchar":
        return text(value)
    if target.base == "varbinary":
        return value
    return from_varchar(g, value) if source.base == "varchar" else from_varbinary(g, value)
