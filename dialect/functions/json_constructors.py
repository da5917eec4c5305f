"""Trino's functions/json.md. The SQL/JSON constructors of json.md: json_array and json_object, with their
clauses.

json_object: the SQL/JSON object constructor with its clauses, members in
the order Trino 476 writes them.

Trino (io.trino.operator.scalar.json.JsonObjectFunction) puts the members into a
`new java.util.HashMap<>()`, wraps it in a Jackson ObjectNode and writes that with
ObjectMapper.writeTree (JsonOutputFunctions), so the members come out in the HashMap's iteration
order, which is deterministic: by bucket `spread(key.hashCode()) & (capacity - 1)`, and within a
bucket in insertion order (a resize splits buckets keeping their relative order). The capacity
starts at 16 and doubles when the size exceeds 3/4 of it. A member put into a bucket that already
holds 8 turns the bucket into a tree, or forces an early resize (HashMap.putVal, treeifyBin):
lakegate refuses, at run time, a member that finds 8 earlier ones in its bucket of the table at the
time it is put, so the order it writes is never a guess. The order is computed in DuckDB from the
keys, so key expressions work as literal keys do.

Errors as JsonObjectFunction raises them, at run time, in member order: a NULL key, a repeated key
(NOT_SUPPORTED, or INVALID_FUNCTION_ARGUMENT under WITH UNIQUE KEYS). Facts: trinodb/trino
docs/src/main/sphinx/functions/json.md (json_object) and TestJsonObjectFunction.
"""

from __future__ import annotations

import json

from sqlglot import exp

from lakegate.dialect import json_values as jv
from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.arguments import literal_str
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


# --- json_array (SQL/JSON constructor, without clauses) --------------------------------------------
def _nested_json(node: exp.Expression) -> bool:
    """A JSON-returning function as an argument: its text is embedded as JSON ("the FORMAT option is
    implicit", json.md json_array and json_object)."""
    return (isinstance(node, exp.Anonymous) and node.name.lower() in ("json_array", "json_object")) or (
        isinstance(node, exp.JSONExtract) and node.args.get("json_query") and not node.meta.get("omit")
    )


def _format_json(call: Call, node: exp.Expression) -> None:
    """`'text' FORMAT JSON`: the text read as JSON and written back compactly, as Trino does
    (Jackson readTree, members in their order); a constant string only."""
    text = literal_str(call, call.args.index(node))
    if node.meta_get("format_json") is not True or text is None:
        call.fail(
            f"unsupported in lakegate: {call.name} argument ... FORMAT JSON of other than a string", "NOT_SUPPORTED"
        )

    def members(pairs):
        if len({key for key, _ in pairs}) != len(pairs):
            raise ValueError
        return dict(pairs)

    try:
        value = json.loads(text, object_pairs_hook=members, parse_float=_no_float, parse_constant=_no_float)
    except ValueError:
        call.fail(
            f"unsupported in lakegate: {call.name} argument ... FORMAT JSON of text that is not JSON "
            "with distinct keys and integer numbers",
            "NOT_SUPPORTED",
        )
    written = json.dumps(value, ensure_ascii=False, separators=(",", ":"))
    if "\\u" in written.replace("\\\\", ""):  # a control character: Jackson writes \u001F, Python \u001f
        call.fail(
            f"unsupported in lakegate: {call.name} argument ... FORMAT JSON of control characters", "NOT_SUPPORTED"
        )
    node.meta["json"] = written


def _no_float(text: str):
    raise ValueError(text)


def _json_array(call: Call) -> TType:
    meta = call.node.meta_get
    returning = meta("returning")
    if returning is not None and not (
        returning.is_type("varchar") and not returning.expressions and meta("returning_format") in (None, "JSON")
    ):
        target = returning.sql(dialect="trino")
        call.fail(f"unsupported in lakegate: json_array ... RETURNING {target}", "NOT_SUPPORTED")
    for node, t in zip(call.args, call.types):
        check_json_value(call, node, t)
    return tt.VARCHAR


def check_json_value(call: Call, node: exp.Expression, t: TType | None) -> None:
    """Refuse (NOT_SUPPORTED) a json_array element or json_object value lakegate does not write as
    Trino does (SqlJsonLiteralConverter.getJsonNode); note the text of a FORMAT JSON literal."""
    if node.meta_get("format_json"):
        _format_json(call, node)
        return
    if isinstance(node, exp.JSONExtract) and node.meta.get("omit"):
        call.fail(f"unsupported in lakegate: json_query ... OMIT QUOTES inside {call.name}", "NOT_SUPPORTED")
    if t is not None and t.base == "json" and not _nested_json(node):
        # a value of the json type: an "other" value cast to varchar (json.md), which fails for objects and arrays
        call.fail(
            f"unsupported in lakegate: {call.name} of a json value (use FORMAT JSON on its text)", "NOT_SUPPORTED"
        )
    if t is None or not (t.is_numeric or t.base in ("boolean", "varchar", "json", "unknown", "date")):
        call.fail(f"unsupported in lakegate: {call.name} of a {t} value", "NOT_SUPPORTED")


def json_value_text(g, arg: exp.Expression) -> str:
    """The JSON text of a json_array element or json_object value checked by check_json_value:
    booleans, numbers as Jackson writes them, JSON (FORMAT JSON, a nested JSON function) as it is,
    other values as JSON strings of their varchar text; NULL for NULL."""
    t = ttype(arg)
    if arg.meta_get("format_json"):
        return tf.string(arg.meta["json"])
    if _nested_json(arg):
        return f"CAST({g.sql(arg)} AS VARCHAR)"
    if t.base == "date":
        return jv.to_json(g, f"CAST({g.sql(arg)} AS VARCHAR)", tt.VARCHAR)
    return jv.to_json(g, g.sql(arg), t)


def _render_json_array(g, node, args) -> str:
    """The elements as JSON; NULLs are left out, ABSENT ON NULL being the default."""
    texts = [json_value_text(g, arg) for arg in args]
    if node.meta_get("null") == "NULL":  # NULL ON NULL: a JSON null for each NULL
        texts = [f"coalesce({text}, 'null')" for text in texts]
    # DuckDB's array_to_string of only NULLs is NULL: '' (Trino's json_array(NULL) is '[]')
    return f"'[' || coalesce(array_to_string([{', '.join(texts)}]::VARCHAR[], ','), '') || ']'" if texts else "'[]'"


#: java.util.HashMap: the first table's capacity, and the size of a bucket that is turned into a
#: tree (TREEIFY_THRESHOLD + 1); the table doubles past 3/4 full (DEFAULT_LOAD_FACTOR).
_FIRST_CAPACITY = 16

_TREE_BUCKET = 9


_NULL_KEY = "null value passed for JSON object key to JSON_OBJECT function"

_DUPLICATE = "NOT_SUPPORTED: cannot construct a JSON object with duplicate key"

_TREE = "NOT_SUPPORTED: json_object with 9 or more keys in one bucket of Java's HashMap (their order is not reproduced)"


def _java_hash_sql(text: str) -> str:
    """Java's String.hashCode of a VARCHAR as a 32-bit unsigned BIGINT (s[0]*31^(n-1) + ... over
    UTF-16 code units, modulo 2^32), then HashMap.hash's spread (h ^ (h >>> 16))."""
    point = f'unicode({text}["_i" + 1])'
    units = (
        f'flatten(list_transform(range(length({text})), lambda "_i": CASE WHEN {point} > 65535 '
        f"THEN [55296 + (({point} - 65536) >> 10), 56320 + (({point} - 65536) & 1023)] ELSE [{point}] END))"
    )
    code = f'list_reduce(list_concat([0], {units}), lambda "_h", "_u": ("_h" * 31 + "_u") % 4294967296)'
    return f'list_transform([{code}], lambda "_h": xor("_h", "_h" >> 16))[1]'


def _capacities(members: int) -> list[tuple[int, int]]:
    """(largest size, capacity) of each table a HashMap of up to `members` entries passes through."""
    capacity, tables = _FIRST_CAPACITY, []
    while True:
        tables.append((capacity * 3 // 4, capacity))
        if members <= capacity * 3 // 4:
            return tables
        capacity *= 2


def _json_object(call: Call) -> TType:
    meta = call.node.meta_get
    returning, form = meta("returning"), meta("returning_format")
    if returning is not None and not (
        (returning.is_type("varchar") and not returning.expressions and form in (None, "JSON"))
        or (returning.is_type("varbinary") and form in (None, "JSON", "UTF8"))
    ):
        text = returning.sql(dialect="trino") + ("" if form in (None, "JSON") else f" FORMAT JSON ENCODING {form}")
        call.fail(f"unsupported in lakegate: json_object ... RETURNING {text}", "NOT_SUPPORTED")
    keys, values = call.args[::2], call.args[1::2]
    for key, t in zip(keys, call.types[::2]):
        if t.base not in ("varchar", "char", "unknown"):
            call.analyzer.fail(f"JSON object key must be of character string type: {t}", key, "TYPE_MISMATCH")
        if t.base == "char":
            call.fail("unsupported in lakegate: json_object of a char(n) key", "NOT_SUPPORTED")
    if meta("unique") == "WITH" and any(v.meta_get("format_json") for v in values):
        call.fail(
            "WITH UNIQUE KEYS behavior is not supported for JSON_OBJECT function when input expression has FORMAT",
            "NOT_SUPPORTED",
        )
    for value, t in zip(values, call.types[1::2]):
        check_json_value(call, value, t)
    return tt.VARBINARY if returning is not None and returning.is_type("varbinary") else tt.VARCHAR


def _part(name: str) -> str:
    return f"struct_extract(\"_e\", '{name}')"


def _render_json_object(g, node, args) -> str:
    """The checks in member order (a NULL key, a repeated key), then the object text."""
    keys = [g.coerce(key, tt.VARCHAR) for key in args[::2]]
    values = [json_value_text(g, value) for value in args[1::2]]
    absent = node.meta_get("null") == "ABSENT"
    present = [f"(({value}) IS NOT NULL)" if absent else "true" for value in values]
    duplicate = (
        g.fail(tf.string("duplicate key passed to JSON_OBJECT function"))
        if node.meta_get("unique") == "WITH"
        else f"error({tf.string(_DUPLICATE)})"
    )
    checks = []
    for i, key in enumerate(keys):
        if not isinstance(args[2 * i], exp.Literal):
            checks.append(f"WHEN {key} IS NULL THEN {g.fail(tf.string(_NULL_KEY))}")
        earlier = [f"({present[j]} AND {keys[j]} = {key})" for j in range(i) if _may_equal(args[2 * j], args[2 * i])]
        if earlier:
            checks.append(f"WHEN {present[i]} AND ({' OR '.join(earlier)}) THEN {duplicate}")
    # The members (key, position, "key":value text) outside any lambda: DuckDB has no subqueries in lambdas.
    entries = ", ".join(
        f'struct_pack("k" := {key}, "i" := {i}, "m" := CASE WHEN {present[i]} THEN '
        f"{jv.to_json(g, key, tt.VARCHAR)} || ':' || coalesce({value}, 'null') END)"
        for i, (key, value) in enumerate(zip(keys, values))
    )
    hashed = f'struct_pack("h" := {_java_hash_sql(_part("k"))}, "i" := {_part("i")}, "m" := {_part("m")})'
    members = f'list_transform(list_filter([{entries}], lambda "_e": {_part("m")} IS NOT NULL), lambda "_e": {hashed})'
    result = f'list_transform([{members}], lambda "_o": {_object_text(len(keys))})[1]' if keys else "'{}'"
    if checks:
        result = f"CASE {' '.join(checks)} ELSE {result} END"
    return f"encode({result})" if ttype(node).base == "varbinary" else result


def _object_text(pairs: int) -> str:
    """The object text of the present members "_o" (hash h, position i, text m) of a call with
    `pairs` members: sorted by bucket in the table their count leads to, then by position."""
    tables = _capacities(pairs)
    mask = (
        f"{tables[0][1] - 1}"
        if len(tables) == 1
        else "CASE " + " ".join(f'WHEN len("_o") <= {size} THEN {capacity - 1}' for size, capacity in tables) + " END"
    )
    bucketed = f'struct_pack("b" := {_part("h")} & {mask}, "i" := {_part("i")}, "m" := {_part("m")})'
    ordered = f'list_sort(list_transform("_o", lambda "_e": {bucketed}))'
    text = f"'{{' || array_to_string(list_transform({ordered}, lambda \"_e\": {_part('m')}), ',') || '}}'"
    if pairs < _TREE_BUCKET:
        return text
    # The capacity when member "_p" (1-based) is put, with "_p" - 1 members already in the map.
    then = "CASE " + " ".join(f'WHEN "_p" - 1 <= {size} THEN {capacity - 1}' for size, capacity in tables) + " END"
    earlier = (
        f'len(list_filter(list_slice("_o", 1, "_p" - 1), '
        f'lambda "_c": (struct_extract("_c", \'h\') & {then}) = ({_part("h")} & {then})))'
    )
    crowded = f'list_max(list_transform("_o", lambda "_e", "_p": {earlier}))'
    return f"CASE WHEN {crowded} >= {_TREE_BUCKET - 1} THEN error({tf.string(_TREE)}) ELSE {text} END"


def _may_equal(a: exp.Expression, b: exp.Expression) -> bool:
    """Whether two keys can be equal: unless both are string literals, known only at run time."""
    both = all(isinstance(k, exp.Literal) and k.is_string for k in (a, b))
    return not both or a.name == b.name


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "json_array",
        "json",
        "json_array([value, ...]) -> varchar",
        _json_array,
        _render_json_array,
        notes="ABSENT ON NULL (the default) and NULL ON NULL; RETURNING varchar; FORMAT JSON of a string literal. "
        "RETURNING varchar(n) or varbinary, ENCODING and FORMAT JSON of other values are refused (NOT_SUPPORTED).",
    )

    register(
        "json_object",
        "json",
        "json_object([key : value, ...]) -> varchar",
        _json_object,
        _render_json_object,
        notes="KEY ... VALUE and `:` members, NULL ON NULL (the default) and ABSENT ON NULL, WITH / WITHOUT UNIQUE "
        "KEYS, RETURNING varchar or varbinary (UTF8), FORMAT JSON of a string literal; members in the order of "
        "Trino's java.util.HashMap. RETURNING varchar(n), other encodings and 9 or more keys in one HashMap bucket "
        "are refused (NOT_SUPPORTED).",
    )
