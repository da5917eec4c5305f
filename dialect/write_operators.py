"""DuckDB SQL of Trino's operators, as named transforms of the Writer (transforms.py): integer,
decimal and temporal arithmetic, IEEE comparisons with Trino's NULL and NaN rules, IN and BETWEEN,
CASE / IF, NULL ordering, subscripts and ARRAY constructors.
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import chars, pico_times, wide_decimals, zoned_times, zones
from lakegate.dialect import trino_types as tt
from lakegate.dialect import wide_timestamps as wide
from lakegate.dialect.transforms import Writer, cast, quote, string, ten, transform
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import ttype
from lakegate.dialect.write_casts import RANGES, cast_value, floor_div, floor_micros, with_nanos


# --- arithmetic ----------------------------------------------------------------------------------
def _operands(g: Writer, node: exp.Binary) -> tuple[str, str]:
    return g.sql(node.this), g.sql(node.expression)


def checked_integer(g: Writer, sql: str, t: TType, what: str) -> str:
    """`sql` (computed wider, as HUGEINT) as integral type `t`, failing with Trino's
    NUMERIC_VALUE_OUT_OF_RANGE when it does not fit."""
    low, high = RANGES[t.base]
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
    if wide.is_wide(t):
        return wide_interval_arithmetic(g, node, op)
    if t.base == "timestamp_tz" and tt.INTERVAL_YM in (ttype(node.this), ttype(node.expression)):
        # months move the wall time in the value's zone; a day-to-second interval moves the instant
        zone = tt.zone_of(t)
        stamp, months = (left, right) if ttype(node.this).base == "timestamp_tz" else (right, left)
        return cast(zones.instant(f"({zones.local(stamp, zone)} {op} {months})", zone), t)
    if t.base == "timestamp" and t.args[0] > 6:
        return nanosecond_interval_arithmetic(g, node, op)
    if t == tt.INTERVAL_DS and ttype(node.this).base == "timestamp":
        return timestamp_difference(g, node)
    if t.base == "time_tz" or t == tt.INTERVAL_DS and ttype(node.this).base == "time_tz":
        return zoned_time_arithmetic(g, node, op)
    if pico_times.is_wide(t) or t == tt.INTERVAL_DS and ttype(node.this).base == "time":
        return time_picos_arithmetic(g, node, op)
    return sql


def zoned_time_arithmetic(g: Writer, node: exp.Binary, op: str) -> str:
    """time with time zone ± a day-to-second interval (the local time moved modulo a day, the offset
    kept), and the difference of two (their times at +00:00, rounded HALF_UP to milliseconds):
    TimeWithTimeZoneOperators."""
    left, right = g.sql(node.this), g.sql(node.expression)
    if ttype(node.this).base == ttype(node.expression).base == "time_tz":
        millis = floor_div(f"{zoned_times.difference_picos(left, right)} + 500000000", 1_000_000_000)
        return f"to_milliseconds({millis})"
    value, interval = (left, right) if ttype(node.this).base == "time_tz" else (right, left)
    delta = zoned_times.interval_picos(interval)
    return zoned_times.add_picos(value, delta if op == "+" else f"-{delta}", ttype(node).args[0])


def wide_interval_arithmetic(g: Writer, node: exp.Binary, op: str) -> str:
    """timestamp(7..12) with time zone ± interval: the interval moves the microseconds (months the wall
    time in the value's zone), the picoseconds below them stay (TimestampWithTimeZoneOperators)."""
    t = ttype(node)
    stamp, interval = node.this, node.expression
    if ttype(stamp).base.startswith("interval"):
        stamp, interval = interval, stamp
    sql, amount = g.sql(stamp), g.sql(interval)
    micros = wide.micros(sql)
    zoned = t.base == "timestamp_tz"
    if ttype(interval) == tt.INTERVAL_YM and zoned:
        zone = tt.zone_of(t)
        moved = zones.instant(f"({zones.local(micros, zone)} {op} {amount})", zone)
    else:
        moved = f"({micros} {op} {amount})"
    return wide.make(moved, wide.picos(sql), zoned)


def time_picos_arithmetic(g: Writer, node: exp.Binary, op: str) -> str:
    """time(p > 6) ± a day-to-second interval (moved modulo a day), and the difference of two times of
    any precision (rounded HALF_UP to milliseconds): TimeOperators on picoseconds (pico_times.py)."""
    left, right = g.sql(node.this), g.sql(node.expression)
    if ttype(node.this).base == ttype(node.expression).base == "time":
        return pico_times.difference(
            pico_times.picos(left, ttype(node.this)), pico_times.picos(right, ttype(node.expression))
        )
    value, interval = (left, right) if ttype(node.this).base == "time" else (right, left)
    delta = zoned_times.interval_picos(interval)
    return pico_times.moved(value, delta if op == "+" else f"-{delta}")


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
    if wide.is_wide(t):
        return f"epoch_us({wide.micros(sql)})"
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
        return f"({left} // {nonzero(g, right, left)})"
    if t.is_decimal:
        return decimal_division(g, node.this, node.expression, t)
    sql = f"{cast(left, t)} / {cast(right, t)}" if t.base == "real" else f"{left} / {right}"
    return cast(sql, t) if t.base == "real" else sql


def nonzero(g: Writer, sql: str, dividend: str | None = None) -> str:
    """A divisor that fails with DIVISION_BY_ZERO (NULL inside try()) when it is zero, unless the
    `dividend` is NULL (Trino's operators are NULL on a NULL operand: nothing is divided)."""
    if sql.lstrip("-").isdigit() and int(sql) != 0:
        return sql
    if g.in_try and g.catching != g.in_try:
        return f"NULLIF({sql}, 0)"
    present = f" AND ({dividend}) IS NOT NULL" if dividend is not None else ""
    return f"CASE WHEN {sql} = 0{present} THEN {g.fail(string('Division by zero'), 'DIVISION_BY_ZERO')} ELSE {sql} END"


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
    denominator = nonzero(g, denominator, numerator)
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


def approx_remainder(left: str, right: str) -> str:
    """Java's DOUBLE/REAL remainder: NaN for a zero divisor, NULL when either side is NULL."""
    return f"CASE WHEN {right} = 0 THEN {left} * CAST('NaN' AS DOUBLE) ELSE {left} % {right} END"


@transform(exp.Mod)
def modulus(g: Writer, node: exp.Mod) -> str:
    """Remainder with the dividend's sign; integer and decimal zero divisors fail, doubles give NaN."""
    t = ttype(node)
    left, right = _operands(g, node)
    if t.is_approx:
        return cast(approx_remainder(left, right), t)
    sql = f"({left} % {nonzero(g, right, left)})"
    return cast(sql, t) if t.is_decimal else sql


@transform(exp.DPipe)
def concat_operator(g: Writer, node: exp.DPipe) -> str:
    """`||` on strings is NULL when either side is; on arrays it concatenates or appends."""
    if not node.meta.get("array"):
        return f"({g.sql(node.this)} || {g.sql(node.expression)})"
    t = ttype(node)
    left, right = node.this, node.expression
    lt, rt = ttype(left), ttype(right)
    if lt.is_unknown or rt.is_unknown:  # x || NULL as array(x): always NULL
        return f"CAST(NULL AS {tt.duckdb_type(t) or 'INTEGER[]'})"  # array(unknown): any list type
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
        # NULL against NaN is NULL: the NaN test only once neither side is NULL
        nan = " OR ".join(f"isnan({s})" for s in sides)
        nulls = " OR ".join(f"({s}) IS NULL" for s in sides)
        if len(sides) == 1:
            nulls = f"({left}) IS NULL OR ({right}) IS NULL"
        unordered = "true" if op == "<>" else "false"
        return f"CASE WHEN {nulls} THEN NULL WHEN {nan} THEN {unordered} ELSE {left} {op} {right} END"
    if common.base == "time_tz":  # the times at offset +00:00 (dialect/zoned_times.py)
        return f"{zoned_times.utc(_as(g, node.this, common))} {op} {zoned_times.utc(_as(g, node.expression, common))}"
    if wide.is_wide(common):  # structs ordered as the instants (wide_timestamps.py)
        return f"{g.coerce(node.this, common)} {op} {g.coerce(node.expression, common)}"
    if pico_times.is_wide(common):  # both sides as picoseconds
        return f"{_as(g, node.this, common)} {op} {_as(g, node.expression, common)}"
    if common.base in ("array", "map", "row") and op in ("=", "<>"):
        equal = trino_equal(left, right, common)
        return equal if op == "=" else f"NOT ({equal})"
    if common.base in ("array", "row"):
        return ordered_comparison(left, right, common, op)
    return f"{left} {op} {right}"


def _as(g: Writer, node: exp.Expression, t: TType) -> str:
    """`node` cast to `t` by Trino's CAST (a time or NULL to time with time zone)."""
    return cast_value(g, g.sql(node), ttype(node), t)


@transform(exp.NullSafeEQ, exp.NullSafeNEQ)
def distinct_from(g: Writer, node: exp.Binary) -> str:
    """IS [NOT] DISTINCT FROM; of time with time zone values, on their times at +00:00."""
    op = "IS NOT DISTINCT FROM" if isinstance(node, exp.NullSafeEQ) else "IS DISTINCT FROM"
    common = node.meta.get("compare")
    if common is not None and common.base == "time_tz":
        return f"{zoned_times.utc(_as(g, node.this, common))} {op} {zoned_times.utc(_as(g, node.expression, common))}"
    if wide.is_wide(common):
        return f"{g.coerce(node.this, common)} {op} {g.coerce(node.expression, common)}"
    if pico_times.is_wide(common):
        return f"{_as(g, node.this, common)} {op} {_as(g, node.expression, common)}"
    return f"{g.sql(node.this)} {op} {g.sql(node.expression)}"


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
    common = node.meta.get("compare")
    if items and common is not None and common.is_approx:
        sql = _nan_in_list(g, node, common, sql)
    elif items and common is not None and common.base in ("array", "map", "row"):
        sql = _nested_in_list(g, node, common)
    elif items and common is not None and common.base == "time_tz":  # the times at +00:00 (zoned_times.py)
        value, *listed = (zoned_times.utc(_as(g, side, common)) for side in (node.this, *items))
        sql = f"{value} IN ({', '.join(listed)})"
    elif items and wide.is_wide(common):
        value, *listed = (g.coerce(side, common) for side in (node.this, *items))
        sql = f"{value} IN ({', '.join(listed)})"
    elif items and pico_times.is_wide(common):
        value, *listed = (_as(g, side, common) for side in (node.this, *items))
        sql = f"{value} IN ({', '.join(listed)})"
    if node.find(exp.Column) is not None or all(isinstance(i, (exp.Literal, exp.Null)) for i in items):
        return sql
    return f"CASE WHEN len([{', '.join(g.coerce(i, common) for i in items)}]) >= 0 THEN {sql} END"


def _nested_in_list(g: Writer, node: exp.In, common: TType) -> str:
    """An array, map or row IN a list: Trino's `=` with each item, ORed (NULL when no item is equal and
    a comparison reaches a NULL inside, `ARRAY[1, NULL] IN (ARRAY[1, 2])`), where DuckDB's IN compares
    NULL inside arrays and rows as a value."""
    value = g.coerce(node.this, common)
    return "(" + " OR ".join(f"({trino_equal(value, g.coerce(i, common), common)})" for i in node.expressions) + ")"


def _variable(node: exp.Expression) -> bool:
    """A column or a lambda's parameter: what Trino's planner does not fold as a constant."""
    return isinstance(node, exp.Column) or isinstance(node, exp.Identifier) and bool(node.meta.get("lambda"))


def _holds_variable(node: exp.Expression) -> bool:
    return any(_variable(n) for n in node.walk())


def _nan_in_list(g: Writer, node: exp.In, common: TType, sql: str) -> str:
    """NaN IN (...) as the real Trino 476 answers: NaN equals no item (DuckDB's IN matches NaN with
    NaN), except where Trino's planner matches before comparing, in a list not wholly constant: the
    very same column as the value (`x IN (x, ...)`), or a constant value and a constant NaN item
    (`nan() IN (x, sqrt(-1))`). NULL when nothing matches and an item is NULL."""
    value = g.coerce(node.this, common)
    matches = []
    if _holds_variable(node):
        if _variable(node.this) and any(item == node.this for item in node.expressions):
            matches.append("true")
        if not _holds_variable(node.this):
            constants = [i for i in node.expressions if not _holds_variable(i)]
            matches += [f"isnan({g.coerce(i, common)})" for i in constants if not isinstance(i, exp.Null)]
    nulls = " OR ".join(f"({g.coerce(i, common)}) IS NULL" for i in node.expressions)
    matched = f"WHEN {' OR '.join(matches)} THEN true " if matches else ""
    return f"CASE WHEN isnan({value}) THEN CASE {matched}WHEN {nulls} THEN NULL ELSE false END ELSE {sql} END"


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
    """`v BETWEEN low AND high` is `low <= v AND v <= high` with IEEE comparisons: each false when a
    double is NaN (DuckDB orders NaN above every number), NULL when a side is NULL."""
    common = node.meta.get("compare")
    if common is not None and common.base in ("array", "row"):
        value, low, high = (g.coerce(side, common) for side in (node.this, node.args["low"], node.args["high"]))
        return f"({ordered_comparison(low, value, common, '<=')} AND {ordered_comparison(value, high, common, '<=')})"
    if common == tt.as_char(tt.VARCHAR):  # char and unbounded varchar
        return chars.between(g, node.this, node.args["low"], node.args["high"])
    if common is not None and common.base == "time_tz":  # the times at +00:00 (zoned_times.py)
        value, low, high = (
            zoned_times.utc(_as(g, side, common)) for side in (node.this, node.args["low"], node.args["high"])
        )
        return f"{value} BETWEEN {low} AND {high}"
    if wide.is_wide(common):
        value, low, high = (g.coerce(side, common) for side in (node.this, node.args["low"], node.args["high"]))
        return f"{value} BETWEEN {low} AND {high}"
    if pico_times.is_wide(common):
        value, low, high = (_as(g, side, common) for side in (node.this, node.args["low"], node.args["high"]))
        return f"{value} BETWEEN {low} AND {high}"
    sql = g.between_sql(node)
    if common is None or not common.is_approx:
        return sql
    value, low, high = (g.sql(side) for side in (node.this, node.args["low"], node.args["high"]))

    def at_most(a: str, b: str) -> str:  # IEEE a <= b: NULL with a NULL side, false with a NaN
        nulls, nan = f"({a}) IS NULL OR ({b}) IS NULL", f"isnan({a}) OR isnan({b})"
        return f"CASE WHEN {nulls} THEN NULL WHEN {nan} THEN false ELSE {a} <= {b} END"

    return f"(({at_most(low, value)}) AND ({at_most(value, high)}))"


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
    zoned = node.this.meta.get("t") if node.this._meta else None
    if isinstance(node.this, exp.Literal) and not node.this.is_string:  # ORDER BY 2: the output column's type
        query = node.find_ancestor(exp.Select, exp.SetOperation)
        outputs = query.meta.get("outputs") if query is not None and query._meta else None
        index = int(node.this.name) - 1
        if outputs and 0 <= index < len(outputs) and outputs[index][2].base == "time_tz":
            key, zoned = quote(outputs[index][1]), outputs[index][2]
    if zoned is not None and zoned.base == "time_tz":
        key = zoned_times.utc(key)  # equal times at +00:00 are ties (a later key decides) and window peers
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
    """arr[i] fails out of range; map[key] fails for a missing key (element_at gives NULL); row[i] is
    its i-th field (analysis checked i)."""
    container = ttype(node.this)
    if container.base == "row":
        return f"struct_extract_at({g.sql(node.this)}, {int(node.expressions[0].name)})"
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
