"""The DuckDB SQL writer: sqlglot's DuckDB generator plus named transforms, one small function per
Trino/DuckDB difference, in the style of sqlglot's dialect modules (`TRANSFORMS = {exp.X: fn}`).

Every transform reads the Trino types that `analyze` attached to the tree (`node.meta["t"]`) and
writes DuckDB SQL that gives Trino's answer: integer division truncates, decimal division and
`avg(decimal)` round HALF_UP at Trino's scale, subscripts fail out of range, doubles print as Trino
prints them, NULLs order last. Runtime failures are raised with DuckDB's `error()` and Trino's
message text; inside `try(...)` the same transforms yield NULL instead (`Writer.fail`).
"""

from __future__ import annotations

from sqlglot import exp
from sqlglot.generators.duckdb import DuckDBGenerator

from lakegate.dialect import chars, registry, times, wide_decimals, zoned_nanos, zones
from lakegate.dialect import trino_types as tt
from lakegate.dialect.errors import DialectError
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import FloorMicros, ttype


class DuckCast(exp.Expression):
    """CAST to a DuckDB type given as text (added by `finalize`; never written by users)."""

    arg_types = {"this": True, "to": True}


def string(value: str) -> str:
    """A DuckDB string literal."""
    return "'" + value.replace("'", "''") + "'"


def quote(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def cast(sql: str, t: TType) -> str:
    """`sql` cast to the DuckDB type of Trino type `t` (unchanged when DuckDB has no name for it)."""
    duck = tt.duckdb_type(t)
    return sql if duck is None else f"CAST({sql} AS {duck})"


def ten(power: int, scale: int = 0) -> str:
    """10^power as an exact DuckDB decimal constant (power may be negative with scale = -power)."""
    if power >= 0:
        return f"CAST('1{'0' * power}' AS DECIMAL({min(38, power + 1)},0))"
    return f"CAST('0.{'0' * (-power - 1)}1' AS DECIMAL({-power},{-power}))"


#: Longest DuckDB SQL a query may translate to. Some translations repeat an argument's SQL (a CASE
#: that checks it, then uses it), so nesting such calls multiplies the text; this bounds it early.
MAX_SQL_CHARS = 1_000_000


def _inside(t: TType, *bases: str) -> bool:
    """Whether an array, map or row type holds values of one of these base types."""
    return any(inner.base in bases for inner in tt.inner_types(t))


class Writer(DuckDBGenerator):
    """Writes the analyzed Trino tree as DuckDB SQL."""

    def __init__(self, time_zone: str = "UTC", **kwargs):
        super().__init__(identify=True, comments=False, **kwargs)
        self.time_zone = time_zone  # the session zone
        self.in_try = 0
        self._written: dict[tuple, tuple[exp.Expression, str]] = {}

    def sql(self, expression, key=None, comment=True) -> str:
        """The node's SQL, written once per node (transforms that use an argument twice would
        otherwise write its subtree again, 2^depth times for nested calls), at most MAX_SQL_CHARS long."""
        if not isinstance(expression, exp.Expression):
            return super().sql(expression, key, comment)
        memo = (id(expression), key, comment, self.in_try)
        if memo in self._written:
            return self._written[memo][1]
        text = super().sql(expression, key, comment)
        self._written[memo] = (expression, text)  # the node is kept so that its id is not reused
        if len(text) > MAX_SQL_CHARS:
            raise DialectError(
                f"unsupported in lakegate: the query translates to more than {MAX_SQL_CHARS} "
                "characters of DuckDB SQL (deeply nested function calls); simplify it",
                error_name="NOT_SUPPORTED",
            )
        return text

    # --- helpers for transforms and the function registry ---------------------------------------
    def fail(self, message_sql: str, error_name: str = "INVALID_FUNCTION_ARGUMENT") -> str:
        """SQL that raises Trino's error `error_name` with message `message_sql` (a SQL string
        expression) at run time, as `NAME: message` (see errors.runtime_error), or NULL inside try()."""
        return "NULL" if self.in_try else f"error({string(error_name + ': ')} || {message_sql})"

    def coerce(self, node: exp.Expression, target: TType) -> str:
        """`node` as SQL, cast to `target` when its Trino type differs (implicit coercion)."""
        sql = self.sql(node)
        source = ttype(node)
        if source == target or (source.base == target.base == "varchar"):
            return sql
        if source.is_unknown:
            return cast("NULL", target)
        if target.base == "char":  # from char or varchar (chars.py)
            return chars.pad(sql, target.args[0])
        if target.base == "timestamp_tz" and source.base in ("timestamp", "date"):  # in the session zone
            return zones.instant(f"CAST({sql} AS TIMESTAMP)", self.time_zone)
        if self.time_zone != zones.UTC and _inside(target, "timestamp_tz") and _inside(source, "date", "timestamp"):
            raise DialectError(  # DuckDB would read nested dates and timestamps in UTC
                f"unsupported in lakegate: {source} coerced to {target} in the session zone {self.time_zone}",
                error_name="NOT_SUPPORTED",
            )
        return cast(sql, target)

    def agg(self, node: exp.Expression, name: str, args: list[str]) -> str:
        """An aggregate or window call `name(args)` carrying the node's DISTINCT, ORDER BY, FILTER,
        IGNORE NULLS and OVER clauses."""
        meta = node.meta
        inner = ", ".join(args)
        if meta.get("distinct"):
            inner = f"DISTINCT {inner}"
        if meta.get("order") is not None:
            inner += " ORDER BY " + ", ".join(self.sql(o) for o in meta["order"].expressions)
        if meta.get("nulls"):
            inner += " " + meta["nulls"]
        sql = f"{name}({inner})"
        if meta.get("filter") is not None:
            sql += f" FILTER(WHERE {self.sql(meta['filter'])})"
        if meta.get("over") is not None:
            return self.windowed(sql, meta["over"])
        return sql

    def windowed(self, call: str, window: exp.Window) -> str:
        """`call OVER (...)`. DuckDB refuses error() (volatile) in a window's keys, so keys that can
        fail are windowed by their unchecked value (failures as NULL) and checked beside the window,
        on the same rows: a failing key fails the query, as in Trino."""
        over = self.over(window)
        if "error(" not in over:
            return f"{call} {over}"
        order = window.args.get("order")
        keys = [*(window.args.get("partition_by") or []), *(o.this for o in (order.expressions if order else []))]
        checks = [f"({sql}) IS NULL" for sql in map(self.sql, keys) if "error(" in sql]
        self.in_try += 1
        try:
            over = self.over(window)
        finally:
            self.in_try -= 1
        return f"CASE WHEN {' OR '.join(checks)} THEN {call} {over} ELSE {call} {over} END"

    def over(self, window: exp.Window) -> str:
        parts = []
        partition = window.args.get("partition_by")
        if partition:
            parts.append("PARTITION BY " + ", ".join(self.sql(p) for p in partition))
        order = window.args.get("order")
        if order is not None:
            parts.append(self.order_sql(order).strip())
        spec = window.args.get("spec")
        if spec is not None:
            parts.append(self.sql(spec))
        return f"OVER ({' '.join(parts)})"

    def lambda_(self, node: exp.Lambda) -> str:
        params = ", ".join(quote(p.name.lower()) for p in node.expressions)
        return f"lambda {params}: {self.sql(node.this)}"

    TRANSFORMS = {**DuckDBGenerator.TRANSFORMS}


def transform(*types: type):
    """Register a named transform for the given expression types."""

    def register(fn):
        for t in types:
            Writer.TRANSFORMS[t] = fn
        return fn

    return register


# --- names ---------------------------------------------------------------------------------------
@transform(exp.Column)
def qualified_column(g: Writer, node: exp.Column) -> str:
    """Columns are written fully qualified as resolved (so DuckDB cannot bind them differently);
    row fields become struct_extract."""
    ref = node.meta.get("ref")
    if ref is None:
        return DuckDBGenerator.column_sql(g, node)
    qualifier, name, fields = ref
    sql = quote(name) if qualifier is None else f"{quote(qualifier)}.{quote(name)}"
    sql = node.meta.get("sql", sql)  # a JOIN USING column
    for field in fields:
        sql = f"struct_extract({sql}, {string(field)})"
    return sql


@transform(exp.Identifier)
def lambda_parameter(g: Writer, node: exp.Identifier) -> str:
    """Lambda parameters are written quoted and lower-cased, as their declarations are."""
    if node.meta.get("lambda") if node._meta else False:
        return quote(node.name.lower())
    return DuckDBGenerator.identifier_sql(g, node)


@transform(exp.Dot)
def row_field(g: Writer, node: exp.Dot) -> str:
    field = node.meta["field"]
    if isinstance(field, int):  # by position (row_expression.*: dialect/row_star.py)
        return f"struct_extract_at({g.sql(node.this)}, {field})"
    return f"struct_extract({g.sql(node.this)}, {string(field)})"


@transform(exp.Lambda)
def lambda_syntax(g: Writer, node: exp.Lambda) -> str:
    return g.lambda_(node)


# --- literals ------------------------------------------------------------------------------------
@transform(exp.Literal)
def typed_literal(g: Writer, node: exp.Literal) -> str:
    """Decimal literals get Trino's exact type (`0.5` is decimal(1,1), DuckDB says DECIMAL(2,1))."""
    if node.is_string:
        return string(node.name)
    t = node.meta.get("t") if node._meta else None
    if t is not None and t.is_decimal:
        return f"CAST({string(node.name)} AS {tt.duckdb_type(t)})"
    return node.name


@transform(exp.HexString)
def binary_literal(g: Writer, node: exp.HexString) -> str:
    """X'58F7' is the bytes its hex digits spell."""
    return f"unhex({string(node.name)})"


@transform(exp.UnicodeString)
def unicode_literal(g: Writer, node: exp.UnicodeString) -> str:
    """U&'...' is the text its escapes spell (decoded by analyze)."""
    return string(node.meta["text"])


@transform(DuckCast)
def duck_cast(g: Writer, node: DuckCast) -> str:
    return f"CAST({g.sql(node.this)} AS {node.args['to']})"


# --- arithmetic ----------------------------------------------------------------------------------
def _operands(g: Writer, node: exp.Binary) -> tuple[str, str]:
    return g.sql(node.this), g.sql(node.expression)


_RANGES = {
    "tinyint": (-(2**7), 2**7 - 1),
    "smallint": (-(2**15), 2**15 - 1),
    "integer": (-(2**31), 2**31 - 1),
    "bigint": (-(2**63), 2**63 - 1),
}


def checked_integer(g: Writer, sql: str, t: TType, what: str) -> str:
    """`sql` (computed wider, as HUGEINT) as integral type `t`, failing with Trino's
    NUMERIC_VALUE_OUT_OF_RANGE when it does not fit."""
    low, high = _RANGES[t.base]
    return (
        f"CASE WHEN {sql} NOT BETWEEN {low} AND {high} THEN {g.fail(what, 'NUMERIC_VALUE_OUT_OF_RANGE')} "
        f"ELSE {cast(sql, t)} END"
    )


@transform(exp.Add, exp.Sub, exp.Mul)
def decimal_result_type(g: Writer, node: exp.Binary) -> str:
    """+, - and *: decimals and reals are cast to Trino's result type (DuckDB's widths and float
    promotion differ). Integers keep their type in both; DuckDB checks their overflow itself, at
    full speed, and errors.runtime_error names its 'Overflow in ...' NUMERIC_VALUE_OUT_OF_RANGE."""
    t = ttype(node)
    op = {exp.Add: "+", exp.Sub: "-", exp.Mul: "*"}[type(node)]
    left, right = _operands(g, node)
    sql = f"{left} {op} {right}"
    if t.is_decimal or t.base == "real":
        return cast(sql, t)
    if t.base == "date":
        return whole_days(g, node, sql)
    if t.base == "timestamp" and t.args[0] > 6:
        return nanosecond_interval_arithmetic(g, node, op)
    if t == tt.INTERVAL_DS and ttype(node.this).base == "timestamp":
        return timestamp_difference(g, node)
    return sql


def nanosecond_interval_arithmetic(g: Writer, node: exp.Binary, op: str) -> str:
    """timestamp(7..9) ± interval: the interval moves the microseconds, the nanoseconds below them stay
    (TimestampOperators on LongTimestamp); DuckDB would round the value to microseconds first."""
    stamp = node.this if ttype(node.this).base == "timestamp" else node.expression
    sql = g.sql(stamp)
    left, right = (
        (floor_micros(sql), g.sql(node.expression)) if stamp is node.this else (g.sql(node.this), floor_micros(sql))
    )
    return with_nanos(f"({left} {op} {right})", sql)


def timestamp_difference(g: Writer, node: exp.Sub) -> str:
    """timestamp - timestamp: the epoch microseconds' difference rounded HALF_UP to milliseconds, the
    precision of Trino's interval day to second (TimestampOperators.TimestampMinusTimestamp)."""
    left, right = (epoch_micros(g.sql(side), ttype(side)) for side in (node.this, node.expression))
    return f"to_milliseconds({floor_div(f'{left} - {right} + 500', 1000)})"


def epoch_micros(sql: str, t: TType) -> str:
    """A timestamp's epoch microseconds (floored for a TIMESTAMP_NS, as LongTimestamp.getEpochMicros)."""
    return floor_div(f"epoch_ns({sql})", 1000) if t.args[0] > 6 else f"epoch_us({sql})"


def whole_days(g: Writer, node: exp.Binary, sql: str) -> str:
    """DATE ± interval: Trino refuses a day-to-second interval that is not whole days
    (io.trino.type.DateTimeOperators: "Cannot add hour, minutes or seconds to a date")."""
    verb = "add hour, minutes or seconds to" if isinstance(node, exp.Add) else "subtract hour, minutes or seconds from"
    side = node.expression if ttype(node.expression).base.startswith("interval_") else node.this
    interval = g.sql(side)
    if ttype(side) == tt.INTERVAL_YM:
        return f"CAST({sql} AS DATE)"
    return (
        f"CASE WHEN epoch({interval}) % 86400 <> 0 THEN {g.fail(string(f'Cannot {verb} a date'))} "
        f"ELSE CAST({sql} AS DATE) END"
    )


@transform(exp.Div)
def integer_division(g: Writer, node: exp.Div) -> str:
    """Integer operands divide with truncation toward zero; decimals divide exactly (HALF_UP at
    Trino's scale); zero divisors fail with DIVISION_BY_ZERO (doubles give Infinity/NaN)."""
    t = ttype(node)
    left, right = _operands(g, node)
    if t.is_integral:
        return f"({left} // {nonzero(g, right)})"
    if t.is_decimal:
        return decimal_division(g, node.this, node.expression, t)
    sql = f"{cast(left, t)} / {cast(right, t)}" if t.base == "real" else f"{left} / {right}"
    return cast(sql, t) if t.base == "real" else sql


def nonzero(g: Writer, sql: str) -> str:
    """A divisor that fails with DIVISION_BY_ZERO (NULL inside try()) when it is zero."""
    if sql.lstrip("-").isdigit() and int(sql) != 0:
        return sql
    if g.in_try:
        return f"NULLIF({sql}, 0)"
    return f"CASE WHEN {sql} = 0 THEN {g.fail(string('Division by zero'), 'DIVISION_BY_ZERO')} ELSE {sql} END"


def unscaled(g: Writer, node: exp.Expression) -> str:
    """The unscaled integer value (HUGEINT) of an integral or decimal expression."""
    return unscaled_sql(g.sql(node), ttype(node))


def unscaled_sql(sql: str, t: TType) -> str:
    """The unscaled integer value (HUGEINT) of `sql`, of integral or decimal type `t`."""
    if not (t.is_decimal and t.args[1]):
        return f"CAST({sql} AS HUGEINT)"
    precision, scale = t.args
    if precision + scale > 38:  # DuckDB's x * 10^s could overflow 38 digits: read the digits
        return f"CAST(replace(CAST({sql} AS VARCHAR), '.', '') AS HUGEINT)"
    # in 128 bits: DuckDB multiplies two short decimals in 64, whatever the result's precision
    return f"CAST(CAST({sql} AS DECIMAL(38,{scale})) * {ten(scale)} AS HUGEINT)"


def rounded_quotient(g: Writer, numerator: str, denominator: str, result: TType, checked: bool = False) -> str:
    """numerator / denominator (HUGEINT unscaled values) rounded HALF_UP, as a decimal of type
    `result` whose unscaled value is the quotient; `checked`: a quotient past 38 digits fails with
    Trino's 'Decimal overflow' (DecimalOperators.divide*)."""
    denominator = nonzero(g, denominator)
    quotient = (
        f"({numerator}) // ({denominator}) + CASE WHEN 2 * abs(({numerator}) % ({denominator})) >= "
        f"abs({denominator}) THEN sign({numerator}) * sign({denominator}) ELSE 0 END"
    )
    scale = result.args[1]
    value = f"CAST({quotient} AS DECIMAL(38,0))"
    if checked:  # TRY_CAST: DuckDB folds constant branches it does not take too
        value = f"CASE WHEN abs({quotient}) >= {_TEN_38} THEN {decimal_overflow(g)} ELSE TRY_{value} END"
    if scale:
        value = f"{value} * {ten(-scale)}"
    return cast(value, result)


def decimal_division(g: Writer, left: exp.Expression, right: exp.Expression, result: TType) -> str:
    """Trino's decimal division: rescale the dividend to the result scale, divide the unscaled
    values and round HALF_UP (io.trino.type.DecimalOperators)."""
    (_, s1), (_, s2) = tt.as_decimal(ttype(left)).args, tt.as_decimal(ttype(right)).args
    rescale = result.args[1] - s1 + s2
    numerator, divisor = unscaled(g, left), unscaled(g, right)
    if not rescale:
        return rounded_quotient(g, numerator, divisor, result, checked=True)
    # The rescaled dividend past 128 bits: divided exactly by a Python function (wide_decimals).
    # DuckDB may compute the branch a CASE does not take: that one multiplies by 0 instead.
    wide = f"abs({numerator}) > CAST('{(2**127 - 1) // 10**rescale}' AS HUGEINT)"
    factor = f"CAST('1{'0' * rescale}' AS HUGEINT)" if rescale <= 38 else "0"  # past 10^38 only 0 is not wide
    rescaled = f"{numerator} * CASE WHEN {wide} THEN 0 ELSE {factor} END"
    quotient = rounded_quotient(g, rescaled, divisor, result, checked=True)
    exact = f"{wide_decimals.UDF_NAME}({numerator}, {divisor}, {rescale}, {'false' if g.in_try else 'true'})"
    too_wide = f"CAST({exact} AS DECIMAL(38,0))"
    if result.args[1]:
        too_wide = f"{too_wide} * {ten(-result.args[1])}"
    too_wide = cast(too_wide, result)
    return f"CASE WHEN {wide} AND ({divisor}) <> 0 THEN {too_wide} ELSE {quotient} END"


_TEN_38 = f"CAST('1{'0' * 38}' AS HUGEINT)"


def decimal_overflow(g: Writer) -> str:
    """Trino's failure of a decimal result past 38 digits (DecimalOperators)."""
    return g.fail(string("Decimal overflow"), "NUMERIC_VALUE_OUT_OF_RANGE")


@transform(exp.Mod)
def modulus(g: Writer, node: exp.Mod) -> str:
    """Remainder with the dividend's sign; integer and decimal zero divisors fail, doubles give NaN."""
    t = ttype(node)
    left, right = _operands(g, node)
    if t.is_approx:
        return cast(f"CASE WHEN {right} = 0 THEN CAST('NaN' AS DOUBLE) ELSE {left} % {right} END", t)
    sql = f"({left} % {nonzero(g, right)})"
    return cast(sql, t) if t.is_decimal else sql


@transform(exp.DPipe)
def concat_operator(g: Writer, node: exp.DPipe) -> str:
    """`||` on strings is NULL when either side is; on arrays it concatenates or appends."""
    if not node.meta.get("array"):
        return f"({g.sql(node.this)} || {g.sql(node.expression)})"
    t = ttype(node)
    left, right = node.this, node.expression
    lt, rt = ttype(left), ttype(right)
    if lt.base == "array" and rt.base == "array":
        a, b = g.coerce(left, t), g.coerce(right, t)
        return f"CASE WHEN {a} IS NULL OR {b} IS NULL THEN NULL ELSE list_concat({a}, {b}) END"
    a, b = (
        g.coerce(left, t if lt.base == "array" else t.element),
        g.coerce(right, t if rt.base == "array" else t.element),
    )
    appended = f"list_append({a}, {b})" if lt.base == "array" else f"list_prepend({a}, {b})"
    return f"CASE WHEN {a} IS NULL OR {b} IS NULL THEN NULL ELSE {appended} END"  # a NULL element too


# --- comparisons ---------------------------------------------------------------------------------
_COMPARE = {exp.EQ: "=", exp.NEQ: "<>", exp.GT: ">", exp.GTE: ">=", exp.LT: "<", exp.LTE: "<="}


@transform(*_COMPARE)
def ieee_comparison(g: Writer, node: exp.Binary) -> str:
    """Doubles compare as IEEE 754 does in Trino (NaN is unequal to everything, itself included;
    DuckDB orders NaN above all numbers and equal to itself); arrays compare equal only when no
    element comparison is NULL."""
    op = _COMPARE[type(node)]
    left, right = g.sql(node.this), g.sql(node.expression)
    common = node.meta.get("compare")
    if common is None or isinstance(node.expression, (exp.Any, exp.All)):
        return f"{left} {op} {right}"
    if common == tt.as_char(tt.VARCHAR) and op not in ("=", "<>"):  # char and unbounded varchar (= in chars.coerce)
        return chars.compare(g, op, node.this, node.expression)
    if common.is_approx:
        # number literals are never NaN: only the other sides need the check
        sides = [
            sql
            for sql, side in ((left, node.this), (right, node.expression))
            if not (isinstance(side, exp.Literal) or isinstance(side, exp.Neg) and isinstance(side.this, exp.Literal))
        ]
        if not sides:
            return f"{left} {op} {right}"
        if op == "<>":
            return f"({left} <> {right} OR " + " OR ".join(f"isnan({s})" for s in sides) + ")"
        return f"({left} {op} {right} AND " + " AND ".join(f"NOT isnan({s})" for s in sides) + ")"
    if common.base in ("array", "map", "row") and op in ("=", "<>"):
        equal = trino_equal(left, right, common)
        return equal if op == "=" else f"NOT ({equal})"
    if common.base in ("array", "row"):
        return ordered_comparison(left, right, common, op)
    return f"{left} {op} {right}"


def ordered_comparison(left: str, right: str, t: TType, op: str) -> str:
    """`<`, `<=`, `>`, `>=` on arrays and rows: element by element (then by length), failing as Trino
    does when the comparison reaches a NULL element (see `null_reached`)."""
    reached, failure = null_reached(left, right, t)
    return (
        f"CASE WHEN ({left}) IS NULL OR ({right}) IS NULL THEN NULL WHEN {reached} THEN {failure} "
        f"ELSE {left} {op} {right} END"
    )


def null_reached(left: str, right: str, t: TType) -> tuple[str, str]:
    """SQL that is true when ordering two arrays (or rows) of type `t` reaches a NULL element, on
    either side, before the first unequal pair, and the error Trino raises then: the ArrayType and
    RowType comparison operators check each position they compare (checkElementNotNull), where
    DuckDB would order NULL elements last."""
    if t.base == "array":
        pair = (f'({left})["_i"]', f'({right})["_i"]')
        stops = f"{pair[0]} IS NULL OR {pair[1]} IS NULL OR {pair[0]} <> {pair[1]}"
        first = f'list_filter(range(1, least(len({left}), len({right})) + 1), lambda "_i": {stops})[1]'
        at = (f"({left})[{first}]", f"({right})[{first}]")
        reached = f"({first} IS NOT NULL AND ({at[0]} IS NULL OR {at[1]} IS NULL))"
        what = "ARRAY comparison not supported for arrays with null elements"
    else:
        whens = []
        for i in range(1, len(t.args) + 1):
            a, b = f"struct_extract_at({left}, {i})", f"struct_extract_at({right}, {i})"
            whens.append(f"WHEN {a} IS NULL OR {b} IS NULL THEN true WHEN {a} <> {b} THEN false")
        reached = f"CASE {' '.join(whens)} ELSE false END"
        what = "ROW comparison not supported for fields with null elements"
    return reached, f"error({string('NOT_SUPPORTED: ' + what)})"  # not an error try() catches


def trino_equal(left: str, right: str, t: TType, depth: int = 0) -> str:
    """Trino's `=` on values of type `t`: NULL when either side is NULL; NaN equals nothing; arrays,
    maps (in any key order) and rows are equal when every element is, false when one element is not,
    NULL otherwise (io.trino.type.ArrayType, MapType and RowType equal operators). DuckDB would compare
    NULL elements as equal values."""
    nulls = f"({left}) IS NULL OR ({right}) IS NULL"
    if t.base in ("double", "real"):
        return f"CASE WHEN {nulls} THEN NULL ELSE ({left}) = ({right}) AND NOT isnan({left}) END"
    if t.base == "row":
        fields = [
            trino_equal(f"struct_extract_at({left}, {i + 1})", f"struct_extract_at({right}, {i + 1})", f, depth)
            for i, (_, f) in enumerate(t.args)
        ]
        return f"CASE WHEN {nulls} THEN NULL ELSE ({' AND '.join(fields)}) END"
    z = quote(f"_z{depth}")
    if t.base == "array":
        element = trino_equal(f"struct_extract({z}, 1)", f"struct_extract({z}, 2)", t.element, depth + 1)
        flags, size = (
            f"list_transform(list_zip({left}, {right}), lambda {z}: {element})",
            f"len({left}) <> len({right})",
        )
    elif t.base == "map":
        value = trino_equal(f"({left})[{z}]", f"({right})[{z}]", t.args[1], depth + 1)
        flags = (
            f"list_transform(map_keys({left}), lambda {z}: CASE WHEN NOT list_contains(map_keys({right}), {z}) "
            f"THEN false ELSE {value} END)"
        )
        size = f"cardinality({left}) <> cardinality({right})"
    else:
        return f"({left}) = ({right})"
    return (
        f"CASE WHEN {nulls} THEN NULL WHEN {size} THEN false WHEN list_contains({flags}, false) THEN false "
        f"WHEN list_count({flags}) < len({flags}) THEN NULL ELSE true END"
    )


@transform(exp.In)
def eager_constant_in_list(g: Writer, node: exp.In) -> str:
    """A constant IN list whose items can fail (`3 IN (2, 3, 5 / 0)`) evaluates every item first, as
    Trino's interpreter does (io.trino.sql.query.TestInlining: "Division by zero"); DuckDB stops at
    the first match. IN over columns short-circuits in both."""
    if "row_in" in node.meta:
        return row_in_subquery(g, node)
    sql = g.in_sql(node)
    items = node.expressions
    if node.find(exp.Column) is not None or all(isinstance(i, (exp.Literal, exp.Null)) for i in items):
        return sql
    common = node.meta["compare"]
    return f"CASE WHEN len([{', '.join(g.coerce(i, common) for i in items)}]) >= 0 THEN {sql} END"


def row_in_subquery(g: Writer, node: exp.In) -> str:
    """`(a, b) IN (SELECT x, y ...)`: true when a subquery row equals on every field, false when every
    row differs on a field where neither side is NULL. Otherwise (NULL fields, NaN) Trino's answer
    depends on its plan (its semi join matches rows IS NOT DISTINCT FROM, its documented `=` gives
    NULL; trinodb/trino#7798), so the query fails with NOT_SUPPORTED instead."""
    query = node.args["query"]
    inner = g.sql(query.this if isinstance(query, exp.Subquery) else query)
    fields = node.meta["row_in"]
    lefts = [g.sql(e) for e in node.this.expressions] if isinstance(node.this, (exp.Tuple, exp.Struct)) else None
    if lefts is None or len(lefts) != len(fields):
        left = g.sql(node.this)
        lefts = [f"struct_extract_at({left}, {i + 1})" for i in range(len(fields))]
    names = [quote(f"_lg_in{i + 1}") for i in range(len(fields))]
    equal, differ = [], []
    for value, name, t in zip(lefts, names, fields, strict=True):
        column = f'"_lg_in".{name}'
        equal.append(f"({value}) = {column}" + (f" AND NOT isnan({column})" if t.is_approx else ""))
        differ.append(f"(({value}) IS NOT NULL AND {column} IS NOT NULL AND ({value}) <> {column})")
    what = string("NOT_SUPPORTED: row IN (SELECT ...) where a row field is NULL or NaN")
    return (
        f"(SELECT CASE WHEN bool_or({' AND '.join(equal)}) THEN true "
        f"WHEN count(*) FILTER (WHERE {' OR '.join(differ)}) = count(*) THEN false ELSE error({what}) END "
        f'FROM ({inner}) AS "_lg_in"({", ".join(names)}))'
    )


@transform(exp.Between)
def ieee_between(g: Writer, node: exp.Between) -> str:
    """`v BETWEEN low AND high` is `low <= v AND v <= high` with IEEE comparisons: false when a double
    is NaN (DuckDB orders NaN above every number)."""
    common = node.meta.get("compare")
    if common is not None and common.base in ("array", "row"):
        value, low, high = (g.coerce(side, common) for side in (node.this, node.args["low"], node.args["high"]))
        return f"({ordered_comparison(low, value, common, '<=')} AND {ordered_comparison(value, high, common, '<=')})"
    if common == tt.as_char(tt.VARCHAR):  # char and unbounded varchar
        return chars.between(g, node.this, node.args["low"], node.args["high"])
    sql = g.between_sql(node)
    if common is None or not common.is_approx:
        return sql
    sides = [g.sql(side) for side in (node.this, node.args["low"], node.args["high"])]
    return f"({sql} AND " + " AND ".join(f"NOT isnan({side})" for side in sides) + ")"


# --- conditionals --------------------------------------------------------------------------------
@transform(exp.Case)
def case_common_type(g: Writer, node: exp.Case) -> str:
    """CASE with every result coerced to Trino's common type (DuckDB would pick its own)."""
    t = ttype(node)
    parts = ["CASE"]
    if node.args.get("this") is not None:
        parts.append(g.sql(node.this))
    for branch in node.args.get("ifs") or []:
        parts.append(f"WHEN {g.sql(branch.this)} THEN {g.coerce(branch.args['true'], t)}")
    if node.args.get("default") is not None:
        parts.append(f"ELSE {g.coerce(node.args['default'], t)}")
    parts.append("END")
    return " ".join(parts)


@transform(exp.If)
def if_function(g: Writer, node: exp.If) -> str:
    t = ttype(node)
    false = node.args.get("false")
    tail = f" ELSE {g.coerce(false, t)}" if false is not None else ""
    return f"CASE WHEN {g.sql(node.this)} THEN {g.coerce(node.args['true'], t)}{tail} END"


# --- ordering ------------------------------------------------------------------------------------
@transform(exp.Ordered)
def explicit_null_order(g: Writer, node: exp.Ordered) -> str:
    """Trino sorts NULLs last for ASC and DESC unless told otherwise: always say so explicitly."""
    direction = "DESC" if node.args.get("desc") else "ASC"
    nulls = "NULLS FIRST" if node.args.get("nulls_first") else "NULLS LAST"
    key, t = g.sql(node.this), node.meta.get("key")
    if t is not None:  # an array or row key: Trino fails when sorting reaches a NULL element
        key = f"CASE WHEN {null_element(key, t)} THEN {null_reached(key, key, t)[1]} ELSE {key} END"
    return f"{key} {direction} {nulls}"


def null_element(sql: str, t: TType) -> str:
    """SQL that is true when the array or row `sql` holds a NULL element (field). Sorting such keys
    is refused whenever one is met, though Trino fails only when a comparison reaches it."""
    if t.base == "array":
        return f"list_count({sql}) < len({sql})"
    return " OR ".join(f"struct_extract_at({sql}, {i}) IS NULL" for i in range(1, len(t.args) + 1)) or "false"


# --- subscripts ----------------------------------------------------------------------------------
def subscript(g: Writer, array_sql: str, index_node: exp.Expression) -> str:
    """arr[i]: 1-based; an index out of range fails with Trino's message."""
    index_sql = g.sql(index_node)
    literal = index_node if isinstance(index_node, exp.Literal) else None
    if literal is not None and literal.name.isdigit() and int(literal.name) >= 1:
        n = literal.name
        message = (
            string(f"Array subscript must be less than or equal to array length: {n} > ") + f" || len({array_sql})"
        )
        return f"CASE WHEN len({array_sql}) < {n} THEN {g.fail(message)} ELSE {array_sql}[{n}] END"
    too_big = (
        string("Array subscript must be less than or equal to array length: ")
        + f" || ({index_sql}) || ' > ' || len({array_sql})"
    )
    negative = string("Array subscript is negative: ") + f" || ({index_sql})"
    return (
        f"CASE WHEN ({index_sql}) = 0 THEN {g.fail(string('SQL array indices start at 1'))} "
        f"WHEN ({index_sql}) < 0 THEN {g.fail(negative)} "
        f"WHEN ({index_sql}) > len({array_sql}) THEN {g.fail(too_big)} "
        f"ELSE {array_sql}[{index_sql}] END"
    )


@transform(exp.Bracket)
def array_subscript(g: Writer, node: exp.Bracket) -> str:
    """arr[i] fails out of range; map[key] fails for a missing key (element_at gives NULL)."""
    container = ttype(node.this)
    if container.base == "map":
        map_sql, key = g.sql(node.this), g.coerce(node.expressions[0], container.args[0])
        missing = string("Key not present in map: ") + f" || ({key})"
        return (
            f"CASE WHEN NOT map_contains({map_sql}, {key}) THEN {g.fail(missing)} "
            f"ELSE map_extract_value({map_sql}, {key}) END"
        )
    return subscript(g, g.sql(node.this), node.expressions[0])


@transform(exp.Array)
def array_constructor(g: Writer, node: exp.Array) -> str:
    t = ttype(node)
    if not node.expressions:
        return "[]" if t.element.is_unknown else cast("[]", t)
    return "[" + ", ".join(g.coerce(e, t.element) for e in node.expressions) + "]"


# --- casts ---------------------------------------------------------------------------------------
@transform(exp.Cast)
def trino_cast(g: Writer, node: exp.Cast) -> str:
    if node.meta.get("trimmed"):
        return chars.trimmed(g, node)
    return cast_value(g, *cast_operand(g, node), ttype(node))


def cast_operand(g: Writer, node: exp.Cast) -> tuple[str, TType]:
    """The operand of a cast as SQL and its type; a text literal cast to timestamp with time zone as
    its wall time (the zone it names is the target's: analyze._cast_zone)."""
    local = node.meta.get("local")
    if local is None:
        return g.sql(node.this), node.meta["from"]
    wall = tt.timestamp(ttype(node).args[0])
    return parse_varchar(g, string(local), wall), wall


@transform(exp.TryCast)
def trino_try_cast(g: Writer, node: exp.TryCast) -> str:
    g.in_try += 1
    try:
        sql = cast_value(g, *cast_operand(g, node), ttype(node))
    finally:
        g.in_try -= 1
    return try_wrap(sql)


def try_wrap(sql: str) -> str:
    """DuckDB's TRY(...) around `sql` unless it contains what TRY refuses (aggregates, windows,
    volatile functions); the transforms already yield NULL for Trino's own failures inside try."""
    lowered = sql.lower()
    if " over (" in lowered or "error(" in lowered or "random()" in lowered or "(select" in lowered:
        return sql
    for name in _AGGREGATE_NAMES:
        if f"{name}(" in lowered:
            return sql
    return f"TRY({sql})"


_AGGREGATE_NAMES = (
    "sum",
    "avg",
    "count",
    "min",
    "max",
    "any_value",
    "arg_max",
    "arg_min",
    "list",
    "array_agg",
    "quantile",
    "stddev",
    "var_",
    "corr",
    "covar",
    "bool_",
    "string_agg",
    "approx",
    "geometric",
    "kurtosis",
    "skewness",
    "regr_",
    "bit_",
    "first",
    "last",
    "entropy",
    "mode",
    "median",
    "product",
)

_INTEGRAL_RANGE = {"tinyint": "TINYINT", "smallint": "SMALLINT", "integer": "INT", "bigint": "BIGINT"}


def cast_value(g: Writer, sql: str, source: TType, target: TType) -> str:
    """Trino's CAST(sql AS target) for a value of type `source`."""
    if source == target:
        return sql
    if source.is_unknown:
        return cast("NULL", target)
    if zoned_nanos.is_zoned_nanos(source):  # to timestamp, date or varchar (zoned_nanos.check_use)
        wall = zoned_nanos.wall_time(sql, tt.zone_of(source))
        if target.base == "varchar":
            return varchar_of(g, wall, tt.timestamp(9)) + f" || {string(' ' + tt.zone_of(source))}"
        return cast_value(g, wall, tt.timestamp(9), target)
    if target.base == "char":  # truncated or padded with spaces: the padded text the client gets
        return chars.pad(sql, target.args[0])
    if target.base == "json":
        return registry.JSON_CASTS["to_json"](g, sql, source)
    if source.base == "json":
        return registry.JSON_CASTS["from_json"](g, sql, target)
    if target.base == "varchar":
        text = varchar_of(g, sql, source)
        length = tt.varchar_length(target)
        if length is None:
            return text
        if source.base in ("varchar", "char"):  # a char's padded text (CharacterStringCasts.charToVarcharCast)
            return f"left({text}, {length})"
        message = f"'Value ' || ({text}) || ' cannot be represented as varchar({length})'"
        return f"CASE WHEN length({text}) > {length} THEN {g.fail(message, 'INVALID_CAST_ARGUMENT')} ELSE {text} END"
    if target.base == "varbinary":
        return f"encode({sql})"  # varchar: its UTF-8 bytes
    if source.base == "varchar":
        return parse_varchar(g, sql, target)
    if target.is_integral and source.is_approx:
        return checked_cast(g, f"round({sql})", source, target)
    if target.is_decimal and source.is_approx:
        # Trino converts the shortest decimal text of the float (BigDecimal.valueOf(double),
        # Float.toString: io.trino.type.DecimalCasts), HALF_UP; DuckDB would convert its binary value
        return checked_cast(g, f"CAST({sql} AS VARCHAR)", source, target)
    if target.is_integral and (source.is_integral or source.is_decimal) or target.is_decimal and source.is_numeric:
        return checked_cast(g, sql, source, target)
    if target.base == "time" and source.base in ("time", "timestamp"):  # p <= 6 (analyze._cast)
        if source.base == "time":
            return times.round_time(sql, target.args[0], source.args[0])
        return times.of_timestamp(sql, target.args[0])
    if target.base == "timestamp" and source.base in ("timestamp", "date"):
        precision = target.args[0]
        if source.base == "timestamp" and precision < source.args[0]:
            return round_timestamp(sql, precision, source.args[0])
        if precision > 6 and tt.duckdb_type(source) != "TIMESTAMP_NS":
            return as_nanoseconds(g, sql)
        return cast(sql, target)
    if target.base == "timestamp" and source.base == "timestamp_tz":
        return cast(zones.local(sql, tt.zone_of(source)), target)
    if target.base == "timestamp_tz" and source.base in ("timestamp", "date"):
        sql = zoned_precision(sql, source, target.args[0])
        return zones.instant(f"CAST({sql} AS TIMESTAMP)", tt.zone_of(target))
    if target.base == "date" and source.base == "timestamp" and source.args[0] > 6:
        return f"CAST({floor_micros(sql)} AS DATE)"  # DuckDB would round to the nearest microsecond
    if target.base == "date" and source.base == "timestamp_tz":
        return f"CAST({zones.local(sql, tt.zone_of(source))} AS DATE)"
    if target.base == "array":
        inner = cast_value(g, '"_e"', source.element, target.element)
        if inner == cast('"_e"', target.element):
            return cast(sql, target)
        return f'list_transform({sql}, lambda "_e": {inner})'
    if target.base == "row":
        fields = []
        for index, ((_, s), (name, t)) in enumerate(zip(source.args, target.args)):
            src_name = source.args[index][0]
            value = f"struct_extract({sql}, {string(src_name) if src_name else index + 1})"
            fields.append(f"{quote(name or f'field{index}')} := {cast_value(g, value, s, t)}")
        return f"struct_pack({', '.join(fields)})"
    return cast(sql, target)


def _cast_name(t: TType) -> str:
    """A numeric type as Trino's cast messages name it: INTEGER, DECIMAL(5, 2)."""
    return f"DECIMAL({t.args[0]}, {t.args[1]})" if t.is_decimal else t.base.upper()


def checked_cast(g: Writer, sql: str, source: TType, target: TType) -> str:
    """A numeric CAST that can overflow: Trino's error (NUMERIC_VALUE_OUT_OF_RANGE for integers,
    INVALID_CAST_ARGUMENT for decimals and doubles) instead of DuckDB's."""
    if _fits(source, target):
        return cast(sql, target)
    duck = tt.duckdb_type(target)
    if target.is_integral and not source.is_approx:
        error_name, message = "NUMERIC_VALUE_OUT_OF_RANGE", f"'Out of range for {target}: ' || ({sql})"
    elif target.is_decimal and (source.is_integral or source.is_decimal):  # DecimalCasts, DecimalConversions
        error_name = "INVALID_CAST_ARGUMENT"
        message = f"'Cannot cast {_cast_name(source)} ''' || ({sql}) || ''' to {_cast_name(target)}'"
    else:
        error_name, message = "INVALID_CAST_ARGUMENT", f"'Cannot cast {source} ''' || ({sql}) || ''' to {target}'"
    return (
        f"CASE WHEN ({sql}) IS NOT NULL AND TRY_CAST({sql} AS {duck}) IS NULL THEN "
        f"{g.fail(message, error_name)} ELSE CAST({sql} AS {duck}) END"
    )


def _fits(source: TType, target: TType) -> bool:
    """Whether every value of `source` converts to `target` without overflow."""
    if source.is_integral and target.is_integral:
        return _RANGES[source.base][1] <= _RANGES[target.base][1]
    if (source.is_integral or source.is_decimal) and target.is_decimal:
        digits = tt.INTEGRAL[source.base] if source.is_integral else source.args[0] - source.args[1]
        return digits <= target.args[0] - target.args[1]
    if source.is_decimal and target.is_integral:
        return source.args[0] - source.args[1] < len(str(_RANGES[target.base][1]))
    return False


def floor_div(sql: str, divisor: int) -> str:
    """Integer `sql` divided by `divisor`, rounded toward negative infinity (DuckDB's // truncates)."""
    return f"(({sql}) - ((({sql}) % {divisor}) + {divisor}) % {divisor}) // {divisor}"


def floor_micros(sql: str) -> str:
    """A TIMESTAMP_NS floored to a microsecond TIMESTAMP: Trino's timestamp(p > 6) functions read the
    epoch microseconds (LongTimestamp.getEpochMicros) and keep or drop the rest; DuckDB's own
    conversion rounds to the nearest microsecond (23:59:59.9999999 would become the next day)."""
    return f"make_timestamp({floor_div(f'epoch_ns({sql})', 1000)})"


def with_nanos(micros_sql: str, source_sql: str) -> str:
    """Microsecond TIMESTAMP `micros_sql` as TIMESTAMP_NS, with the nanoseconds below the microsecond
    of TIMESTAMP_NS `source_sql` (Trino's timestamp(p > 6) arithmetic keeps its picosOfMicro)."""
    return f"make_timestamp_ns(epoch_ns({micros_sql}) + ((epoch_ns({source_sql}) % 1000) + 1000) % 1000)"


#: The days DuckDB's TIMESTAMP_NS holds whole (int64 nanoseconds: 1677-09-21 to 2262-04-11).
NANOSECOND_RANGE = ("1677-09-22", "2262-04-11")


def as_nanoseconds(g: Writer, sql: str) -> str:
    """TIMESTAMP or DATE `sql` as TIMESTAMP_NS, or NOT_SUPPORTED outside its range (Trino's reaches
    further; DuckDB's own message would not say why)."""
    low, high = NANOSECOND_RANGE
    message = string(f"unsupported in lakegate: timestamp(p) with p > 6 outside [{low}, {high})")
    return (
        f"CASE WHEN ({sql}) >= TIMESTAMP '{low}' AND ({sql}) < TIMESTAMP '{high}' "
        f"THEN CAST({sql} AS TIMESTAMP_NS) ELSE {g.fail(message, 'NOT_SUPPORTED')} END"
    )


def round_timestamp(sql: str, precision: int, source: int = 6) -> str:
    """A timestamp(source) rounded HALF_UP to `precision` fractional digits, before 1970 too (Trino's
    timestamp(p) casts: io.trino.spi.type.Timestamps.round)."""
    digits = 9 if source > 6 else 6
    unit = 10 ** (digits - precision)
    shifted = f"(epoch_{'ns' if digits == 9 else 'us'}({sql}) + {unit // 2})"  # then floored to a multiple of unit
    rounded = f"{shifted} - ((({shifted} % {unit}) + {unit}) % {unit})"
    if digits == 6:
        return f"make_timestamp({rounded})"
    return f"make_timestamp_ns({rounded})" if precision > 6 else f"make_timestamp(({rounded}) // 1000)"


def parse_varchar(g: Writer, sql: str, target: TType) -> str:
    """CAST(varchar AS target) accepting exactly what Trino accepts (Java's trim + parse), failing
    with INVALID_CAST_ARGUMENT otherwise (DuckDB alone would accept '1.5', ' 1_000', 'yes' ...)."""
    name = _INTEGRAL_RANGE.get(target.base, target.base.upper())
    bad = g.fail(f"'Cannot cast ''' || {sql} || ''' to {name}'", "INVALID_CAST_ARGUMENT")
    if target.is_integral:
        pattern = "^[\\x00-\\x20]*([+-]?[0-9]+)[\\x00-\\x20]*$"
        return (
            f"CASE WHEN regexp_matches({sql}, {string(pattern)}) THEN "
            f"{cast(f'regexp_extract({sql}, {string(pattern)}, 1)', target)} ELSE {bad} END"
        )
    if target.is_approx or target.is_decimal:
        number = "[+-]?([0-9]+[.]?[0-9]*|[.][0-9]+)([eE][+-]?[0-9]+)?"
        if target.is_approx:
            number = f"([+-]?(NaN|Infinity)|{number}[fFdD]?)"
        pattern = f"^[\\x00-\\x20]*{number}[\\x00-\\x20]*$"
        value = (
            f"regexp_replace(trim({sql}, chr(32) || chr(9) || chr(10) || chr(13)), '[fFdD]$', '')"
            if target.is_approx
            else f"trim({sql}, chr(32) || chr(9) || chr(10) || chr(13))"
        )
        converted = cast(value, target)
        if target.is_decimal:  # DecimalCasts.varcharToShortDecimal / varcharToLongDecimal
            head = f"'Cannot cast VARCHAR ''' || {sql} || ''' to {_cast_name(target)}. '"
            bad = g.fail(f"{head} || 'Value is not a number.'", "INVALID_CAST_ARGUMENT")
            too_large = g.fail(f"{head} || 'Value too large.'", "INVALID_CAST_ARGUMENT")
            converted = f"CASE WHEN TRY_{converted} IS NULL THEN {too_large} ELSE TRY_{converted} END"
        return f"CASE WHEN regexp_matches({sql}, {string(pattern)}) THEN {converted} ELSE {bad} END"
    if target.base == "boolean":
        return (
            f"CASE WHEN lower({sql}) IN ('t', '1', 'true') THEN true "
            f"WHEN lower({sql}) IN ('f', '0', 'false') THEN false ELSE {bad} END"
        )
    if target.base == "date":
        pattern = "^[\\x00-\\x20]*[0-9]{4}-[0-9]{1,2}-[0-9]{1,2}[\\x00-\\x20]*$"
        return (
            f"CASE WHEN regexp_matches({sql}, {string(pattern)}) AND TRY_CAST(trim({sql}) AS DATE) IS NOT NULL "
            f"THEN CAST(trim({sql}) AS DATE) ELSE {bad} END"
        )
    if target.base == "timestamp":
        return parse_timestamp(g, sql, target.args[0], bad)
    if target.base == "time":
        message = f"'Value cannot be cast to time: ' || {sql}"
        return times.parse(sql, target.args[0], g.fail(message, "INVALID_CAST_ARGUMENT"))
    return cast(sql, target)


def zoned_precision(sql: str, source: TType, precision: int) -> str:
    """A timestamp(p) or date rounded HALF_UP for CAST to timestamp(precision) with time zone: to
    milliseconds first when the target holds milliseconds at most and the source microseconds
    (operator/scalar/timestamp/TimestampToTimestampWithTimeZoneCast: shortToShort rounds twice)."""
    if source.base != "timestamp" or precision >= source.args[0]:
        return sql
    if precision < 3 < source.args[0] <= 6:
        sql = round_timestamp(sql, 3)
    return round_timestamp(sql, precision, source.args[0])


def parse_timestamp(g: Writer, sql: str, precision: int, bad: str) -> str:
    """CAST(varchar AS timestamp(precision)): the fraction's digits rounded HALF_UP to `precision`
    (io.trino.operator.scalar.timestamp.VarcharToTimestampCast); DuckDB would cut them at six or nine."""
    pattern = "^[0-9]{4}-[0-9]{1,2}-[0-9]{1,2}( [0-9]{1,2}:[0-9]{1,2}(:[0-9]{1,2}([.][0-9]{1,12})?)?)?$"
    text = f"trim({sql})"
    seconds_text = f"regexp_replace({text}, '[.][0-9]*$', '')"
    seconds = (
        f"TRY_CAST({seconds_text} AS TIMESTAMP)"  # TRY_: DuckDB folds a constant CAST early, and `valid` checks it
    )
    unit = 10 ** (12 - precision)  # of the fraction read as picoseconds
    fraction = f"((CAST(rpad(regexp_extract({text}, '[.]([0-9]*)$', 1), 12, '0') AS BIGINT) + {unit // 2}) // {unit})"
    if precision > 6:
        value = f"make_timestamp_ns(epoch_ns({as_nanoseconds(g, seconds)}) + {fraction} * {10 ** (9 - precision)})"
    else:
        value = f"{seconds} + to_microseconds({fraction} * {10 ** (6 - precision)})"
    valid = f"regexp_matches({text}, {string(pattern)}) AND TRY_CAST({seconds_text} AS TIMESTAMP) IS NOT NULL"
    return f"CASE WHEN {valid} THEN {value} ELSE {bad} END"


def varchar_of(g: Writer, sql: str, source: TType) -> str:
    """Trino's text of a value (CAST AS VARCHAR): doubles as 1.5E0, decimals with their full scale,
    timestamps with exactly p fractional digits."""
    if source.base in ("varchar", "char"):
        return sql
    if source.is_approx:
        return approx_text(sql, source)
    if source.is_decimal:
        precision, scale = source.args
        if precision == scale:
            return f"regexp_replace(CAST({sql} AS VARCHAR), '^(-?)[.]', '\\10.')"
        return f"CAST({sql} AS VARCHAR)"
    if source.base == "timestamp":
        return timestamp_text(sql, source.args[0])
    if source.base == "time":
        return times.text(sql, source.args[0])
    if source.base == "timestamp_tz":
        zone = tt.zone_of(source)
        return timestamp_text(zones.local(sql, zone), source.args[0]) + f" || {string(' ' + zone)}"
    return f"CAST({sql} AS VARCHAR)"


def timestamp_text(sql: str, precision: int) -> str:
    formats = {0: "%Y-%m-%d %H:%M:%S", 3: "%Y-%m-%d %H:%M:%S.%g", 6: "%Y-%m-%d %H:%M:%S.%f", 9: "%Y-%m-%d %H:%M:%S.%n"}
    if precision in formats:
        return f"strftime({sql}, {string(formats[precision])})"
    digits = 6 if precision < 6 else 9
    return f"left(strftime({sql}, {string(formats[digits])}), {20 + precision})"


def approx_text(sql: str, source: TType) -> str:
    """A double or real as Trino prints it: Java's DecimalFormat("0.0###E0") of the shortest
    round-trip digits (1.5E0, 1.0E10, -2.5E-4, 0E0, NaN, Infinity)."""
    value = f"CAST({sql} AS {'FLOAT' if source.base == 'real' else 'DOUBLE'})"
    text = f"CAST(abs({value}) AS VARCHAR)"
    digits = f"regexp_replace(replace(split_part({text}, 'e', 1), '.', ''), '^0+|0+$', '', 'g')"
    exponent = f"CAST(split_part(format('{{:.16e}}', CAST(abs({value}) AS DOUBLE)), 'e', 2) AS INTEGER)"
    mantissa = f"left({digits}, 1) || '.' || coalesce(nullif(substr({digits}, 2), ''), '0')"
    return (
        f"CASE WHEN isnan({value}) THEN 'NaN' "
        f"WHEN isinf({value}) THEN CASE WHEN {value} > 0 THEN 'Infinity' ELSE '-Infinity' END "
        f"WHEN {value} = 0 THEN CASE WHEN starts_with(CAST({value} AS VARCHAR), '-') THEN '-0E0' ELSE '0E0' END "
        f"ELSE CASE WHEN {value} < 0 THEN '-' ELSE '' END || {mantissa} || 'E' || CAST({exponent} AS VARCHAR) END"
    )


@transform(FloorMicros)
def floored_micros(g: Writer, node: FloorMicros) -> str:
    return floor_micros(g.sql(node.this))


# --- function calls ------------------------------------------------------------------------------
@transform(exp.Anonymous)
def registered_function(g: Writer, node: exp.Anonymous) -> str:
    """Every function call is written by its registry entry (registry.SUPPORTED)."""
    return node.meta["spec"].render(g, node, node.meta["args"])


@transform(exp.Filter)
def aggregate_filter(g: Writer, node: exp.Filter) -> str:
    """FILTER (WHERE ...) is written by the aggregate itself (`Writer.agg`), inside any cast."""
    return g.sql(node.this)


@transform(exp.Window)
def window_call(g: Writer, node: exp.Window) -> str:
    """OVER (...) is written by the function itself (`Writer.agg`), inside any cast."""
    inner = node.this
    while isinstance(inner, (exp.IgnoreNulls, exp.RespectNulls, exp.Filter)):
        inner = inner.this
    return g.sql(inner)


@transform(exp.CurrentTimestamp)
def current_timestamp_millis(g: Writer, node: exp.Expression) -> str:
    """timestamp(3) with time zone: milliseconds, as Trino's current_timestamp."""
    return "date_trunc('millisecond', current_timestamp)"


@transform(exp.Localtimestamp)
def localtimestamp_millis(g: Writer, node: exp.Expression) -> str:
    """The wall time now in the session zone."""
    return f"date_trunc('millisecond', {zones.local('current_timestamp', g.time_zone)})"


@transform(exp.CurrentDate)
def current_date_in_zone(g: Writer, node: exp.Expression) -> str:
    """Today in the session zone."""
    return f"CAST({zones.local('current_timestamp', g.time_zone)} AS DATE)"


_EXTRACT = {
    "DAY_OF_MONTH": "day",
    "DAY_OF_WEEK": "isodow",
    "DOW": "isodow",
    "DAY_OF_YEAR": "doy",
    "DOY": "doy",
    "YEAR_OF_WEEK": "isoyear",
    "YOW": "isoyear",
    "WEEK": "week",
}


@transform(exp.Extract)
def extract_field(g: Writer, node: exp.Extract) -> str:
    """EXTRACT with Trino's field meanings (DAY_OF_WEEK is ISO: Monday = 1)."""
    unit = node.this.name.upper()
    value = node.expression
    if unit in ("TIMEZONE_HOUR", "TIMEZONE_MINUTE"):
        return zone_offset(g, value, unit.split("_")[1].lower())
    sql = wall_time(g, value)
    return f"CAST(date_part({string(_EXTRACT.get(unit, unit.lower()))}, {sql}) AS BIGINT)"


@transform(exp.Interval)
def interval_literal(g: Writer, node: exp.Interval) -> str:
    return f"INTERVAL {string(node.this.name.strip())} {node.args['unit'].name.upper()}"


@transform(exp.AtTimeZone)
def at_time_zone(g: Writer, node: exp.AtTimeZone) -> str:
    """The same instant, shown in another zone (the zone is the type's); a timestamp is first read in the
    session zone."""
    return g.coerce(node.this, ttype(node))


def zone_offset(g: Writer, node: exp.Expression, part: str) -> str:
    """The hour or minute part of the UTC offset of a timestamp with time zone's zone at its instant
    (Trino's timezone_hour / timezone_minute: -5 and 0 for New York in winter, 5 and 45 for Kathmandu);
    a timestamp is read in the session zone."""
    t = ttype(node)
    zone = tt.zone_of(t) if t.base == "timestamp_tz" else g.time_zone
    sql = g.coerce(node, tt.timestamp(t.args[0] if t.args else 3, True, zone))
    minutes = f"CAST(epoch({zones.local(sql, zone)}) - epoch({zones.local(sql, zones.UTC)}) AS BIGINT) // 60"
    if part == "hour":
        return f"CAST(trunc(({minutes}) / 60) AS BIGINT)"
    return f"CAST(({minutes}) - trunc(({minutes}) / 60) * 60 AS BIGINT)"


def wall_time(g: Writer, node: exp.Expression) -> str:
    """SQL of a date or timestamp value as DuckDB computes its fields: a timestamp with time zone as its
    wall time in its zone (analysis refused one of no single zone)."""
    sql = g.sql(node)
    t = ttype(node)
    return zones.local(sql, tt.zone_of(t)) if t.base == "timestamp_tz" else sql


@transform(exp.Substring)
def substring_from(g: Writer, node: exp.Substring) -> str:
    """substr(s, start[, length]): start 0 or a negative length give '' (DuckDB counts them)."""
    value, start = g.sql(node.this), g.sql(node.args["start"])
    length = node.args.get("length")
    if length is None:
        return f"CASE WHEN ({start}) = 0 OR abs({start}) > length({value}) THEN '' ELSE substr({value}, {start}) END"
    length_sql = g.sql(length)
    return (
        f"CASE WHEN ({start}) = 0 OR ({length_sql}) <= 0 OR abs({start}) > length({value}) THEN '' "
        f"ELSE substr({value}, {start}, {length_sql}) END"
    )


#: Characters Trino's trim/ltrim/rtrim remove (Unicode whitespace, io.airlift.slice.SliceUtf8).
WHITESPACE = "".join(
    chr(c)
    for c in (
        9,
        10,
        11,
        12,
        13,
        28,
        29,
        30,
        31,
        32,
        0x1680,
        0x2000,
        0x2001,
        0x2002,
        0x2003,
        0x2004,
        0x2005,
        0x2006,
        0x2008,
        0x2009,
        0x200A,
        0x2028,
        0x2029,
        0x205F,
        0x3000,
    )
)


@transform(exp.Trim)
def trim_whitespace(g: Writer, node: exp.Trim) -> str:
    """TRIM removes Trino's whitespace set (DuckDB's trim only removes spaces)."""
    chars = node.args.get("expression")
    chars_sql = g.sql(chars) if chars is not None else string(WHITESPACE)
    position = (node.args.get("position") or "BOTH").upper()
    name = {"BOTH": "trim", "LEADING": "ltrim", "TRAILING": "rtrim"}[position]
    return f"{name}({g.sql(node.this)}, {chars_sql})"


@transform(exp.StrPosition)
def strpos(g: Writer, node: exp.StrPosition) -> str:
    return f"CAST(strpos({g.sql(node.this)}, {g.sql(node.args['substr'])}) AS BIGINT)"


# --- relations -----------------------------------------------------------------------------------
@transform(exp.Unnest)
def unnest_relation(g: Writer, node: exp.Unnest) -> str:
    """UNNEST(a [, b ...]) [WITH ORDINALITY] AS t(...): arrays of rows expand into their fields,
    several arrays zip with NULL padding, as in Trino."""
    name = quote(node.meta["qualifier"])
    names = node.meta["names"]
    elements = node.meta["elements"]
    selects = []
    position = 0
    arrays = []
    for arg, fields in zip(node.expressions, elements):
        array_sql = g.sql(arg)
        arrays.append(array_sql)
        t = ttype(arg)
        if t.base == "map":
            selects.append(f"unnest(map_keys({array_sql})) AS {quote(names[position])}")
            selects.append(f"unnest(map_values({array_sql})) AS {quote(names[position + 1])}")
            position += 2
            continue
        if len(fields) == 1 and fields[0][0] is None and t.element.base != "row":
            selects.append(f"unnest({array_sql}) AS {quote(names[position])}")
            position += 1
            continue
        for index, (field_name, _) in enumerate(fields):
            key = string(field_name) if field_name else str(index + 1)
            selects.append(f"struct_extract(unnest({array_sql}), {key}) AS {quote(names[position])}")
            position += 1
    if node.args.get("offset"):
        lengths = ", ".join(f"coalesce(len({a}), 0)" for a in arrays)
        longest = lengths if len(arrays) == 1 else f"greatest({lengths})"
        selects.append(f"unnest(range(1, {longest} + 1)) AS {quote(names[position])}")
    return f"LATERAL (SELECT {', '.join(selects)}) AS {name}"


@transform(exp.Values)
def typed_values(g: Writer, node: exp.Values) -> str:
    """VALUES rows with every cell coerced to its column's Trino common type."""
    types = node.meta["types"]
    rows = []
    for row in node.expressions:
        cells = row.expressions if isinstance(row, exp.Tuple) else [row]
        rows.append("(" + ", ".join(g.coerce(c, t) for c, t in zip(cells, types)) + ")")
    sql = "(VALUES " + ", ".join(rows) + ")"
    alias = node.args.get("alias")
    if alias is not None:
        sql += " AS " + g.sql(alias)
    return sql


# --- final shape ---------------------------------------------------------------------------------
def finalize(tree: exp.Expression, outputs: list) -> None:
    """Give every select item its DuckDB name (`_colN` for anonymous ones), cast set-operation
    branches to the common types, and cast the statement's output columns to the DuckDB types of
    their Trino types (so DuckDB's own choices, e.g. HUGEINT sums, never leak out)."""
    for select in tree.find_all(exp.Select):
        outs = select.meta.get("outputs")
        if outs is None:
            continue
        items = []
        for item, (_, duck_name, _) in zip(select.expressions, outs):
            inner = item.this if isinstance(item, exp.Alias) else item
            items.append(exp.Alias(this=inner, alias=exp.to_identifier(duck_name, quoted=True)))
        select.set("expressions", items)
    for operation in tree.find_all(exp.SetOperation):
        _cast_branches(operation, operation.meta["outputs"])
    _cast_outputs(tree, [t for _, _, t in outputs], top=True)


def _branches(node: exp.Expression):
    if isinstance(node, exp.SetOperation):
        yield from _branches(node.this)
        yield from _branches(node.expression)
    elif isinstance(node, exp.Subquery):
        yield from _branches(node.this)
    else:
        yield node


def _cast_branches(operation: exp.SetOperation, outputs: list) -> None:
    for branch in _branches(operation):
        if isinstance(branch, exp.Select):
            for item, (_, _, common) in zip(branch.expressions, outputs):
                if common.base == "char":
                    chars.cast_to(item.this, common)
                elif ttype(item.this) != common and not ttype(item.this).base == common.base == "varchar":
                    _wrap(item, common)


def _cast_outputs(tree: exp.Expression, types: list[TType], top: bool) -> None:
    for branch in _branches(tree):
        if isinstance(branch, exp.Select):
            for item, t in zip(branch.expressions, types):
                _wrap(item, t)


def _wrap(item: exp.Alias, t: TType) -> None:
    duck = tt.duckdb_type(t)
    inner = item.this
    if duck is None or isinstance(inner, DuckCast):
        return
    wrapped = DuckCast(this=inner, to=duck)
    wrapped.meta["t"] = t
    item.set("this", wrapped)


# --- Trino-level rewrites (also seen by the forwarding backend) ----------------------------------
def _output_name(item: exp.Expression) -> str | None:
    if isinstance(item, exp.Alias):
        ident = item.args["alias"]
        return ident.name if ident.quoted else ident.name.lower()
    if isinstance(item, exp.Column) and not isinstance(item.this, exp.Star):
        return item.name.lower() if not item.this.quoted else item.name
    return None


def _first_select(node: exp.Expression) -> exp.Select | None:
    while isinstance(node, (exp.SetOperation, exp.Subquery)):
        node = node.this
    return node if isinstance(node, exp.Select) else None


def _aggregates_or_windows(select: exp.Select) -> bool:
    for item in select.expressions:
        for node in item.walk():
            if isinstance(node, exp.Window):
                return True
            if isinstance(node, exp.Anonymous):
                spec = registry.SUPPORTED.get(node.name.lower())
                if spec is not None and spec.kind != "scalar":
                    return True
    return False


def hoist_derived_order(tree: exp.Expression) -> bool:
    """An ORDER BY inside a derived table is kept for the outer query when that query has none and
    only projects and filters the derived table (`SELECT a, b FROM (... ORDER BY k)`): the rows
    come out in that order, which reports relying on it expect. Whether anything was hoisted."""
    hoisted_any = False
    for select in list(tree.find_all(exp.Select)):
        from_ = select.args.get("from_")
        if from_ is None or not isinstance(from_.this, exp.Subquery) or select.args.get("order") is not None:
            continue
        if any(select.args.get(k) for k in ("joins", "group", "having", "distinct", "laterals")):
            continue
        if _aggregates_or_windows(select) or any(isinstance(i, exp.Star) for i in select.expressions):
            continue
        derived = from_.this
        inner = derived.this
        order = inner.args.get("order")
        first = _first_select(inner)
        if order is None or first is None or any(isinstance(i, exp.Star) for i in first.expressions):
            continue
        alias = derived.args.get("alias")
        names = [_output_name(i) for i in first.expressions]
        if alias is not None and alias.columns:
            names = [c.name if c.quoted else c.name.lower() for c in alias.columns]
        hoisted = []
        for ordered in order.expressions:
            target = ordered.this
            if isinstance(target, exp.Literal) and not target.is_string and target.name.isdigit():
                index = int(target.name) - 1
                name = names[index] if 0 <= index < len(names) else None
            elif isinstance(target, exp.Column) and not target.table:
                wanted = target.name if target.this.quoted else target.name.lower()
                name = next((n for n in names if n is not None and n.lower() == wanted.lower()), None)
            else:
                name = None
            if name is None:
                break
            hoisted.append((name, ordered))
        else:
            if alias is None or not alias.name:
                alias = exp.TableAlias(this=exp.to_identifier("_ordered"))
                derived.set("alias", alias)
            select.set(
                "order",
                exp.Order(
                    expressions=[
                        exp.Ordered(
                            this=exp.column(exp.to_identifier(name, quoted=True), table=alias.this.copy()),
                            desc=ordered.args.get("desc"),
                            nulls_first=ordered.args.get("nulls_first"),
                        )
                        for name, ordered in hoisted
                    ]
                ),
            )
            if inner.args.get("limit") is None and inner.args.get("offset") is None:
                inner.set("order", None)
            hoisted_any = True
    return hoisted_any


# --- scalar subqueries ---------------------------------------------------------------------------
def _single_row(query: exp.Expression) -> bool:
    """Whether a query returns at most one row by its shape (LIMIT 1, or aggregates without GROUP BY)."""
    limit = query.args.get("limit")
    if limit is not None and isinstance(limit.expression, exp.Literal) and limit.expression.name in ("0", "1"):
        return True
    if not isinstance(query, exp.Select) or query.args.get("group") is not None:
        return False
    for item in query.expressions:
        for node in item.walk():
            if isinstance(node, (exp.Subquery, exp.Window)):
                break
            if (
                isinstance(node, exp.Anonymous)
                and node._meta
                and node.meta.get("spec") is not None
                and node.meta["spec"].kind == "aggregate"
                and node.meta.get("over") is None
            ):
                return True
    return False


@transform(exp.Subquery)
def scalar_subquery_single_row(g: Writer, node: exp.Subquery) -> str:
    """A scalar subquery that returns several rows fails with Trino's SUBQUERY_MULTIPLE_ROWS."""
    inner = DuckDBGenerator.subquery_sql(g, node)
    n = node.meta.get("row_subquery") if node._meta else None  # several columns: their row
    if not n and (not node._meta or "t" not in node.meta or _single_row(node.this)):
        return inner
    message = string("Scalar sub-query has returned multiple rows")
    names = [quote(f"_v{i + 1}") for i in range(n)] if n else ['"_v"']
    value = "row(" + ", ".join('"_s".' + name for name in names) + ")" if n else '"_s"."_v"'
    if n and _single_row(node.this):
        return f'(SELECT {value} FROM {inner} AS "_s"({", ".join(names)}))'
    return (
        f"(SELECT CASE WHEN count(*) OVER () > 1 THEN {g.fail(message, 'SUBQUERY_MULTIPLE_ROWS')} "
        f'ELSE {value} END FROM {inner} AS "_s"({", ".join(names)}) LIMIT 1)'
    )
