"""Trino's functions/ipaddress.md. IP address functions: contains(network, address)
(io.trino.operator.scalar.IpAddressFunctions), over the IPADDRESS type of dialect/ipaddresses.py."""

from __future__ import annotations

from lakegate.dialect import ipaddresses
from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.rendering import let_bound
from lakegate.dialect.registry import overload
from lakegate.dialect.transforms import string
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype

#: The 32 bits of an address's IPv4 form (its last 32 of 128), and all 128.
_IPV4_BITS, _IPV6_BITS = 32, 128
_NOT_A_NUMBER = string('For input string: "')


def _contains(call: Call) -> TType | None:
    """contains(varchar, ipaddress), which a NULL takes either place of; None for the other overloads
    (array.py's contains(array, value))."""
    if len(call.types) != 2 or any(t is None for t in call.types):
        return None
    network, address = call.types
    if network.base not in ("varchar", "unknown") or address.base not in ("ipaddress", "unknown"):
        return None
    return tt.BOOLEAN


def _render_contains(g, node, args) -> str:
    """Whether `address` is in the CIDR `network`, as the real Trino 476 answers: an IPv4 network (a
    dotted base) holds only IPv4 addresses and must have no bits set past its prefix; an IPv6 network
    (a base with ':', an IPv4-mapped one too) compares the first `prefix` bits of the 16 bytes. Its
    errors: no '/' (Invalid CIDR), a base that is no address (Invalid network IP address), a prefix
    Integer.parseInt refuses (GENERIC_INTERNAL_ERROR), a negative one (Invalid prefix length), one
    past the address's bits or a base with bits past it (Invalid CIDR)."""
    network, address = g.sql(args[0]), g.sql(args[1])
    if ttype(args[0]).is_unknown or ttype(args[1]).is_unknown:
        return "CAST(NULL AS BOOLEAN)"
    n, base, prefix = '"_net"', '"_base"', '"_prefix"'
    base_text, prefix_text = f"split_part({n}, '/', 1)", f"substr({n}, strpos({n}, '/') + 1)"
    ipv4 = f"NOT contains({base_text}, ':')"
    prefix_value = f"TRY_CAST({prefix_text} AS BIGINT)"
    number = f"regexp_full_match({prefix_text}, '[+-]?[0-9]+') AND {prefix_value} BETWEEN {-(2**31)} AND {2**31 - 1}"
    address_bits = f"CAST(CAST({address} AS BIT) AS VARCHAR)"
    base_bits = f"CAST(CAST({base} AS BIT) AS VARCHAR)"
    v4_bits, v4_address = f"right({base_bits}, {_IPV4_BITS})", f"right({address_bits}, {_IPV4_BITS})"
    mapped = f"starts_with(hex({address}), '{ipaddresses.MAPPED_PREFIX}')"
    invalid_cidr = g.fail("'Invalid CIDR'")
    not_a_number = f"{_NOT_A_NUMBER} || {prefix_text} || '\"'"  # Java's NumberFormatException
    answer = (
        f"CASE WHEN {ipv4} THEN CASE WHEN {prefix} > {_IPV4_BITS} OR contains(substr({v4_bits}, {prefix} + 1), '1') "
        f"THEN {invalid_cidr} ELSE {mapped} AND left({v4_bits}, {prefix}) = left({v4_address}, {prefix}) END "
        f"WHEN {prefix} > {_IPV6_BITS} THEN {invalid_cidr} "
        f"ELSE left({base_bits}, {prefix}) = left({address_bits}, {prefix}) END"
    )
    checked = (
        f"CASE WHEN strpos({n}, '/') = 0 THEN {invalid_cidr} "
        f"WHEN {base} IS NULL THEN {g.fail(string('Invalid network IP address'))} "
        f"WHEN NOT ({number}) THEN "
        f"{g.fail(not_a_number, 'GENERIC_INTERNAL_ERROR')} "
        f"WHEN {prefix_value} < 0 THEN {g.fail(string('Invalid prefix length'))} "
        f"ELSE {let_bound(prefix_value, prefix, answer)} END"
    )
    body = let_bound(ipaddresses.parsed(base_text), base, checked)
    return f"CASE WHEN ({network}) IS NULL OR ({address}) IS NULL THEN NULL ELSE {let_bound(network, n, body)} END"


def install() -> None:
    overload(
        "contains",
        _contains,
        _render_contains,
        "contains(network varchar, address ipaddress) -> boolean",
    )
