"""Trino type inference of literals, names, logical and comparison operators, IN, BETWEEN,
LIKE, arithmetic, `||` and CASE / IF.
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import chars
from lakegate.dialect import trino_types as tt
from lakegate.dialect.analysis_checks import char_concat, check_char_subquery
from lakegate.dialect.analyzer import Analyzer
from lakegate.dialect.guard import COMPARISON_OPERATORS
from lakegate.dialect.name_resolution import nested_order
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import ARITHMETIC, COMPARISONS, handles, set, ttype


@handles(exp.Column)
def _column(a: Analyzer, node, scope, env):
    return a.column(node, scope, env)


@handles(exp.Identifier)
def _identifier(a: Analyzer, node, scope, env):
    name = node.name.lower()
    if name in env:
        node.meta["lambda"] = True
        return env[name]
    column = exp.Column(this=node.copy())
    node.replace(column)
    return a.expr(column, scope, env)


@handles(exp.Dot)
def _dot(a: Analyzer, node, scope, env):
    t = a.expr(node.this, scope, env)
    if "row_position" in node.meta:  # a field of row_expression.* (dialect/row_star.py), by position
        node.meta["field"] = node.meta["row_position"]
        return t.args[node.meta["row_position"] - 1][1]
    if not isinstance(node.expression, exp.Identifier):
        a.unsupported(
            "row_expression.* (every field of a row)" if isinstance(node.expression, exp.Star) else "a field reference",
            node,
        )
    result, real = a.field(t, node.expression.name, node.expression.quoted, node)
    node.meta["field"] = real
    return result


@handles(exp.Literal)
def _literal(a: Analyzer, node: exp.Literal, scope, env):
    text = node.name
    if node.is_string:
        return tt.varchar(len(text))
    try:
        if "e" in text.lower():
            return tt.DOUBLE
        if "." in text:
            return tt.decimal_literal_type(text)
        return tt.integer_literal_type(text)
    except ValueError as error:
        a.fail(str(error), node, "INVALID_LITERAL")


@handles(exp.HexString)
def _binary_literal(a: Analyzer, node: exp.HexString, scope, env):
    if len(node.name) % 2:
        a.fail("Binary literal must contain an even number of digits", node, "SYNTAX_ERROR")
    return tt.VARBINARY


@handles(exp.UnicodeString)
def _unicode_literal(a: Analyzer, node: exp.UnicodeString, scope, env):
    """U&'...' [UESCAPE 'c']: the text with its escapes decoded (AstBuilder.decodeUnicodeLiteral)."""
    escape = node.args.get("escape")
    mark = escape.name if isinstance(escape, exp.Literal) else "\\"
    if len(mark) != 1 or mark in "+'\"" or mark.isspace() or mark in "0123456789abcdefABCDEF":
        a.fail(f"Invalid Unicode escape character: {mark}", node, "SYNTAX_ERROR")
    try:
        node.meta["text"] = decode_unicode_escapes(node.name, mark)
    except ValueError as error:
        a.fail(str(error), node, "SYNTAX_ERROR")
    return tt.varchar(len(node.meta["text"]))


def decode_unicode_escapes(raw: str, mark: str) -> str:
    """Trino's Unicode string literal: `mark` + 4 hex digits or `mark` + '+' + 6 hex digits is a code
    point (surrogates refused), a doubled `mark` is the mark itself."""
    out, i = [], 0
    while i < len(raw):
        if raw[i] != mark:
            out.append(raw[i])
            i += 1
            continue
        if raw[i + 1 : i + 2] == mark:
            out.append(mark)
            i += 2
            continue
        size, start = (6, i + 2) if raw[i + 1 : i + 2] == "+" else (4, i + 1)
        digits = raw[start : start + size]
        if len(digits) != size or not all(c in "0123456789abcdefABCDEF" for c in digits):
            raise ValueError(f"Incomplete escape sequence: {digits}")
        code = int(digits, 16)
        if code > 0x10FFFF or 0xD800 <= code <= 0xDFFF:
            raise ValueError(f"Invalid escaped character: {digits}")
        out.append(chr(code))
        i = start + size
    return "".join(out)


@handles(exp.Null)
def _null(a, node, scope, env):
    return tt.UNKNOWN


@handles(exp.Boolean)
def _boolean(a, node, scope, env):
    return tt.BOOLEAN


@handles(exp.Paren)
def _paren(a: Analyzer, node, scope, env):
    return a.expr(node.this, scope, env)


@handles(exp.Neg)
def _neg(a: Analyzer, node, scope, env):
    t = a.expr(node.this, scope, env)
    if not (t.is_numeric or t.base in ("interval_ds", "interval_ym", "unknown")):
        a.fail(f"Cannot negate {t}", node, "TYPE_MISMATCH")
    return t


@handles(exp.Not)
def _not(a: Analyzer, node, scope, env):
    t = a.expr(node.this, scope, env)
    if t.base not in ("boolean", "unknown"):
        a.fail(f"Value of logical NOT expression must evaluate to a boolean (actual: {t})", node, "TYPE_MISMATCH")
    return tt.BOOLEAN


@handles(exp.And, exp.Or)
def _logical(a: Analyzer, node, scope, env):
    for side in (node.this, node.expression):
        t = a.expr(side, scope, env)
        if t.base not in ("boolean", "unknown"):
            a.fail(f"{node.key.upper()} operand must evaluate to a boolean (actual: {t})", side, "TYPE_MISMATCH")
    return tt.BOOLEAN


def _comparable(a: Analyzer, node, left: TType, right: TType, op: str) -> TType:
    common = tt.common_super_type(left, right)
    if common is None:
        a.fail(f"Cannot apply operator: {left} {op} {right}", node, "TYPE_MISMATCH")
    return common


def _quantified(node: exp.Expression) -> exp.Expression:
    """`x op ALL (VALUES ...)` and `SOME (...)` as sqlglot parses them (a call named ALL / SOME) made
    the ALL / ANY node it gives `ANY (VALUES ...)` (SOME is ANY in Trino's grammar, SqlBase.g4)."""
    right = node.expression
    if (
        isinstance(right, exp.Anonymous)
        and right.name.upper() in ("ALL", "SOME", "ANY")
        and len(right.expressions) == 1
        and isinstance(right.expressions[0], (exp.Query, exp.Values))
    ):
        kind = exp.All if right.name.upper() == "ALL" else exp.Any
        right = right.replace(kind(this=exp.Subquery(this=right.expressions[0])))
    return right


@handles(*COMPARISONS)
def _comparison(a: Analyzer, node, scope, env):
    if isinstance(_quantified(node), (exp.Any, exp.All)):
        left = a.expr(node.this, scope, env)
        sub = node.expression.this
        query = sub.this if isinstance(sub, exp.Subquery) else sub
        if not isinstance(query, (exp.Query, exp.Values)):
            a.unsupported(f"{node.expression.key.upper()} with a non-subquery", node.expression)
        cols = a.query(query, scope)
        if len(cols) != 1:
            a.fail("Multiple columns returned by subquery are not yet supported", sub, "NOT_SUPPORTED")
        common = _comparable(a, node, left, cols[0][2], COMPARISON_OPERATORS[type(node)])
        check_char_subquery(a, node, left, cols[0][2], common)
        if common.base == "timestamp_tz" and {left.base, cols[0][2].base} != {"timestamp_tz"}:
            a.unsupported(f"{node.expression.key.upper()} comparing {left} with {cols[0][2]}", node.expression)
        node.meta["compare"] = common
        return tt.BOOLEAN
    for side in (node.this, node.expression):
        if isinstance(side, exp.Subquery):
            side.meta["row_ok"] = True  # `(a, b) = (SELECT x, y ...)`: a row there (_scalar_subquery)
    left, right = a.expr(node.this, scope, env), a.expr(node.expression, scope, env)
    op = COMPARISON_OPERATORS[type(node)]
    common = _comparable(a, node, left, right, op)
    json_order = common.base == "json" and type(node) not in (exp.EQ, exp.NEQ, exp.NullSafeEQ, exp.NullSafeNEQ)
    if json_order or (common.base == "map" and type(node) not in (exp.EQ, exp.NEQ)):
        a.fail(f"Cannot apply operator: {left} {op} {right}", node, "TYPE_MISMATCH")
    if type(node) not in (exp.EQ, exp.NEQ) and nested_order(common):
        a.unsupported(f"ordering comparison ({op}) of {common}: its elements hold arrays or rows", node)
    node.meta["compare"] = common
    _in_session_zone(a, [node.this, node.expression], common)
    chars.coerce([node.this, node.expression], common, type(node) in (exp.EQ, exp.NEQ, exp.NullSafeEQ, exp.NullSafeNEQ))
    return tt.BOOLEAN


def _in_session_zone(a: Analyzer, sides: list[exp.Expression], common: TType) -> None:
    """Dates and timestamps compared with a timestamp with time zone are read in the session zone
    (Trino's implicit coercion, io.trino.type.DateTimeOperators / TimestampToTimestampWithTimeZoneCast):
    each becomes an explicit cast, which every comparison writer then converts alike."""
    if common.base != "timestamp_tz":
        return
    for side in sides:
        t = ttype(side)
        if t.base in ("date", "timestamp"):
            cast = exp.Cast(to=exp.DataType.build("timestamptz"))
            side.replace(cast)
            cast.set("this", side)
            cast.meta.update({"from": t, "t": tt.timestamp(common.args[0], True, a.time_zone)})


@handles(exp.Is)
def _is(a: Analyzer, node, scope, env):
    a.expr(node.this, scope, env)
    if not isinstance(node.expression, exp.Null):
        a.unsupported("IS TRUE / IS FALSE", node)
    return tt.BOOLEAN


@handles(exp.In)
def _in(a: Analyzer, node, scope, env):
    left = a.expr(node.this, scope, env)
    if node.args.get("query") is not None:
        query = node.args["query"]
        cols = a.query(query.this if isinstance(query, exp.Subquery) else query, scope)
        if len(cols) != 1:
            return _row_in(a, node, left, [c[2] for c in cols])
        common = _comparable(a, node, left, cols[0][2], "IN")
        check_char_subquery(a, node, left, cols[0][2], common)
    else:
        if node.args.get("unnest") or node.args.get("field"):
            a.unsupported("IN UNNEST", node)
        common = left
        for item in node.expressions:
            common = _comparable(a, item, common, a.expr(item, scope, env), "IN")
        _in_session_zone(a, [node.this, *node.expressions], common)
        chars.coerce([node.this, *node.expressions], common, equality=True)
    node.meta["compare"] = common
    return tt.BOOLEAN


def _row_in(a: Analyzer, node: exp.In, left: TType, types: list[TType]) -> TType:
    """`(a, b) IN (SELECT x, y ...)`: the subquery is a row of its columns, and the value must coerce
    to a common row type with it (Trino's ExpressionAnalyzer.analyzePredicateWithSubquery); see
    transforms.row_in_subquery for the NULL rule."""
    value, row = left if left.base == "row" else tt.row([(None, left)]), tt.row([(None, t) for t in types])
    common = tt.common_super_type(value, row) if len(value.args) == len(types) else None
    if common is None:
        message = f"Value expression and result of subquery must be of the same type: {value} vs {row}"
        a.fail(message, node, "TYPE_MISMATCH")
    if node.this.find(exp.Window, exp.AggFunc) or a._aggregate_inside(node.this):
        a.unsupported("aggregate or window function in a row compared with IN (SELECT ...)", node.this)
    fields = [f for _, f in common.args]
    if any(f.base in ("array", "map", "row", "json", "timestamp_tz") for f in fields):
        a.unsupported(f"IN (SELECT ...) comparing {left} with {row}", node)
    node.meta["row_in"] = fields
    return tt.BOOLEAN


@handles(exp.Between)
def _between(a: Analyzer, node, scope, env):
    value = a.expr(node.this, scope, env)
    low, high = a.expr(node.args["low"], scope, env), a.expr(node.args["high"], scope, env)
    common = _comparable(a, node, _comparable(a, node, value, low, "BETWEEN"), high, "BETWEEN")
    if nested_order(common):
        a.unsupported(f"BETWEEN of {common}: its elements hold arrays or rows", node)
    node.meta["compare"] = common
    _in_session_zone(a, [node.this, node.args["low"], node.args["high"]], common)
    chars.coerce([node.this, node.args["low"], node.args["high"]], common)
    return tt.BOOLEAN


@handles(exp.Like)
def _like(a: Analyzer, node, scope, env):
    for side in (node.this, node.expression):
        t = a.expr(side, scope, env)
        if t.base not in ("varchar", "char", "unknown"):
            a.fail(f"Left side of LIKE expression must evaluate to a varchar (actual: {t})", side, "TYPE_MISMATCH")
    return tt.BOOLEAN


@handles(exp.Escape)
def _escape(a: Analyzer, node, scope, env):
    if not isinstance(node.this, exp.Like):
        a.unsupported("ESCAPE", node)
    escape = node.expression
    if not (isinstance(escape, exp.Literal) and escape.is_string and len(escape.name) == 1):
        a.fail("Escape string must be a single character", escape, "INVALID_FUNCTION_ARGUMENT")
    a.expr(node.this, scope, env)
    return tt.BOOLEAN


@handles(*ARITHMETIC)
def _arithmetic(a: Analyzer, node, scope, env):
    op = ARITHMETIC[type(node)]
    left, right = a.expr(node.this, scope, env), a.expr(node.expression, scope, env)
    result = tt.arithmetic_type(op, left, right)
    if result is None:
        result = _temporal_arithmetic(op, left, right)
    if result is None and op == "-" and left.base == right.base == "time":
        result = tt.INTERVAL_DS  # rounded HALF_UP to milliseconds (TimeOperators.subtract)
    if result is None:
        a.fail(f"Cannot apply operator: {left} {op} {right}", node, "TYPE_MISMATCH")
    if op == "-" and left.base == right.base == "timestamp_tz" and max(left.args[0], right.args[0]) > 3:
        a.unsupported(f"{left} - {right} (Trino rounds the difference to milliseconds)", node)
    if op == "%" and not remainder_fits(left, right, result):
        a.unsupported(f"% of {left} by {right} (the operands at a common scale exceed 38 digits)", node)
    return result


def remainder_fits(left: TType, right: TType, result: TType) -> bool:
    """Whether DuckDB computes decimal `left % right` exactly: both operands at the common scale fit in
    38 digits (Trino rescales in 256 bits, io.trino.type.DecimalOperators)."""
    if not result.is_decimal or not (left.is_decimal or right.is_decimal):
        return True
    a, b = tt.as_decimal(left), tt.as_decimal(right)
    scale = max(a.args[1], b.args[1])
    return max(a.args[0] - a.args[1], b.args[0] - b.args[1]) + scale <= 38


def _at_least_millis(t: TType) -> TType:
    """timestamp(p) ± a day-to-second interval is timestamp(max(p, 3)): the interval carries milliseconds
    (io.trino.operator.scalar.timestamp.TimestampOperators.TimestampPlusIntervalDayToSecond)."""
    if t.base in ("timestamp", "timestamp_tz") and t.args[0] < 3:
        return tt.with_precision(t, 3)
    return t


def _temporal_arithmetic(op: str, left: TType, right: TType) -> TType | None:
    intervals = ("interval_ds", "interval_ym")
    if op in "+-" and left.base in ("date", "timestamp", "timestamp_tz") and right.base in intervals:
        return _at_least_millis(left) if right.base == "interval_ds" else left
    if op == "+" and right.base in ("date", "timestamp", "timestamp_tz") and left.base in intervals:
        return _at_least_millis(right) if left.base == "interval_ds" else right
    if op in "+-" and left.base == "time" and right.base == "interval_ds" or op == "+" and left.base == "interval_ds":
        time = left if left.base == "time" else right  # wraps around midnight (TimeOperators)
        if time.base == "time":
            return TType("time", (max(3, time.args[0]),))
    if op in "+-" and left.base == "time_tz" and right.base == "interval_ds":
        return TType("time_tz", (max(3, left.args[0]),))  # TimeWithTimeZoneOperators: wraps around midnight
    if op == "+" and left.base == "interval_ds" and right.base == "time_tz":
        return TType("time_tz", (max(3, right.args[0]),))
    if op == "-" and left.base == right.base == "time_tz":
        return tt.INTERVAL_DS  # of the times at +00:00, rounded HALF_UP to milliseconds
    if op in "+-" and left.base == right.base and left.base in intervals:
        return left
    if op == "*" and (left.base in intervals and right.is_integral or left.is_integral and right.base in intervals):
        return left if left.base in intervals else right  # exact in DuckDB (IntervalDayTimeOperators.multiply)
    if op == "-" and left.base == right.base and left.base in ("timestamp", "timestamp_tz"):
        return tt.INTERVAL_DS
    return None


@handles(exp.DPipe)
def _dpipe(a: Analyzer, node, scope, env):
    left, right = a.expr(node.this, scope, env), a.expr(node.expression, scope, env)
    if left.is_unknown or right.is_unknown:
        t = tt.concat_with_null([left, right])
        if t is None:
            a.fail(tt.AMBIGUOUS, node, "AMBIGUOUS_FUNCTION_CALL")
        node.meta["array"] = True
        return t
    if left.base == "array" or right.base == "array":
        if left.base == right.base == "array":
            element = tt.common_super_type(left.element, right.element)
        elif left.base == "array":
            element = tt.common_super_type(left.element, right)
        else:
            element = tt.common_super_type(left, right.element)
        if element is None:
            a.fail(f"Cannot apply operator: {left} || {right}", node, "TYPE_MISMATCH")
        node.meta["array"] = True
        return tt.array(element)
    if "varbinary" in (left.base, right.base) and {left.base, right.base} <= {"varbinary", "unknown"}:
        return tt.VARBINARY
    if "char" in (left.base, right.base) and {left.base, right.base} <= {"char", "varchar", "unknown"}:
        return char_concat(a, node, [node.this, node.expression])
    for t in (left, right):
        if t.base not in ("varchar", "char", "unknown"):
            a.fail(f"Cannot apply operator: {left} || {right}", node, "TYPE_MISMATCH")
    return tt.VARCHAR  # Trino's variadic concat returns unbounded varchar


@handles(exp.Case)
def _case(a: Analyzer, node, scope, env):
    operand = node.args.get("this")
    operand_type = a.expr(operand, scope, env) if operand is not None else None
    results = []
    for branch in node.args.get("ifs") or []:
        cond = a.expr(branch.this, scope, env)
        if operand_type is not None:
            _comparable(a, branch.this, operand_type, cond, "=")
        elif cond.base not in ("boolean", "unknown"):
            a.fail(f"CASE WHEN clause must evaluate to a boolean (actual: {cond})", branch.this, "TYPE_MISMATCH")
        results.append(set(branch, a.expr(branch.args["true"], scope, env)))
    if operand is not None:  # the operand and the WHEN values are compared at their common type
        compared = [node.this, *(branch.this for branch in node.args.get("ifs") or [])]
        common = tt.common_super_type_of([ttype(n) for n in compared])
        if common is not None:
            chars.coerce(compared, common, equality=True)
    default = node.args.get("default")
    if default is not None:
        results.append(a.expr(default, scope, env))
    common = tt.common_super_type_of(results)
    if common is None:
        a.fail(
            f"All CASE results must be the same type or coercible to a common type: {', '.join(map(str, results))}",
            node,
            "TYPE_MISMATCH",
        )
    return common


@handles(exp.If)
def _if(a: Analyzer, node, scope, env):
    cond = a.expr(node.this, scope, env)
    if cond.base not in ("boolean", "unknown"):
        a.fail(f"IF condition must evaluate to a boolean (actual: {cond})", node.this, "TYPE_MISMATCH")
    results = [a.expr(node.args["true"], scope, env)]
    if node.args.get("false") is not None:
        results.append(a.expr(node.args["false"], scope, env))
    common = tt.common_super_type_of(results)
    if common is None:
        a.fail(
            f"Result types for IF must be the same or coercible to a common type: {', '.join(map(str, results))}",
            node,
            "TYPE_MISMATCH",
        )
    return common
