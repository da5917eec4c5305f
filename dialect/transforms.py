"""The DuckDB SQL writer: sqlglot's DuckDB generator plus named transforms, one small function per
Trino/DuckDB difference, in the style of sqlglot's dialect modules (`TRANSFORMS = {exp.X: fn}`).

Every transform reads the Trino types that `analyze` attached to the tree (`node.meta["t"]`) and
writes DuckDB SQL that gives Trino's answer: integer division truncates, decimal division and
`avg(decimal)` round HALF_UP at Trino's scale, subscripts fail out of range, doubles print as Trino
prints them, NULLs order last. Runtime failures are raised with DuckDB's `error()` and Trino's
message text; inside `try(...)` the same transforms yield NULL instead (`Writer.fail`).

This module holds the Writer, the transforms of names, literals, calls and relations; those of
operators are in write_operators.py, those of casts in write_casts.py (translate.py lists them),
and the rewrites of the tree before it is written in tree_rewrites.py.
"""

from __future__ import annotations

from sqlglot import exp
from sqlglot.generators.duckdb import DuckDBGenerator

from lakegate.dialect import (
    chars,
    intervals,
    null_folding,
    pico_times,
    time_casts,
    times,
    wide_timestamps,
    zoned_times,
    zones,
)
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
#: A failure inside try() that DuckDB's TRY(...) catches (error() is volatile, which TRY refuses): a
#: failing cast, typed NULL so that it fits where any value does.
CAUGHT_FAILURE = "(CASE WHEN CAST('failure inside try()' AS INTEGER) IS NULL THEN NULL END)"


def _inside(t: TType, *bases: str) -> bool:
    """Whether an array, map or row type holds values of one of these base types."""
    return any(inner.base in bases for inner in tt.inner_types(t))


class Writer(DuckDBGenerator):
    """Writes the analyzed Trino tree as DuckDB SQL."""

    def __init__(self, time_zone: str = "UTC", **kwargs):
        super().__init__(identify=True, comments=False, **kwargs)
        self.time_zone = time_zone  # the session zone
        self.in_try = 0
        self.catching = 0  # the in_try depth of the try() whose failures DuckDB's TRY(...) catches
        self._written: dict[tuple, tuple[exp.Expression, str]] = {}

    def sql(self, expression, key=None, comment=True) -> str:
        """The node's SQL, written once per node (transforms that use an argument twice would
        otherwise write its subtree again, 2^depth times for nested calls), at most MAX_SQL_CHARS long."""
        if not isinstance(expression, exp.Expression):
            return super().sql(expression, key, comment)
        memo = (id(expression), key, comment, self.in_try, self.catching == self.in_try)
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
        expression) at run time, as `NAME: message` (see errors.runtime_error). Inside try() or
        TRY_CAST it is NULL, except directly inside a try() that DuckDB's TRY(...) wraps: there it
        is a failure TRY catches, so that the whole try() is NULL, as in Trino."""
        if not self.in_try:
            return f"error({string(error_name + ': ')} || {message_sql})"
        return CAUGHT_FAILURE if self.catching == self.in_try else "NULL"

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
        if wide_timestamps.is_wide(target):
            zoned = target.base == "timestamp_tz"  # a timestamp read in the session zone
            return wide_timestamps.coerce(sql, source, self.time_zone, zoned)
        if time_casts.handles(source, target):  # a time(7..12) or to one: DuckDB cannot cast the picoseconds
            return time_casts.cast(self, sql, source, target)
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
        order = window.args.get("order")
        keys = [*(window.args.get("partition_by") or []), *(o.this for o in (order.expressions if order else []))]
        checks = [f"({sql}) IS NULL" for sql in map(self.sql, keys) if "error(" in sql]
        if not checks:
            return f"{call} {over}"
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
        spec = window.args.get("spec")
        if spec is not None and spec.meta.get("range_type") is not None:
            parts.extend(range_frame(self, order.expressions[0], spec))
        else:
            if order is not None:
                parts.append(self.order_sql(order).strip())
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


# --- function calls ------------------------------------------------------------------------------
@transform(exp.Anonymous)
def registered_function(g: Writer, node: exp.Anonymous) -> str:
    """Every function call is written by its registry entry (registry.SUPPORTED), except a call that
    Trino folds to NULL, whose other arguments are not evaluated (null_folding.py)."""
    if node.meta["spec"].kind == "scalar" and null_folding.folds_to_null(node):
        return cast("NULL", ttype(node))
    t, args = ttype(node), node.meta["args"]
    floored = next(
        (a.this for a in args if isinstance(a, FloorMicros) and wide_timestamps.is_wide(ttype(a.this))), None
    )
    if floored is None or not wide_timestamps.is_wide(t):
        return node.meta["spec"].render(g, node, args)
    # date_trunc, date_add: written on the microseconds (timestamp(6) with time zone), as Trino reads them
    node.meta["t"] = tt.with_precision(t, 6)
    try:
        sql = node.meta["spec"].render(g, node, args)
    finally:
        node.meta["t"] = t
    kept = wide_timestamps.picos(g.sql(floored)) if node.name.lower() == "date_add" else "0"
    return wide_timestamps.make(sql, kept, zoned=t.base == "timestamp_tz")


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
    if ttype(value).base == "time_tz":
        return zoned_times.field(g.sql(value), unit.lower())
    if ttype(value).base == "time":
        return zoned_times.clock_field(pico_times.picos(g.sql(value), ttype(value)), unit.lower())
    if unit in ("TIMEZONE_HOUR", "TIMEZONE_MINUTE"):
        return zone_offset(g, value, unit.split("_")[1].lower())
    if ttype(value).base in intervals.FIELDS:
        return intervals.field(g.sql(value), ttype(value).base, unit.lower())
    sql = field_time(g, value)
    return f"CAST(date_part({string(_EXTRACT.get(unit, unit.lower()))}, {sql}) AS BIGINT)"


@transform(exp.Interval)
def interval_literal(g: Writer, node: exp.Interval) -> str:
    unit = node.args["unit"]
    if isinstance(unit, exp.IntervalSpan):
        spanned = intervals.span_value(node.this.name, unit.name.upper(), unit.expression.name.upper())
        return intervals.duckdb_interval(*spanned)  # type: ignore[misc]  # analysis refused what it cannot read
    return f"INTERVAL {string(node.this.name.strip())} {node.args['unit'].name.upper()}"


@transform(exp.AtTimeZone)
def at_time_zone(g: Writer, node: exp.AtTimeZone) -> str:
    """The same instant, shown in another zone (the zone is the type's); a timestamp is first read in the
    session zone. A time with time zone keeps its instant at the offset (infer_calls._time_at_time_zone)."""
    if ttype(node).base == "time_tz":
        sql, source = g.sql(node.this), ttype(node.this)
        if pico_times.is_wide(source):
            sql = zoned_times.of_local(sql, str(zoned_times.offset_of(g.time_zone)))
        elif source.base == "time":
            sql = zoned_times.of_time_micros(times.micros(sql), zoned_times.offset_of(g.time_zone))
        return zoned_times.make(zoned_times.utc(sql), str(node.meta["offset"]))
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


def field_time(g: Writer, node: exp.Expression) -> str:
    """`wall_time` as the argument of DuckDB's date_part: a timestamp as a microsecond TIMESTAMP
    (DuckDB 2.0's date_part reads a TIMESTAMP_MS, _S or _NS as microseconds when the statistics of
    its result feed an ORDER BY or GROUP BY: year 57577 for 2025); a nanosecond one floored."""
    sql = wall_time(g, node)
    t = ttype(node)
    if t.base not in ("timestamp", "timestamp_tz"):
        return sql
    if (t.args[0] if t.args else 3) <= 6:
        return f"CAST({sql} AS TIMESTAMP)"
    nanos = f"epoch_ns({sql})"
    return f"make_timestamp((({nanos}) - ((({nanos}) % 1000) + 1000) % 1000) // 1000)"


@transform(exp.Substring)
def substring_from(g: Writer, node: exp.Substring) -> str:
    """substr(s, start[, length]): NULL on a NULL argument; then start 0 or a negative length give ''
    (DuckDB counts them); from a positive start, a length past the text's is the text's (DuckDB fails
    past 2^32; Trino fails from a negative start when the end overflows an int, left to DuckDB)."""
    value, start = g.sql(node.this), g.sql(node.args["start"])
    length = node.args.get("length")
    nulls = f"({value}) IS NULL OR ({start}) IS NULL"
    if length is None:
        return (
            f"CASE WHEN {nulls} THEN NULL WHEN ({start}) = 0 OR abs({start}) > length({value}) THEN '' "
            f"ELSE substr({value}, {start}) END"
        )
    length_sql = g.sql(length)
    return (
        f"CASE WHEN {nulls} OR ({length_sql}) IS NULL THEN NULL "
        f"WHEN ({start}) = 0 OR ({length_sql}) <= 0 OR abs({start}) > length({value}) THEN '' "
        f"ELSE substr({value}, {start}, CASE WHEN ({start}) > 0 THEN least({length_sql}, length({value})) "
        f"ELSE {length_sql} END) END"
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


def range_frame(g: Writer, key: exp.Ordered, spec: exp.WindowSpec) -> tuple[str, str]:
    """ORDER BY and frame of a RANGE frame with offsets: the sort key and the offsets in the type Trino
    compares them in (analysis_checks.range_comparison_type), each offset checked where the frame is computed:
    negative or NULL fails with INVALID_WINDOW_FRAME, and a day-to-second interval that is not whole days
    over a date key with Trino's date arithmetic error."""
    t = spec.meta["range_type"]
    order = "ORDER BY " + g.sql(exp.Ordered(this=exp.Var(this=g.coerce(key.this, t)), **_direction(key)))
    bounds = []
    for side in ("start", "end"):
        bound, direction = spec.args.get(side), spec.args.get(f"{side}_side")
        if not isinstance(bound, exp.Expression):  # UNBOUNDED PRECEDING / FOLLOWING, CURRENT ROW
            bounds.append(" ".join(part for part in (bound or "CURRENT ROW", direction) if part))
            continue
        bounds.append(f"{_range_offset(g, bound, t, direction == 'PRECEDING')} {direction}")
    return order, f"{spec.args['kind']} BETWEEN {bounds[0]} AND {bounds[1]}"


def _direction(key: exp.Ordered) -> dict:
    return {"desc": key.args.get("desc"), "nulls_first": key.args.get("nulls_first")}


def _range_offset(g: Writer, bound: exp.Expression, key: TType, preceding: bool) -> str:
    source = ttype(bound)
    sql = g.sql(bound)
    interval = source.base in ("interval_ds", "interval_ym")
    value = sql if interval else g.coerce(bound, key)
    zero = "INTERVAL 0 SECOND" if interval else "0"
    checks = [
        (
            f"({sql}) IS NULL OR ({sql}) < {zero}",
            "INVALID_WINDOW_FRAME: Window frame offset value must not be negative or null",
        )
    ]
    if key.base == "date" and source.base == "interval_ds":
        verb = "subtract hour, minutes or seconds from" if preceding else "add hour, minutes or seconds to"
        checks.append((f"epoch({sql}) % 86400 <> 0", f"INVALID_FUNCTION_ARGUMENT: Cannot {verb} a date"))
    whens = " ".join(f"WHEN {check} THEN error({string(message)})" for check, message in checks)
    return f"(CASE {whens} ELSE {value} END)"
