"""Trino type inference of subscripts, ARRAY / ROW constructors, intervals, the current date and
time, EXTRACT, subqueries, function calls, windows and frames, grouping(), listagg, lambdas, AT TIME
ZONE and the special forms (SUBSTRING, TRIM, POSITION).
"""

from __future__ import annotations

import re

from sqlglot import exp

from lakegate.dialect import intervals, zoned_times
from lakegate.dialect import trino_types as tt
from lakegate.dialect.analysis_checks import check_range_offset, range_comparison_type
from lakegate.dialect.analyzer import Analyzer
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import floor_micros, handles, set, ttype


@handles(exp.Bracket)
def _bracket(a: Analyzer, node, scope, env):
    container = a.expr(node.this, scope, env)
    if len(node.expressions) != 1:
        a.unsupported("slice subscript", node)
    index = a.expr(node.expressions[0], scope, env)
    if container.base == "array":
        if not (index.is_integral or index.is_unknown):
            a.fail(f"Cannot use {index} for subscript of {container}", node, "TYPE_MISMATCH")
        return container.element
    if container.base == "map":
        if container.args[0].base in ("array", "map", "row"):
            a.unsupported(f"subscript of a map with {container.args[0].base} keys", node)
        if tt.common_super_type(container.args[0], index) is None:
            a.fail(f"Cannot use {index} for subscript of {container}", node, "TYPE_MISMATCH")
        return container.args[1]
    if container.base == "row":
        return _row_field(a, container, node)
    a.fail(f"Cannot use subscript on {container}", node, "TYPE_MISMATCH")


def _row_field(a: Analyzer, container, node: exp.Bracket):
    """row[i]: the i-th field (1-based), i an integer literal (Trino: a constant index)."""
    index = node.expressions[0]
    if not (isinstance(index, exp.Literal) and index.is_int):
        a.unsupported("row subscript with an index that is not an integer literal", node)
    position = int(index.name)
    if position == 0:
        a.fail("Invalid subscript index: 0. ROW indices start at 1", node, "INVALID_FUNCTION_ARGUMENT")
    if position > len(container.args):
        message = f"Subscript index out of bounds: {position}, max value is {len(container.args)}"
        a.fail(message, node, "INVALID_FUNCTION_ARGUMENT")
    return container.args[position - 1][1]


@handles(exp.Array)
def _array(a: Analyzer, node, scope, env):
    types = [a.expr(e, scope, env) for e in node.expressions]
    element = tt.common_super_type_of(types)
    if element is None:
        a.fail(f"All ARRAY elements must be the same type: {', '.join(map(str, types))}", node, "TYPE_MISMATCH")
    return tt.array(element)


@handles(exp.Tuple)
def _tuple(a: Analyzer, node, scope, env):
    return tt.row([(None, a.expr(e, scope, env)) for e in node.expressions])


@handles(exp.Interval)
def _interval(a: Analyzer, node, scope, env):
    unit = node.args.get("unit")
    value = node.this
    if not (isinstance(value, exp.Literal) and value.is_string) or unit is None:
        a.unsupported("interval syntax (use INTERVAL '3' DAY)", node)
    unit_name = unit.name.upper()
    if isinstance(unit, exp.IntervalSpan):
        last = unit.expression.name.upper()
        text = value.name  # Trino refuses white space around the fields
        if intervals.span_value(text, unit_name, last) is None:
            a.unsupported(f"interval literal '{text}' {unit_name} TO {last}", node)
        return tt.INTERVAL_YM if unit_name == "YEAR" else tt.INTERVAL_DS
    if unit_name not in ("YEAR", "MONTH", "DAY", "HOUR", "MINUTE", "SECOND"):
        a.unsupported(f"interval unit {unit_name}", node)
    text = value.name.strip()
    if not _is_number(text.lstrip("+-")) or ("." in text and unit_name != "SECOND"):
        a.unsupported(f"interval literal '{text}' {unit_name}", node)
    return tt.INTERVAL_YM if unit_name in ("YEAR", "MONTH") else tt.INTERVAL_DS


def _is_number(text: str) -> bool:
    head, _, tail = text.partition(".")
    return head.isdigit() and (tail == "" or tail.isdigit())


@handles(exp.CurrentTimestamp)
def _current_timestamp(a, node, scope, env):
    if node.this is not None:
        a.unsupported("current_timestamp(p)", node)
    return tt.timestamp(3, True, a.time_zone)


@handles(exp.CurrentDate)
def _current_date(a, node, scope, env):
    return tt.DATE


@handles(exp.Localtimestamp)
def _localtimestamp(a, node, scope, env):
    return tt.timestamp(3)


@handles(exp.Extract)
def _extract(a: Analyzer, node, scope, env):
    unit = node.this.name.upper()
    t = a.expr(node.expression, scope, env)
    allowed = {
        "YEAR",
        "QUARTER",
        "MONTH",
        "WEEK",
        "DAY",
        "DAY_OF_MONTH",
        "DAY_OF_WEEK",
        "DOW",
        "DAY_OF_YEAR",
        "DOY",
        "YEAR_OF_WEEK",
        "YOW",
        "HOUR",
        "MINUTE",
        "SECOND",
    }
    if t.base == "time":  # io.trino.operator.scalar.time: ExtractHour, ExtractMinute, ExtractSecond
        if unit not in ("HOUR", "MINUTE", "SECOND"):
            a.fail(f"Cannot extract {unit} from {t}", node, "TYPE_MISMATCH")
        return tt.BIGINT
    if t.base == "time_tz":  # io.trino.operator.scalar.timetz: ExtractHour, ..., TimeZoneHour
        if unit not in ("HOUR", "MINUTE", "SECOND", "TIMEZONE_HOUR", "TIMEZONE_MINUTE"):
            a.fail(f"Cannot extract {unit} from {t}", node, "TYPE_MISMATCH")
        return tt.BIGINT
    if unit in ("TIMEZONE_HOUR", "TIMEZONE_MINUTE") and t.base == "timestamp_tz":
        a.zone(t, node, f"EXTRACT({unit} FROM ...)")
        node.set("expression", floor_micros(node.expression))  # the offset at the microsecond
        return tt.BIGINT
    if unit in ("TIMEZONE_HOUR", "TIMEZONE_MINUTE") and not t.is_unknown:  # only zoned values have an offset
        a.fail(f"Cannot extract {unit} from {t}", node, "TYPE_MISMATCH")
    if t.base in intervals.FIELDS and unit.lower() in intervals.FIELDS[t.base]:
        return tt.BIGINT
    if unit not in allowed:
        a.unsupported(f"EXTRACT({unit} FROM ...)", node)
    if t.base not in ("date", "timestamp", "timestamp_tz", "unknown"):
        a.fail(f"Cannot extract {unit} from {t}", node, "TYPE_MISMATCH")
    if t.base == "timestamp_tz":
        a.zone(t, node, f"EXTRACT({unit} FROM ...)")
    if t.base == "date" and unit in ("HOUR", "MINUTE", "SECOND"):
        a.fail(f"Cannot extract {unit} from {t}", node, "TYPE_MISMATCH")
    node.set("expression", floor_micros(node.expression))
    return tt.BIGINT


@handles(exp.Subquery)
def _scalar_subquery(a: Analyzer, node, scope, env):
    cols = a.query(node.this, scope)
    a._modifiers(node, cols, scope)
    if len(cols) != 1 and node.meta.get("row_ok") and not any(c[2].base == "timestamp_tz" for c in cols):
        node.meta["row_subquery"] = len(cols)  # compared with a row: the row of its columns (Trino's RowType)
        return tt.row([(None, c[2]) for c in cols])
    if len(cols) != 1:
        a.fail("Multiple columns returned by subquery are not yet supported", node, "NOT_SUPPORTED")
    return cols[0][2]


@handles(exp.Exists)
def _exists(a: Analyzer, node, scope, env):
    a.query(node.this, scope)
    return tt.BOOLEAN


@handles(exp.Anonymous)
def _anonymous(a: Analyzer, node, scope, env):
    return a.function(node, scope, env)


@handles(exp.Filter)
def _filter(a: Analyzer, node, scope, env):
    inner = node.this
    if not isinstance(inner, (exp.Anonymous, exp.GroupConcat)):
        a.unsupported("FILTER on this expression", node)
    t = a.expr(inner, scope, env)
    inner = node.this  # listagg(...) WITHIN GROUP (...) is replaced by its call
    if inner.meta["spec"].kind != "aggregate":
        a.fail("FILTER is only valid for aggregation functions", node, "FUNCTION_NOT_AGGREGATE")
    a.condition(node.expression.this, scope, "FILTER")
    inner.meta["filter"] = node.expression.this
    return t


@handles(exp.Window)
def _window(a: Analyzer, node, scope, env):
    if node.args.get("alias") is not None:  # a name that no WINDOW clause of its query defines
        a.fail(f"Cannot resolve WINDOW name {node.args['alias'].name}", node.args["alias"], "INVALID_WINDOW_REFERENCE")
    inner = node.this
    nulls = None
    if isinstance(inner, (exp.IgnoreNulls, exp.RespectNulls)):
        nulls = "IGNORE NULLS" if isinstance(inner, exp.IgnoreNulls) else "RESPECT NULLS"
        inner = inner.this
    filter_node = None
    if isinstance(inner, exp.Filter):
        filter_node = inner
        inner = inner.this
    if not isinstance(inner, exp.Anonymous):
        a.unsupported("window over this expression", node)
    t = a.function(inner, scope, env, window=True)
    set(inner, t)
    if inner.meta["spec"].kind == "scalar":
        a.fail(f"Not a window function: {inner.name.lower()}", inner, "FUNCTION_NOT_WINDOW")
    if filter_node is not None:
        a.condition(filter_node.expression.this, scope, "FILTER")
        inner.meta["filter"] = filter_node.expression.this
    if nulls is not None:
        if inner.name.lower() not in ("lag", "lead", "first_value", "last_value", "nth_value"):
            a.fail(f"{nulls} is not allowed for {inner.name.lower()}", node, "NULL_TREATMENT_NOT_ALLOWED")
        inner.meta["nulls"] = nulls
    for part in node.args.get("partition_by") or []:
        a.expr(part, scope, env)
    order = node.args.get("order")
    if order is not None:
        for ordered in order.expressions:
            a.expr(ordered.this, scope, env)
    spec = node.args.get("spec")
    if spec is not None:
        _frame(a, spec, order.expressions if order is not None else [], scope, env)
    inner.meta["over"] = node
    return t


def _frame(a: Analyzer, spec: exp.WindowSpec, order: list, scope, env) -> None:
    """Check a window frame as Trino's StatementAnalyzer does (ROWS / GROUPS offsets are integers,
    GROUPS needs ORDER BY, a RANGE offset needs one numeric sort key); DuckDB runs the same frames.
    RANGE offsets: `check_range_offset`. Not translated: EXCLUDE."""
    kind = spec.args.get("kind", "").upper()
    if spec.args.get("exclude"):
        a.unsupported("window frame EXCLUDE", spec)
    offsets = [b for b in (spec.args.get("start"), spec.args.get("end")) if isinstance(b, exp.Expression)]
    if kind == "GROUPS" and offsets and not order:
        a.fail("Window frame of type GROUPS PRECEDING or FOLLOWING requires ORDER BY", spec, "MISSING_ORDER_BY")
    for bound in offsets:
        bound_type = a.expr(bound, scope, env)
        if kind == "RANGE":
            check_range_offset(a, order, bound, bound_type)
        elif not bound_type.is_integral:
            a.fail(f"Window frame offset must be an integer: {bound_type}", bound, "TYPE_MISMATCH")
    if kind == "RANGE" and offsets:
        spec.meta["range_type"] = range_comparison_type(a, ttype(order[0].this), offsets)


def a_literal_number(node: exp.Expression) -> exp.Literal | None:
    """`node` when it is a number literal."""
    return node if isinstance(node, exp.Literal) and not node.is_string else None


@handles(exp.Grouping)
def _grouping(a: Analyzer, node, scope, env):
    """grouping(k1, ..., kn) -> integer (as the real Trino 476 types it): bit i (from the right) is 1
    when key k(n-i) is not grouped (docs/src/main/sphinx/functions/aggregate.md); the arguments are
    checked against the GROUP BY keys with the rest of the query (Analyzer.check_grouping)."""
    for argument in node.expressions:
        a.expr(argument, scope, env)
    a.groupings.append(node)
    if len(node.expressions) > 63:
        a.fail("GROUPING supports up to 63 column arguments", node, "TOO_MANY_ARGUMENTS")
    return tt.INTEGER


@handles(exp.GroupConcat)
def _listagg(a: Analyzer, node, scope, env):
    if not isinstance(node.this, exp.Order):  # SqlBase.g4 #listagg: WITHIN GROUP is not optional
        a.fail("listagg requires WITHIN GROUP (ORDER BY ...)", node, "FUNCTION_NOT_FOUND")
    args = [node.this] + ([node.args["separator"]] if node.args.get("separator") is not None else [])
    call = exp.Anonymous(this="listagg", expressions=args)
    call.meta["overflow_truncate"] = isinstance(node.args.get("on_overflow"), exp.OverflowTruncateBehavior)
    call.meta.update({k: v for k, v in (node._meta or {}).items() if k in ("line", "col", "start", "end")})
    node.replace(call)
    node.meta["replaced_by"] = call
    return set(call, a.function(call, scope, env))


@handles(exp.Lambda)
def _lambda(a: Analyzer, node, scope, env):
    a.fail("Lambda expression is only allowed as a function argument", node, "SYNTAX_ERROR")


@handles(exp.Placeholder, exp.Parameter)
def _placeholder(a: Analyzer, node, scope, env):
    a.fail("Incorrect number of parameters: the query has more '?' than values given", node, "INVALID_PARAMETER_USAGE")


@handles(exp.AtTimeZone)
def _at_time_zone(a: Analyzer, node, scope, env):
    t = a.expr(node.this, scope, env)
    zone = node.args.get("zone")
    if t.base in ("time", "time_tz") and isinstance(zone, exp.Interval):
        a.expr(zone, scope, env)
        return _time_at_time_zone(a, node, t, _offset_of_interval(a, zone))
    if not (isinstance(zone, exp.Literal) and zone.is_string):
        a.unsupported("AT TIME ZONE with a non-literal zone", node)
    if t.base not in ("timestamp", "timestamp_tz", "time", "time_tz"):
        a.fail(
            f"Type of value must be a time or timestamp with or without time zone (actual {t})", node, "TYPE_MISMATCH"
        )
    a.expr(zone, scope, env)
    if t.base in ("time", "time_tz"):
        return _time_at_time_zone(a, node, t, a.zone_literal(zone))
    return tt.timestamp(t.args[0], True, a.zone_literal(zone))


def _offset_of_interval(a: Analyzer, interval: exp.Interval) -> str:
    """The offset zone (+hh:mm) of `AT TIME ZONE INTERVAL '10' HOUR`: a literal of whole minutes within
    14 hours (Trino fails on seconds and past 14 hours; lakegate refuses those)."""
    unit = interval.args.get("unit")
    text = interval.this.name.strip()
    if isinstance(unit, exp.IntervalSpan):
        value = intervals.span_value(text, unit.name.upper(), unit.expression.name.upper())
        millis = value[1] if value is not None and value[0] == "millis" else None
    else:
        scale = {"HOUR": 3_600_000, "MINUTE": 60_000}.get(unit.name.upper() if unit is not None else "")
        millis = int(text) * scale if scale is not None and re.fullmatch(r"[+-]?[0-9]{1,4}", text) else None
    if millis is None or millis % 60_000 or abs(millis) > zoned_times.MAX_OFFSET_MINUTES * 60_000:
        a.unsupported("AT TIME ZONE an interval that is not whole minutes within 14 hours", interval)
    minutes = millis // 60_000
    return f"{'-' if minutes < 0 else '+'}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"


def _time_at_time_zone(a: Analyzer, node: exp.AtTimeZone, t: TType, zone: str) -> TType:
    """A time with time zone at another offset, its instant kept (a time is first at the session zone's
    offset); a region's offset depends on the date, which Trino takes from the session: refused."""
    offsets = [zoned_times.offset_of(zone)] + ([zoned_times.offset_of(a.time_zone)] if t.base == "time" else [])
    if offsets[0] is None:
        a.unsupported(f"{t} AT TIME ZONE a region (its offset depends on the session's date)", node)
    if None in offsets:
        a.unsupported(f"{t} AT TIME ZONE in the session zone {a.time_zone} (its offset depends on the date)", node)
    node.meta["offset"] = offsets[0]
    return TType("time_tz", t.args)


@handles(exp.Substring)
def _substring(a: Analyzer, node, scope, env):
    t = a.expr(node.this, scope, env)
    if t.base in ("varbinary", "char"):  # SUBSTRING(x FROM s [FOR n]) is the substr(x, ...) call
        args = [node.this] + [node.args[k] for k in ("start", "length") if node.args.get(k) is not None]
        call = exp.Anonymous(this="substr", expressions=args)
        node.replace(call)
        node.meta["replaced_by"] = call
        return set(call, a.function(call, scope, env))
    for key in ("start", "length"):
        arg = node.args.get(key)
        if arg is not None and not (a.expr(arg, scope, env).is_integral or ttype(arg).is_unknown):
            a.fail("Unexpected parameters for function substr", node, "FUNCTION_NOT_FOUND")
    if t.base not in ("varchar", "unknown"):
        a.fail(f"Unexpected parameters ({t}) for function substr", node, "FUNCTION_NOT_FOUND")
    if t.is_unknown:  # substr(varchar(x), ...) and substr(varbinary, ...) both take a NULL literal
        a.fail(
            "Could not choose a best candidate operator. Explicit type casts must be added.\nCandidates are:\n"
            "\t * (varchar(0),bigint):varchar(0)\n\t * (varbinary,bigint):varbinary",
            node,
            "AMBIGUOUS_FUNCTION_CALL",
        )
    return t


@handles(exp.Trim)
def _trim(a: Analyzer, node, scope, env):
    t = a.expr(node.this, scope, env)
    chars = node.args.get("expression")
    if chars is not None:
        a.expr(chars, scope, env)
    if t.base == "char":  # TRIM([BOTH | LEADING | TRAILING] ...) of a char is its trim, ltrim or rtrim call
        name = {"BOTH": "trim", "LEADING": "ltrim", "TRAILING": "rtrim"}[(node.args.get("position") or "BOTH").upper()]
        call = exp.Anonymous(this=name, expressions=[node.this] + ([chars] if chars is not None else []))
        node.replace(call)
        node.meta["replaced_by"] = call
        return set(call, a.function(call, scope, env))
    if t.base not in ("varchar", "unknown"):
        a.fail(f"Unexpected parameters ({t}) for function trim", node, "FUNCTION_NOT_FOUND")
    return t if t.base == "varchar" else tt.varchar(0)  # a NULL literal binds varchar(x) with x = 0


@handles(exp.StrPosition)
def _position(a: Analyzer, node, scope, env):
    for key in ("this", "substr"):
        t = a.expr(node.args[key], scope, env)
        if t.base not in ("varchar", "unknown"):
            a.fail("Unexpected parameters for function strpos", node, "FUNCTION_NOT_FOUND")
    if node.args.get("position") is not None or node.args.get("occurrence") is not None:
        a.unsupported("position with a start", node)
    return tt.BIGINT
