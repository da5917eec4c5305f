"""Trino's functions/aggregate.md. Aggregate functions: general, bitwise, map, approximate and statistical
aggregates.
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import write_casts as casts
from lakegate.dialect import write_operators as ops
from lakegate.dialect.functions.arguments import as_double, fixed, literal_int, map_arg, need, plain_key, same
from lakegate.dialect.functions.rendering import (
    ENTRY,
    ENTRY_KEY,
    agg_as,
    grouped_values,
    let_bound,
    map_entries,
)
from lakegate.dialect.registry import Render, overload, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


# === aggregate ====================================================================================
def _sum(call: Call) -> TType:
    (t,) = need(call, "number")
    if t.is_integral or t.is_unknown:
        return tt.BIGINT
    if t.is_decimal:
        return tt.decimal(38, t.args[1])
    return t


def _avg(call: Call) -> TType:
    (t,) = need(call, "number")
    if t.is_decimal or t.base == "real":
        return t
    return tt.DOUBLE


def _render_avg(g, node, args) -> str:
    t = ttype(node)
    if not t.is_decimal:
        return tf.cast(g.agg(node, "avg", [g.sql(args[0])]), t)
    scale = t.args[1]
    total = g.agg(node, "sum", [g.sql(args[0])])
    count = g.agg(node, "count", [g.sql(args[0])])
    numerator = ops.unscaled_sql(total, tt.decimal(38, scale))  # DuckDB's sum of decimal(p, s) is decimal(38, s)
    return f"CASE WHEN {count} = 0 THEN NULL ELSE {ops.rounded_quotient(g, numerator, count, t)} END"


def _minmax(call: Call) -> TType:
    if len(call.args) == 2:
        t, n = need(call, "orderable", "integral")
        if call.name == "max" and t.is_approx:
            call.fail(
                "unsupported in lakegate: max(x, n) over real or double (Trino's NaN ordering is not translated)",
                "NOT_SUPPORTED",
            )
        return tt.array(t)
    (t,) = need(call, "orderable")
    if t.base == "row" or t.base == "array":
        call.fail(f"min/max over {t} is not supported in lakegate", "NOT_SUPPORTED")
    return t


# Trino's max, max_by, greatest and array_max order NaN below every number, min and friends above
# (io.trino.util.MinMaxCompare: COMPARISON_UNORDERED_FIRST / _LAST), so NaN wins only when all values
# are NaN; DuckDB orders NaN above every number, which is right for the min side only. So max is the
# negated min of the negated values: one aggregate (about as fast as DuckDB's max), exact negation
# keeps -0.0's sign, and ties keep the first value seen, as Trino's max does.
def _render_max(g, node, args) -> str:
    if len(args) == 2 or not ttype(args[0]).is_approx:
        return agg_as("max")(g, node, args)
    return f"-({g.agg(node, 'min', [f'-({g.sql(args[0])})'])})"


def _render_max_by(g, node, args) -> str:
    value, key = g.sql(args[0]), g.sql(args[1])
    if ttype(args[1]).is_approx:  # non-NaN keys above NaN keys, then by value
        key = f"CASE WHEN {key} IS NULL THEN NULL ELSE struct_pack(n := NOT isnan({key}), v := {key}) END"
    return tf.cast(g.agg(node, "arg_max_null", [value, key]), ttype(node))


def _by(call: Call) -> TType:
    if len(call.args) == 3:
        return _by_n(call)
    x, y = need(call, "any", "orderable")
    return x


#: MaxByNStateFactory.MAX_NUMBER_OF_VALUES
MAX_BY_N = 10_000


def _by_n(call: Call) -> TType:
    """max_by(x, y, n) / min_by(x, y, n) -> array(x): a literal n in 1..10000, as Trino checks it."""
    x, _, _ = need(call, "any", "orderable", "integral")
    n = literal_int(call, 2)
    if n is None:
        call.fail(f"unsupported in lakegate: {call.name} with a count that is not a literal", "NOT_SUPPORTED")
    if call.node.meta.get("distinct") or call.node.meta.get("order") is not None:
        call.fail(f"unsupported in lakegate: {call.name} with a count and DISTINCT or ORDER BY", "NOT_SUPPORTED")
    if n <= 0:
        call.fail(f"third argument of {call.name} must be a positive integer", "INVALID_FUNCTION_ARGUMENT")
    if n > MAX_BY_N:
        call.fail(
            f"third argument of {call.name} must be less than or equal to {MAX_BY_N}; found {n}",
            "INVALID_FUNCTION_ARGUMENT",
        )
    return tt.array(x)


def _render_by(duck: str, descending: bool) -> Render:
    """max_by / min_by; with a count, the x of the n rows of largest (smallest) non-NULL y, in that
    order, NULL x kept (MinMaxByNAggregationFunction). A NaN key never wins, as with Trino's
    COMPARISON_UNORDERED_FIRST / _LAST ordering."""
    plain = agg_as(duck)

    def render(g, node, args):
        if len(args) == 2:
            return plain(g, node, args)
        x, y = g.sql(args[0]), g.sql(args[1])
        keys = (f"isnan({y}), " if ttype(args[1]).is_approx else "") + f"{y} {'DESC' if descending else 'ASC'}"
        where = f"({y}) IS NOT NULL"
        if node.meta.get("filter") is not None:
            where += f" AND ({g.sql(node.meta['filter'])})"
        over = f" {g.over(node.meta['over'])}" if node.meta.get("over") is not None else ""
        collected = f"array_agg({x} ORDER BY {keys}) FILTER (WHERE {where}){over}"
        return tf.cast(f"list_slice({collected}, 1, {g.sql(args[2])})", ttype(node))

    return render


def _array_agg(call: Call) -> TType:
    (t,) = need(call, "any")
    return tt.array(t)


def _approx_percentile(call: Call) -> TType:
    if len(call.args) != 2:
        call.fail("approx_percentile with weights or accuracy is not supported in lakegate", "NOT_SUPPORTED")
    x, p = call.types
    if x is None or not (x.is_integral or x.is_approx or x.is_decimal or x.is_unknown):
        call.mismatch()
    if not _constant_percentage(call):
        call.fail("unsupported in lakegate: approx_percentile with a percentage that is not a literal", "NOT_SUPPORTED")
    if p is not None and p.base == "array":
        return tt.array(percentile_type(x))
    if p is None or not (p.is_numeric or p.is_unknown):
        call.mismatch()
    return percentile_type(x)


def percentile_type(x: TType) -> TType:
    """approx_percentile's value type: Trino has bigint, double and real forms; integers take the
    bigint one, a decimal coerces to real, the most specific form it fits (trinodb/trino#23880)."""
    if x.is_integral:
        return tt.BIGINT
    return tt.REAL if x.is_decimal else x


def _typed_number_literal(node: exp.Expression) -> str | None:
    """The number of a typed literal such as DOUBLE '0.5' (a cast of a string literal), else None."""
    if isinstance(node, exp.Cast) and isinstance(node.this, exp.Literal) and node.this.is_string:
        try:
            return repr(float(node.this.name))
        except ValueError:
            return None
    return None


def _constant_percentage(call: Call) -> bool:
    """DuckDB's quantile needs a constant: a number literal, a typed literal, or an array of them."""
    node = call.args[1]
    if isinstance(node, exp.Array):
        return all(isinstance(e, exp.Literal) or _typed_number_literal(e) for e in node.expressions)
    return call.literal(1) is not None or _typed_number_literal(node) is not None


def _render_approx_percentile(g, node, args) -> str:
    """Trino's t-digest keeps each of up to 39 values as its own centroid and answers the value of
    rank floor(p * n) + 1 (of the n non-NULL values, at most n); the real Trino 476 answers so on
    every input of up to 39 values asked. Past that it merges centroids and interpolates, in an
    order that depends on how the rows reach it: lakegate answers the same rank there (within
    Trino's documented error). NaN and infinities fail, as in Trino."""
    t = ttype(node)
    element = t.element if t.base == "array" else t
    return _ranked(g, node, tf.cast(g.sql(args[0]), element), _percentages(args[1]))


def _ranked(g, node, x: str, percentages: list[float]) -> str:
    """approx_percentile's value of rank floor(p * n) + 1 among the non-NULL values `x` (at most n)."""
    t = ttype(node)
    if any(not 0 <= p <= 1 for p in percentages):  # checked with the first input row, as Trino does
        out_of_range = aggregate_failure(g, tf.string("Percentile must be between 0 and 1"))
        return f"CASE WHEN {g.agg(node, 'count', ['*'])} > 0 THEN {out_of_range} END"
    ranked = '"_ps"'
    picks = [f"{ranked}[least(floor({p!r} * len({ranked})), len({ranked}) - 1)::BIGINT + 1]" for p in percentages]
    value = f"[{', '.join(picks)}]" if t.base == "array" else picks[0]
    sorted_values = f'list_sort(list_filter({g.agg(node, "list", [x])}, lambda "_v": "_v" IS NOT NULL))'
    sql = let_bound(sorted_values, ranked, f"CASE WHEN coalesce(len({ranked}), 0) = 0 THEN NULL ELSE {value} END")
    if not (t.element if t.base == "array" else t).is_approx:
        return sql
    infinite = g.agg(node, "min", [f"CASE WHEN NOT isfinite({x}) THEN CAST({x} AS VARCHAR) END"])
    message = f"'value must be finite; was ' || replace(replace({infinite}, 'inf', 'Infinity'), 'nan', 'NaN')"
    return f"CASE WHEN {infinite} IS NOT NULL THEN {aggregate_failure(g, message)} ELSE {sql} END"


def aggregate_failure(g, message_sql: str) -> str:
    """An aggregate's INVALID_FUNCTION_ARGUMENT: raised even inside try(), which Trino applies to the
    projection over the aggregate's result, not to the aggregation."""
    depth, g.in_try = g.in_try, 0
    try:
        return g.fail(message_sql)
    finally:
        g.in_try = depth


def _render_count_if(g, node, args) -> str:
    """DuckDB's count_if is NULL over no rows or only NULLs; Trino's is 0."""
    return f"COALESCE({g.agg(node, 'count_if', [g.sql(args[0])])}, 0)::BIGINT"


def _render_sum(g, node, args) -> str:
    t = ttype(node)
    total = g.agg(node, "sum", [g.sql(args[0])])
    if t.is_integral:
        return ops.checked_integer(g, total, t, tf.string("bigint addition overflow"))
    return tf.cast(total, t)


def _histogram(call: Call) -> TType:
    (t,) = need(call, "orderable")
    if t.is_unknown:
        call.mismatch()
    return tt.map_of(t, tt.BIGINT)


_render_max_by_n = _render_by("arg_max_null", descending=True)


def _bivariate(call: Call) -> TType:
    """corr, covar_* and regr_*: double when an argument is double or decimal, else real: Trino
    coerces integers (and NULL) to real, the cheaper coercion, and runs its Real* aggregation."""
    types = need(call, "number", "number")
    return tt.DOUBLE if any(t.base in ("double", "decimal") for t in types) else tt.REAL


def _render_bivariate(g, node, args) -> str:
    """The aggregate over the arguments as Trino coerced them (to real, for a real result: the
    values rounded to float, computed in double, the result rounded to float); corr and regr_* are
    NULL when the result is not finite (a zero variance, NaN or infinite input, an overflow), as
    the real Trino 476 answers."""
    name = node.name.lower()
    values = [g.sql(a) for a in args]
    if ttype(node).base == "real":
        values = [f"CAST(CAST({v} AS REAL) AS DOUBLE)" for v in values]
    sql = g.agg(node, name, values)
    if name != "covar_samp" and name != "covar_pop":
        sql = f"CASE WHEN isfinite({sql}) THEN {sql} END"
    elif ttype(node).base == "double":
        # Trino's update multiplies the deviations first (NaN when that product overflows on a group's
        # first row, where DuckDB's gives 0): finite values whose product overflows are refused
        x, y = values
        overflow = g.agg(node, "bool_or", [f"isfinite({x}) AND isfinite({y}) AND isinf({x} * {y})"])
        sql = f"CASE WHEN {overflow} THEN error({tf.string(_COVARIANCE_OVERFLOW)}) ELSE {sql} END"
    return tf.cast(sql, ttype(node))


_COVARIANCE_OVERFLOW = (
    "NOT_SUPPORTED: unsupported in lakegate: covar_samp or covar_pop of values whose product overflows double "
    "(Trino's answer depends on the order of the rows)"
)


#: ListaggAggregationFunction: the output limit (DEFAULT_MAX_PAGE_SIZE_IN_BYTES) and its error.
LISTAGG_MAX_BYTES = 1_048_576


def _render_listagg(g, node, args) -> str:
    text = g.agg(node, "string_agg", [g.sql(args[0]), g.sql(args[1]) if len(args) > 1 else "''"])
    if node.meta.get("overflow_truncate"):
        overflow = (
            "error("
            + tf.string(
                "NOT_SUPPORTED: listagg ON OVERFLOW TRUNCATE of a result longer than "
                f"{LISTAGG_MAX_BYTES} bytes is not supported in lakegate"
            )
            + ")"
        )
    else:
        overflow = (
            "error("
            + tf.string(
                "EXCEEDED_FUNCTION_MEMORY_LIMIT: Concatenated string has the length in "
                f"bytes larger than the maximum output length {LISTAGG_MAX_BYTES}"
            )
            + ")"
        )
    return f"CASE WHEN strlen({text}) > {LISTAGG_MAX_BYTES} THEN {overflow} ELSE {text} END"  # strlen: UTF-8 bytes


def _first_per_key(entries: str) -> str:
    """The entries (a list of (key, value) rows) whose key did not occur earlier in the list."""
    keys = f'list_transform({entries}, lambda "_p": struct_extract_at("_p", 1))'
    return f'list_filter({entries}, lambda "_p", "_i": list_position({keys}, struct_extract_at("_p", 1)) = "_i")'


# === map-building aggregates ======================================================================
def _key_value_agg(call: Call) -> tuple[TType, TType]:
    key, value = need(call, "any", "any")
    if key.is_unknown:
        call.mismatch()
    plain_key(call, key)
    return key, value


def _collected_entries(g, node, key: str, value: str) -> str:
    """The aggregate's (key, value) rows in input order (its ORDER BY), rows with a NULL key
    dropped: the key argument of MapAggregationFunction / MultimapAggregationFunction is not
    nullable, so Trino skips those rows."""
    rows = g.agg(node, "list", [f"row({key}, {value})"])
    return f"list_filter({rows}, lambda {ENTRY}: {ENTRY_KEY} IS NOT NULL)"


def _map_or_null(entries: str, result: str) -> str:
    """NULL over no entries (AbstractMapAggregationState.serialize), else `result` with the entries
    bound to "_es"."""
    return let_bound(entries, '"_es"', f'CASE WHEN len("_es") = 0 THEN NULL ELSE {result} END')


_FIRST_PER_KEY = f"map_from_entries({_first_per_key(tf.quote('_es'))})"


def _render_map_agg(g, node, args) -> str:
    """MapAggregationFunction: the first value of a key wins (in the aggregate's ORDER BY)."""
    entries = _collected_entries(g, node, g.sql(args[0]), g.sql(args[1]))
    return tf.cast(_map_or_null(entries, _FIRST_PER_KEY), ttype(node))


def _render_multimap_agg(g, node, args) -> str:
    entries = _collected_entries(g, node, g.sql(args[0]), g.sql(args[1]))
    keys = f'list_transform("_es", lambda {ENTRY}: {ENTRY_KEY})'
    return tf.cast(_map_or_null(entries, grouped_values('"_es"', keys)), ttype(node))


def _map_union(call: Call) -> TType:
    need(call, "any")
    return map_arg(call)


def _render_map_union(g, node, args) -> str:
    """MapUnionAggregation: NULL maps are skipped; a key held by several maps takes the value of
    the first (Trino: an arbitrary one of them)."""
    maps = g.agg(node, "list", [map_entries(g.sql(args[0]))])
    entries = f'flatten(list_filter({maps}, lambda "_m": "_m" IS NOT NULL))'
    return tf.cast(_map_or_null(entries, _FIRST_PER_KEY), ttype(node))


# === aggregates ===================================================================================
def _bitwise_agg(call: Call) -> TType:
    need(call, "integral")
    return tt.BIGINT


_MOMENT_RANGE = "1e60"  # below it, a fourth power of n values stays finite
_HUGE_MOMENT = (
    "NOT_SUPPORTED: unsupported in lakegate: skewness or kurtosis of values of magnitude 1e60 or more (Trino's "
    "moments overflow in an order of its own)"
)


def _moment(g, node, args, minimum: int, value) -> str:
    """CentralMomentsAggregation: NULL below `minimum` values, NaN when one is NaN or infinite (as
    the real Trino 476 answers; DuckDB fails) or when they are all equal (a zero second moment
    divides zero by zero), else `value(x)` of the values; values of 1e60 or more are refused."""
    x = f"CAST({g.sql(args[0])} AS DOUBLE)"
    safe = f"CASE WHEN abs({x}) < {_MOMENT_RANGE} THEN {x} END"
    count, spread = g.agg(node, "count", [x]), g.agg(node, "var_pop", [safe])
    infinite = g.agg(node, "bool_or", [f"NOT isfinite({x})"])
    huge = g.agg(node, "bool_or", [f"abs({x}) >= {_MOMENT_RANGE} AND isfinite({x})"])
    return (
        f"CASE WHEN {count} < {minimum} THEN NULL WHEN {infinite} THEN CAST('NaN' AS DOUBLE) "
        f"WHEN {huge} THEN error({tf.string(_HUGE_MOMENT)}) "
        f"WHEN {spread} = 0 THEN CAST('NaN' AS DOUBLE) ELSE {value(safe)} END"
    )


def _render_population(duck: str) -> Render:
    """var_pop and stddev_pop: of one value that is NaN or infinite, NaN (Trino's running update
    multiplies it by x - x, NaN; DuckDB's gives 0)."""

    def render(g, node, args) -> str:
        x = f"CAST({g.sql(args[0])} AS DOUBLE)"
        one, infinite = g.agg(node, "count", [x]), g.agg(node, "bool_or", [f"NOT isfinite({x})"])
        return f"CASE WHEN {one} = 1 AND {infinite} THEN CAST('NaN' AS DOUBLE) ELSE {g.agg(node, duck, [x])} END"

    return render


def _render_kurtosis(g, node, args) -> str:
    """Trino's estimator, (n-1)n(n+1)/((n-2)(n-3)) m4/m2^2 - 3(n-1)^2/((n-2)(n-3)), is DuckDB's."""
    return _moment(g, node, args, 4, lambda x: g.agg(node, "kurtosis", [x]))


def _render_skewness(g, node, args) -> str:
    """Trino's is the population skewness sqrt(n) m3 / m2^1.5; DuckDB's is the sample skewness,
    that times sqrt(n(n-1))/(n-2)."""

    def skewness(x: str) -> str:
        n = g.agg(node, "count", [x])
        return f"{g.agg(node, 'skewness', [x])} * ({n} - 2) / sqrt({n} * ({n} - 1))"

    return _moment(g, node, args, 3, skewness)


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
    return tf.cast(let_bound(values, '"_vs"', f'CASE WHEN len("_vs") = 0 THEN NULL ELSE {folded} END'), ttype(node))


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


_HEAVY_WEIGHT = (
    "NOT_SUPPORTED: unsupported in lakegate: approx_percentile with a weight above 1 (Trino's t-digest "
    "interpolates between weighted values)"
)


def render_weighted_percentile(g, node, args) -> str:
    """Weights of 1 answer as the unweighted form, and percentiles 0 and 1 are the minimum and maximum;
    otherwise a weight above 1 is refused: the real Trino 476 interpolates there (weights 1, 1, 2 of
    values 1, 2, 3 give 2 at 0.5, not a rank's 3)."""
    t = ttype(node).element if ttype(node).base == "array" else ttype(node)
    x, w = g.sql(args[0]), f"CAST({g.sql(args[1])} AS BIGINT)"
    included = f"CASE WHEN {w} IS NOT NULL THEN {tf.cast(x, t)} END"  # the input function takes neither as NULL
    ranked = _ranked(g, node, included, node.meta["percentages"])
    lightest = g.agg(node, "min", [f"CASE WHEN {x} IS NOT NULL THEN {w} END"])
    heaviest = g.agg(node, "max", [f"CASE WHEN {x} IS NOT NULL THEN {w} END"])
    as_double = casts.approx_text(f"CAST({lightest} AS DOUBLE)", tt.DOUBLE)  # Java's Double.toString
    weight_text = f"CASE WHEN abs({lightest}) < 10000000 THEN CAST({lightest} AS VARCHAR) || '.0' ELSE {as_double} END"
    weight_error = aggregate_failure(g, f"'weight must be >= 1, was ' || {weight_text}")
    if all(p in (0.0, 1.0) for p in node.meta["percentages"]):  # the minimum and maximum, whatever the weights
        return f"CASE WHEN {lightest} <= 0 THEN {weight_error} ELSE {ranked} END"
    return (
        f"CASE WHEN {lightest} <= 0 THEN {weight_error} WHEN {heaviest} > 1 THEN error({tf.string(_HEAVY_WEIGHT)}) "
        f"ELSE {ranked} END"
    )


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "count",
        "aggregate",
        "count(*) -> bigint; count(x) -> bigint",
        lambda c: tt.BIGINT if len(c.args) <= 1 else c.mismatch(),
        agg_as("count"),
        kind="aggregate",
    )

    register(
        "count_if",
        "aggregate",
        "count_if(boolean) -> bigint",
        fixed(tt.BIGINT, "boolean"),
        _render_count_if,
        kind="aggregate",
    )

    register(
        "sum",
        "aggregate",
        "sum(x) -> bigint for integers, decimal(38,s) for decimal(p,s), same for real/double",
        _sum,
        _render_sum,
        kind="aggregate",
        notes="DuckDB sums integers as HUGEINT; the result is cast to bigint and fails on overflow like Trino.",
    )
    register(
        "avg",
        "aggregate",
        "avg(x) -> double for integers, decimal(p,s) for decimal(p,s), real/double",
        _avg,
        _render_avg,
        kind="aggregate",
        notes="avg(decimal(p,s)) is computed exactly and rounded HALF_UP to scale s, as Trino does.",
    )
    register("min", "aggregate", "min(x) -> same; min(x, n) -> array", _minmax, agg_as("min"), kind="aggregate")
    register(
        "max",
        "aggregate",
        "max(x) -> same; max(x, n) -> array",
        _minmax,
        _render_max,
        kind="aggregate",
        notes="NaN only when every value is NaN, as in Trino.",
    )
    register(
        "arbitrary",
        "aggregate",
        "arbitrary(x) -> same",
        same("any"),
        agg_as("any_value"),
        kind="aggregate",
        aliases=("any_value",),
    )

    register(
        "histogram",
        "aggregate",
        "histogram(x) -> map(K, bigint)",
        _histogram,
        agg_as("histogram"),
        kind="aggregate",
        notes="NULL values are not counted; NULL for no rows (Histogram.java).",
    )
    register(
        "max_by",
        "aggregate",
        "max_by(x, y) -> type of x; max_by(x, y, n) -> array(type of x)",
        _by,
        lambda g, node, args: (_render_max_by_n if len(args) == 3 else _render_max_by)(g, node, args),
        kind="aggregate",
        notes="A NaN y is below every number, as in Trino.",
    )
    register(
        "min_by",
        "aggregate",
        "min_by(x, y) -> type of x; min_by(x, y, n) -> array(type of x)",
        _by,
        _render_by("arg_min_null", descending=False),
        kind="aggregate",
    )
    register(
        "array_agg",
        "aggregate",
        "array_agg(x) -> array(x)",
        _array_agg,
        agg_as("list", cast_result=False),
        kind="aggregate",
    )
    register(
        "approx_distinct",
        "aggregate",
        "approx_distinct(x) -> bigint",
        lambda c: tt.BIGINT if len(c.args) in (1, 2) and c.types[0] is not None else c.mismatch(),
        lambda g, node, args: tf.cast(g.agg(node, "count", [f"DISTINCT {g.sql(args[0])}"]), tt.BIGINT),  # FILTER too
        kind="aggregate",
        notes="Returns the exact distinct count, which is within Trino's documented standard error (2.3%).",
    )
    register(
        "approx_percentile",
        "aggregate",
        "approx_percentile(x[, w], percentage) -> same as x (real for a decimal x); "
        "approx_percentile(x[, w], array(double)) -> array",
        _approx_percentile,
        _render_approx_percentile,
        kind="aggregate",
        notes="The value of rank floor(p * n) + 1, as Trino's t-digest answers up to 39 values (past that Trino "
        "interpolates, lakegate keeps the rank: within Trino's documented error); NaN and infinities fail; weights "
        "of 1 only (a weight above 1 is refused, except for percentiles 0 and 1); the accuracy variant is rejected.",
    )
    register(
        "bool_and",
        "aggregate",
        "bool_and(boolean) -> boolean",
        fixed(tt.BOOLEAN, "boolean"),
        agg_as("bool_and", cast_result=False),
        kind="aggregate",
        aliases=("every",),
    )
    register(
        "bool_or",
        "aggregate",
        "bool_or(boolean) -> boolean",
        fixed(tt.BOOLEAN, "boolean"),
        agg_as("bool_or", cast_result=False),
        kind="aggregate",
    )
    for _name, _duck in (
        ("stddev", "stddev_samp"),
        ("stddev_samp", "stddev_samp"),
        ("variance", "var_samp"),
        ("var_samp", "var_samp"),
    ):
        register(_name, "aggregate", f"{_name}(x) -> double", as_double("number"), agg_as(_duck), kind="aggregate")
    for _name in ("stddev_pop", "var_pop"):
        register(
            _name,
            "aggregate",
            f"{_name}(x) -> double",
            as_double("number"),
            _render_population(_name),
            kind="aggregate",
        )

    for _name in ("corr", "covar_samp", "covar_pop", "regr_slope", "regr_intercept"):
        register(
            _name,
            "aggregate",
            f"{_name}(y, x) -> real (double when y or x is double or decimal)",
            _bivariate,
            _render_bivariate,
            kind="aggregate",
        )

    register(
        "listagg",
        "aggregate",
        "listagg(x, separator) WITHIN GROUP (ORDER BY ...) -> varchar",
        lambda c: (
            tt.VARCHAR
            if len(c.args) in (1, 2) and all(t is not None and t.base in ("varchar", "unknown") for t in c.types)
            else c.mismatch()
        ),
        lambda g, node, args: _render_listagg(g, node, args),
        kind="aggregate",
        notes="ON OVERFLOW ERROR (the default) fails past 1,048,576 bytes as in Trino; ON OVERFLOW TRUNCATE is "
        "answered until the result would be truncated, then refused at run time (NOT_SUPPORTED).",
    )
    register(
        "geometric_mean",
        "aggregate",
        "geometric_mean(x) -> double",
        as_double("number"),
        # DuckDB's geometric_mean is this macro, which takes no FILTER, DISTINCT or OVER
        lambda g, node, args: f"exp({g.agg(node, 'avg', [f'ln(CAST({g.sql(args[0])} AS DOUBLE))'])})",
        kind="aggregate",
    )

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

    for _name, _duck in (("bitwise_and_agg", "bit_and"), ("bitwise_or_agg", "bit_or"), ("bitwise_xor_agg", "bit_xor")):
        register(
            _name,
            "aggregate",
            f"{_name}(x) -> bigint",
            _bitwise_agg,
            lambda g, node, args, duck=_duck: tf.cast(
                g.agg(node, duck, [f"CAST({g.sql(args[0])} AS BIGINT)"]), tt.BIGINT
            ),
            kind="aggregate",
            notes="Two's complement over bigint; NULL values are skipped; NULL for no rows.",
        )

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

    overload(
        "approx_percentile",
        lambda call: weighted_percentile(call) if len(call.args) == 3 else None,
        render_weighted_percentile,
        "approx_percentile(x, w, percentage[s]) -> same as x",
    )
