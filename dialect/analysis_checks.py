"""The checks Trino makes at analysis that a translation would otherwise skip: grouping,
SELECT DISTINCT with ORDER BY, char(n) operands, operations on timestamp(7..9), RANGE frame offsets.
"""

from __future__ import annotations

import re

from sqlglot import exp

from lakegate.dialect import chars
from lakegate.dialect import trino_types as tt
from lakegate.dialect.guard import COMPARISON_OPERATORS, trino_name
from lakegate.dialect.name_resolution import grouping_keys, same_field_or_inside, same_value
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import COMPARISONS, WIDE_TIME_OPERATIONS, Analysis, NameScope, set, ttype

#: The functions that read a timestamp(7..9) through FloorMicros (as Trino's do), and those that handle
#: nanoseconds themselves (date_add keeps them; min, max and count compare them).
MICROS_READERS = frozenset(
    "date_trunc date_add date_diff date_format date last_day_of_month year quarter month week week_of_year day "
    "day_of_month day_of_week dow day_of_year doy year_of_week yow hour minute second millisecond".split()
)

_NANOSECOND_FUNCTIONS = MICROS_READERS | {"min", "max", "count", "arbitrary", "coalesce", "typeof"}

#: The expressions written for timestamp(7..9) operands (functions: only _NANOSECOND_FUNCTIONS).
_NANOSECOND_OPERATIONS = (
    *WIDE_TIME_OPERATIONS,
    exp.AtTimeZone,
    exp.Anonymous,
)


#: The functions written for time with time zone operands (dialect/zoned_times.py): ordering and picking
#: values (on the struct, whose order is Trino's but for ties of one instant in two offsets), fields, units.
_TIME_TZ_FUNCTIONS = frozenset(
    "min max min_by max_by count arbitrary any_value coalesce typeof hour minute second millisecond "
    "timezone_hour timezone_minute timezone date_trunc date_add date_diff".split()
)

#: The expressions written for time with time zone operands (functions: only _TIME_TZ_FUNCTIONS).
_TIME_TZ_OPERATIONS = (
    *WIDE_TIME_OPERATIONS,
    exp.AtTimeZone,
    exp.Subquery,
    exp.Anonymous,
)


def _holds_time_tz(t: TType | None) -> bool:
    return t is not None and any(inner.base == "time_tz" for inner in (t, *tt.inner_types(t)))


CHAR_TYPE = re.compile(r"(?<![a-z])char\(")


def has_char(t: TType) -> bool:
    return any(inner.base == "char" for inner in (t, *tt.inner_types(t)))


#: Operations that take char(n) operands exactly (dialect/chars.py): casts, IS NULL, LIKE (on the
#: padded text, LikeFunctions.likeChar), CASE and IF (Writer.coerce pads to the common char type),
#: `||` of char (char_concat); comparisons, IN and BETWEEN once their operands are cast to one char type.
_CHAR_NODES = (exp.Cast, exp.TryCast, exp.Paren, exp.Alias, exp.Is, exp.Ordered, exp.Like, exp.Case, exp.If)


#: Functions that take char(n) values whole: typeof, count, min, max, arbitrary (ordering and picking
#: padded texts of one length), coalesce, greatest and least (their arguments coerced to the common
#: char type); the char overloads of string functions mark their calls (functions/string.py).
_CHAR_FUNCTIONS = ("typeof", "count", "min", "max", "arbitrary", "any_value", "coalesce", "greatest", "least")


def check_char_use(a: Analysis, node: exp.Expression) -> None:
    """Refuse an operation on char(n) values (written as their padded text) that lakegate does not
    translate with Trino's char semantics (arrays, maps and rows of char, functions without a char
    overload here, comparisons with a subquery of another type)."""
    if node._meta and "replaced_by" in node.meta:  # SUBSTRING(x FROM ...) and TRIM(... FROM x) as calls
        node = node.meta["replaced_by"]
    types = [child.meta.get("t") for child in node.iter_expressions() if child._meta]
    char_types = [t for t in types if t is not None and has_char(t)]
    if not char_types or isinstance(node, _CHAR_NODES) or isinstance(node, exp.DPipe) and not node.meta.get("array"):
        return
    if isinstance(node, exp.Anonymous) and (node.name.lower() in _CHAR_FUNCTIONS or node.meta.get("char")):
        return
    if isinstance(node, (*COMPARISONS, exp.In, exp.Between)) and all(
        t is not None and (t == char_types[0] or t.is_unknown) for t in types
    ):
        return
    a.unsupported(
        f"{trino_name(node)} of {char_types[0]} values (lakegate translates char in casts, comparisons, "
        "CASE, coalesce, LIKE, ||, and the char overloads of length, lower, upper, trim, ltrim, rtrim, substr, "
        "lpad and concat)",
        node,
    )


def check_char_subquery(a: Analysis, node: exp.Expression, left: TType, column: TType, common: TType) -> None:
    """Refuse IN, ANY and ALL comparing a char with a subquery column of another type: the column's
    values would have to be padded to the common char type inside the subquery."""
    if common.base == "char" and left != column:
        what = "IN" if isinstance(node, exp.In) else f"{COMPARISON_OPERATORS[type(node)]} {node.expression.key.upper()}"
        a.unsupported(f"{what} (subquery) comparing {left} with {column}", node)


def char_concat(a: Analysis, node: exp.Expression, sides: list[exp.Expression]) -> TType:
    """`x || y` with a char operand: the other side coerced to char, the result char(x + y)
    (StringFunctions.concat(char(x), char(y)) pads the left value, keeps the right one)."""
    types = [ttype(side) for side in sides]
    t = chars.concat_type(*types)
    if t is None:
        a.unsupported(f"concatenation of {types[0]} and {types[1]} (longer than char(65536))", node)
    for side, side_type in zip(sides, types):
        chars.cast_to(side, tt.as_char(side_type))
    return t


def check_range_offset(a: Analysis, keys: list, bound: exp.Expression, offset: TType) -> None:
    """A RANGE frame offset, as Trino's StatementAnalyzer checks it: one sort key, numeric with a
    numeric offset or date/timestamp with an interval. lakegate takes any offset without a subquery
    over a numeric key (typed literals, casts and expressions as well as plain numbers), and an interval
    literal over a date or timestamp(p <= 6) key: what DuckDB frames alike. A negative or NULL offset
    fails when the frame is computed (transforms.range_frame), as in Trino."""
    if len(keys) != 1:
        a.fail(
            "Window frame of type RANGE PRECEDING or FOLLOWING requires single sort item in ORDER BY "
            f"(actual: {len(keys)})",
            bound,
            "INVALID_ORDER_BY",
        )
    key = ttype(keys[0].this)
    if not (key.is_numeric or key.base in ("date", "timestamp", "timestamp_tz")):
        a.fail(
            "Window frame of type RANGE PRECEDING or FOLLOWING requires that sort item type be numeric, "
            f"datetime or interval (actual: {key})",
            bound,
            "TYPE_MISMATCH",
        )
    temporal = key.base in ("date", "timestamp", "timestamp_tz")
    if (offset.base in ("interval_ds", "interval_ym")) != temporal or not (temporal or offset.is_numeric):
        a.fail(
            f"Window frame RANGE value type ({offset}) not compatible with sort item type ({key})",
            bound,
            "TYPE_MISMATCH",
        )
    unsupported = f"RANGE frame with offset {bound.sql(dialect='trino')} over a {key} sort key"
    if bound.find(exp.Subquery, exp.Select):
        a.unsupported(unsupported, bound)
    if temporal and (
        not (isinstance(bound, exp.Interval) and isinstance(bound.this, exp.Literal))
        or key.base == "timestamp_tz"
        or (key.base == "timestamp" and key.args[0] > 6)  # DuckDB's frame bound would be in microseconds
    ):
        a.unsupported(unsupported, bound)


def _exact(t: TType) -> bool:
    return t.is_integral or t.is_decimal


def range_comparison_type(a: Analysis, key: TType, bounds: list[exp.Expression]) -> TType:
    """The type Trino compares a numeric RANGE frame in: the sort key's common super type with each
    offset (an integer key with a 2.5 offset compares as a decimal, a real key with a double offset as a
    double); the key itself for a date or timestamp. The key is sorted as that type, which must keep
    its distinct values distinct (a bigint key cast to double would make peers of values Trino keeps
    apart), and both offsets must ask for the same comparison when it is approximate."""
    if not key.is_numeric:
        return key
    wanted = [tt.common_super_type(key, ttype(bound)) for bound in bounds]
    common = tt.common_super_type_of([key, *wanted])
    if common is None or any(t != common and not (_exact(t) and _exact(common)) for t in wanted):
        a.unsupported(f"RANGE frame whose offsets compare the {key} sort key as different types", bounds[0])
    lossless = (
        key == common
        or _exact(common)
        or (common.base == "double" and (key.base in ("tinyint", "smallint", "integer", "real")))
        or (common.base == "double" and key.is_decimal and key.args[0] <= 15)
        or (common.base == "real" and (key.base in ("tinyint", "smallint") or (key.is_decimal and key.args[0] <= 6)))
    )
    if not lossless:
        a.unsupported(
            f"RANGE frame with a {ttype(bounds[0])} offset over a {key} sort key (compared as {common}, "
            f"in which distinct {key} values can be equal)",
            bounds[0],
        )
    return common


class Checks:
    """The checks Trino makes at analysis: SELECT DISTINCT with ORDER BY, expressions not grouped,
    operations on timestamp(7..9) (a mixin of analyzer.Analyzer)."""

    #: Whether the query has a value holding a time with time zone (check_time_tz_use saw its type).
    time_tz_seen = False

    def check_distinct_order(self, node: exp.Select) -> None:
        """SELECT DISTINCT orders only by what it selects (io.trino.sql.analyzer.StatementAnalyzer,
        EXPRESSION_NOT_IN_DISTINCT); DuckDB would order by an arbitrary row of each group. An
        expression that names an output column is none of them, even one written as an item
        (`SELECT DISTINCT a, -a ... ORDER BY -a`: its `a` is the output's, as the real Trino says)."""
        items = [i.this if isinstance(i, exp.Alias) else i for i in node.expressions]
        for ordered in node.args["order"].expressions:
            target = ordered.this
            if (
                isinstance(target, exp.Literal)
                and not target.is_string
                or isinstance(target, exp.Column)
                and target.meta.get("output")
            ):
                continue
            names_output = any(c._meta and c.meta.get("output") for c in target.find_all(exp.Column))
            if names_output or not any(same_value(target, item) for item in items):
                self.fail(
                    "For SELECT DISTINCT, ORDER BY expressions must appear in select list",
                    self._select_keyword(node),
                    "EXPRESSION_NOT_IN_DISTINCT",
                )

    def _select_keyword(self, node: exp.Select) -> exp.Expression:
        """A marker at the SELECT keyword of `node`, where the real Trino points a query specification's
        errors: the last `select` in the text before the first select item's."""
        starts = [s.meta["start"] for item in node.expressions for s in item.walk() if s._meta and "start" in s.meta]
        keywords = list(re.finditer(r"(?i)\bselect\b", self.sql[: min(starts)])) if starts else []
        if not keywords:
            return node
        marker = exp.Literal.number(0)
        marker.meta["start"] = keywords[-1].start()
        return marker

    def check_grouping(self, node: exp.Select, scope: NameScope) -> None:
        """In an aggregation, every column outside an aggregate must be a GROUP BY key, as Trino
        requires (DuckDB would say so too, but not in Trino's words)."""
        group = node.args.get("group")
        having = node.args.get("having")
        items = [i.this if isinstance(i, exp.Alias) else i for i in node.expressions]
        checked = items + ([having.this] if having is not None else []) + node.meta.get("window_keys", [])
        for grouping in self.groupings:
            if group is None and grouping.find_ancestor(exp.Select) is node:
                self.fail(
                    "A GROUPING() operation can only be used with a corresponding GROUPING SET/CUBE/ROLLUP/"
                    "GROUP BY clause",
                    grouping,
                    "MISSING_GROUP_BY",
                )
        self._check_grouping_in_order_by(node)
        if group is None and not any(self._aggregate_inside(i) for i in checked):
            return
        keys = []
        for key in group.expressions if group is not None else []:
            if isinstance(key, (exp.Rollup, exp.Cube, exp.GroupingSets)):
                keys.extend(grouping_keys(key))
            elif isinstance(key, exp.Literal) and not key.is_string:
                keys.append(items[int(key.name) - 1])
            else:
                keys.append(key)
        qualifiers = {s.qualifier for s in scope.sources}
        for item in checked:
            self._grouped(item, keys, qualifiers)

    def _check_grouping_in_order_by(self, node: exp.Select) -> None:
        """In ORDER BY a name is first an output column, which grouping() may not take: Trino's
        INVALID_ARGUMENTS for `SELECT x ... ORDER BY grouping(x)` (a qualified `t.x` is the source's)."""
        order = node.args.get("order")
        if order is None:
            return
        outputs = {item.output_name.lower() for item in node.expressions if item.output_name}
        for grouping in order.find_all(exp.Grouping):
            if grouping.find_ancestor(exp.Select) is not node:
                continue
            for argument in grouping.expressions:
                if isinstance(argument, exp.Column) and not argument.table and argument.name.lower() in outputs:
                    self.fail(
                        "Invalid reference to output of SELECT clause from grouping() expression in ORDER BY",
                        grouping,
                        "INVALID_ARGUMENTS",
                    )

    def _aggregate_inside(self, node: exp.Expression) -> bool:
        if isinstance(node, (exp.Subquery, exp.Exists, exp.Window)):
            return False
        spec = node.meta.get("spec") if isinstance(node, exp.Anonymous) and node._meta else None
        if spec is not None and spec.kind == "aggregate":
            return True
        return any(self._aggregate_inside(child) for child in node.iter_expressions())

    def _grouped(self, node: exp.Expression, keys: list, qualifiers: set) -> None:
        if any(node == key for key in keys):
            return
        if (
            isinstance(node, exp.Anonymous)
            and node._meta
            and node.meta.get("spec") is not None
            and node.meta["spec"].kind != "scalar"
        ):
            return
        if isinstance(node, (exp.Window, exp.Subquery, exp.Exists, exp.Lambda, exp.Filter)):
            return
        if isinstance(node, exp.Grouping):
            for argument in node.expressions:
                if not any(argument == key for key in keys):
                    self.fail(
                        "The arguments to GROUPING() must be expressions referenced by the GROUP BY at the "
                        f"associated query level. Mismatch due to {argument.sql(dialect='trino')}.",
                        node,
                        "INVALID_ARGUMENTS",
                    )
            return
        if isinstance(node, exp.Column) and node._meta and node.meta.get("ref") is not None:
            if any(same_field_or_inside(node.meta["ref"], key) for key in keys):
                return  # `t.r` or `t.r.f1` with GROUP BY r: the same column, or a field of it
            if node.meta["ref"][0] in qualifiers and not node.meta.get("lambda"):
                self.fail(
                    f"'{node.sql(dialect='trino')}' must be an aggregate expression or appear in GROUP BY clause",
                    node,
                    "EXPRESSION_NOT_AGGREGATE",
                )
            return
        for child in node.iter_expressions():
            self._grouped(child, keys, qualifiers)

    def check_time_tz_use(self, node: exp.Expression, t: TType) -> None:
        """Refuse an operation on time with time zone values (DuckDB structs, dialect/zoned_times.py) that
        would compare whole structs, where Trino compares the time at +00:00 alone: values nested in
        arrays, maps or rows, IN a subquery, ANY / ALL, a simple CASE, DISTINCT inside a call, and the functions
        not written for them."""
        if _holds_time_tz(t):
            self.time_tz_seen = True
            if t.base != "time_tz":
                self.unsupported(f"{t} (lakegate holds time with time zone only as a plain value)", node)
        children = list(node.iter_expressions())
        if isinstance(node, exp.Anonymous) and children and isinstance(children[0], exp.Distinct):
            children = list(children[0].expressions)  # f(DISTINCT x)
        types = [child.meta.get("t") for child in children if child._meta]
        zoned = next((t for t in types if t is not None and _holds_time_tz(t)), None)
        if zoned is None:
            return
        simple_case = isinstance(node, exp.Case) and node.this is not None
        subquery = isinstance(node, exp.In) and node.args.get("query") is not None
        subquery = subquery or isinstance(node.args.get("expression"), (exp.Any, exp.All))  # = ANY (SELECT ...)
        distinct = isinstance(node, exp.Anonymous) and node.meta.get("distinct")  # compares whole structs
        if (
            isinstance(node, _TIME_TZ_OPERATIONS)
            and not simple_case
            and not subquery
            and not distinct
            and (not isinstance(node, exp.Anonymous) or node.name.lower() in _TIME_TZ_FUNCTIONS)
        ):
            return
        self.unsupported(
            f"{trino_name(node)} of {zoned} (lakegate compares time with time zone values only in "
            "=, <>, <, <=, >, >=, BETWEEN, IN a list, IS DISTINCT FROM, ORDER BY, min and max)",
            node,
        )

    def check_time_tz_keys(self, node: exp.Select) -> None:
        """Refuse GROUP BY, SELECT DISTINCT and PARTITION BY keys of time with time zone: DuckDB would
        tell apart values of one instant in two offsets, which Trino groups together."""
        if not self.time_tz_seen:  # every key's type went through check_time_tz_use
            return
        items = [i.this if isinstance(i, exp.Alias) else i for i in node.expressions]
        keys = list(items) if node.args.get("distinct") else []
        for key in node.args["group"].expressions if node.args.get("group") else []:
            if isinstance(key, (exp.Rollup, exp.Cube, exp.GroupingSets)):
                keys.extend(grouping_keys(key))
            elif isinstance(key, exp.Literal) and not key.is_string and 0 < int(key.name) <= len(items):
                keys.append(items[int(key.name) - 1])
            else:
                keys.append(key)
        for window in node.find_all(exp.Window):
            keys += window.args.get("partition_by") or []
        for key in keys:
            if key._meta and _holds_time_tz(key.meta.get("t")):
                self.unsupported(f"GROUP BY, DISTINCT or PARTITION BY of {key.meta['t']}", key)

    def _check_nanosecond_use(self, node: exp.Expression) -> None:
        """Refuse an operation on a timestamp(7..9) (DuckDB's TIMESTAMP_NS) that is not written for
        nanoseconds: DuckDB's other functions round such a value to the nearest microsecond."""
        if isinstance(node, _NANOSECOND_OPERATIONS) and (
            not isinstance(node, exp.Anonymous) or node.name.lower() in _NANOSECOND_FUNCTIONS
        ):
            return
        for child in node.iter_expressions():
            t = child.meta.get("t") if child._meta else None
            if t is not None and t.base == "timestamp" and t.args[0] > 6:
                self.unsupported(
                    f"{trino_name(node)} of {t} (lakegate translates only casts, comparisons, "
                    "interval arithmetic and the date and time functions for p > 6)",
                    node,
                )
