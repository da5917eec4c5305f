"""Trino's functions/array.md. Array functions and operators (those taking a lambda are in lambdas.py)."""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import write_casts as casts
from lakegate.dialect import write_operators as ops
from lakegate.dialect.functions.arguments import VARBINARY, array_arg, binary_args, literal_int, need
from lakegate.dialect.functions.rendering import (
    call_as,
    checked,
    let_bound,
    nested,
    null_if_any_null,
    ordered_pick,
    refuse_nested_floats,
    sqls,
)
from lakegate.dialect.registry import overload, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype

# --- rendering helpers ---------------------------------------------------------------------------
#: Trino's limits on results sized by an argument (SequenceFunction.MAX_RESULT_ENTRIES,
#: RepeatFunction.MAX_RESULT_ENTRIES and MAX_SIZE_IN_BYTES), and lakegate's own cap on lpad / rpad
#: and format() widths: DuckDB allocates such strings outside its memory limit.
MAX_SEQUENCE_ENTRIES = 10_000

MAX_REPEAT_ENTRIES = 10_000

MAX_REPEAT_BYTES = 1_000_000


def _cardinality(call: Call) -> TType:
    if len(call.args) != 1:
        call.mismatch()
    t = call.types[0]
    if t is None or t.base not in ("array", "map", "unknown"):
        call.mismatch()
    return tt.BIGINT


def _contains(call: Call) -> TType:
    need(call, "array", "any")
    element = array_arg(call).element
    if tt.common_super_type(element, call.types[1]) is None:
        call.mismatch()
    return tt.BOOLEAN


def _nested_common(args) -> TType | None:
    """The common type of the elements and the value when it is an array, map or row, else None."""
    common = tt.common_super_type(ttype(args[0]).element, ttype(args[1]))
    return common if common is not None and common.base in ("array", "map", "row") else None


#: Names bound in the SQL of `_matches`: the per-element flags, the array and the value.
FLAGS, ARRAY, VALUE = '"_flags"', '"_arr"', '"_value"'


def _matches(g, args, common: TType, body: str) -> str:
    """`body` with FLAGS bound to, per element of the array, Trino's `=` of it and the value: 0 for a
    NULL element (never compared), 1 equal, 2 unequal, 3 indeterminate (a NULL inside reached), and
    ARRAY to the array; NULL when the array or the value is NULL. Trino's contains, array_position
    and array_remove fail on an indeterminate comparison they reach (io.trino.operator.scalar.
    ArrayContains, ArrayPositionFunction, ArrayRemoveFunction), where DuckDB compares NULL inside
    arrays and rows as a value."""
    arr, value = g.coerce(args[0], tt.array(common)), g.coerce(args[1], common)
    e = '"_elem"'
    equal = ops.trino_equal(e, VALUE, common)
    flag = f"CASE WHEN {e} IS NULL THEN 0 ELSE CASE ({equal}) WHEN true THEN 1 WHEN false THEN 2 ELSE 3 END END"
    flags = f"list_transform({ARRAY}, lambda {e}: {flag})"
    bound = let_bound(arr, ARRAY, let_bound(value, VALUE, let_bound(flags, FLAGS, body)))
    return f"CASE WHEN ({arr}) IS NULL OR ({value}) IS NULL THEN NULL ELSE {bound} END"


def _indeterminate(name: str) -> str:
    """SQL raising Trino's NOT_SUPPORTED for function `name` reaching an indeterminate comparison (not
    an error try() catches)."""
    message = f"NOT_SUPPORTED: {name} does not support arrays with elements that are null or contain null"
    return f"error({tf.string(message)})"


def _render_contains(g, node, args) -> str:
    if (common := _nested_common(args)) is not None:
        stop = f'list_filter({FLAGS}, lambda "_f": "_f" IN (1, 3))[1]'
        return _matches(
            g,
            args,
            common,
            f"CASE {stop} WHEN 3 THEN {_indeterminate('contains')} WHEN 1 THEN true "
            f"ELSE CASE WHEN list_contains({FLAGS}, 0) THEN NULL ELSE false END END",
        )
    arr, value = g.sql(args[0]), g.sql(args[1])
    found = f"list_contains({arr}, {value})"
    if ttype(args[1]).is_approx:  # Trino's EQUAL: NaN is never found (io.trino.operator.scalar.ArrayContains)
        found += f" AND NOT isnan({value})"
    return (
        f"CASE WHEN ({value}) IS NULL OR ({arr}) IS NULL THEN NULL WHEN {found} THEN true "
        f"WHEN list_count({arr}) < len({arr}) THEN NULL ELSE false END"
    )


def _array_position(call: Call) -> TType:
    _contains(call)
    return tt.BIGINT


def _render_array_position(g, node, args) -> str:
    if (common := _nested_common(args)) is not None:
        at = f'list_position(list_transform({FLAGS}, lambda "_f": "_f" IN (1, 3)), true)'
        return _matches(
            g,
            args,
            common,
            f"CAST(CASE WHEN {at} IS NULL THEN 0 WHEN {FLAGS}[{at}] = 3 THEN {_indeterminate('array_position')} "
            f"ELSE {at} END AS BIGINT)",
        )
    arr, value = g.sql(args[0]), g.sql(args[1])
    # NaN equals nothing in Trino, not even a NaN element (DuckDB finds it)
    nan = f"WHEN isnan(CAST({value} AS DOUBLE)) THEN 0 " if _approx(args[0], args[1]) else ""
    return (
        f"CASE WHEN ({arr}) IS NULL OR ({value}) IS NULL THEN NULL {nan}"
        f"ELSE CAST(coalesce(list_position({arr}, {value}), 0) AS BIGINT) END"
    )


def _approx(array: exp.Expression, value: exp.Expression) -> bool:
    """Whether an array's element or a value is a double or real (a value that may be NaN)."""
    element = ttype(array).element if ttype(array).base == "array" else tt.UNKNOWN
    return element.is_approx or ttype(value).is_approx


def _array_join(call: Call) -> TType:
    need(call, "array", "string", "string", optional=1)
    element = array_arg(call).element
    if element.base in ("array", "map", "row", "json"):
        call.mismatch()
    call.analyzer.zones(element, call.node, "array_join")
    return tt.VARCHAR


def _render_array_join(g, node, args) -> str:
    arr, delim = g.sql(args[0]), g.sql(args[1])
    element = ttype(args[0]).element if ttype(args[0]).base == "array" else tt.UNKNOWN
    text = casts.varchar_of(g, '"_e"', element)
    if len(args) == 3:
        text = f"coalesce({text}, {g.sql(args[2])})"
    items = arr if text == '"_e"' else f'list_transform({arr}, lambda "_e": {text})'
    # NULL elements are skipped, so an all-NULL array joins to '' (io.trino.operator.scalar.ArrayJoin)
    if isinstance(args[1], exp.Literal):
        return null_if_any_null(g, args, f"coalesce(array_to_string({items}, {delim}), '')")
    # DuckDB's array_to_string takes a constant separator only: a separator of each row is put before
    # every element, and the first one cut off
    kept = f'list_filter({items}, lambda "_e": "_e" IS NOT NULL)'
    joined = f'list_reduce({kept}, lambda "_a", "_b": "_a" || {delim} || "_b", \'\')'
    return null_if_any_null(g, args, f"substr({joined}, length({delim}) + 1)")


def _array_distinct(call: Call) -> TType:
    need(call, "array")
    return array_arg(call)


def _render_array_distinct(g, node, args) -> str:
    arr = g.sql(args[0])
    # NULL of a NULL array (DuckDB's list_zip of NULLs is an empty list)
    return (
        f"CASE WHEN ({arr}) IS NULL THEN NULL ELSE "
        f"list_transform(list_filter(list_zip({arr}, range(1, len({arr}) + 1)), "
        f'lambda "_p": list_position({arr}, struct_extract("_p", 1)) = struct_extract("_p", 2)), '
        f'lambda "_p": struct_extract("_p", 1)) END'
    )


def _trim_array(call: Call) -> TType:
    need(call, "array", "integral")
    return array_arg(call)


def _render_trim_array(g, node, args) -> str:
    """ArrayTrimFunction: drop `size` elements from the end; a negative size or one past the
    cardinality is INVALID_FUNCTION_ARGUMENT."""
    arr, size = g.sql(args[0]), f"CAST({g.sql(args[1])} AS BIGINT)"
    negative = g.fail(f"{tf.string('size must not be negative: ')} || {size}")
    too_big = g.fail(
        f"{tf.string('size must not exceed array cardinality ')} || len({arr}) || {tf.string(': ')} || {size}"
    )
    return (  # NULL on NULL input, before any check (the real Trino 476 answers so)
        f"CASE WHEN ({arr}) IS NULL OR {size} IS NULL THEN NULL WHEN {size} < 0 THEN {negative} "
        f"WHEN {size} > len({arr}) THEN {too_big} ELSE list_slice({arr}, 1, len({arr}) - {size}) END"
    )


def _array_histogram(call: Call) -> TType:
    need(call, "array")
    element = array_arg(call).element
    if element.base in ("map", "json"):
        call.mismatch()
    return tt.map_of(element, tt.BIGINT)


def _render_array_histogram(g, node, args) -> str:
    """NULL elements are ignored; an array without non-NULL elements gives an empty map."""
    arr = g.sql(args[0])
    counted = f'(SELECT histogram("_e") FROM (SELECT unnest({arr}) AS "_e"))'
    return tf.cast(f"CASE WHEN ({arr}) IS NULL THEN NULL ELSE coalesce({counted}, map()) END", ttype(node))


def _array_minmax(call: Call) -> TType:
    need(call, "array")
    element = array_arg(call).element
    if element.base in ("map", "json") or element.base in ("row", "array") and nested(element):
        call.mismatch()
    refuse_nested_floats(call, element)
    return element


def _render_array_minmax(g, node, args) -> str:
    arr = g.sql(args[0])
    if ttype(node).base in ("array", "row"):
        return ordered_pick(arr, ttype(node), node.name.lower() == "array_max")
    name = "list_max" if node.name.lower() == "array_max" else "list_min"
    if name == "list_max" and ttype(node).is_approx:  # NaN only when all are NaN (ArrayMaxFunction)
        nan = tf.cast("'NaN'", ttype(node))
        return (
            f"CASE WHEN list_count({arr}) < len({arr}) OR coalesce(len({arr}), 0) = 0 THEN NULL ELSE "
            f'coalesce(list_max(list_filter({arr}, lambda "_x": NOT isnan("_x"))), {nan}) END'
        )
    return f"CASE WHEN list_count({arr}) < len({arr}) THEN NULL ELSE {name}({arr}) END"


def _element_at(call: Call) -> TType:
    t = call.types[0] if call.types else None
    if len(call.args) != 2 or t is None:
        call.mismatch()
    if t.base == "map":
        if tt.common_super_type(t.args[0], call.types[1]) is None:
            call.mismatch()
        return t.args[1]
    need(call, "array", "integral")
    return array_arg(call).element


def _render_element_at(g, node, args) -> str:
    container, index = g.sql(args[0]), g.sql(args[1])
    if ttype(args[0]).base == "map":
        return f"map_extract_value({container}, {g.coerce(args[1], ttype(args[0]).args[0])})"
    if isinstance(args[1], exp.Literal) and args[1].name != "0":
        return f"list_extract({container}, {index})"
    return (
        f"CASE WHEN ({index}) = 0 THEN {g.fail(tf.string('SQL array indices start at 1'))} "
        f"ELSE list_extract({container}, {index}) END"
    )


def _sequence(call: Call) -> TType:
    need(call, "integral", "integral", "integral", optional=1)
    return tt.array(tt.BIGINT)


def _render_sequence(g, node, args) -> str:
    # start, stop and step are bound once, as the list "_s", since the checks use each several times
    bounds = ", ".join(f"CAST({g.sql(a)} AS BIGINT)" for a in args)
    start, stop = '"_s"[1]', '"_s"[2]'
    step = '"_s"[3]' if len(args) == 3 else f"CASE WHEN {stop} >= {start} THEN 1 ELSE -1 END"
    wrong_way = (
        "sequence stop value should be greater than or equal to start value if step is greater than zero "
        "otherwise stop should be less than or equal to start"
    )
    checked_stop = checked(
        g,
        stop,
        (
            (f"{step} = 0", "step must not be zero"),
            (f"{step} > 0 AND {start} > {stop}", wrong_way),
            (f"{step} < 0 AND {start} < {stop}", wrong_way),
            (
                f"(CAST({stop} AS HUGEINT) - {start}) // {step} + 1 > {MAX_SEQUENCE_ENTRIES}",
                f"result of sequence function must not have more than {MAX_SEQUENCE_ENTRIES} entries",
            ),
        ),
    )
    null_bound = " OR ".join(f"{v} IS NULL" for v in (start, stop, step))
    return (  # NULL on a NULL bound or step, before any check (the real Trino 476 answers so)
        f'list_transform([[{bounds}]], lambda "_s": CASE WHEN {null_bound} THEN NULL ELSE '
        f"CAST(generate_series({start}, {checked_stop}, {step}) AS BIGINT[]) END)[1]"
    )


def _slice(call: Call) -> TType:
    need(call, "array", "integral", "integral")
    return array_arg(call)


def _render_slice(g, node, args) -> str:
    arr, start, length = sqls(g, args)
    begin = f"CASE WHEN ({start}) > 0 THEN ({start}) ELSE len({arr}) + ({start}) + 1 END"
    return (  # NULL on NULL input, before any check (the real Trino 476 answers so)
        f"CASE WHEN ({arr}) IS NULL OR ({start}) IS NULL OR ({length}) IS NULL THEN NULL "
        f"WHEN ({start}) = 0 THEN {g.fail(tf.string('SQL array indices start at 1'))} "
        f"WHEN ({length}) < 0 THEN {g.fail(tf.string('length must be greater than or equal to 0'))} "
        f"WHEN ({start}) < 0 AND -({start}) > len({arr}) THEN list_slice({arr}, 1, 0) "
        f"ELSE list_slice({arr}, {begin}, {begin} + ({length}) - 1) END"
    )


def _flatten(call: Call) -> TType:
    need(call, "array")
    arr = array_arg(call)
    if arr.element.base not in ("array", "unknown"):
        call.mismatch()
    return arr.element if arr.element.base == "array" else arr


def _reverse(call: Call) -> TType:
    (t,) = need(call, "any")
    if t.base == "array":
        return t
    if t.base == "varchar":
        return t
    if t.is_unknown:  # reverse(varchar(x)), reverse(varbinary) and reverse(array(E)) all take a NULL
        call.fail(tt.AMBIGUOUS, "AMBIGUOUS_FUNCTION_CALL")
    call.mismatch()


def _render_reverse(g, node, args) -> str:
    value = g.sql(args[0])
    return f"list_reverse({value})" if ttype(node).base == "array" else f"reverse({value})"


def _array_remove(call: Call) -> TType:
    """array(E) of the common type of the elements and the value (the real Trino 476 coerces both)."""
    _contains(call)
    arr, value = array_arg(call), call.types[1]
    common = None if value is None or value.is_unknown else tt.common_super_type(arr.element, value)
    return tt.array(common) if common is not None else arr


def _render_array_remove(g, node, args) -> str:
    if (common := _nested_common(args)) is not None:
        kept = f'list_filter({ARRAY}, lambda "_e", "_i": {FLAGS}["_i"] <> 1)'
        return _matches(
            g,
            args,
            common,
            f"CASE WHEN list_contains({FLAGS}, 3) THEN {_indeterminate('array_remove')} ELSE {kept} END",
        )
    arr, value = g.coerce(args[0], ttype(node)), g.sql(args[1])
    # Trino's EQUAL: a NaN is unequal to everything and stays (io.trino.operator.scalar.ArrayRemoveFunction)
    keep_nan = ' OR isnan("_e")' if ttype(args[1]).is_approx else ""
    return (
        f'CASE WHEN ({value}) IS NULL THEN NULL ELSE list_filter({arr}, lambda "_e": '
        f'"_e" IS NULL OR "_e" <> {value}{keep_nan}) END'
    )


def _arrays_overlap(call: Call) -> TType:
    need(call, "array", "array")
    if tt.common_super_type(array_arg(call, 0), array_arg(call, 1)) is None:
        call.mismatch()
    return tt.BOOLEAN


def _render_arrays_overlap(g, node, args) -> str:
    a, b = g.sql(args[0]), g.sql(args[1])
    return (
        f"CASE WHEN ({a}) IS NULL OR ({b}) IS NULL THEN NULL WHEN list_has_any({a}, {b}) THEN true "
        f"WHEN len({a}) > 0 AND len({b}) > 0 AND (list_count({a}) < len({a}) OR list_count({b}) < len({b})) "
        f"THEN NULL ELSE false END"
    )


def _repeat(call: Call) -> TType:
    types = need(call, "any", "integral")
    return tt.array(types[0])


def _render_repeat(g, node, args) -> str:
    value, count = g.sql(args[0]), g.sql(args[1])
    checks = [
        (
            f"({count}) > {MAX_REPEAT_ENTRIES}",
            f"count argument of repeat function must be less than or equal to {MAX_REPEAT_ENTRIES}",
        ),
        (f"({count}) < 0", "count argument of repeat function must be greater than or equal to 0"),
    ]
    if ttype(args[0]).base == "varchar":  # Trino counts each entry's bytes plus 5 (offset and null flag)
        checks.append(
            (
                f"({count}) > 0 AND strlen({value}) + 5 > ({MAX_REPEAT_BYTES} + ({count})) // ({count})",
                f"result of repeat function must not take more than {MAX_REPEAT_BYTES} bytes",
            )
        )
    return f'list_transform(range({checked(g, f"CAST({count} AS BIGINT)", checks)}), lambda "_i": {value})'


_MINMAX_NOTE = "Over arrays or rows too: a comparison reaching a NULL inside them fails as in Trino."


def _render_reverse_binary(g, node, args) -> str:
    return f"unhex(array_to_string(list_reverse(regexp_extract_all(hex({g.sql(args[0])}), '..')), ''))"


# === arrays =======================================================================================
def _two_arrays(call: Call) -> TType:
    """Both arguments coerced to their common array type (the result type of the set functions)."""
    need(call, "array", "array")
    t = tt.common_super_type(array_arg(call, 0), array_arg(call, 1))
    if t is None or t.element.base in ("map", "json"):
        call.mismatch()
    return t


def _first_occurrences(arr: str) -> str:
    """The elements of `arr` not equal to an earlier one; NULL and NaN are values and kept once (DuckDB's
    list_position finds NULL and NaN, as Trino's IDENTICAL operator does)."""
    return f'list_filter({arr}, lambda "_x", "_i": list_position({arr}, "_x") = "_i")'


def _array_union(call: Call) -> TType:
    t = _two_arrays(call)
    if t.element.base in ("array", "row"):
        call.fail("unsupported in lakegate: array_union of arrays of arrays or rows", "NOT_SUPPORTED")
    return t


def _render_array_union(g, node, args) -> str:
    """ArrayUnionFunction: x's then y's elements, each value once (NULL once, and NaN once: the real
    Trino 476 answers `array_union(ARRAY[nan()], ARRAY[nan()])` with one NaN)."""
    t = ttype(node)
    both = f"list_concat({g.coerce(args[0], t)}, {g.coerce(args[1], t)})"
    return null_if_any_null(g, args, let_bound(both, '"_u"', _first_occurrences('"_u"')))


def _render_array_intersect(g, node, args) -> str:
    """ArrayIntersectFunction: the distinct elements of the longer array (the first when equally
    long) found in the other, in the longer array's order; IDENTICAL, so NULL and NaN match."""
    t = ttype(node)
    x, y = g.coerce(args[0], t), g.coerce(args[1], t)

    def intersect(longer: str, shorter: str) -> str:
        found = f'list_filter({longer}, lambda "_y": list_position({shorter}, "_y") IS NOT NULL)'
        return let_bound(found, '"_f"', _first_occurrences('"_f"'))

    return null_if_any_null(g, args, f"CASE WHEN len({x}) < len({y}) THEN {intersect(y, x)} ELSE {intersect(x, y)} END")


def _render_array_except(g, node, args) -> str:
    """ArrayExceptFunction: x unchanged when either array is empty, else x's distinct elements not in
    y, in x's order; IDENTICAL, so NULL and NaN match."""
    t = ttype(node)
    x, y = g.coerce(args[0], t), g.coerce(args[1], t)
    distinct = let_bound(x, '"_d"', _first_occurrences('"_d"'))
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
    _, n = need(call, "array", "integral")
    if n.base == "bigint":  # ngrams(array(T), integer): a bigint does not coerce to integer
        call.mismatch()
    return tt.array(array_arg(call))


def _render_ngrams(g, node, args) -> str:
    """ArrayNgramsFunction: windows of min(n, cardinality) adjacent elements, so an empty array gives
    one empty n-gram; n must be positive."""
    arr, n = g.sql(args[0]), f"CAST({g.sql(args[1])} AS BIGINT)"
    size = f"least(len({arr}), {n})"
    grams = (
        f'list_transform(range(0, len({arr}) - {size} + 1), lambda "_i": list_slice({arr}, "_i" + 1, "_i" + {size}))'
    )
    nulls = f"({arr}) IS NULL OR {n} IS NULL"
    return f"CASE WHEN {nulls} THEN NULL WHEN {n} <= 0 THEN {g.fail(tf.string('N must be positive'))} ELSE {grams} END"


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
    outermost loop, so that a too large result fails before it is built (see checked)."""
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
            f"{span} // {step_number} + 1 > {MAX_SEQUENCE_ENTRIES}",
            f"result of sequence function must not have more than {MAX_SEQUENCE_ENTRIES} entries",
        ),
    ]
    count = checked(g, f"{span} // {step_number} + 1", checks)
    value = tf.cast(f'{start} + {unit}(CAST("_i" * {step_number} AS BIGINT))', t)
    nulls = " OR ".join(f"({v}) IS NULL" for v in (start, stop, step) if v is not None)
    # NULL on a NULL bound or step, before any check (the real Trino 476 answers so)
    return f'CASE WHEN {nulls} THEN NULL ELSE list_transform(range(0, {count}), lambda "_i": {value}) END'


def install() -> None:
    """Register the functions of this page (called by pages.py)."""
    register("trim_array", "array", "trim_array(x, n) -> array", _trim_array, _render_trim_array)
    register(
        "array_histogram", "array", "array_histogram(x) -> map(K, bigint)", _array_histogram, _render_array_histogram
    )
    register(
        "cardinality",
        "array",
        "cardinality(array) -> bigint; cardinality(map) -> bigint",
        _cardinality,
        lambda g, node, args: (
            f"CAST({'cardinality' if ttype(args[0]).base == 'map' else 'len'}({g.sql(args[0])}) AS BIGINT)"
        ),
    )
    register(
        "contains",
        "array",
        "contains(array, element) -> boolean",
        _contains,
        _render_contains,
        notes="NULL when the element is absent and the array holds a NULL, as in Trino.",
    )
    register(
        "array_position",
        "array",
        "array_position(array, element) -> bigint",
        _array_position,
        _render_array_position,
        notes="0 when absent, as in Trino (DuckDB gives NULL).",
    )
    register(
        "array_join",
        "array",
        "array_join(array, delimiter[, null_replacement]) -> varchar",
        _array_join,
        _render_array_join,
        notes="Elements render as CAST(... AS VARCHAR) does in Trino; NULLs are skipped.",
    )
    register(
        "array_distinct",
        "array",
        "array_distinct(array) -> array",
        _array_distinct,
        _render_array_distinct,
        notes="Keeps the first occurrence of each value in order, as in Trino.",
    )
    register(
        "array_max", "array", "array_max(array) -> element", _array_minmax, _render_array_minmax, notes=_MINMAX_NOTE
    )
    register(
        "array_min", "array", "array_min(array) -> element", _array_minmax, _render_array_minmax, notes=_MINMAX_NOTE
    )
    register(
        "element_at",
        "array",
        "element_at(array, index) -> element; element_at(map, key) -> value",
        _element_at,
        _render_element_at,
        notes="NULL beyond the end; negative indexes count from the end.",
    )
    register(
        "sequence",
        "array",
        "sequence(start, stop[, step]) -> array(bigint); sequence(date, date[, interval]) -> array(date); "
        "sequence(timestamp, timestamp, interval) -> array(timestamp)",
        _sequence,
        _render_sequence,
        notes="A month step adds i months to the start (clamped to the month's end), as Trino.",
    )
    register("slice", "array", "slice(array, start, length) -> array", _slice, _render_slice)
    register("flatten", "array", "flatten(array(array(T))) -> array(T)", _flatten, call_as("flatten"))
    register("reverse", "array", "reverse(array) -> array; reverse(string) -> varchar", _reverse, _render_reverse)
    register("array_remove", "array", "array_remove(array, element) -> array", _array_remove, _render_array_remove)
    register(
        "arrays_overlap", "array", "arrays_overlap(array, array) -> boolean", _arrays_overlap, _render_arrays_overlap
    )
    register("repeat", "array", "repeat(element, count) -> array", _repeat, _render_repeat)
    overload(
        "reverse",
        lambda c: VARBINARY if binary_args(c, 1) else None,
        _render_reverse_binary,
        "reverse(binary) -> varbinary",
    )

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
