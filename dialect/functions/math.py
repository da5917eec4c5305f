"""Trino's functions/math.md. Mathematical functions and operators, with the statistical and cosine functions."""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import write_operators as ops
from lakegate.dialect.functions.arguments import as_double, fixed, need
from lakegate.dialect.functions.rendering import call_as, sqls
from lakegate.dialect.infer_operators import remainder_fits
from lakegate.dialect.registry import Render, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


# === math =========================================================================================
def _abs(call: Call) -> TType:
    (t,) = need(call, "number")
    return t


def _round(call: Call) -> TType:
    types = need(call, "number", "integral", optional=1)
    if len(types) == 2 and types[1].base == "bigint":  # MathFunctions.round(x, INTEGER decimals)
        call.mismatch()
    t = types[0]
    if len(types) == 2 and not (t.is_approx or types[1].is_unknown or call.literal(1) is not None):
        call.fail("unsupported in lakegate: round(x, d) of an exact number with a non-literal d", "NOT_SUPPORTED")
    if t.is_decimal:
        p, s = t.args
        if len(types) == 2:
            return tt.decimal(min(38, p + 1), s)
        return tt.decimal(p - s + min(s, 1), 0)
    return t


def _render_round(g, node, args) -> str:
    t = ttype(node)
    source = ttype(args[0])
    value = g.sql(args[0])
    digits = g.sql(args[1]) if len(args) == 2 else "0"
    if source.is_decimal:
        # DuckDB rounds decimals HALF_UP but narrows the scale: widen back to Trino's type
        return tf.cast(f"round({value}, {digits})", t) if len(args) == 2 else tf.cast(f"round({value})", t)
    if source.is_integral:
        return value if len(args) == 1 else _round_integral(g, value, digits, t)
    if source.base == "real":  # rounded as a double, then narrowed (round(REAL '2.675', 2) is 2.67)
        return tf.cast(_round_double(f"CAST({value} AS DOUBLE)", digits), t)
    return _round_double(value, digits)


def _round_double(value: str, digits: str) -> str:
    """round(double, d) as Trino 476 answers it: |x| scaled by 10^d in double arithmetic, rounded half
    up, divided back, the sign put back for x < 0 only (so -0.0 gives 0.0). A scaled value that is
    infinite gives x (round(1e300, 10), round(1.5, 400)); 0 x 10^400 is NaN and rounds to 0; a factor of
    0 (d <= -324) gives 0 / 0 = NaN. DuckDB's own round is not Java's: since 2.0.1 it gives 3.17 for
    round(3.175, 2), where 3.175 x 100 is exactly 317.5 and Trino gives 3.18."""
    factor = f"power(10.0, {digits})"
    scaled = f"(abs({value}) * {factor})"
    up = f"CASE WHEN {scaled} - floor({scaled}) >= 0.5 THEN 1.0 ELSE 0.0 END"
    rounded = (
        f"CASE WHEN isnan({scaled}) THEN 0.0 WHEN {scaled} >= 4503599627370496.0 THEN {scaled} "
        f"ELSE floor({scaled}) + {up} END"
    )
    return (
        f"CASE WHEN {factor} IS NULL THEN NULL WHEN isnan({value}) OR isinf({value}) OR isinf({scaled}) THEN {value} "
        f"ELSE CASE WHEN {value} < 0 THEN -1.0 ELSE 1.0 END * (({rounded}) / {factor}) END"
    )


def _round_integral(g, value: str, digits: str, t: TType) -> str:
    """round(integer, d): HALF_UP to 10^-d, failing with NUMERIC_VALUE_OUT_OF_RANGE when 10^-d or
    the result overflows (io.trino.operator.scalar.MathFunctions.roundLong)."""
    rounded = f"round(CAST({value} AS DECIMAL(38,0)), {digits})"
    overflow = f"{tf.string('numerical overflow: ')} || CAST({value} AS VARCHAR)"
    if t.base != "bigint":
        overflow = f"{tf.string(f'Out of range for {t.base}: ')} || CAST({rounded} AS VARCHAR)"
    too_small = g.fail(f"{tf.string('numerical overflow: ')} || CAST({value} AS VARCHAR)", "NUMERIC_VALUE_OUT_OF_RANGE")
    return f"CASE WHEN ({digits}) < -18 THEN {too_small} ELSE {ops.checked_integer(g, rounded, t, overflow)} END"


def _ceil_floor(call: Call) -> TType:
    (t,) = need(call, "number")
    if t.is_decimal:
        p, s = t.args
        return tt.decimal(p - s + min(s, 1), 0)
    return t


def _render_ceil_floor(duck: str) -> Render:
    """DuckDB's ceil/floor, except for integers, which are their own ceiling and floor (DuckDB's go
    through a double and lose a bigint's last digits)."""
    as_duck = call_as(duck, cast_result=True)

    def render(g, node, args) -> str:
        return tf.cast(g.sql(args[0]), ttype(node)) if ttype(args[0]).is_integral else as_duck(g, node, args)

    return render


def _truncate(call: Call) -> TType:
    if len(call.args) == 2:
        return _truncate_n(call)
    (t,) = need(call, "number")
    if t.is_integral:  # Trino has truncate(decimal), not truncate(integer): the integer is a decimal(p, 0)
        return tt.as_decimal(t)
    if t.is_decimal:
        p, s = t.args
        return tt.decimal(max(1, p - s), 0)
    return t


def _truncate_n(call: Call) -> TType:
    """truncate(x, n): Trino has it for decimal(p, s) and INTEGER n only (MathFunctions.TruncateN), an
    integral x taken as a decimal; a double or real x is FUNCTION_NOT_FOUND as in Trino."""
    x, n = need(call, "number", "integral")
    if not (x.is_decimal or x.is_integral) or n.base == "bigint":
        call.mismatch()
    if not (n.is_unknown or call.literal(1) is not None):  # DuckDB's trunc needs a constant
        call.fail("unsupported in lakegate: truncate(x, n) with a non-literal n", "NOT_SUPPORTED")
    return tt.as_decimal(x)


def _render_truncate(g, node, args) -> str:
    """truncate(decimal, n) drops digits toward zero and keeps the type (DuckDB's trunc narrows the
    scale: cast back); n beyond the scale keeps x, n at or below -(p - s) gives 0, as TruncateN does."""
    t = ttype(node)
    if len(args) == 1:
        return tf.cast(f"trunc({g.sql(args[0])})", t)
    if ttype(args[1]).is_unknown:
        return tf.cast("NULL", t)
    return tf.cast(f"trunc({tf.cast(g.sql(args[0]), t)}, {g.sql(args[1])})", t)


def _sign(call: Call) -> TType:
    (t,) = need(call, "number")
    return tt.decimal(1, 0) if t.is_decimal else t


def _render_sign(g, node, args) -> str:
    value = g.sql(args[0])
    sql = f"sign({value})"
    if ttype(args[0]).is_approx:  # DuckDB: sign(NaN) = 0
        sql = f"CASE WHEN isnan({value}) THEN {value} ELSE {sql} END"
    return tf.cast(sql, ttype(node))


#: The largest magnitude `_constant_integer` computes (past it Trino's arithmetic may overflow).
_SMALL = 2**31 - 1


def _constant_integer(node: exp.Expression) -> int | None:
    """The value of an integer constant Trino's planner folds without failing: integer literals (typed
    or not), -, +, * and casts of them, and the ceiling, floor and abs of them; None otherwise."""
    value: int | None = None
    if isinstance(node, exp.Paren):
        value = _constant_integer(node.this)
    elif isinstance(node, exp.Literal):
        text = node.name.strip()
        value = int(text) if text.lstrip("+-").isdigit() else None
    elif isinstance(node, exp.Cast) and node.to.is_type(*exp.DataType.INTEGER_TYPES):
        value = _constant_integer(node.this)
    elif isinstance(node, exp.Neg):
        inner = _constant_integer(node.this)
        value = None if inner is None else -inner
    elif isinstance(node, (exp.Add, exp.Sub, exp.Mul)):
        left, right = _constant_integer(node.this), _constant_integer(node.expression)
        if left is not None and right is not None:
            value = {exp.Add: left + right, exp.Sub: left - right, exp.Mul: left * right}[type(node)]
    elif isinstance(node, exp.Anonymous) and node.name.lower() in ("abs", "ceil", "ceiling", "floor"):
        inner = _constant_integer(node.expressions[0]) if len(node.expressions) == 1 else None
        value = None if inner is None else abs(inner) if node.name.lower() == "abs" else inner
    return value if value is not None and abs(value) <= _SMALL else None


def _mod(call: Call) -> TType:
    """mod(n, m). Of integers by zero it is Java's ArithmeticException (GENERIC_INTERNAL_ERROR '/ by
    zero', which try() does not catch), raised while planning when both are constants."""
    a, b = need(call, "number", "number")
    result = tt.arithmetic_type("%", a, b)
    if result is None:
        call.mismatch()
    if result.is_integral and _constant_integer(call.args[1]) == 0 and _constant_integer(call.args[0]) is not None:
        call.fail("/ by zero", "GENERIC_INTERNAL_ERROR")
    if not remainder_fits(a, b, result):
        call.fail(
            f"unsupported in lakegate: mod({a}, {b}) (the operands at a common scale exceed 38 digits)", "NOT_SUPPORTED"
        )
    return result


def _render_mod(g, node, args) -> str:
    t = ttype(node)
    left, right = g.sql(args[0]), g.sql(args[1])
    if t.is_approx:
        return tf.cast(ops.approx_remainder(left, right), t)
    if t.is_integral:  # Java's ArithmeticException, even inside try()
        failure = f"error({tf.string('GENERIC_INTERNAL_ERROR: / by zero')})"
        divisor = f"CASE WHEN {right} = 0 AND ({left}) IS NOT NULL THEN {failure} ELSE {right} END"
        return tf.cast(f"({left} % {divisor})", t)
    return tf.cast(f"({left} % {ops.nonzero(g, right, left)})", t)


def _render_power(g, node, args) -> str:
    """Java's Math.pow: a base of 1 or -1 to an infinite power, and 1 to NaN, are NaN (C's pow gives 1)."""
    base, power = (f"CAST({g.sql(a)} AS DOUBLE)" for a in args)
    return (
        f"CASE WHEN abs({base}) = 1 AND (isinf({power}) OR isnan({power})) THEN CAST('NaN' AS DOUBLE) "
        f"ELSE pow({base}, {power}) END"
    )


def double_fn(duck: str) -> Render:
    """A DuckDB math function over the argument as double (DuckDB, like Java, gives NaN / Infinity
    outside the domain)."""

    def render(g, node, args):
        return f"{duck}({', '.join(f'CAST({g.sql(a)} AS DOUBLE)' for a in args)})"

    return render


def _random(call: Call) -> TType:
    if not call.args:
        return tt.DOUBLE
    types = need(call, "integral", "integral", optional=1)
    return tt.common_super_type_of([t for t in types])


def _render_random(g, node, args) -> str:
    if not args:
        return "random()"
    t = ttype(node)
    low, high = ("0", g.sql(args[0])) if len(args) == 1 else (g.sql(args[0]), g.sql(args[1]))
    return tf.cast(
        f"CASE WHEN ({high}) <= ({low}) THEN {g.fail(tf.string('bound must be greater than origin'))} "
        f"ELSE ({low}) + CAST(floor(random() * (({high}) - ({low}))) AS BIGINT) END",
        t,
    )


def _render_width_bucket(g, node, args) -> str:
    """MathFunctions.widthBucket(operand, bound1, bound2, bucketCount)."""
    x, b1, b2 = (f"CAST({g.sql(a)} AS DOUBLE)" for a in args[:3])
    n = f"CAST({g.sql(args[3])} AS BIGINT)"
    lower, upper = f"least({b1}, {b2})", f"greatest({b1}, {b2})"
    checks = [
        (f"{n} <= 0", "bucketCount must be greater than 0"),
        (f"isnan({x})", "operand must not be NaN"),
        (f"NOT isfinite({b1})", "first bound must be finite"),
        (f"NOT isfinite({b2})", "second bound must be finite"),
        (f"{b1} = {b2}", "bounds cannot equal each other"),
    ]
    whens = " ".join(f"WHEN {c} THEN {g.fail(tf.string(m))}" for c, m in checks)
    bucket = (
        f"CASE WHEN {x} < {lower} THEN 0 WHEN {x} >= {upper} THEN {n} + 1 "
        f"ELSE CAST(trunc(CAST({n} AS DOUBLE) * ({x} - {lower}) / ({upper} - {lower}) + 1) AS BIGINT) END"
    )
    return (
        f"CASE WHEN {x} IS NULL OR {b1} IS NULL OR {b2} IS NULL OR {n} IS NULL THEN NULL {whens} "
        f"WHEN {b1} > {b2} THEN {n} - ({bucket}) + 1 ELSE {bucket} END"
    )


def _render_width_bucket_bins(g, node, args) -> str:
    """MathFunctions.widthBucket(operand, bins): the number of bins <= operand. Trino's binary search
    fails when it meets unsorted or non-finite bins; here any such bin fails."""
    x, bins = f"CAST({g.sql(args[0])} AS DOUBLE)", g.sql(args[1])
    unsorted = f'len(list_filter(range(1, len({bins})), lambda "_i": {bins}["_i"] > {bins}["_i" + 1])) > 0'
    infinite = f'len(list_filter({bins}, lambda "_b": NOT isfinite("_b"))) > 0'
    return (
        f"CASE WHEN {x} IS NULL OR {bins} IS NULL THEN NULL "
        f"WHEN len({bins}) = 0 THEN {g.fail(tf.string('Bins cannot be an empty array'))} "
        f"WHEN isnan({x}) THEN {g.fail(tf.string('Operand cannot be NaN'))} "
        f'WHEN list_contains(list_transform({bins}, lambda "_b": "_b" IS NULL), true) THEN '
        f"{g.fail(tf.string('NULL bins are not supported in lakegate'), 'NOT_SUPPORTED')} "
        f"WHEN {unsorted} THEN {g.fail(tf.string('Bin values are not sorted in ascending order'))} "
        f"WHEN {infinite} THEN {g.fail(tf.string('Bin value must be finite'))} "
        f'ELSE CAST(len(list_filter({bins}, lambda "_b": "_b" <= {x})) AS BIGINT) END'
    )


def _width_bucket(call: Call) -> TType:
    if len(call.args) == 2:
        x, bins = call.types
        if x is None or not (x.is_numeric or x.is_unknown) or bins is None or bins.base not in ("array", "unknown"):
            call.mismatch()
        if bins.base == "array" and not (bins.element.is_numeric or bins.element.is_unknown):
            call.mismatch()
        return tt.BIGINT
    need(call, "number", "number", "number", "integral")
    return tt.BIGINT


def _render_width_bucket_any(g, node, args) -> str:
    return (_render_width_bucket_bins if len(args) == 2 else _render_width_bucket)(g, node, args)


_DIGITS = "0123456789abcdefghijklmnopqrstuvwxyz"


def _radix_check(radix: str) -> tuple[str, str]:
    return (f"{radix} NOT BETWEEN 2 AND 36", "Radix must be between 2 and 36")


def _render_from_base(g, node, args) -> str:
    """Long.parseLong(value, radix): an optional sign, then at least one digit of the radix (either
    case); the value must fit a bigint. Digits are summed in HUGEINT, saturating past 2^64."""
    text, radix = sqls(g, args)
    digits = f"lower(regexp_replace({text}, '^[+-]', ''))"
    value = (
        f'list_reduce(string_split({digits}, \'\'), lambda "_v", "_c": CASE WHEN "_v" > {2**64} THEN "_v" '
        f'ELSE "_v" * {radix} + strpos(\'{_DIGITS}\', "_c") - 1 END, CAST(0 AS HUGEINT))'
    )
    signed = f"CASE WHEN starts_with({text}, '-') THEN -{value} ELSE {value} END"
    valid_digit = f"strpos(left('{_DIGITS}', CAST({radix} AS INTEGER)), \"_c\") > 0"
    valid = (
        f"regexp_full_match({text}, '[+-]?[0-9A-Za-z]+') AND "
        f"len(list_filter(string_split({digits}, ''), lambda \"_c\": NOT ({valid_digit}))) = 0"
    )
    bad = g.fail(f"'Not a valid base-' || {radix} || ' number: ' || {text}")
    check, message = _radix_check(radix)
    return (
        f"CASE WHEN {text} IS NULL OR {radix} IS NULL THEN NULL WHEN {check} THEN {g.fail(tf.string(message))} "
        f"WHEN NOT ({valid}) THEN {bad} "
        f"WHEN ({signed}) NOT BETWEEN {-(2**63)} AND {2**63 - 1} THEN {bad} "
        f"ELSE CAST({signed} AS BIGINT) END"
    )


def _render_to_base(g, node, args) -> str:
    """Long.toString(value, radix): lower-case digits, '-' for negative values."""
    value, radix = (f"CAST({g.sql(a)} AS BIGINT)" for a in args)
    check, message = _radix_check(radix)
    minimum = -(2**63)
    radix_sql = radix
    radix = f"CAST(least(greatest({radix}, 2), 36) AS INTEGER)"  # DuckDB's to_base takes an INTEGER radix
    return (
        f"CASE WHEN {value} IS NULL OR {radix_sql} IS NULL THEN NULL WHEN {check} THEN {g.fail(tf.string(message))} "
        f"WHEN {value} = {minimum} THEN '-' || lower(to_base(CAST(-({value} // {radix}) AS BIGINT), {radix}) || "
        f"to_base(CAST(-({value} % {radix}) AS BIGINT), {radix})) "
        f"WHEN {value} < 0 THEN '-' || lower(to_base(CAST(-{value} AS BIGINT), {radix})) "
        f"ELSE lower(to_base({value}, {radix})) END"
    )


def _render_wilson(bound: int) -> Render:
    """WilsonInterval.wilsonInterval, the same double operations in the same order."""

    def render(g, node, args) -> str:
        successes, trials = (f"CAST({g.sql(a)} AS BIGINT)" for a in args[:2])
        z = f"CAST({g.sql(args[2])} AS DOUBLE)"
        p, n = f"(CAST({successes} AS DOUBLE) / CAST({trials} AS DOUBLE))", f"CAST({trials} AS DOUBLE)"
        value = (
            f"({p} + ({z} * {z}) / (2 * {n}) + {bound} * {z} * sqrt(({p} * (1 - {p})) / {n} + "
            f"({z} * {z}) / (4 * {n} * {n}))) / (1 + ({z} * {z}) / {n})"
        )
        checks = [
            (f"{successes} < 0", "number of successes must not be negative"),
            (f"{trials} <= 0", "number of trials must be positive"),
            (f"{successes} > {trials}", "number of successes must not be larger than number of trials"),
            (f"{z} < 0", "z-score must not be negative"),
        ]
        whens = " ".join(f"WHEN {c} THEN {g.fail(tf.string(m))}" for c, m in checks)
        return f"CASE WHEN {successes} IS NULL OR {trials} IS NULL OR {z} IS NULL THEN NULL {whens} ELSE {value} END"

    return render


def _vectors(call: Call) -> TType:
    if len(call.args) != 2:
        call.mismatch()
    if call.name.startswith("cosine_") and all(t is not None and t.base == "map" for t in call.types):
        call.fail(f"unsupported in lakegate: {call.name} of maps (sparse vectors) is not translated", "NOT_SUPPORTED")
    for t in call.types:
        if t is None or not (t.is_unknown or (t.base == "array" and (t.element.is_numeric or t.element.is_unknown))):
            call.mismatch()
    return tt.DOUBLE


def _fold(pairs: str, step: str) -> str:
    """A left-to-right double sum over the element pairs ("_p"[1], "_p"[2]), as Java's loop adds."""
    return (
        f'list_reduce(list_transform({pairs}, lambda "_p": {step}), lambda "_s", "_x": "_s" + "_x", CAST(0 AS DOUBLE))'
    )


def _render_vector(kind: str) -> Render:
    """ArrayVectorFunctions: the arrays must have the same length; NULL elements are refused."""

    def render(g, node, args) -> str:
        a, b = (f"CAST({g.sql(x)} AS DOUBLE[])" for x in args)
        pairs = f'list_transform(range(1, len({a}) + 1), lambda "_i": [{a}["_i"], {b}["_i"]])'
        dot = _fold(pairs, '"_p"[1] * "_p"[2]')
        if kind == "dot":
            value = dot
        elif kind == "euclidean":
            squared = '("_p"[1] - "_p"[2]) * ("_p"[1] - "_p"[2])'
            value = f"sqrt({_fold(pairs, squared)})"
        else:
            first, second = _fold(pairs, '"_p"[1] * "_p"[1]'), _fold(pairs, '"_p"[2] * "_p"[2]')
            similarity = (
                f"CASE WHEN {first} = 0 OR {second} = 0 THEN {g.fail(tf.string('Vector magnitude cannot be zero'))} "
                f"ELSE {dot} / sqrt({first} * {second}) END"
            )
            value = similarity if kind == "cosine" else f"1.0 - ({similarity})"
        has_null = f'list_contains(list_transform(list_concat({a}, {b}), lambda "_x": "_x" IS NULL), true)'
        return (
            f"CASE WHEN {a} IS NULL OR {b} IS NULL THEN NULL "
            f"WHEN len({a}) <> len({b}) THEN {g.fail(tf.string('The arguments must have the same length'))} "
            f"WHEN {has_null} THEN {g.fail(tf.string('NULL elements are not supported in lakegate'), 'NOT_SUPPORTED')} "
            f"ELSE {value} END"
        )

    return render


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register("abs", "math", "abs(x) -> same", _abs, call_as("abs", cast_result=True))
    register(
        "ceiling",
        "math",
        "ceiling(x) -> same (decimal(p-s+min(s,1),0) for decimals)",
        _ceil_floor,
        _render_ceil_floor("ceil"),
        aliases=("ceil",),
    )
    register(
        "floor",
        "math",
        "floor(x) -> same (decimal(p-s+min(s,1),0) for decimals)",
        _ceil_floor,
        _render_ceil_floor("floor"),
    )
    register(
        "round",
        "math",
        "round(x[, d]) -> same (decimal(p+1,s) with d for decimal(p,s))",
        _round,
        _render_round,
        notes="HALF_UP; the result keeps Trino's type, e.g. round(decimal(6,2), 1) is decimal(7,2). A double or real x "
        "is scaled by 10^d in double arithmetic and rounded half up, as Trino 476 does (round(3.175, 2) is 3.18, since "
        "3.175 x 100 is exactly 317.5; DuckDB's own round gives 3.17), with Trino's answers at the extremes.",
    )
    register(
        "truncate",
        "math",
        "truncate(x) -> same (decimal(p-s,0) for decimals, decimal(p,0) for integers); "
        "truncate(decimal(p,s), integer n) -> decimal(p,s)",
        _truncate,
        _render_truncate,
    )
    register("sign", "math", "sign(x) -> same", _sign, _render_sign, notes="sign(NaN) is NaN (Java's Math.signum).")
    register("mod", "math", "mod(n, m) -> same as n % m", _mod, _render_mod)
    register("sqrt", "math", "sqrt(x) -> double", as_double("number"), double_fn("sqrt"))
    register(
        "cbrt",
        "math",
        "cbrt(x) -> double",
        as_double("number"),
        lambda g, node, args: (
            lambda x: (
                f"CASE WHEN round(cbrt({x})) * round(cbrt({x})) * round(cbrt({x})) = {x} "
                f"THEN round(cbrt({x})) ELSE cbrt({x}) END"
            )
        )(f"CAST({g.sql(args[0])} AS DOUBLE)"),
        notes="Exact for perfect cubes, like Java's Math.cbrt.",
    )
    register("exp", "math", "exp(x) -> double", as_double("number"), double_fn("exp"))
    register("ln", "math", "ln(x) -> double", as_double("number"), double_fn("ln"))
    register("log2", "math", "log2(x) -> double", as_double("number"), double_fn("log2"))
    register("log10", "math", "log10(x) -> double", as_double("number"), double_fn("log10"))
    register(
        "log",
        "math",
        "log(b, x) -> double",
        as_double("number", "number"),
        lambda g, node, args: f"(ln(CAST({g.sql(args[1])} AS DOUBLE)) / ln(CAST({g.sql(args[0])} AS DOUBLE)))",
    )
    register(
        "power",
        "math",
        "power(x, p) -> double",
        as_double("number", "number"),
        _render_power,
        aliases=("pow",),
    )
    for _name in ("sin", "cos", "tan", "atan", "sinh", "cosh", "tanh", "degrees", "radians"):
        register(_name, "math", f"{_name}(x) -> double", as_double("number"), double_fn(_name))
    for _name in ("asin", "acos"):
        register(_name, "math", f"{_name}(x) -> double", as_double("number"), double_fn(_name))
    register(
        "atan2",
        "math",
        "atan2(y, x) -> double",
        as_double("number", "number"),
        lambda g, node, args: f"atan2(CAST({g.sql(args[0])} AS DOUBLE), CAST({g.sql(args[1])} AS DOUBLE))",
    )
    register("pi", "math", "pi() -> double", fixed(tt.DOUBLE), lambda g, node, args: "pi()")
    register("e", "math", "e() -> double", fixed(tt.DOUBLE), lambda g, node, args: "exp(1)")
    register(
        "infinity", "math", "infinity() -> double", fixed(tt.DOUBLE), lambda g, node, args: "CAST('Infinity' AS DOUBLE)"
    )
    register("nan", "math", "nan() -> double", fixed(tt.DOUBLE), lambda g, node, args: "CAST('NaN' AS DOUBLE)")
    register(
        "is_nan",
        "math",
        "is_nan(x) -> boolean",
        fixed(tt.BOOLEAN, "approx"),
        lambda g, node, args: f"isnan(CAST({g.sql(args[0])} AS DOUBLE))",
    )
    register(
        "is_finite",
        "math",
        "is_finite(x) -> boolean",
        fixed(tt.BOOLEAN, "approx"),
        lambda g, node, args: f"isfinite(CAST({g.sql(args[0])} AS DOUBLE))",
    )
    register(
        "is_infinite",
        "math",
        "is_infinite(x) -> boolean",
        fixed(tt.BOOLEAN, "approx"),
        lambda g, node, args: f"isinf(CAST({g.sql(args[0])} AS DOUBLE))",
    )
    register(
        "random",
        "math",
        "random() -> double; random(n) / random(m, n) -> same as n",
        _random,
        _render_random,
        aliases=("rand",),
    )
    register(
        "width_bucket",
        "math",
        "width_bucket(x, bound1, bound2, n) -> bigint; width_bucket(x, bins) -> bigint",
        _width_bucket,
        _render_width_bucket_any,
        notes="With bins, any unsorted or non-finite bin fails (Trino fails only on those its binary search meets).",
    )
    register(
        "from_base",
        "math",
        "from_base(string, radix) -> bigint",
        fixed(tt.BIGINT, "string", "integral"),
        _render_from_base,
    )
    register(
        "to_base",
        "math",
        "to_base(x, radix) -> varchar(64)",
        fixed(tt.varchar(64), "integral", "integral"),
        _render_to_base,
    )
    register(
        "wilson_interval_lower",
        "math",
        "wilson_interval_lower(successes, trials, z) -> double",
        fixed(tt.DOUBLE, "integral", "integral", "number"),
        _render_wilson(-1),
    )
    register(
        "wilson_interval_upper",
        "math",
        "wilson_interval_upper(successes, trials, z) -> double",
        fixed(tt.DOUBLE, "integral", "integral", "number"),
        _render_wilson(1),
    )
    for _name, _kind in (
        ("cosine_similarity", "cosine"),
        ("cosine_distance", "distance"),
        ("dot_product", "dot"),
        ("euclidean_distance", "euclidean"),
    ):
        register(
            _name,
            "math",
            f"{_name}(array(double), array(double)) -> double",
            _vectors,
            _render_vector(_kind),
            notes="Arrays only (the map forms are not translated); NULL elements fail.",
        )
