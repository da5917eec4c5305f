"""Maps, arrays and aggregates lifted for issue 14 (families 2-4): the map functions and the
aggregates that build maps, split_to_map, the set-like and combinatorial array functions, sequence
over dates and timestamps, the vector functions, and the bitwise, moment, lambda and
weighted-percentile aggregates. Registered into `registry.SUPPORTED` when
lakegate.dialect.translate imports this module.

DuckDB maps keep their entries in insertion order, as Trino's map blocks do; lambdas over map
entries bind their parameters (k, v) to each entry's key and value. Semantics follow the Trino
classes cited per function (io.trino.operator.scalar.*, io.trino.operator.aggregation.*).
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import functions
from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.analyze import Call, ttype
from lakegate.dialect.functions import array_arg, fixed, literal_int, need, null_if_any_null, percentile_type, sqls
from lakegate.dialect.registry import overload, register
from lakegate.dialect.trino_types import TType


# --- helpers ---------------------------------------------------------------------------------------
def _map_arg(call: Call, index: int = 0) -> TType:
    t = call.types[index] if index < len(call.types) else None
    if t is None or t.base != "map":
        call.mismatch()
    return t


def _plain_key(call: Call, key: TType) -> None:
    """Keys lakegate's maps hold exactly: not maps or JSON (Trino's map keys must be comparable), and
    not arrays or rows (DuckDB map keys lose their type in the result encoding)."""
    if key.base in ("map", "json"):
        call.mismatch()
    if key.base in ("array", "row"):
        call.fail(f"unsupported in lakegate: a map with {key.base} keys", "NOT_SUPPORTED")


def bind(g, lam: exp.Lambda, values: list[str]) -> str:
    """The lambda's body with its parameters bound to `values` (SQL expressions)."""
    body = g.sql(lam.this)
    for param, value in reversed(list(zip(lam.expressions, values))):
        body = f"list_transform([{value}], lambda {tf.quote(param.name.lower())}: {body})[1]"
    return body


_E = '"_e"'
_KEY, _VALUE = f"struct_extract_at({_E}, 1)", f"struct_extract_at({_E}, 2)"


def _entries(map_sql: str) -> str:
    return f"map_entries({map_sql})"


def first_problem(g, keys: str, key_type: TType, entries: str | None = None) -> str:
    """SQL of Trino's message for the first entry whose key is NULL or repeats an earlier key (or,
    given `entries`, which is itself NULL), else NULL: map constructors check entries in order
    (MapFromEntriesFunction, TransformKeysFunction)."""
    null_entry = f"WHEN ({entries})[{tf.quote('_i')}] IS NULL THEN 'map entry cannot be null' " if entries else ""
    key_text = tf.varchar_of(g, '"_k"', key_type)
    duplicate = f"'Duplicate keys (' || {key_text} || ') are not allowed'"
    message = (
        f"CASE {null_entry}WHEN \"_k\" IS NULL THEN 'map key cannot be null' "
        f'WHEN list_position({keys}, "_k") < "_i" THEN {duplicate} END'
    )
    return f'list_filter(list_transform({keys}, lambda "_k", "_i": {message}), lambda "_m": "_m" IS NOT NULL)[1]'


def checked_map(g, problem: str, result: str) -> str:
    return f"CASE WHEN ({problem}) IS NOT NULL THEN {g.fail(problem)} ELSE {result} END"


def _first_per_key(entries: str) -> str:
    """The entries (a list of (key, value) rows) whose key did not occur earlier in the list."""
    keys = f'list_transform({entries}, lambda "_p": struct_extract_at("_p", 1))'
    return f'list_filter({entries}, lambda "_p", "_i": list_position({keys}, struct_extract_at("_p", 1)) = "_i")'


def _let(value: str, name: str, body: str) -> str:
    """`body` with `name` (a quoted identifier) bound to `value`, evaluated once."""
    return f"list_transform([{value}], lambda {name}: {body})[1]"


# === maps =========================================================================================
def _map_entries(call: Call) -> TType:
    need(call, "any")
    m = _map_arg(call)
    return tt.array(tt.row([(None, m.args[0]), (None, m.args[1])]))


def _render_map_entries(g, node, args) -> str:
    return f"list_transform({_entries(g.sql(args[0]))}, lambda {_E}: row({_KEY}, {_VALUE}))"


def _entry_row(call: Call) -> TType:
    need(call, "array")
    row = array_arg(call).element
    if row.base != "row" or len(row.args) != 2:
        call.mismatch()
    _plain_key(call, row.args[0][1])
    return row


def _map_from_entries(call: Call) -> TType:
    row = _entry_row(call)
    return tt.map_of(row.args[0][1], row.args[1][1])


def _render_map_from_entries(g, node, args) -> str:
    """MapFromEntriesFunction: a NULL entry, a NULL key or a repeated key fails, the first in order."""
    arr = g.sql(args[0])
    keys = f"list_transform({arr}, lambda {_E}: {_KEY})"
    result = tf.cast(f"map_from_entries(list_transform({arr}, lambda {_E}: row({_KEY}, {_VALUE})))", ttype(node))
    return checked_map(g, first_problem(g, keys, ttype(node).args[0], entries=arr), result)


def _multimap_from_entries(call: Call) -> TType:
    row = _entry_row(call)
    return tt.map_of(row.args[0][1], tt.array(row.args[1][1]))


def _grouped_values(entries: str, keys: str) -> str:
    """A map from each distinct key (first occurrence order) to its values in entry order."""
    distinct = f'list_filter({keys}, lambda "_k", "_i": list_position({keys}, "_k") = "_i")'
    values = (
        f'list_transform({distinct}, lambda "_k": list_transform(list_filter({entries}, '
        f'lambda {_E}: {_KEY} IS NOT DISTINCT FROM "_k"), lambda {_E}: {_VALUE}))'
    )
    return f"map({distinct}, {values})"


def _render_multimap_from_entries(g, node, args) -> str:
    """MultimapFromEntriesFunction: a NULL entry or a NULL key fails; repeated keys collect values."""
    arr = g.sql(args[0])
    keys = f"list_transform({arr}, lambda {_E}: {_KEY})"
    problem = (
        f"CASE WHEN list_contains(list_transform({arr}, lambda {_E}: {_E} IS NULL), true) "
        f"THEN 'map entry cannot be null' WHEN list_count({keys}) < len({keys}) THEN 'map key cannot be null' END"
    )
    result = f"CASE WHEN ({arr}) IS NULL THEN NULL ELSE {tf.cast(_grouped_values(arr, keys), ttype(node))} END"
    return checked_map(g, problem, result)


def _map_concat(call: Call) -> TType:
    if len(call.args) < 2:
        call.fail("There must be two or more concatenation arguments to map_concat", "INVALID_FUNCTION_ARGUMENT")
    if any(t is None or t.base not in ("map", "unknown") for t in call.types) or all(t.is_unknown for t in call.types):
        call.mismatch()
    return tt.common_super_type_of(call.types) or call.mismatch()


def _render_map_concat(g, node, args) -> str:
    """MapConcatFunction: a key's value comes from the last map holding it; NULL if any map is NULL."""
    maps = ", ".join(g.coerce(a, ttype(node)) for a in args)
    return null_if_any_null(g, args, f"map_concat({maps})")


def _map_lambda(call: Call, index: int = 1) -> tuple[TType, TType]:
    """Type the (k, v) lambda at `index` over the map argument; (map type, lambda body type)."""
    if len(call.args) != index + 1:
        call.mismatch()
    m = _map_arg(call)
    return m, call.lam(index, list(m.args))


def _map_filter(call: Call) -> TType:
    m, body = _map_lambda(call)
    if body.base not in ("boolean", "unknown"):
        call.mismatch()
    return m


def _render_map_filter(g, node, args) -> str:
    kept = f"list_filter({_entries(g.sql(args[0]))}, lambda {_E}: {bind(g, args[1], [_KEY, _VALUE])})"
    return tf.cast(f"map_from_entries({kept})", ttype(node))


def _transform_values(call: Call) -> TType:
    m, body = _map_lambda(call)
    return tt.map_of(m.args[0], body)


def _render_transform_values(g, node, args) -> str:
    value = bind(g, args[1], [_KEY, _VALUE])
    entries = f"list_transform({_entries(g.sql(args[0]))}, lambda {_E}: row({_KEY}, {value}))"
    return tf.cast(f"map_from_entries({entries})", ttype(node))


def _transform_keys(call: Call) -> TType:
    m, body = _map_lambda(call)
    _plain_key(call, body)
    if body.is_unknown:  # TransformKeysFunction: a key of type unknown is always NULL
        call.fail("map key cannot be null", "INVALID_FUNCTION_ARGUMENT")
    return tt.map_of(body, m.args[1])


def _render_transform_keys(g, node, args) -> str:
    """TransformKeysFunction: a NULL or repeated new key fails, the first in entry order."""
    m = g.sql(args[0])
    keys = f"list_transform({_entries(m)}, lambda {_E}: {bind(g, args[1], [_KEY, _VALUE])})"
    body = checked_map(
        g,
        first_problem(g, '"_nk"', ttype(node).args[0]),
        tf.cast(f'map("_nk", map_values({m}))', ttype(node)),
    )
    return _let(keys, '"_nk"', body)


def _map_zip_with(call: Call) -> TType:
    if len(call.args) != 3:
        call.mismatch()
    a, b = _map_arg(call, 0), _map_arg(call, 1)
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
    "map_filter", "map", "map_filter(map(K, V), function(K, V, boolean)) -> map(K, V)", _map_filter, _render_map_filter
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


# === map-building aggregates ======================================================================
def _key_value_agg(call: Call) -> tuple[TType, TType]:
    key, value = need(call, "any", "any")
    if key.is_unknown:
        call.mismatch()
    _plain_key(call, key)
    return key, value


def _collected_entries(g, node, key: str, value: str) -> str:
    """The aggregate's (key, value) rows in input order (its ORDER BY), rows with a NULL key
    dropped: the key argument of MapAggregationFunction / MultimapAggregationFunction is not
    nullable, so Trino skips those rows."""
    rows = g.agg(node, "list", [f"row({key}, {value})"])
    return f"list_filter({rows}, lambda {_E}: {_KEY} IS NOT NULL)"


def _map_or_null(entries: str, result: str) -> str:
    """NULL over no entries (AbstractMapAggregationState.serialize), else `result` with the entries
    bound to "_es"."""
    return _let(entries, '"_es"', f'CASE WHEN len("_es") = 0 THEN NULL ELSE {result} END')


_FIRST_PER_KEY = f"map_from_entries({_first_per_key(tf.quote('_es'))})"


def _render_map_agg(g, node, args) -> str:
    """MapAggregationFunction: the first value of a key wins (in the aggregate's ORDER BY)."""
    entries = _collected_entries(g, node, g.sql(args[0]), g.sql(args[1]))
    return tf.cast(_map_or_null(entries, _FIRST_PER_KEY), ttype(node))


def _render_multimap_agg(g, node, args) -> str:
    entries = _collected_entries(g, node, g.sql(args[0]), g.sql(args[1]))
    keys = f'list_transform("_es", lambda {_E}: {_KEY})'
    return tf.cast(_map_or_null(entries, _grouped_values('"_es"', keys)), ttype(node))


def _map_union(call: Call) -> TType:
    need(call, "any")
    return _map_arg(call)


def _render_map_union(g, node, args) -> str:
    """MapUnionAggregation: NULL maps are skipped; a key held by several maps takes the value of
    the first (Trino: an arbitrary one of them)."""
    maps = g.agg(node, "list", [_entries(g.sql(args[0]))])
    entries = f'flatten(list_filter({maps}, lambda "_m": "_m" IS NOT NULL))'
    return tf.cast(_map_or_null(entries, _FIRST_PER_KEY), ttype(node))


register(
    "map_agg",
    "aggregate",
    "map_agg(key, value) -> map(K, V)",
    lambda c: tt.map_of(*_key_value_agg(c)),
    _render_map_agg,
    kind="aggregate",
    notes="Rows with a NULL key are skipped; the first value of a repeated key is kept; NULL for no rows.",
)
register(
    "multimap_agg",
    "aggregate",
    "multimap_agg(key, value) -> map(K, array(V))",
    lambda c: (lambda k, v: tt.map_of(k, tt.array(v)))(*_key_value_agg(c)),
    _render_multimap_agg,
    kind="aggregate",
    notes="Rows with a NULL key are skipped; NULL for no rows.",
)
register(
    "map_union",
    "aggregate",
    "map_union(x(K, V)) -> map(K, V)",
    _map_union,
    _render_map_union,
    kind="aggregate",
    notes="A key found in several maps takes its value from the first of them (Trino: an arbitrary one).",
)


# === arrays =======================================================================================
def _two_arrays(call: Call) -> TType:
    """Both arguments coerced to their common array type (the result type of the set functions)."""
    need(call, "array", "array")
    t = tt.common_super_type(array_arg(call, 0), array_arg(call, 1))
    if t is None or t.element.base in ("map", "json"):
        call.mismatch()
    return t


def _first_occurrences(arr: str, keep_nan: bool = False) -> str:
    """The elements of `arr` not equal to an earlier one; NULL is a value and kept once (DuckDB's
    list_position finds NULL and NaN, as Trino's IDENTICAL operator does). With `keep_nan` every NaN
    is kept: Trino's EQUAL never finds a NaN in a set."""
    nan = ' OR isnan("_x")' if keep_nan else ""
    return f'list_filter({arr}, lambda "_x", "_i": list_position({arr}, "_x") = "_i"{nan})'


def _array_union(call: Call) -> TType:
    t = _two_arrays(call)
    if t.element.base in ("array", "row"):
        call.fail("unsupported in lakegate: array_union of arrays of arrays or rows", "NOT_SUPPORTED")
    return t


def _render_array_union(g, node, args) -> str:
    """ArrayUnionFunction: x's then y's elements, each value once (EQUAL: NULL once, NaN always)."""
    t = ttype(node)
    both = f"list_concat({g.coerce(args[0], t)}, {g.coerce(args[1], t)})"
    return null_if_any_null(g, args, _let(both, '"_u"', _first_occurrences('"_u"', keep_nan=t.element.is_approx)))


def _render_array_intersect(g, node, args) -> str:
    """ArrayIntersectFunction: the distinct elements of the longer array (the first when equally
    long) found in the other, in the longer array's order; IDENTICAL, so NULL and NaN match."""
    t = ttype(node)
    x, y = g.coerce(args[0], t), g.coerce(args[1], t)

    def intersect(longer: str, shorter: str) -> str:
        found = f'list_filter({longer}, lambda "_y": list_position({shorter}, "_y") IS NOT NULL)'
        return _let(found, '"_f"', _first_occurrences('"_f"'))

    return null_if_any_null(g, args, f"CASE WHEN len({x}) < len({y}) THEN {intersect(y, x)} ELSE {intersect(x, y)} END")


def _render_array_except(g, node, args) -> str:
    """ArrayExceptFunction: x unchanged when either array is empty, else x's distinct elements not in
    y, in x's order; IDENTICAL, so NULL and NaN match."""
    t = ttype(node)
    x, y = g.coerce(args[0], t), g.coerce(args[1], t)
    distinct = _let(x, '"_d"', _first_occurrences('"_d"'))
    kept = f'list_filter({distinct}, lambda "_y": list_position({y}, "_y") IS NULL)'
    return null_if_any_null(g, args, f"CASE WHEN len({x}) = 0 OR len({y}) = 0 THEN {x} ELSE {kept} END")


def _contains_sequence(call: Call) -> TType:
    _two_arrays(call)
    return tt.BOOLEAN


def _render_contains_sequence(g, node, args) -> str:
    """ArrayContainsSequence: seq occurs in x as consecutive elements (IDENTICAL: NULL matches NULL)."""
    t = tt.common_super_type(ttype(args[0]), ttype(args[1]))
    x, seq = g.coerce(args[0], t), g.coerce(args[1], t)
    at = f'list_slice({x}, "_i" + 1, "_i" + len({seq})) IS NOT DISTINCT FROM {seq}'
    found = f'len(list_filter(range(0, len({x}) - len({seq}) + 1), lambda "_i": {at})) > 0'
    return null_if_any_null(g, args, found)


def _ngrams(call: Call) -> TType:
    need(call, "array", "integral")
    return tt.array(array_arg(call))


def _render_ngrams(g, node, args) -> str:
    """ArrayNgramsFunction: windows of min(n, cardinality) adjacent elements, so an empty array gives
    one empty n-gram; n must be positive."""
    arr, n = g.sql(args[0]), f"CAST({g.sql(args[1])} AS BIGINT)"
    size = f"least(len({arr}), {n})"
    grams = (
        f'list_transform(range(0, len({arr}) - {size} + 1), lambda "_i": list_slice({arr}, "_i" + 1, "_i" + {size}))'
    )
    return f"CASE WHEN {n} <= 0 THEN {g.fail(tf.string('N must be positive'))} ELSE {grams} END"


#: ArrayCombinationsFunction.MAX_COMBINATION_LENGTH and MAX_RESULT_ELEMENTS.
MAX_COMBINATION_LENGTH = 5
MAX_COMBINATION_ELEMENTS = 100_000


def _combinations(call: Call) -> TType:
    need(call, "array", "integral")
    call.node.meta["k"] = literal_int(call, 1)
    if call.node.meta["k"] is None:
        call.fail("unsupported in lakegate: combinations with a size that is not a literal", "NOT_SUPPORTED")
    return tt.array(array_arg(call))


def _combination_checks(g, size: str, k: int) -> list[tuple[str, str]]:
    """ArrayCombinationsFunction's checks, in its order, as (condition, message SQL) pairs."""
    if k < 0:
        return [("true", tf.string(f"combination size must not be negative: {k}"))]
    if k > MAX_COMBINATION_LENGTH:
        return [("true", tf.string(f"combination size must not exceed {MAX_COMBINATION_LENGTH}: {k}"))]
    checks, count = [], "CAST(1 AS HUGEINT)"
    too_large = f"'Number of combinations too large for array of size ' || {size} || ' and combination length {k}'"
    for i in range(1, k + 1):  # combinationCount, in Java int arithmetic
        product = f"({count}) * ({size} - {k} + {i})"
        checks.append((f"{size} >= {k} AND {product} > 2147483647", too_large))
        count = f"({product}) // {i}"
    exceeded = tf.string("combinations exceed max size")
    checks.append((f"{size} >= {k} AND ({count}) * {k} > {MAX_COMBINATION_ELEMENTS}", exceeded))
    return checks


def _render_combinations(g, node, args) -> str:
    """ArrayCombinationsFunction: the k-element index sets in its order (colexicographic: by the last
    index, then the one before, ...), each as the array of those elements. The checks size the
    outermost loop, so that a too large result fails before it is built (see functions.checked)."""
    arr, k = g.sql(args[0]), node.meta["k"]
    size = f"len({arr})"
    checks = _combination_checks(g, size, k)
    upper = "CASE " + " ".join(f"WHEN {c} THEN {g.fail(m)}" for c, m in checks) + f" ELSE {size} + 1 END"
    if not 0 <= k <= MAX_COMBINATION_LENGTH:
        return f"CASE WHEN ({arr}) IS NULL THEN NULL ELSE {g.fail(checks[0][1])} END"
    if k == 0:
        return f"CASE WHEN ({arr}) IS NULL THEN NULL ELSE [list_slice({arr}, 1, 0)] END"
    combo = "[" + ", ".join(f'{arr}["_c{j}"]' for j in range(1, k + 1)) + "]"
    for j in range(1, k + 1):  # index j runs below index j + 1, the last one below the size
        bound = upper if j == k else f'"_c{j + 1}"'
        combo = f'list_transform(range(1, {bound}), lambda "_c{j}": {combo})'
        combo = f"flatten({combo})" if j > 1 else combo
    return combo


def _zip(call: Call) -> TType:
    if not 2 <= len(call.args) <= 5:  # ZipFunction.MIN_ARITY, MAX_ARITY
        call.mismatch()
    return tt.array(tt.row([(None, array_arg(call, i).element) for i in range(len(call.args))]))


def _render_zip(g, node, args) -> str:
    """ZipFunction: rows of the i-th elements (anonymous fields), NULL past a shorter array's end."""
    arrays = sqls(g, args)
    longest = "greatest(" + ", ".join(f"len({a})" for a in arrays) + ")"
    fields = ", ".join(f'{a}["_i"]' for a in arrays)
    return null_if_any_null(g, args, f'list_transform(range(1, {longest} + 1), lambda "_i": row({fields}))')


register(
    "array_union",
    "array",
    "array_union(x, y) -> array",
    _array_union,
    _render_array_union,
    notes="x's elements then y's, each once, in order; NULL once; NaN is never equal (ArrayUnionFunction).",
)
register(
    "array_intersect",
    "array",
    "array_intersect(x, y) -> array",
    _two_arrays,
    _render_array_intersect,
    notes="In the order of the longer array (x when equally long), as ArrayIntersectFunction; NULL matches NULL.",
)
register(
    "array_except",
    "array",
    "array_except(x, y) -> array",
    _two_arrays,
    _render_array_except,
    notes="x unchanged (duplicates kept) when x or y is empty, as ArrayExceptFunction.",
)
register(
    "contains_sequence",
    "array",
    "contains_sequence(x, seq) -> boolean",
    _contains_sequence,
    _render_contains_sequence,
)
register(
    "ngrams",
    "array",
    "ngrams(array(T), n) -> array(array(T))",
    _ngrams,
    _render_ngrams,
    notes="In order of position; n larger than the array gives the whole array.",
)
register(
    "combinations",
    "array",
    "combinations(array(T), n) -> array(array(T))",
    _combinations,
    _render_combinations,
    notes="In Trino's order; n must be a literal (0 to 5).",
)
register("zip", "array", "zip(array1, array2[, ...]) -> array(row)", _zip, _render_zip, notes="2 to 5 arrays.")


# === aggregates ===================================================================================
def _bitwise_agg(call: Call) -> TType:
    need(call, "integral")
    return tt.BIGINT


for _name, _duck in (("bitwise_and_agg", "bit_and"), ("bitwise_or_agg", "bit_or"), ("bitwise_xor_agg", "bit_xor")):
    register(
        _name,
        "aggregate",
        f"{_name}(x) -> bigint",
        _bitwise_agg,
        lambda g, node, args, duck=_duck: tf.cast(g.agg(node, duck, [f"CAST({g.sql(args[0])} AS BIGINT)"]), tt.BIGINT),
        kind="aggregate",
        notes="Two's complement over bigint; NULL values are skipped; NULL for no rows.",
    )


def _moment(g, node, args, minimum: int, value: str) -> str:
    """CentralMomentsAggregation: NULL below `minimum` values, NaN when they are all equal (a zero
    second moment divides zero by zero), else `value`."""
    x = f"CAST({g.sql(args[0])} AS DOUBLE)"
    count, spread = g.agg(node, "count", [x]), g.agg(node, "var_pop", [x])
    return f"CASE WHEN {count} < {minimum} THEN NULL WHEN {spread} = 0 THEN CAST('NaN' AS DOUBLE) ELSE {value} END"


def _render_kurtosis(g, node, args) -> str:
    """Trino's estimator, (n-1)n(n+1)/((n-2)(n-3)) m4/m2^2 - 3(n-1)^2/((n-2)(n-3)), is DuckDB's."""
    return _moment(g, node, args, 4, g.agg(node, "kurtosis", [f"CAST({g.sql(args[0])} AS DOUBLE)"]))


def _render_skewness(g, node, args) -> str:
    """Trino's is the population skewness sqrt(n) m3 / m2^1.5; DuckDB's is the sample skewness,
    that times sqrt(n(n-1))/(n-2)."""
    x = f"CAST({g.sql(args[0])} AS DOUBLE)"
    n = g.agg(node, "count", [x])
    return _moment(g, node, args, 3, f"{g.agg(node, 'skewness', [x])} * ({n} - 2) / sqrt({n} * ({n} - 1))")


register(
    "kurtosis",
    "aggregate",
    "kurtosis(x) -> double",
    fixed(tt.DOUBLE, "number"),
    _render_kurtosis,
    kind="aggregate",
    notes="Trino's unbiased estimator; NULL below 4 values. Equal to Trino's up to floating-point rounding.",
)
register(
    "skewness",
    "aggregate",
    "skewness(x) -> double",
    fixed(tt.DOUBLE, "number"),
    _render_skewness,
    kind="aggregate",
    notes="Trino's population skewness; NULL below 3 values. Equal to Trino's up to floating-point rounding.",
)


def _reduce_agg(call: Call) -> TType:
    if len(call.args) != 4 or call.types[0] is None or call.types[1] is None:
        call.mismatch()
    value, state = call.types[0], call.types[1]
    if state.base not in ("boolean", "tinyint", "smallint", "integer", "bigint", "double", "real", "date", "unknown"):
        call.fail(f"State type not supported for reduce_agg: {state}", "NOT_SUPPORTED")
    for index, params in ((2, [state, value]), (3, [state, state])):
        if not tt.coercible(call.lam(index, params), state):
            call.mismatch()
    return state


def _render_reduce_agg(g, node, args) -> str:
    """ReduceAggregationFunction: the input function folds the non-NULL values into the state, which
    starts as the initial value at the first of them (NULL for no values). Evaluated as one state, so
    the combine function is not used; Trino combines partial states with it, which gives the same
    result for the associative functions it is meant for."""
    values = f'list_filter({g.agg(node, "list", [g.sql(args[0])])}, lambda "_v": "_v" IS NOT NULL)'
    folded = f'list_reduce("_vs", {g.lambda_(args[2])}, {g.coerce(args[1], ttype(node))})'
    return tf.cast(_let(values, '"_vs"', f'CASE WHEN len("_vs") = 0 THEN NULL ELSE {folded} END'), ttype(node))


register(
    "reduce_agg",
    "aggregate",
    "reduce_agg(inputValue T, initialState S, inputFunction(S, T, S), combineFunction(S, S, S)) -> S",
    _reduce_agg,
    _render_reduce_agg,
    kind="aggregate",
    notes="The combine function must be associative as Trino assumes; states of boolean, integer, "
    "floating-point and date types, as Trino's ReduceAggregationFunction.",
)


# === sequence over dates and timestamps ===========================================================
_WRONG_WAY = (
    "sequence stop value should be greater than or equal to start value if step is greater than zero "
    "otherwise stop should be less than or equal to start"
)


def temporal_sequence(call: Call) -> TType:
    """sequence over dates and timestamps (io.trino.operator.scalar.SequenceFunction and its
    timestamp variants): a date sequence steps by a day by default, or by a whole-day or a
    year-to-month interval; a timestamp sequence needs the interval."""
    types = call.types
    if not 2 <= len(types) <= 3 or None in types:
        call.mismatch()
    t = tt.common_super_type(types[0], types[1])
    if t is None or t.base != types[0].base or (t.base == "timestamp" and len(types) == 2):
        call.mismatch()
    if t.base == "timestamp" and t.args[0] > 6:
        call.fail(
            "unsupported in lakegate: sequence over timestamps with more than 6 fractional digits", "NOT_SUPPORTED"
        )
    if len(types) == 3 and types[2].base not in ("interval_ds", "interval_ym"):
        call.mismatch()
    return tt.array(t)


def render_temporal_sequence(g, node, args) -> str:
    t = ttype(node).element
    start, stop = (g.coerce(a, t) for a in args[:2])
    step = g.sql(args[2]) if len(args) == 3 else None
    checks = []
    if step is not None and ttype(args[2]).base == "interval_ym":
        step_number, unit = f"(datepart('year', {step}) * 12 + datepart('month', {step}))", "to_months"
        span = f"date_sub('month', {start}, {stop})"
    elif t.base == "date":
        if step is None:
            step_number = f"CASE WHEN {stop} >= {start} THEN 1 ELSE -1 END"
        else:
            step_number = f"(epoch_ms({step}) // 86400000)"
            whole_days = "sequence step must be a day interval if start and end values are dates"
            checks.append((f"epoch_ms({step}) % 86400000 <> 0", whole_days))
        unit, span = "to_days", f"({stop} - {start})"
    else:
        step_number, unit = f"epoch_us({step})", "to_microseconds"
        span = f"(epoch_us({stop}) - epoch_us({start}))"
    checks += [
        (f"{step_number} = 0", "step must not be zero"),
        (f"CASE WHEN {step_number} > 0 THEN {stop} < {start} ELSE {stop} > {start} END", _WRONG_WAY),
        (
            f"{span} // {step_number} + 1 > {functions.MAX_SEQUENCE_ENTRIES}",
            f"result of sequence function must not have more than {functions.MAX_SEQUENCE_ENTRIES} entries",
        ),
    ]
    count = functions.checked(g, f"{span} // {step_number} + 1", checks)
    value = tf.cast(f'{start} + {unit}(CAST("_i" * {step_number} AS BIGINT))', t)
    return f'list_transform(range(0, {count}), lambda "_i": {value})'


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
    keys = f'list_transform("_r", lambda {_E}: {_KEY})'
    problems = f'list_transform("_r", lambda {_E}, "_i": coalesce(struct_extract_at({_E}, 3), '
    if node.name.lower() == "split_to_map":
        problems += (
            f'CASE WHEN list_position({keys}, {_KEY}) < "_i" '
            f"THEN 'Duplicate keys (' || {_KEY} || ') are not allowed' END))"
        )
        result = f'map_from_entries(list_transform("_r", lambda {_E}: row({_KEY}, {_VALUE})))'
    else:
        problems += "NULL))"
        result = _grouped_values('"_r"', keys)
    first = f'list_filter({problems}, lambda "_m": "_m" IS NOT NULL)[1]'
    body = checked_map(g, f"coalesce({checks}, {first})", tf.cast(result, ttype(node)))
    return null_if_any_null(g, args, _let(rows, '"_r"', body))


register(
    "split_to_map",
    "map",
    "split_to_map(string, entryDelimiter, keyValueDelimiter) -> map(varchar, varchar)",
    _split_to_map,
    _render_split_to_map,
    notes=(
        "Errors as Trino: empty or equal delimiters, an entry without exactly one key-value delimiter, a repeated key."
    ),
)
register(
    "split_to_multimap",
    "map",
    "split_to_multimap(string, entryDelimiter, keyValueDelimiter) -> map(varchar, array(varchar))",
    _split_to_map,
    _render_split_to_map,
)


# === approx_percentile with weights ===============================================================
def _percentages(node: exp.Expression) -> list[float] | None:
    """The constant percentages of a literal, a typed literal or an ARRAY of them, else None."""
    items = node.expressions if isinstance(node, exp.Array) else [node]
    values = []
    for item in items:
        negative = isinstance(item, exp.Neg)
        item = item.this if negative else item
        literal = isinstance(item, exp.Literal) and not item.is_string
        typed = isinstance(item, exp.Cast) and isinstance(item.this, exp.Literal) and item.this.is_string
        if not (literal or typed):
            return None
        try:
            number = float(item.this.name if typed else item.name)
        except ValueError:
            return None
        values.append(-number if negative else number)
    return values


def weighted_percentile(call: Call) -> TType:
    """approx_percentile(x, w, percentage[s])."""
    x, w, p = call.types
    if x is None or not (x.is_integral or x.is_approx or x.is_decimal or x.is_unknown):
        call.mismatch()
    if w is None or not w.is_integral:
        call.mismatch()
    call.node.meta["percentages"] = _percentages(call.args[2])
    if call.node.meta["percentages"] is None:
        call.fail("unsupported in lakegate: approx_percentile with a percentage that is not a literal", "NOT_SUPPORTED")
    t = tt.BIGINT if x.is_unknown else percentile_type(x)
    return tt.array(t) if p is not None and p.base == "array" else t


def _weighted_rank(g, entries: str, total: str, percentage: float, t: TType) -> str:
    """The first value (in ascending order) at which the running weight reaches ceil(total *
    percentage), at least 1: the nearest rank of the data with each value repeated `weight` times,
    as quantile_disc answers the unweighted form."""
    rank = f"greatest(ceil({total} * {percentage!r}), 1)"
    reached = f"struct_extract(\"_s\", 'c') + struct_extract_at({_E}, 2)"
    step = (
        f'CASE WHEN struct_extract("_s", \'v\') IS NOT NULL THEN "_s" ELSE struct_pack(c := {reached}, '
        f"v := CASE WHEN {reached} >= {rank} THEN struct_extract_at({_E}, 1) END) END"
    )
    start = f"struct_pack(c := CAST(0 AS HUGEINT), v := {tf.cast('NULL', t)})"
    return f"struct_extract(list_reduce(list_sort({entries}), lambda \"_s\", {_E}: {step}, {start}), 'v')"


def render_weighted_percentile(g, node, args) -> str:
    t = ttype(node).element if ttype(node).base == "array" else ttype(node)
    percentages = node.meta["percentages"]
    if any(not 0 <= p <= 1 for p in percentages):  # checked with the first input row, as Trino does
        out_of_range = g.fail(tf.string("Percentile must be between 0 and 1"))
        return f"CASE WHEN {g.agg(node, 'count', ['*'])} > 0 THEN {out_of_range} END"
    x, w = g.sql(args[0]), f"CAST({g.sql(args[1])} AS BIGINT)"
    included = f"{x} IS NOT NULL AND {w} IS NOT NULL"  # the input function takes neither as NULL
    rows = g.agg(node, "list", [f"CASE WHEN {included} THEN row({tf.cast(x, t)}, {w}) END"])
    entries = f"list_filter({rows}, lambda {_E}: {_E} IS NOT NULL)"
    total = g.agg(node, "sum", [f"CASE WHEN {included} THEN {w} END"])
    values = [_weighted_rank(g, '"_es"', total, p, t) for p in percentages]
    value = f"[{', '.join(values)}]" if ttype(node).base == "array" else values[0]
    lightest = g.agg(node, "min", [f"CASE WHEN {included} THEN {w} END"])
    weight_error = g.fail(tf.string("Percentile weight must be positive"))
    weighted = _let(entries, '"_es"', f'CASE WHEN len("_es") = 0 THEN NULL ELSE {value} END')
    return f"CASE WHEN {lightest} <= 0 THEN {weight_error} ELSE {weighted} END"


overload(
    "approx_percentile",
    lambda call: weighted_percentile(call) if len(call.args) == 3 else None,
    render_weighted_percentile,
    "approx_percentile(x, w, percentage[s]) -> same as x",
)
overload(
    "sequence",
    lambda call: (
        temporal_sequence(call)
        if call.types and call.types[0] is not None and call.types[0].base in ("date", "timestamp")
        else None
    ),
    render_temporal_sequence,
    "sequence(start, stop, step interval) -> array(date or timestamp)",
)
