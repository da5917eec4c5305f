"""DuckDB SQL shared by the function pages: calls of a DuckDB function, checked arguments, NULL propagation, NaN-
aware ordering and the entries of a map.
"""

from __future__ import annotations

from collections.abc import Iterable

from sqlglot import exp

from lakegate.dialect import transforms as tf
from lakegate.dialect import write_operators as ops
from lakegate.dialect.registry import Render
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import ttype

MAX_PAD_LENGTH = 1_000_000


def checked(g, value: str, checks: Iterable[tuple[str, str]]) -> str:
    """`value` (SQL), or Trino's INVALID_FUNCTION_ARGUMENT with the message of the first of `checks`
    ((condition SQL, message) pairs) that holds. Use it as the argument that sizes an allocation
    (range(n), lpad's width): DuckDB folds constant arguments before running a query, even in a CASE
    branch that is never taken, but never folds error(), so the check fires before any allocation."""
    whens = " ".join(f"WHEN {condition} THEN {g.fail(tf.string(message))}" for condition, message in checks)
    return f"CASE {whens} ELSE {value} END"


def sqls(g, args) -> list[str]:
    return [g.sql(a) for a in args]


def call_as(duck: str, cast_result: bool = False) -> Render:
    """DuckDB function `duck` with the same arguments (cast to the Trino result type if asked)."""

    def render(g, node, args):
        sql = f"{duck}({', '.join(sqls(g, args))})"
        return tf.cast(sql, ttype(node)) if cast_result else sql

    return render


def agg_as(duck: str, cast_result: bool = True) -> Render:
    def render(g, node, args):
        sql = g.agg(node, duck, ["*" if isinstance(a, exp.Star) else g.sql(a) for a in args])
        return tf.cast(sql, ttype(node)) if cast_result else sql

    return render


def null_if_any_null(g, args, sql: str) -> str:
    """`sql`, or NULL when any argument is NULL (DuckDB's variadic functions skip NULLs)."""
    checks = " OR ".join(f"({g.sql(a)}) IS NULL" for a in args if not isinstance(a, exp.Literal))
    return f"CASE WHEN {checks} THEN NULL ELSE {sql} END" if checks else sql


def not_nan(sql: str) -> str:
    """A double as SQL, NULL when it is NaN."""
    return f"CASE WHEN isnan({sql}) THEN NULL ELSE {sql} END"


def nested(t: TType) -> bool:
    members = [t.element] if t.base == "array" else [f for _, f in t.args]
    return any(m.base in ("array", "map", "row") for m in members)


def ordered_pick(arr: str, element: TType, largest: bool) -> str:
    """The largest (smallest) of the elements of `arr`, arrays or rows, as ArrayMaxFunction's loop
    finds it: each element is compared with the one kept so far, a NULL element makes the result
    NULL, and a comparison that reaches a NULL inside the elements fails as Trino's does."""
    kept = "struct_extract(\"_s\", 'v')"
    reached, failure = ops.null_reached('"_x"', kept, element)
    step = (
        f'CASE WHEN struct_extract("_s", \'n\') THEN "_s" '
        f'WHEN "_x" IS NULL THEN struct_pack(v := "_x", n := true) '
        f'WHEN {kept} IS NULL THEN struct_pack(v := "_x", n := false) WHEN {reached} THEN {failure} '
        f'WHEN "_x" {">" if largest else "<"} {kept} THEN struct_pack(v := "_x", n := false) ELSE "_s" END'
    )
    start = f"struct_pack(v := ({arr})[len({arr}) + 1], n := false)"  # v: a NULL of the element type
    return f'struct_extract(list_reduce({arr}, lambda "_s", "_x": {step}, {start}), \'v\')'


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


ENTRY = '"_e"'

ENTRY_KEY, ENTRY_VALUE = f"struct_extract_at({ENTRY}, 1)", f"struct_extract_at({ENTRY}, 2)"


def map_entries(map_sql: str) -> str:
    return f"map_entries({map_sql})"


def let_bound(value: str, name: str, body: str) -> str:
    """`body` with `name` (a quoted identifier) bound to `value`, evaluated once."""
    return f"list_transform([{value}], lambda {name}: {body})[1]"


def grouped_values(entries: str, keys: str) -> str:
    """A map from each distinct key (first occurrence order) to its values in entry order."""
    distinct = f'list_filter({keys}, lambda "_k", "_i": list_position({keys}, "_k") = "_i")'
    values = (
        f'list_transform({distinct}, lambda "_k": list_transform(list_filter({entries}, '
        f'lambda {ENTRY}: {ENTRY_KEY} IS NOT DISTINCT FROM "_k"), lambda {ENTRY}: {ENTRY_VALUE}))'
    )
    return f"map({distinct}, {values})"
