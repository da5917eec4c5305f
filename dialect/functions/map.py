"""Trino's functions/map.md. Map functions and operators. DuckDB maps keep their entries in insertion order, as
Trino's map blocks do; lambdas over map entries bind their parameters (k, v) to each entry's key and value.
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import write_casts as casts
from lakegate.dialect.functions.arguments import array_arg, map_arg, need, plain_key
from lakegate.dialect.functions.rendering import (
    ENTRY,
    ENTRY_KEY,
    ENTRY_VALUE,
    call_as,
    grouped_values,
    let_bound,
    map_entries,
    null_if_any_null,
    sqls,
)
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


def _map(call: Call) -> TType:
    if not call.args:
        return tt.map_of(tt.UNKNOWN, tt.UNKNOWN)
    need(call, "array", "array")
    keys, values = array_arg(call, 0), array_arg(call, 1)
    if keys.element.base in ("map", "json"):
        call.mismatch()
    if not _textual_key(keys.element):  # its text in the error for an indeterminate key
        call.fail(f"unsupported in lakegate: a map with {keys.element} keys", "NOT_SUPPORTED")
    return tt.map_of(keys.element, values.element)


def _textual_key(t: TType) -> bool:
    """Whether a map key of type `t` is a scalar, or an array or row of keys whose text
    _key_text writes as Trino's object value prints."""
    if t.base in ("array", "row"):
        return all(_key_leaf(leaf) for leaf in _leaves(t))
    return True


def _leaves(t: TType) -> list[TType]:
    if t.base == "array":
        return _leaves(t.element)
    if t.base == "row":
        return [leaf for _, field in t.args for leaf in _leaves(field)]
    return [t]


def _key_leaf(t: TType) -> bool:
    return t.is_integral or t.is_decimal or t.base in ("varchar", "boolean", "date", "timestamp", "unknown")


def _indeterminate(sql: str, t: TType, depth: int = 0) -> str:
    """SQL that is true when an array or row value holds a NULL at any depth (Trino's INDETERMINATE)."""
    if t.base == "array":
        z = f'"_k{depth}"'
        return (
            f"coalesce(list_bool_or(list_transform({sql}, lambda {z}: "
            f"{z} IS NULL OR {_indeterminate(z, t.element, depth + 1)})), false)"
        )
    if t.base == "row":
        fields = [f"struct_extract_at({sql}, {i + 1})" for i in range(len(t.args))]
        return (
            "("
            + " OR ".join(f"{f} IS NULL OR {_indeterminate(f, field, depth)}" for f, (_, field) in zip(fields, t.args))
            + ")"
        )
    return "false"


def _key_text(g, sql: str, t: TType, depth: int = 0) -> str:
    """SQL for a key's text as Java prints Trino's object value (`[1, null]` for ARRAY[1, NULL])."""
    if t.base == "array":
        z = f'"_t{depth}"'
        element = _key_text(g, z, t.element, depth + 1)
        return f"'[' || array_to_string(list_transform({sql}, lambda {z}: coalesce({element}, 'null')), ', ') || ']'"
    if t.base == "row":
        fields = [
            _key_text(g, f"struct_extract_at({sql}, {i + 1})", field, depth) for i, (_, field) in enumerate(t.args)
        ]
        return "'[' || " + " || ', ' || ".join(f"coalesce({f}, 'null')" for f in fields) + " || ']'"
    return casts.varchar_of(g, sql, t)


def _indeterminate_keys(g, keys: str, t: TType) -> str:
    """The WHEN clause failing on a key that holds a NULL inside (MapConstructor), or ''."""
    if t.base not in ("array", "row"):
        return ""
    z = '"_key"'
    bad = f"list_filter({keys}, lambda {z}: {_indeterminate(z, t)})"
    text = _key_text(g, f"({bad})[1]", t)
    return f"WHEN len({bad}) > 0 THEN {g.fail(tf.string('map key cannot be indeterminate: ') + ' || ' + text)} "


def _render_map(g, node, args) -> str:
    if not args:
        return "map()"
    keys, values = g.sql(args[0]), g.sql(args[1])
    return (  # a NULL array of either side gives NULL before any key is checked
        f"CASE WHEN ({keys}) IS NULL OR ({values}) IS NULL THEN NULL WHEN len({keys}) <> len({values}) THEN "
        f"{g.fail(tf.string('Key and value arrays must be the same length'))} "
        f"WHEN list_count({keys}) < len({keys}) THEN {g.fail(tf.string('map key cannot be null'))} "
        f"{_indeterminate_keys(g, keys, ttype(args[0]).element)}"
        f"WHEN len(list_distinct({keys})) < len({keys}) THEN "
        f"{g.fail(tf.string('Duplicate map keys are not allowed'))} ELSE map({keys}, {values}) END"
    )


#: Functions whose maps Trino orders as its hash table holds the keys (histogram(['b', 'a', 'c']) lists
#: c, a, b), an order lakegate cannot reproduce; maps made otherwise keep the order they were given.
HASH_ORDERED = ("histogram", "array_histogram", "map_agg", "multimap_agg", "map_union", "map_union_sum")


def refuse_hash_order(call: Call) -> None:
    """NOT_SUPPORTED when the map argument comes from a function of HASH_ORDERED and the call shows
    its entry order (map_keys, map_values, map_entries)."""
    for node in call.args[0].walk():
        if isinstance(node, exp.Anonymous) and node.name.lower() in HASH_ORDERED:
            call.fail(
                f"unsupported in lakegate: {call.name} of a map made by {node.name.lower()} (Trino orders its "
                "entries as its hash table holds them)",
                "NOT_SUPPORTED",
            )


def _map_part(call: Call) -> TType:
    (t,) = need(call, "any")
    if t.base != "map":
        call.mismatch()
    refuse_hash_order(call)
    return tt.array(t.args[0] if call.name == "map_keys" else t.args[1])


def bind(g, lam: exp.Lambda, values: list[str]) -> str:
    """The lambda's body with its parameters bound to `values` (SQL expressions)."""
    body = g.sql(lam.this)
    for param, value in reversed(list(zip(lam.expressions, values))):
        body = f"list_transform([{value}], lambda {tf.quote(param.name.lower())}: {body})[1]"
    return body


def first_problem(g, keys: str, key_type: TType, entries: str | None = None) -> str:
    """SQL of Trino's message for the first entry whose key is NULL or repeats an earlier key (or,
    given `entries`, which is itself NULL), else NULL: map constructors check entries in order
    (MapFromEntriesFunction, TransformKeysFunction)."""
    null_entry = f"WHEN ({entries})[{tf.quote('_i')}] IS NULL THEN 'map entry cannot be null' " if entries else ""
    key_text = casts.varchar_of(g, '"_k"', key_type)
    duplicate = f"'Duplicate keys (' || {key_text} || ') are not allowed'"
    message = (
        f"CASE {null_entry}WHEN \"_k\" IS NULL THEN 'map key cannot be null' "
        f'WHEN list_position({keys}, "_k") < "_i" THEN {duplicate} END'
    )
    return f'list_filter(list_transform({keys}, lambda "_k", "_i": {message}), lambda "_m": "_m" IS NOT NULL)[1]'


def checked_map(g, problem: str, result: str) -> str:
    return f"CASE WHEN ({problem}) IS NOT NULL THEN {g.fail(problem)} ELSE {result} END"


# === maps =========================================================================================
def _map_entries(call: Call) -> TType:
    need(call, "any")
    m = map_arg(call)
    refuse_hash_order(call)
    return tt.array(tt.row([(None, m.args[0]), (None, m.args[1])]))


def _render_map_entries(g, node, args) -> str:
    return f"list_transform({map_entries(g.sql(args[0]))}, lambda {ENTRY}: row({ENTRY_KEY}, {ENTRY_VALUE}))"


def _entry_row(call: Call) -> TType:
    need(call, "array")
    row = array_arg(call).element
    if row.base != "row" or len(row.args) != 2:
        call.mismatch()
    plain_key(call, row.args[0][1])
    return row


def _map_from_entries(call: Call) -> TType:
    row = _entry_row(call)
    return tt.map_of(row.args[0][1], row.args[1][1])


def _render_map_from_entries(g, node, args) -> str:
    """MapFromEntriesFunction: a NULL entry, a NULL key or a repeated key fails, the first in order."""
    arr = g.sql(args[0])
    keys = f"list_transform({arr}, lambda {ENTRY}: {ENTRY_KEY})"
    result = tf.cast(
        f"map_from_entries(list_transform({arr}, lambda {ENTRY}: row({ENTRY_KEY}, {ENTRY_VALUE})))", ttype(node)
    )
    return checked_map(g, first_problem(g, keys, ttype(node).args[0], entries=arr), result)


def _multimap_from_entries(call: Call) -> TType:
    row = _entry_row(call)
    return tt.map_of(row.args[0][1], tt.array(row.args[1][1]))


def _render_multimap_from_entries(g, node, args) -> str:
    """MultimapFromEntriesFunction: a NULL entry or a NULL key fails; repeated keys collect values."""
    arr = g.sql(args[0])
    keys = f"list_transform({arr}, lambda {ENTRY}: {ENTRY_KEY})"
    problem = (
        f"CASE WHEN list_contains(list_transform({arr}, lambda {ENTRY}: {ENTRY} IS NULL), true) "
        f"THEN 'map entry cannot be null' WHEN list_count({keys}) < len({keys}) THEN 'map key cannot be null' END"
    )
    result = f"CASE WHEN ({arr}) IS NULL THEN NULL ELSE {tf.cast(grouped_values(arr, keys), ttype(node))} END"
    return checked_map(g, problem, result)


def _map_concat(call: Call) -> TType:
    if len(call.args) < 2:
        call.fail("There must be two or more concatenation arguments to map_concat", "INVALID_FUNCTION_ARGUMENT")
    if any(t is None or t.base not in ("map", "unknown") for t in call.types) or all(t.is_unknown for t in call.types):
        call.mismatch()
    return tt.common_super_type_of(call.types) or call.mismatch()


def _render_map_concat(g, node, args) -> str:
    """MapConcatFunction: a key's value comes from the last map holding it, and the entries come
    in the order the real Trino 476 gives them: the last map's, then each earlier map's new keys,
    from the last but one to the first; NULL if any map is NULL."""
    entries = ", ".join(map_entries(g.coerce(a, ttype(node))) for a in reversed(args))
    keys = 'list_transform("_all", lambda "_y": struct_extract_at("_y", 1))'
    first = f'list_filter("_all", lambda "_x", "_i": list_position({keys}, struct_extract_at("_x", 1)) = "_i")'
    distinct = let_bound(f"flatten([{entries}])", '"_all"', first)
    return null_if_any_null(g, args, f"map_from_entries({distinct})")


def _map_lambda(call: Call, index: int = 1) -> tuple[TType, TType]:
    """Type the (k, v) lambda at `index` over the map argument; (map type, lambda body type)."""
    if len(call.args) != index + 1:
        call.mismatch()
    m = map_arg(call)
    return m, call.lam(index, list(m.args))


def _map_filter(call: Call) -> TType:
    m, body = _map_lambda(call)
    if body.base not in ("boolean", "unknown"):
        call.mismatch()
    return m


def _render_map_filter(g, node, args) -> str:
    kept = f"list_filter({map_entries(g.sql(args[0]))}, lambda {ENTRY}: {bind(g, args[1], [ENTRY_KEY, ENTRY_VALUE])})"
    return tf.cast(f"map_from_entries({kept})", ttype(node))


def _transform_values(call: Call) -> TType:
    m, body = _map_lambda(call)
    return tt.map_of(m.args[0], body)


def _render_transform_values(g, node, args) -> str:
    value = bind(g, args[1], [ENTRY_KEY, ENTRY_VALUE])
    entries = f"list_transform({map_entries(g.sql(args[0]))}, lambda {ENTRY}: row({ENTRY_KEY}, {value}))"
    return tf.cast(f"map_from_entries({entries})", ttype(node))


def _transform_keys(call: Call) -> TType:
    m, body = _map_lambda(call)
    plain_key(call, body)
    if body.is_unknown:  # TransformKeysFunction: a key of type unknown is always NULL
        call.fail("map key cannot be null", "INVALID_FUNCTION_ARGUMENT")
    return tt.map_of(body, m.args[1])


def _render_transform_keys(g, node, args) -> str:
    """TransformKeysFunction: a NULL or repeated new key fails, the first in entry order."""
    m = g.sql(args[0])
    keys = f"list_transform({map_entries(m)}, lambda {ENTRY}: {bind(g, args[1], [ENTRY_KEY, ENTRY_VALUE])})"
    body = checked_map(
        g,
        first_problem(g, '"_nk"', ttype(node).args[0]),
        tf.cast(f'map("_nk", map_values({m}))', ttype(node)),
    )
    return let_bound(keys, '"_nk"', body)


def _map_zip_with(call: Call) -> TType:
    if len(call.args) != 3:
        call.mismatch()
    a, b = map_arg(call, 0), map_arg(call, 1)
    key = tt.common_super_type(a.args[0], b.args[0])
    if key is None:
        call.mismatch()
    call.node.meta["key"] = key
    return tt.map_of(key, call.lam(2, [key, a.args[1], b.args[1]]))


def _render_map_zip_with(g, node, args) -> str:
    """MapZipWithFunction: every key of either map (the first map's order, then the second's new
    keys), with NULL for the value a map lacks."""
    key = node.meta["key"]
    a = g.coerce(args[0], tt.map_of(key, ttype(args[0]).args[1]))
    b = g.coerce(args[1], tt.map_of(key, ttype(args[1]).args[1]))
    keys = (
        f'list_concat(map_keys({a}), list_filter(map_keys({b}), lambda "_k": NOT list_contains(map_keys({a}), "_k")))'
    )
    value = bind(g, args[2], ['"_k"', f'map_extract_value({a}, "_k")', f'map_extract_value({b}, "_k")'])
    result = f'map({keys}, list_transform({keys}, lambda "_k": {value}))'
    return null_if_any_null(g, args[:2], tf.cast(result, ttype(node)))


# === split_to_map, split_to_multimap ==============================================================
def _split_to_map(call: Call) -> TType:
    need(call, "string", "string", "string")
    return tt.map_of(tt.VARCHAR, tt.array(tt.VARCHAR) if call.name == "split_to_multimap" else tt.VARCHAR)


def _split_entries(g, args, quote: str) -> tuple[str, str]:
    """The entries of the string (SQL of a list of (key, value, problem) rows) and the delimiter
    checks (SQL of the first failed check's message or NULL), as StringFunctions.splitToMap splits:
    an empty string has no entries and a final entry delimiter ends the last entry. `quote` goes around
    the bad entry in the message ('' for split_to_map, nothing for split_to_multimap, as Trino)."""
    text, entry, pair = sqls(g, args)
    parts = f"string_split({text}, {entry})"
    entries = (
        f"CASE WHEN {text} = '' THEN [] WHEN ends_with({text}, {entry}) "
        f"THEN list_slice({parts}, 1, len({parts}) - 1) ELSE {parts} END"
    )
    at = f'strpos("_p", {pair})'
    value = f'substr("_p", {at} + length({pair}))'
    bad = f"'Key-value delimiter must appear exactly once in each entry. Bad input: {quote}' || \"_p\" || '{quote}'"
    row = (
        f'list_transform({entries}, lambda "_p": row(substr("_p", 1, {at} - 1), {value}, '
        f"CASE WHEN {at} = 0 OR strpos({value}, {pair}) > 0 THEN {bad} END))"
    )
    checks = (
        f"CASE WHEN {entry} = '' THEN 'entryDelimiter is empty' WHEN {pair} = '' THEN 'keyValueDelimiter is empty' "
        f"WHEN {entry} = {pair} THEN 'entryDelimiter and keyValueDelimiter must not be the same' END"
    )
    return row, checks


def _render_split_to_map(g, node, args) -> str:
    rows, checks = _split_entries(g, args, "''" if node.name.lower() == "split_to_map" else "")
    keys = f'list_transform("_r", lambda {ENTRY}: {ENTRY_KEY})'
    problems = f'list_transform("_r", lambda {ENTRY}, "_i": coalesce(struct_extract_at({ENTRY}, 3), '
    if node.name.lower() == "split_to_map":
        problems += (
            f'CASE WHEN list_position({keys}, {ENTRY_KEY}) < "_i" '
            f"THEN 'Duplicate keys (' || {ENTRY_KEY} || ') are not allowed' END))"
        )
        result = f'map_from_entries(list_transform("_r", lambda {ENTRY}: row({ENTRY_KEY}, {ENTRY_VALUE})))'
    else:
        problems += "NULL))"
        result = grouped_values('"_r"', keys)
    first = f'list_filter({problems}, lambda "_m": "_m" IS NOT NULL)[1]'
    body = checked_map(g, f"coalesce({checks}, {first})", tf.cast(result, ttype(node)))
    return null_if_any_null(g, args, let_bound(rows, '"_r"', body))


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "map",
        "map",
        "map(array(K), array(V)) -> map(K, V)",
        _map,
        _render_map,
        notes="Duplicate or NULL keys fail as in Trino.",
    )
    register("map_keys", "map", "map_keys(map(K, V)) -> array(K)", _map_part, call_as("map_keys"))
    register("map_values", "map", "map_values(map(K, V)) -> array(V)", _map_part, call_as("map_values"))

    register(
        "map_entries",
        "map",
        "map_entries(map(K, V)) -> array(row(K, V))",
        _map_entries,
        _render_map_entries,
    )
    register(
        "map_from_entries",
        "map",
        "map_from_entries(array(row(K, V))) -> map(K, V)",
        _map_from_entries,
        _render_map_from_entries,
        notes="A NULL entry, a NULL key or a repeated key fails as in Trino.",
    )
    register(
        "multimap_from_entries",
        "map",
        "multimap_from_entries(array(row(K, V))) -> map(K, array(V))",
        _multimap_from_entries,
        _render_multimap_from_entries,
    )
    register(
        "map_concat",
        "map",
        "map_concat(map1(K, V), map2(K, V), ..., mapN(K, V)) -> map(K, V)",
        _map_concat,
        _render_map_concat,
        notes="A key's value comes from the last map holding it.",
    )
    register(
        "map_filter",
        "map",
        "map_filter(map(K, V), function(K, V, boolean)) -> map(K, V)",
        _map_filter,
        _render_map_filter,
    )
    register(
        "transform_values",
        "map",
        "transform_values(map(K, V1), function(K, V1, V2)) -> map(K, V2)",
        _transform_values,
        _render_transform_values,
    )
    register(
        "transform_keys",
        "map",
        "transform_keys(map(K1, V), function(K1, V, K2)) -> map(K2, V)",
        _transform_keys,
        _render_transform_keys,
        notes="A NULL or repeated new key fails as in Trino.",
    )
    register(
        "map_zip_with",
        "map",
        "map_zip_with(map(K, V1), map(K, V2), function(K, V1, V2, V3)) -> map(K, V3)",
        _map_zip_with,
        _render_map_zip_with,
    )

    register(
        "split_to_map",
        "map",
        "split_to_map(string, entryDelimiter, keyValueDelimiter) -> map(varchar, varchar)",
        _split_to_map,
        _render_split_to_map,
        notes=(
            "Errors as Trino: empty or equal delimiters, an entry without exactly one key-value "
            "delimiter, a repeated key."
        ),
    )
    register(
        "split_to_multimap",
        "map",
        "split_to_multimap(string, entryDelimiter, keyValueDelimiter) -> map(varchar, array(varchar))",
        _split_to_map,
        _render_split_to_map,
    )
