"""Name resolution and Trino type inference over a parsed Trino query.

`analyze(tree, schema, sql)` walks the whole tree once: it resolves every table and column
against the schema (CTEs, derived tables, VALUES, UNNEST, joins, correlated subqueries, lambda
parameters), expands `*`, computes the Trino type of every expression (stored in `node.meta["t"]`)
and the output columns of every query, and rejects what Trino would reject (unknown names, type
mismatches) or what lakegate cannot answer identically (unsupported syntax and functions), always
with the position in the original SQL text. The generator in `translate.py` then reads the types.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NoReturn

from sqlglot import exp

from lakegate.dialect import chars, registry, row_star, times, zoned_nanos, zones
from lakegate.dialect import trino_types as tt
from lakegate.dialect.errors import DialectError
from lakegate.dialect.guard import COMPARISON_OPERATORS, trino_name
from lakegate.dialect.named_windows import resolve_named_windows, window_keys
from lakegate.dialect.trino_types import TType
from lakegate.dialect.with_ties import rank_filter, rank_keys, with_ties

#: Output column of a query: (Trino name or None when anonymous, name in the DuckDB SQL, type).
OutCol = tuple["str | None", str, TType]


def position(node: exp.Expression, sql: str) -> tuple[int | None, int | None]:
    """1-based (line, column) of `node` in the original SQL text, from the token offsets sqlglot
    keeps on identifiers, literals and function names (the leftmost one inside `node`)."""
    start = None
    for sub in node.walk():
        meta = sub._meta
        if meta and "start" in meta and (start is None or meta["start"] < start):
            start = meta["start"]
    if start is None:
        parent = node.parent
        return position(parent, sql) if parent is not None else (None, None)
    line = sql.count("\n", 0, start) + 1
    return line, start - (sql.rfind("\n", 0, start) + 1) + 1


@dataclass
class Source:
    """One relation in a FROM clause: its qualifier in the DuckDB SQL and its columns."""

    name: str | None  # Trino name to qualify with (alias or table name), lower case
    qualifier: str  # identifier used in the DuckDB SQL
    columns: list[OutCol]
    using: dict[str, str] = field(default_factory=dict)  # JOIN USING column name -> its DuckDB SQL

    def find(self, name: str) -> list[OutCol]:
        return [c for c in self.columns if c[0] is not None and c[0].lower() == name]


@dataclass
class Scope:
    """The names visible to an expression: FROM sources, then enclosing queries' (correlation)."""

    sources: list[Source] = field(default_factory=list)
    outer: Scope | None = None
    ctes: dict[str, list[OutCol]] = field(default_factory=dict)
    outputs: list[OutCol] | None = None  # select outputs, visible in ORDER BY

    def derived(self) -> Scope:
        """The scope of a derived table in this FROM: this query's CTEs, not its other sources."""
        return Scope(outer=self.outer, ctes=self.ctes)

    def cte(self, name: str) -> list[OutCol] | None:
        scope: Scope | None = self
        while scope is not None:
            if name in scope.ctes:
                return scope.ctes[name]
            scope = scope.outer
        return None


def _same_value(a: exp.Expression, b: exp.Expression) -> bool:
    """The same expression, columns compared by what they resolved to."""
    if isinstance(a, exp.Column) and isinstance(b, exp.Column) and a._meta and b._meta:
        return a.meta.get("ref") == b.meta.get("ref") and a.meta.get("sql") == b.meta.get("sql")
    return a == b


def _using_value(source: Source, col: OutCol, common: TType) -> str:
    """The DuckDB SQL of one side's USING column, cast to the join column's type."""
    quoted = ".".join('"' + part.replace('"', '""') + '"' for part in (source.qualifier, col[1]))
    sql = source.using.get(col[1].lower(), quoted)
    return sql if col[2] == common else f"CAST({sql} AS {tt.duckdb_type(common)})"


def ttype(node: exp.Expression) -> TType:
    """The Trino type the analysis attached to an expression."""
    return node.meta["t"]


def _set(node: exp.Expression, t: TType) -> TType:
    node.meta["t"] = t
    return t


class Call:
    """What a function's type rule sees: the call, its arguments and their types."""

    def __init__(
        self,
        analyzer: Analyzer,
        node: exp.Expression,
        name: str,
        args: list[exp.Expression],
        scope: Scope,
        env: dict[str, TType],
    ):
        self.analyzer, self.node, self.name, self.args = analyzer, node, name, args
        self.scope, self.env = scope, env
        self.types: list[TType | None] = [
            None if isinstance(a, (exp.Lambda, exp.Star)) else analyzer.expr(a, scope, env) for a in args
        ]
        for i, a in enumerate(args):  # an argument that analysis replaced (listagg) is written as its replacement
            if a._meta and "replaced_by" in a._meta:
                args[i] = a.meta["replaced_by"]

    def lam(self, index: int, params: list[TType]) -> TType:
        """Type the lambda at argument `index` with the given parameter types; its body's type."""
        node = self.args[index] if index < len(self.args) else None
        if not isinstance(node, exp.Lambda):
            self.mismatch()
        names = [p.name.lower() for p in node.expressions]
        if len(names) != len(params):
            self.fail(f"Expected a lambda that takes {len(params)} argument(s) but got {len(names)}")
        node.meta["params"] = dict(zip(names, params))
        return _set(node, self.analyzer.expr(node.this, self.scope, {**self.env, **dict(zip(names, params))}))

    def fail(self, message: str, error_name: str = "TYPE_MISMATCH") -> NoReturn:
        self.analyzer.fail(message, self.node, error_name)

    def mismatch(self) -> NoReturn:
        types = ", ".join("function" if t is None else str(t) for t in self.types)
        self.fail(f"Unexpected parameters ({types}) for function {self.name}", "FUNCTION_NOT_FOUND")

    def literal(self, index: int) -> exp.Literal | None:
        """The argument at `index` when it is a literal (a parameter bound as a literal counts)."""
        node = self.args[index]
        while isinstance(node, exp.Paren):
            node = node.this
        if isinstance(node, exp.Neg) and isinstance(node.this, exp.Literal) and not node.this.is_string:
            return exp.Literal.number("-" + node.this.name)
        return node if isinstance(node, exp.Literal) else None


_COMPARISONS = (exp.EQ, exp.NEQ, exp.GT, exp.GTE, exp.LT, exp.LTE, exp.NullSafeEQ, exp.NullSafeNEQ)


class FloorMicros(exp.Expression):
    """A timestamp(7..9) argument floored to a microsecond timestamp(6): what Trino's date and time
    functions read of a LongTimestamp (getEpochMicros). Added by the analysis, never written by users."""

    arg_types = {"this": True}


#: The functions that read a timestamp(7..9) through FloorMicros (as Trino's do), and those that handle
#: nanoseconds themselves (date_add keeps them; min, max and count compare them).
_MICROS_READERS = frozenset(
    "date_trunc date_add date_diff date_format date last_day_of_month year quarter month week week_of_year day "
    "day_of_month day_of_week dow day_of_year doy year_of_week yow hour minute second millisecond".split()
)
_NANOSECOND_FUNCTIONS = _MICROS_READERS | {"min", "max", "count", "arbitrary", "coalesce", "typeof"}
#: The expressions written for timestamp(7..9) operands (functions: only _NANOSECOND_FUNCTIONS).
_NANOSECOND_OPERATIONS = (
    exp.Cast,
    exp.TryCast,
    *_COMPARISONS,
    exp.Between,
    exp.In,
    exp.Is,
    exp.Case,
    exp.If,
    exp.Add,
    exp.Sub,
    exp.Paren,
    exp.Alias,
    exp.Ordered,
    exp.Window,
    exp.Filter,
    exp.Extract,
    exp.Anonymous,
)


_CHAR_TYPE = re.compile(r"(?<![a-z])char\(")


def _has_char(t: TType) -> bool:
    return any(inner.base == "char" for inner in (t, *tt.inner_types(t)))


#: Operations that take char(n) operands exactly (dialect/chars.py): casts, IS NULL, LIKE (on the
#: padded text, LikeFunctions.likeChar), CASE and IF (Writer.coerce pads to the common char type),
#: `||` of char (_char_concat); comparisons, IN and BETWEEN once their operands are cast to one char type.
_CHAR_NODES = (exp.Cast, exp.TryCast, exp.Paren, exp.Alias, exp.Is, exp.Ordered, exp.Like, exp.Case, exp.If)

#: Functions that take char(n) values whole: typeof, count, min, max, arbitrary (ordering and picking
#: padded texts of one length), coalesce, greatest and least (their arguments coerced to the common
#: char type); the char overloads of string functions mark their calls (functions/string.py).
_CHAR_FUNCTIONS = ("typeof", "count", "min", "max", "arbitrary", "any_value", "coalesce", "greatest", "least")


def _check_char_use(a: Analyzer, node: exp.Expression) -> None:
    """Refuse an operation on char(n) values (written as their padded text) that lakegate does not
    translate with Trino's char semantics (arrays, maps and rows of char, functions without a char
    overload here, comparisons with a subquery of another type)."""
    if node._meta and "replaced_by" in node.meta:  # SUBSTRING(x FROM ...) and TRIM(... FROM x) as calls
        node = node.meta["replaced_by"]
    types = [child.meta.get("t") for child in node.iter_expressions() if child._meta]
    char_types = [t for t in types if t is not None and _has_char(t)]
    if not char_types or isinstance(node, _CHAR_NODES) or isinstance(node, exp.DPipe) and not node.meta.get("array"):
        return
    if isinstance(node, exp.Anonymous) and (node.name.lower() in _CHAR_FUNCTIONS or node.meta.get("char")):
        return
    if isinstance(node, (*_COMPARISONS, exp.In, exp.Between)) and all(
        t is not None and (t == char_types[0] or t.is_unknown) for t in types
    ):
        return
    a.unsupported(
        f"{trino_name(node)} of {char_types[0]} values (lakegate translates char in casts, comparisons, "
        "CASE, coalesce, LIKE, ||, and the char overloads of length, lower, upper, trim, ltrim, rtrim, substr, "
        "lpad and concat)",
        node,
    )


def _check_char_subquery(a: Analyzer, node: exp.Expression, left: TType, column: TType, common: TType) -> None:
    """Refuse IN, ANY and ALL comparing a char with a subquery column of another type: the column's
    values would have to be padded to the common char type inside the subquery."""
    if common.base == "char" and left != column:
        what = "IN" if isinstance(node, exp.In) else f"{COMPARISON_OPERATORS[type(node)]} {node.expression.key.upper()}"
        a.unsupported(f"{what} (subquery) comparing {left} with {column}", node)


def _char_concat(a: Analyzer, node: exp.Expression, sides: list[exp.Expression]) -> TType:
    """`x || y` with a char operand: the other side coerced to char, the result char(x + y)
    (StringFunctions.concat(char(x), char(y)) pads the left value, keeps the right one)."""
    types = [ttype(side) for side in sides]
    t = chars.concat_type(*types)
    if t is None:
        a.unsupported(f"concatenation of {types[0]} and {types[1]} (longer than char(65536))", node)
    for side, side_type in zip(sides, types):
        chars.cast_to(side, tt.as_char(side_type))
    return t


def floor_micros(node: exp.Expression) -> exp.Expression:
    """`node` read as Trino's functions read a timestamp(7..9): floored to microseconds."""
    t = node.meta.get("t") if node._meta else None
    if t is None or t.base != "timestamp" or t.args[0] <= 6:
        return node
    floored = FloorMicros(this=node)
    _set(floored, tt.timestamp(6))
    return floored


_ARITHMETIC = {exp.Add: "+", exp.Sub: "-", exp.Mul: "*", exp.Div: "/", exp.Mod: "%"}
_UNORDERABLE = ("json", "map", "varbinary", "unknown")


class Analyzer:
    """One analysis of one statement (not reused: it keeps the SQL text and a counter)."""

    def __init__(self, schema: dict[str, list[tuple[str, TType]]], sql: str, time_zone: str = zones.UTC):
        self.schema = schema
        self.sql = sql
        self.time_zone = time_zone  # the session zone
        self._alias_counter = 0
        self.groupings: list[exp.Grouping] = []  # every grouping() operation, checked by check_grouping

    # --- errors ---------------------------------------------------------------------------------
    def fail(self, message: str, node: exp.Expression, error_name: str = "NOT_SUPPORTED") -> NoReturn:
        line, column = position(node, self.sql)
        if error_name in ("TYPE_MISMATCH", "FUNCTION_NOT_FOUND") and _CHAR_TYPE.search(message):
            # Trino coerces char(x) and char(y) (and varchar) to a common type and has char functions
            message, error_name = f"unsupported in lakegate: char operands here ({message})", "NOT_SUPPORTED"
        raise DialectError(message, line=line, column=column, error_name=error_name)

    def unsupported(self, what: str, node: exp.Expression) -> NoReturn:
        self.fail(f"unsupported in lakegate: {what}", node, "NOT_SUPPORTED")

    def zone_literal(self, node: exp.Literal) -> str:
        """The canonical zone a string literal names (Trino's NOT_SUPPORTED error for an unknown one)."""
        try:
            return zones.canonical(node.name)
        except ValueError as error:
            self.fail(str(error), node, "NOT_SUPPORTED")

    def zone(self, t: TType, node: exp.Expression, what: str) -> str:
        """The one zone the timestamp with time zone values of `node` carry; refused (naming `what`)
        when they may carry different zones (a CASE, COALESCE, UNION or VALUES mixing zones)."""
        zone = tt.zone_of(t)
        if zone is None:
            self.unsupported(
                f"{what} of timestamp with time zone values that may carry different zones "
                "(a CASE, COALESCE, UNION, VALUES, greatest or least mixing zones, or dates or timestamps with them)",
                node,
            )
        return zone

    def zones(self, t: TType, node: exp.Expression, what: str) -> None:
        """`zone` of every timestamp with time zone in `t`, nested ones included."""
        for inner in (t, *tt.inner_types(t)):
            if inner.base == "timestamp_tz":
                self.zone(inner, node, what)

    def zoned_cast_in_utc_only(self, a: TType, b: TType, node: exp.Expression, what: str) -> None:
        """Where DuckDB itself casts a date or timestamp to timestamp with time zone (set operation
        branches, JOIN USING columns) it reads it in UTC: refused in any other session zone."""
        if self.time_zone != zones.UTC and {a.base, b.base} in (
            {"date", "timestamp_tz"},
            {"timestamp", "timestamp_tz"},
        ):
            self.unsupported(
                f"{what} in the session zone {self.time_zone} "
                f"(a timestamp with time zone and a {a.base if a.base != 'timestamp_tz' else b.base})",
                node,
            )

    def fresh_alias(self) -> str:
        self._alias_counter += 1
        return f"_q{self._alias_counter}"

    # --- queries --------------------------------------------------------------------------------
    def query(self, node: exp.Expression, outer: Scope | None) -> list[OutCol]:
        """Analyze a query (SELECT, set operation, VALUES, parenthesized query); its output columns."""
        if isinstance(node, exp.Subquery) and not node.alias:
            cols = self.query(node.this, outer)
            self._modifiers(node, cols, outer)
            return cols
        if isinstance(node, exp.Select):
            return self.select(node, outer)
        if isinstance(node, exp.SetOperation):
            return self.set_operation(node, outer)
        if isinstance(node, exp.Values):
            return self.values(node, outer)
        self.unsupported(f"statement {node.key.upper()}", node)

    def _with(self, node: exp.Expression, outer: Scope | None) -> Scope:
        scope = Scope(outer=outer)
        with_ = node.args.get("with_")
        if with_ is not None:
            if with_.args.get("recursive"):
                self.unsupported("WITH RECURSIVE", with_)
            for cte in with_.expressions:
                cols = self.query(cte.this, scope)
                names = [c.name for c in cte.args["alias"].columns] if cte.args["alias"].columns else None
                if names:
                    if len(names) != len(cols):
                        self.fail(
                            f"WITH query name {cte.alias} specifies {len(names)} column names, "
                            f"but the query has {len(cols)}",
                            cte,
                            "MISMATCHED_COLUMN_ALIASES",
                        )
                    cols = [(_ident_name(i), _ident_name(i), c[2]) for i, c in zip(cte.args["alias"].columns, cols)]
                scope.ctes[cte.alias.lower()] = cols
        return scope

    def select(self, node: exp.Select, outer: Scope | None) -> list[OutCol]:
        for key in (
            "qualify",
            "laterals",
            "connect",
            "pivots",
            "prewhere",
            "sample",
            "distribute",
            "sort",
            "cluster",
            "into",
            "locks",
            "settings",
            "format",
            "options",
            "match",
            "exclude",
            "for_",
        ):
            if node.args.get(key):
                self.unsupported(
                    {"sample": "TABLESAMPLE"}.get(key, key.upper().rstrip("_")),
                    node.args[key] if isinstance(node.args[key], exp.Expression) else node,
                )
        definitions = resolve_named_windows(node, self.sql, self.fail)
        if with_ties(node.args.get("limit")) and node.args.get("order") is not None:
            node.meta["rank_keys"] = rank_keys(node)
        scope = self._with(node, outer)
        from_ = node.args.get("from_")
        if from_ is not None:
            self.relation(from_.this, scope)
        for join in node.args.get("joins") or []:
            self.join(join, scope)
        where = node.args.get("where")
        if where is not None:
            self.condition(where.this, scope, "WHERE")
        outputs = self.projection(node, scope)
        group = node.args.get("group")
        if group is not None:
            self.group(group, node, scope)
        having = node.args.get("having")
        if having is not None:
            self.condition(having.this, scope, "HAVING")
        node.meta["window_keys"] = [key for d in definitions for key in window_keys(d)]
        for key in node.meta["window_keys"]:  # Trino analyzes every WINDOW definition, used or not
            self.expr(key, scope, {})
        distinct = node.args.get("distinct")
        if distinct is not None and distinct.args.get("on"):
            self.unsupported("DISTINCT ON", distinct)
        node.meta["outputs"] = outputs
        self._modifiers(node, outputs, scope)
        self.check_grouping(node, scope)
        if distinct is not None and node.args.get("order") is not None:
            self.check_distinct_order(node)
        return outputs

    def check_distinct_order(self, node: exp.Select) -> None:
        """SELECT DISTINCT orders only by what it selects (io.trino.sql.analyzer.StatementAnalyzer,
        EXPRESSION_NOT_IN_DISTINCT); DuckDB would order by an arbitrary row of each group."""
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
            if not any(_same_value(target, item) for item in items):
                self.fail(
                    "For SELECT DISTINCT, ORDER BY expressions must appear in select list",
                    target,
                    "EXPRESSION_NOT_IN_DISTINCT",
                )

    def check_grouping(self, node: exp.Select, scope: Scope) -> None:
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
            if any(_same_field_or_inside(node.meta["ref"], key) for key in keys):
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

    def _modifiers(self, node: exp.Expression, outputs: list[OutCol], scope: Scope | None) -> None:
        order = node.args.get("order")
        if order is not None:
            order_scope = scope if scope is not None else Scope()
            order_scope = Scope(order_scope.sources, order_scope.outer, order_scope.ctes, outputs)
            for ordered in order.expressions:
                self.order_item(ordered, outputs, order_scope)
        for key in ("limit", "offset"):
            clause = node.args.get(key)
            if clause is None:
                continue
            if isinstance(clause, exp.Fetch):
                count = clause.args.get("count")
                options = clause.args.get("limit_options")  # where sqlglot keeps WITH TIES now
                if clause.args.get("percent") or options and options.args.get("percent"):
                    self.unsupported("FETCH FIRST ... PERCENT", clause)
                if isinstance(count, exp.Literal) and count.name == "0":
                    message = "FETCH FIRST row count must be positive (actual value: 0)"
                    self.fail(message, clause, "NUMERIC_VALUE_OUT_OF_RANGE")
                if with_ties(clause):
                    self.fetch_with_ties(node, clause, scope)
            else:
                count = clause.expression
            if count is not None and not (
                isinstance(count, exp.Literal) and not count.is_string and count.name.isdigit()
            ):
                if not (isinstance(count, exp.Var) and count.name.upper() == "ALL"):
                    self.fail(f"{key.upper()} must be a non-negative integer literal", clause, "TYPE_MISMATCH")

    def fetch_with_ties(self, node: exp.Expression, fetch: exp.Fetch, scope: Scope | None) -> None:
        """FETCH FIRST n ROWS WITH TIES becomes QUALIFY rank() ... <= offset + n (dialect/with_ties.py)."""
        order = node.args.get("order")
        if order is None:
            self.fail("FETCH FIRST WITH TIES clause requires ORDER BY", fetch, "MISSING_ORDER_BY")
        keys = node.meta.get("rank_keys") if isinstance(node, exp.Select) else None
        if keys is None or node.args.get("distinct") is not None:
            of = "SELECT DISTINCT" if keys is not None else "a set operation or parenthesized query"
            self.unsupported(f"FETCH FIRST ... WITH TIES of {of}", fetch)
        if any(o.meta.get("key") for o in order.expressions) or any(k.find(exp.Window) for k in keys):
            self.unsupported("FETCH FIRST ... WITH TIES ordered by an array, a row or a window function", fetch)
        count, offset = fetch.args.get("count"), node.args.get("offset")
        rows = int(count.name) if isinstance(count, exp.Literal) and count.name.isdigit() else 1
        if offset is not None and isinstance(offset.expression, exp.Literal) and offset.expression.name.isdigit():
            rows += int(offset.expression.name)
        condition = rank_filter(keys, rows)
        node.set("qualify", exp.Qualify(this=condition))
        self.condition(condition, scope, "FETCH FIRST WITH TIES")
        node.set("limit", None)

    def order_item(self, ordered: exp.Ordered, outputs: list[OutCol], scope: Scope) -> None:
        target = ordered.this
        if isinstance(target, exp.Literal) and not target.is_string:
            index = int(target.name) if target.name.isdigit() else 0
            if not 1 <= index <= len(outputs):
                self.fail(f"ORDER BY position {target.name} is not in select list", target, "INVALID_COLUMN_REFERENCE")
            t = outputs[index - 1][2]
        else:
            t = self.expr(target, scope, {})
        if t.base in _UNORDERABLE:
            self.fail(f"Type {t} is not orderable, and therefore cannot be used in ORDER BY", target, "TYPE_MISMATCH")
        if t.base in ("array", "row"):  # Trino fails when sorting reaches a NULL element: checked per key
            if _nested_order(t) or isinstance(target, exp.Literal):
                self.unsupported(f"ORDER BY {'position of ' if isinstance(target, exp.Literal) else ''}{t}", target)
            ordered.meta["key"] = t

    def projection(self, node: exp.Select, scope: Scope) -> list[OutCol]:
        items: list[exp.Expression] = []
        for item in node.expressions:
            row = row_star.target(item, scope)
            if row is not None:
                items.extend(row_star.expand(self, item, row, scope, len(items)))
                continue
            whole = item.this if isinstance(item, exp.Aliases) else item
            star = (
                whole
                if isinstance(whole, exp.Star)
                else (whole if isinstance(whole, exp.Column) and isinstance(whole.this, exp.Star) else None)
            )
            if star is None:
                items.append(item)
                continue
            if isinstance(item, exp.Aliases) and isinstance(star, exp.Star):
                self.fail("Column aliases not supported", item, "NOT_SUPPORTED")
            columns = self.expand_star(star, scope)
            items.extend(row_star.rename(self, item, columns) if isinstance(item, exp.Aliases) else columns)
        node.set("expressions", items)
        outputs = []
        for index, item in enumerate(items):
            target = item.this if isinstance(item, exp.Alias) else item
            t = self.expr(target, scope, {})
            if isinstance(item, exp.Alias):
                name = _ident_name(item.args["alias"])
            elif isinstance(item, exp.Column):
                name = item.meta["ref"][1] if item.meta.get("resolved") else item.parts[-1].name
            elif isinstance(item, exp.Dot):
                name = item.name
            else:
                name = None
            outputs.append((name, name if name is not None else f"_col{index}", t))
            item.meta["t"] = t
        return outputs

    def expand_star(self, star: exp.Expression, scope: Scope) -> list[exp.Expression]:
        if isinstance(star, exp.Column):
            wanted = star.table.lower()
            sources = [s for s in scope.sources if s.name == wanted]
            if not sources:
                self.fail(f"Unable to resolve reference {star.table}", star, "TABLE_NOT_FOUND")
        else:
            if star.args.get("except_") or star.args.get("replace") or star.args.get("rename"):
                self.unsupported("SELECT * EXCEPT / REPLACE", star)
            sources = scope.sources
            if not sources:
                self.fail("SELECT * not allowed in queries without FROM clause", star, "COLUMN_NOT_FOUND")
        expanded: list[exp.Expression] = []
        for source in sources:
            for col in source.columns:
                ref = exp.column(
                    exp.to_identifier(col[1], quoted=True), table=exp.to_identifier(source.qualifier, quoted=True)
                )
                alias = f"_col{len(expanded)}" if col[0] is None else col[0]
                expanded.append(exp.Alias(this=ref, alias=exp.to_identifier(alias, quoted=True)))
                ref.meta["ref"] = (source.qualifier, col[1], ())
                if col[1].lower() in source.using:
                    ref.meta["sql"] = source.using[col[1].lower()]
                _set(ref, col[2])
                ref.meta["resolved"] = True
        return expanded

    def group(self, group: exp.Group, select: exp.Select, scope: Scope) -> None:
        if group.args.get("all"):
            self.unsupported("GROUP BY ALL", group)
        for key in ("grouping_sets", "cube", "rollup", "totals"):
            for item in group.args.get(key) or []:
                self.unsupported(
                    f"GROUP BY {key.upper().replace('_', ' ')}", item if isinstance(item, exp.Expression) else group
                )
        for item in group.expressions:
            if isinstance(item, (exp.Rollup, exp.Cube, exp.GroupingSets)):
                for key in grouping_keys(item):
                    if isinstance(key, exp.Literal) and not key.is_string:
                        self.unsupported(f"a column position in {_GROUPING_ELEMENT[type(item)]}", key)
                    self.expr(key, scope, {})
                continue
            if isinstance(item, exp.Literal) and not item.is_string:
                index = int(item.name) if item.name.isdigit() else 0
                if not 1 <= index <= len(select.expressions):
                    self.fail(f"GROUP BY position {item.name} is not in select list", item, "INVALID_COLUMN_REFERENCE")
                continue
            self.expr(item, scope, {})

    def condition(self, node: exp.Expression, scope: Scope, clause: str) -> None:
        t = self.expr(node, scope, {})
        if t.base not in ("boolean", "unknown"):
            self.fail(f"{clause} clause must evaluate to a boolean: actual type {t}", node, "TYPE_MISMATCH")

    def set_operation(self, node: exp.SetOperation, outer: Scope | None) -> list[OutCol]:
        if node.args.get("by_name"):  # Trino matches the common columns by name; DuckDB's BY NAME keeps all
            self.unsupported(f"{node.key.upper()} CORRESPONDING", node)
        scope = self._with(node, outer)
        branches = []
        for branch in (node.this, node.expression):
            branches.append(self.query(branch, scope))
        left, right = branches
        if len(left) != len(right):
            self.fail(
                f"{node.key.upper()} query has different number of fields: {len(left)}, {len(right)}",
                node,
                "TYPE_MISMATCH",
            )
        outputs = []
        for index, (a, b) in enumerate(zip(left, right)):
            common = tt.common_super_type(a[2], b[2])
            if common is None:
                self.fail(
                    f"column {index + 1} in {node.key.upper()} query has incompatible types: {a[2]}, {b[2]}",
                    node,
                    "TYPE_MISMATCH",
                )
            self.zoned_cast_in_utc_only(a[2], b[2], node, f"{node.key.upper()} of {a[2]} and {b[2]}")
            outputs.append((a[0], a[1], common))
        if node.args.get("distinct") or isinstance(node, (exp.Intersect, exp.Except)):
            for col in outputs:
                if col[2].base in _UNORDERABLE[:3]:
                    self.fail(
                        f"Type {col[2]} is not comparable, and therefore cannot be used in {node.key.upper()}",
                        node,
                        "TYPE_MISMATCH",
                    )
        node.meta["outputs"] = outputs
        self._modifiers(node, outputs, Scope(outer=scope))
        return outputs

    def values(self, node: exp.Values, outer: Scope | None) -> list[OutCol]:
        scope = Scope(outer=outer)
        rows = []
        for row in node.expressions:
            cells = row.expressions if isinstance(row, exp.Tuple) else [row]
            if len(cells) == 1 and self.expr(cells[0], scope, {}).base == "row":
                cells = self._row_fields(row, cells[0])
            rows.append([self.expr(c, scope, {}) for c in cells])
        width = len(rows[0])
        if any(len(r) != width for r in rows):
            self.fail("Values rows have mismatched sizes", node, "TYPE_MISMATCH")
        types = []
        for index in range(width):
            common = tt.common_super_type_of([r[index] for r in rows])
            if common is None:
                self.fail(
                    f"Values rows have mismatched types: {', '.join(str(r[index]) for r in rows)}",
                    node,
                    "TYPE_MISMATCH",
                )
            types.append(common)
        node.meta["types"] = types
        return [(None, f"_col{i}", t) for i, t in enumerate(types)]

    def _row_fields(self, row: exp.Expression, cell: exp.Expression) -> list[exp.Expression]:
        """A VALUES item of a row type is one column per field in Trino (StatementAnalyzer.visitValues);
        written as ROW(...) it becomes those fields, any other row-typed item is refused."""
        if not (isinstance(cell, exp.Anonymous) and cell.name.upper() == "ROW"):
            self.unsupported("a VALUES item of a row type that is not ROW(...) (Trino makes each field a column)", cell)
        fields = list(cell.expressions)
        (row if isinstance(row, exp.Tuple) else cell).replace(exp.Tuple(expressions=fields))
        return fields

    # --- FROM -----------------------------------------------------------------------------------
    def relation(self, node: exp.Expression, scope: Scope, lateral_scope: Scope | None = None) -> None:
        """Add the relation `node` (table, derived table, VALUES, UNNEST) to `scope.sources`."""
        alias = node.args.get("alias")
        alias_name = alias.name.lower() if alias is not None and alias.name else None
        column_names = [_ident_name(c) for c in alias.columns] if alias is not None and alias.columns else None
        if isinstance(node, exp.Table):
            if isinstance(node.this, (exp.Anonymous, exp.Func)):
                self.unsupported(
                    f"table function '{node.this.name if isinstance(node.this, exp.Anonymous) else node.this.key}'",
                    node,
                )
            if node.args.get("sample"):
                self.unsupported("TABLESAMPLE", node)
            if node.args.get("joins") or node.args.get("pivots"):
                self.unsupported("table sampling or pivot", node)
            name = node.name.lower()
            parts = [p.name.lower() for p in (node.args.get("catalog"), node.args.get("db")) if p is not None]
            cte = scope.cte(name) if not parts else None
            if cte is not None:
                cols = cte
            else:
                key = ".".join(parts + [name])
                if key not in self.schema:
                    self.fail(f"Table '{key}' does not exist", node, "TABLE_NOT_FOUND")
                cols = [(c, c, t) for c, t in self.schema[key]]
            qualifier = alias_name or name
            if alias is None:
                node.set("alias", exp.TableAlias(this=exp.to_identifier(qualifier, quoted=True)))
        elif isinstance(node, exp.Subquery):
            cols = self.query(node.this, lateral_scope or scope.derived())
            self._modifiers(node, cols, scope)
            qualifier = alias_name or self.fresh_alias()
            if alias is None:
                node.set("alias", exp.TableAlias(this=exp.to_identifier(qualifier, quoted=True)))
        elif isinstance(node, exp.Values):
            cols = self.values(node, lateral_scope or scope.derived())
            qualifier = alias_name or self.fresh_alias()
            if alias is None or not alias.columns:
                node.set(
                    "alias",
                    exp.TableAlias(
                        this=exp.to_identifier(qualifier, quoted=True),
                        columns=[exp.to_identifier(c[1], quoted=True) for c in cols],
                    ),
                )
        elif isinstance(node, exp.Unnest):
            cols = self.unnest(node, scope, column_names)
            qualifier = alias_name or self.fresh_alias()
            node.meta["qualifier"] = qualifier
            column_names = None
        elif isinstance(node, exp.Lateral):
            if not isinstance(node.this, exp.Subquery):
                self.unsupported("LATERAL", node)
            cols = self.query(node.this.this, scope)
            qualifier = alias_name or self.fresh_alias()
            if alias is None or (isinstance(node.this.this, exp.Values) and not alias.columns):
                columns = [exp.to_identifier(c[1], quoted=True) for c in cols]  # VALUES names them _col0, ...
                node.set(
                    "alias",
                    exp.TableAlias(
                        this=exp.to_identifier(qualifier, quoted=True),
                        columns=columns if isinstance(node.this.this, exp.Values) else [],
                    ),
                )
        else:
            self.unsupported(f"FROM item {node.key.upper()}", node)
        if column_names is not None:
            if len(column_names) != len(cols):
                self.fail(
                    f"Column alias list has {len(column_names)} entries but '{qualifier}' has {len(cols)} columns "
                    "available",
                    alias,
                    "MISMATCHED_COLUMN_ALIASES",
                )
            cols = [(n, n, c[2]) for n, c in zip(column_names, cols)]
        source = Source(alias_name or (node.name.lower() if isinstance(node, exp.Table) else None), qualifier, cols)
        if any(s.name is not None and s.name == source.name for s in scope.sources):
            self.fail(f"Duplicate relation name '{source.name}' in FROM clause", node, "DUPLICATE_NAMED_QUERY")
        scope.sources.append(source)

    def unnest(self, node: exp.Unnest, scope: Scope, names: list[str] | None) -> list[OutCol]:
        lateral = Scope(scope.sources, scope.outer, scope.ctes)
        offset = node.args.get("offset")
        if isinstance(offset, exp.Identifier) and names is not None:
            names = names + [_ident_name(offset)]
        cols: list[OutCol] = []
        element_columns = []
        for arg in node.expressions:
            t = self.expr(arg, lateral, {})
            if t.base == "array":
                element = t.element
                if element.base == "row":
                    fields = [(n, f) for n, f in element.args]
                    element_columns.append(fields)
                    cols.extend((n, n or "", f) for n, f in fields)
                else:
                    element_columns.append([(None, element)])
                    cols.append((None, "", element))
            elif t.base == "map":
                element_columns.append([(None, t.args[0]), (None, t.args[1])])
                cols.extend([(None, "", t.args[0]), (None, "", t.args[1])])
            else:
                self.fail(f"Cannot unnest type: {t}", arg, "TYPE_MISMATCH")
        if node.args.get("offset"):
            cols.append((None, "", tt.BIGINT))
        if names is not None:
            if len(names) != len(cols):
                self.fail(
                    f"Column alias list has {len(names)} entries but UNNEST has {len(cols)} columns available",
                    node.args["alias"],
                    "MISMATCHED_COLUMN_ALIASES",
                )
            cols = [(n, n, c[2]) for n, c in zip(names, cols)]
        else:
            cols = [(c[0], c[0] or f"_col{i}", c[2]) for i, c in enumerate(cols)]
        node.meta["elements"] = element_columns
        node.meta["names"] = [c[1] for c in cols]
        return cols

    def join(self, join: exp.Join, scope: Scope) -> None:
        kind = (join.args.get("kind") or "").upper()
        if (join.args.get("method") or "").upper() == "NATURAL":  # StatementAnalyzer.visitJoin refuses it so
            self.fail("Natural join not supported", join, "NOT_SUPPORTED")
        if (
            kind in ("SEMI", "ANTI", "ASOF", "POSITIONAL")
            or join.args.get("method")
            or join.args.get("match_condition")
        ):
            self.unsupported(f"{kind or join.args.get('method')} JOIN", join)
        self.relation(
            join.this, scope, lateral_scope=scope if isinstance(join.this, (exp.Unnest, exp.Lateral)) else None
        )
        on = join.args.get("on")
        if on is not None:
            self.condition(on, scope, "JOIN ON")
        using = join.args.get("using")
        if using:
            self.join_using(join, using, scope)

    def join_using(self, join: exp.Join, using: list, scope: Scope) -> None:
        """JOIN ... USING (k): each k becomes one unqualified column of the common type, listed first by
        `*` (the left value, the right one for RIGHT JOIN, coalesced for FULL JOIN); `t.k` no longer
        resolves (io.trino.sql.analyzer.StatementAnalyzer.analyzeJoinUsing, io.trino.sql.query.TestJoinUsing)."""
        side = (join.args.get("side") or "").upper()
        joined: list[OutCol] = []
        sql: dict[str, str] = {}
        for ident in using:
            name = ident.name.lower()
            if name in sql:
                self.fail(
                    f"Column '{ident.name}' appears multiple times in USING clause", ident, "DUPLICATE_COLUMN_NAME"
                )
            left = [(s, c) for s in scope.sources[:-1] for c in s.find(name)]
            right = [(scope.sources[-1], c) for c in scope.sources[-1].find(name)]
            if not right or not left:
                self.fail(
                    f"Column '{ident.name}' is missing from {'right' if not right else 'left'} side of join",
                    ident,
                    "COLUMN_NOT_FOUND",
                )
            common = tt.common_super_type(left[0][1][2], right[0][1][2])
            if common is None:
                self.fail(f"Column types of '{ident.name}' in USING do not match", ident, "TYPE_MISMATCH")
            if common.base == "char" and left[0][1][2] != right[0][1][2]:  # the join keys would need padding
                self.unsupported(f"JOIN USING ({ident.name}) of {left[0][1][2]} and {right[0][1][2]}", ident)
            self.zoned_cast_in_utc_only(left[0][1][2], right[0][1][2], ident, f"JOIN USING ({ident.name})")
            values = [_using_value(source, col, common) for source, col in (left[0], right[0])]
            sql[name] = {"RIGHT": values[1], "FULL": f"COALESCE({values[0]}, {values[1]})"}.get(side, values[0])
            joined.append((left[0][1][0], left[0][1][1], common))
        for index, source in enumerate(scope.sources):
            kept = [c for c in source.columns if c[0] is None or c[0].lower() not in sql]
            scope.sources[index] = Source(source.name, source.qualifier, kept, source.using)
        scope.sources.insert(0, Source(None, scope.sources[0].qualifier, joined, sql))

    # --- expressions ----------------------------------------------------------------------------
    def expr(self, node: exp.Expression, scope: Scope, env: dict[str, TType]) -> TType:
        """The Trino type of expression `node` (stored on it), analyzing its children."""
        handler = _HANDLERS.get(type(node))
        if type(node) in _DUCKDB_SYNTAX:
            self.fail(f"mismatched input: {_DUCKDB_SYNTAX[type(node)]} is not Trino syntax", node, "SYNTAX_ERROR")
        if handler is None:
            self.unsupported(trino_name(node), node)
        t = handler(self, node, scope, env)
        zoned_nanos.check_use(self, node, t)
        if zoned_nanos.is_zoned_nanos(t) and not zoned_nanos.produces(node):
            self.unsupported(
                f"{t} (lakegate keeps zoned timestamps in microseconds, past them only from_unixtime_nanos)", node
            )
        if t.base == "timestamp" and t.args[0] > 9:
            self.unsupported(f"{t} (lakegate keeps nanoseconds at most; digits past them would be dropped)", node)
        self._check_nanosecond_use(node)
        _check_char_use(self, node)
        return _set(node, t)

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

    def column(self, node: exp.Column, scope: Scope, env: dict[str, TType]) -> TType:
        if node.meta.get("resolved"):
            return ttype(node)
        parts = [p.name for p in node.parts]
        quoted = [p.quoted for p in node.parts]
        lower = [p.lower() for p in parts]
        # lambda parameter with field access: x.name
        if lower[0] in env:
            t = env[lower[0]]
            node.meta["ref"] = (None, lower[0], ())
            node.meta["lambda"] = True
            return self._fields(node, t, parts[1:], quoted[1:])
        if scope.outputs is not None and len(parts) == 1:
            # ORDER BY sees the select's output names first
            matches = [c for c in scope.outputs if c[0] is not None and c[0].lower() == lower[0]]
            if len(matches) == 1:
                node.meta["ref"] = (None, matches[0][1], ())
                node.meta["output"] = True
                return matches[0][2]
        search: Scope | None = scope
        while search is not None:
            # [schema.]table.column[.field ...] or column[.field ...]: the longest qualifier wins
            for split in range(min(len(parts) - 1, 2), -1, -1):
                sources = [s for s in search.sources if s.name == lower[split - 1]] if split else search.sources
                matches = [(s, c) for s in sources for c in s.find(lower[split])]
                if len(matches) > 1:
                    self.fail(f"Column '{parts[split]}' is ambiguous", node, "AMBIGUOUS_NAME")
                if matches:
                    source, col = matches[0]
                    node.meta["ref"] = (source.qualifier, col[1], ())
                    if col[1].lower() in source.using:
                        node.meta["sql"] = source.using[col[1].lower()]
                    return self._fields(node, col[2], parts[split + 1 :], quoted[split + 1 :])
            search = search.outer
        self.fail(f"Column '{'.'.join(parts)}' cannot be resolved", node, "COLUMN_NOT_FOUND")

    def _fields(self, node: exp.Expression, t: TType, fields: list[str], quoted: list[bool]) -> TType:
        path = []
        for name, q in zip(fields, quoted):
            t, real = self.field(t, name, q, node)
            path.append(real)
        ref = node.meta["ref"]
        node.meta["ref"] = (ref[0], ref[1], tuple(path))
        return t

    def field(self, t: TType, name: str, quoted: bool, node: exp.Expression) -> tuple[TType, str]:
        if t.base != "row":
            self.fail(f"Expression of type {t} is not a row; cannot dereference '{name}'", node, "TYPE_MISMATCH")
        for field_name, field_type in t.args:
            if field_name is not None and field_name.lower() == name.lower():
                return field_type, field_name
        self.fail(f"Column '{name}' cannot be resolved", node, "COLUMN_NOT_FOUND")

    def function(self, node: exp.Anonymous, scope: Scope, env: dict[str, TType], window: bool = False) -> TType:
        name = node.name.lower()
        spec = registry.SUPPORTED.get(name)
        if spec is None:
            if name in registry.REJECTED:
                self.fail(
                    f"unsupported in lakegate: function '{name}': {registry.REJECTED[name]}",
                    node,
                    "NOT_SUPPORTED",
                )
            self.fail(f"Function '{name}' not registered", node, "FUNCTION_NOT_FOUND")
        if spec.kind == "window" and not window:
            self.fail(f"Window function {name} requires an OVER clause", node, "MISSING_OVER")
        args = list(node.expressions)
        if len(args) == 1 and isinstance(args[0], exp.Distinct):
            if spec.kind != "aggregate":
                self.fail("DISTINCT is not supported for non-aggregation functions", node, "FUNCTION_NOT_AGGREGATE")
            node.meta["distinct"] = True
            args = list(args[0].expressions)
        at = next((i for i in (0, len(args) - 1) if args and isinstance(args[i], exp.Order)), None)
        if at is not None:  # f(x ORDER BY ...), f(k, v ORDER BY ...), and listagg's WITHIN GROUP
            if spec.kind != "aggregate":
                self.fail("ORDER BY is only allowed in aggregation functions", node, "FUNCTION_NOT_AGGREGATE")
            order = args[at]
            node.meta["order"] = order
            args[at] = order.this
            for ordered in order.expressions:
                self.expr(ordered.this, scope, env)
        if any(isinstance(a, exp.Star) for a in args) and name != "count":
            self.fail("'*' is only allowed in count(*)", node, "SYNTAX_ERROR")
        node.meta["args"] = args
        node.meta["spec"] = spec
        t = spec.infer(Call(self, node, name, args, scope, env))
        if name in _MICROS_READERS:
            args[:] = [floor_micros(arg) for arg in args]
        return t


def _same_field_or_inside(ref: tuple, key: exp.Expression) -> bool:
    """Whether a column reference (qualifier, column, field path) is GROUP BY key `key`, a column,
    or one of its fields."""
    if not (isinstance(key, exp.Column) and key._meta and key.meta.get("ref") is not None):
        return False
    qualifier, column, path = key.meta["ref"]
    return ref[:2] == (qualifier, column) and ref[2][: len(path)] == path


def _ident_name(ident: exp.Expression) -> str:
    """Trino's output name for an identifier: as written, quoted or not (names are matched without
    regard to case)."""
    return ident.name


_GROUPING_ELEMENT = {exp.Rollup: "ROLLUP", exp.Cube: "CUBE", exp.GroupingSets: "GROUPING SETS"}


def grouping_keys(element: exp.Expression) -> list[exp.Expression]:
    """The expressions a ROLLUP, CUBE or GROUPING SETS element groups by (sets and their parentheses
    unwrapped; `()` holds none)."""
    keys = []
    for item in element.expressions:
        if isinstance(item, (exp.Tuple, exp.Paren)):
            keys.extend(
                grouping_keys(exp.Tuple(expressions=[item.this]))
                if isinstance(item, exp.Paren)
                else grouping_keys(item)
            )
        elif isinstance(item, (exp.Rollup, exp.Cube, exp.GroupingSets)):
            keys.extend(grouping_keys(item))
        else:
            keys.append(item)
    return keys


#: DuckDB expressions sqlglot's Trino reader accepts that Trino's grammar has not (trinodb/trino
#: core/trino-grammar/src/main/antlr4/io/trino/grammar/sql/SqlBase.g4), named as written.
_DUCKDB_SYNTAX = {
    exp.ILike: "ILIKE",
    exp.Glob: "GLOB",
    exp.SimilarTo: "SIMILAR TO",
    exp.Comprehension: "a list comprehension [x FOR x IN ...]",
    exp.Slice: "an array slice a[i:j]",
    exp.BitwiseXor: "the '^' operator",
    exp.PropertyEQ: "the ':=' operator",
}


# --- expression handlers ---------------------------------------------------------------------------
Handler = Callable[[Analyzer, exp.Expression, Scope, dict], TType]
_HANDLERS: dict[type, Handler] = {}


def handles(*types: type) -> Callable[[Handler], Handler]:
    def register(fn: Handler) -> Handler:
        for t in types:
            _HANDLERS[t] = fn
        return fn

    return register


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


@handles(*_COMPARISONS)
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
        _check_char_subquery(a, node, left, cols[0][2], common)
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
    if type(node) not in (exp.EQ, exp.NEQ) and _nested_order(common):
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


def _nested_order(t: TType) -> bool:
    """An array or row whose elements are themselves arrays, maps or rows: the ordering of
    transforms.ordered_comparison checks one level of NULL elements only."""
    members = [t.element] if t.base == "array" else [f for _, f in t.args] if t.base == "row" else []
    return any(m.base in ("array", "map", "row") for m in members)


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
        _check_char_subquery(a, node, left, cols[0][2], common)
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
    if _nested_order(common):
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


@handles(*_ARITHMETIC)
def _arithmetic(a: Analyzer, node, scope, env):
    op = _ARITHMETIC[type(node)]
    left, right = a.expr(node.this, scope, env), a.expr(node.expression, scope, env)
    result = tt.arithmetic_type(op, left, right)
    if result is None:
        result = _temporal_arithmetic(op, left, right)
    if result is None and op == "-" and left.base == right.base == "time":
        a.unsupported(f"{left} - {right} (the interval between two times)", node)
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
    if op in "+-" and left.base == right.base and left.base in intervals:
        return left
    if op == "-" and left.base == right.base and left.base in ("timestamp", "timestamp_tz"):
        return tt.INTERVAL_DS
    return None


@handles(exp.DPipe)
def _dpipe(a: Analyzer, node, scope, env):
    left, right = a.expr(node.this, scope, env), a.expr(node.expression, scope, env)
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
        return _char_concat(a, node, [node.this, node.expression])
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
        results.append(_set(branch, a.expr(branch.args["true"], scope, env)))
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


def _typed_literal(a: Analyzer, node: exp.Cast) -> bool:
    """Whether a Cast is Trino's typed literal (`DECIMAL '1.50'`, `TIMESTAMP '...'`): sqlglot parses
    both the same way; the source text tells them apart."""
    literal = node.this
    if not (isinstance(node, exp.Cast) and isinstance(literal, exp.Literal) and literal.is_string and literal._meta):
        return False
    before = a.sql[: literal._meta.get("start", 0)].rstrip()
    return bool(before) and (before[-1].isalnum() or before[-1] in ")_")


@handles(exp.Cast, exp.TryCast)
def _cast(a: Analyzer, node, scope, env):
    source = a.expr(node.this, scope, env)
    try:
        target = tt.from_datatype(node.args["to"])
    except ValueError as error:
        if node.args["to"].this == exp.DataType.Type.TIMETZ:
            a.unsupported(times.with_time_zone(node, _typed_literal(a, node)), node)
        a.unsupported(f"cast to {error}", node)
    if _typed_literal(a, node):
        text = node.this.name.strip()
        if target.base == "char":  # CHAR 'abc ': char(4), of the literal's characters (spaces included)
            target = TType("char", (len(node.this.name),))
        if target.is_decimal:
            try:
                target = tt.decimal_literal_type(text)
            except ValueError:
                a.fail(f"'{text}' is not a valid decimal literal", node, "INVALID_LITERAL")
        elif target.base == "timestamp" and re.search(
            r"[0-9]:[0-9]{2}(:[0-9]{2}([.][0-9]*)?)?\s*([A-Za-z]|[+-][0-9])", text
        ):
            a.unsupported("timestamp literal with a time zone", node)
        elif target.base == "time":
            target = _time_literal_type(a, node, text)
    if source.base == "char" and target.base == "varchar":
        node.meta["from"] = source
        return target  # the padded text, cut to the varchar's length (CharacterStringCasts.charToVarcharCast)
    if _has_char(source) or _has_char(target):
        if source.base not in ("varchar", "char", "unknown") or target.base != "char":
            a.unsupported(f"CAST({source} AS {target})", node)
        if target.args[0] > 65536:  # CharType.MAX_LENGTH
            a.unsupported(f"{target} (Trino's char holds at most 65536 characters)", node)
        node.meta["from"] = source
        return target  # truncated or padded with spaces to the length (CharacterStringCasts.varcharToCharCast)
    if target.base == "varbinary" and source.base in ("varchar", "varbinary", "unknown"):
        node.meta["from"] = source
        return target  # the UTF-8 bytes of the text (VarcharOperators.castToVarbinary)
    if "json" in (source.base, target.base) and source != target:
        _check_json_cast(a, node, source, target)
    elif "time" in (source.base, target.base):
        _check_time_cast(a, node, source, target)
    elif target.base in ("time_tz", "uuid", "varbinary", "map"):
        a.unsupported(f"cast to {target}", node)
    if target.base == "timestamp_tz":
        target = tt.timestamp(target.args[0], True, _cast_zone(a, node, source))
    else:
        a.zones(source, node, f"CAST to {target}")
    if not castable(source, target) and any(t.base == "time" for t in tt.inner_types(target)):
        a.unsupported(f"CAST({source} AS {target})", node)  # nested time(p > 6) or timestamp(p > 6)
    if not castable(source, target):
        a.fail(f"Cannot cast {source} to {target}", node, "TYPE_MISMATCH")
    node.meta["from"] = source
    return target


def _time_literal_type(a: Analyzer, node: exp.Cast, text: str) -> TType:
    """TIME '01:02:03.456' is time(p), p its fraction digits (DateTimes.extractTimePrecision)."""
    match = re.fullmatch(times.TIME_TEXT[1:-1], node.this.name)
    if match is None or int(match[1]) > 23 or int(match[2]) > 59 or int(match[4] or 0) > 59:
        a.fail(f"'{text}' is not a valid TIME literal", node, "INVALID_LITERAL")
    return TType("time", (len(match[6] or ""),))


def _check_time_cast(a: Analyzer, node: exp.Cast, source: TType, target: TType) -> None:
    """time(p <= 6) from varchar, time and timestamp(p <= 6), and to varchar (TimeOperators,
    TimestampToTimeCast); the casts that need the session's date or zone are refused."""
    for t in (source, target):
        if t.base == "time" and t.args[0] > 6:
            a.unsupported(f"{t} (time with more than microsecond precision)", node)
    if source.base == "timestamp" and source.args[0] > 6:
        a.unsupported(f"CAST({source} AS {target}) (more than microsecond precision)", node)
    if source.base == "time" and target.base in ("timestamp", "timestamp_tz", "time_tz"):
        a.unsupported(f"CAST({source} AS {target}) (it depends on the session's date and zone)", node)
    if target.base == "time" and source.base in ("timestamp_tz", "time_tz"):
        a.unsupported(f"CAST({source} AS {target})", node)


def _check_json_cast(a: Analyzer, node: exp.Cast, source: TType, target: TType) -> None:
    """Casts to and from json (JsonUtil.canCastToJson / canCastFromJson): Trino's, less those
    lakegate does not translate (trino_types.castable_to_json / castable_from_json), refused."""
    if target.base == "json":
        if not tt.castable_to_json(source):
            a.unsupported(f"CAST({source} AS json)", node)
    elif not tt.castable_from_json(target):
        a.unsupported(f"CAST(json AS {target})", node)


#: The zone at the end of a timestamp text: a region name or an offset.
_ZONE_SUFFIX = re.compile(
    r"[0-9]:[0-9]{2}(?::[0-9]{2}(?:[.][0-9]*)?)?\s*([A-Za-z][A-Za-z0-9_/+-]*|[+-][0-9]{1,2}(?::?[0-9]{2})?)\s*$"
)


def _cast_zone(a: Analyzer, node: exp.Cast, source: TType) -> str | None:
    """The zone of a value cast to timestamp with time zone: a timestamp with time zone keeps its own,
    a text literal has the zone it names (its wall time is kept in node.meta["local"]), anything else
    takes the session zone (io.trino.type.TimestampToTimestampWithTimeZoneCast,
    DateTimes.parseTimestampWithTimeZone)."""
    if source.base == "timestamp_tz":
        return tt.zone_of(source)
    if source.base != "varchar":
        return a.time_zone
    if not (isinstance(node.this, exp.Literal) and node.this.is_string):
        a.unsupported(
            "CAST of a non-literal varchar to timestamp with time zone (each value's zone would be lost)", node
        )
    text = node.this.name.strip()
    suffix = _ZONE_SUFFIX.search(text)
    if suffix is None:
        node.meta["local"] = text
        return a.time_zone
    try:
        zone = zones.canonical(suffix.group(1))
    except ValueError as error:
        a.fail(str(error), node, "NOT_SUPPORTED")
    node.meta["local"] = text[: suffix.start(1)].strip()
    return zone


def castable(source: TType, target: TType) -> bool:
    """Whether Trino has a CAST from `source` to `target` (the subset lakegate translates)."""
    if source == target or source.is_unknown:
        return True
    if "json" in (source.base, target.base):
        return tt.castable_to_json(source) if target.base == "json" else tt.castable_from_json(target)
    scalar = ("boolean", "varchar")
    if source.is_numeric or source.base in scalar:
        if target.is_numeric or target.base in scalar:
            return True
    if source.base in ("varchar", "date", "timestamp", "timestamp_tz") and target.base in (
        "varchar",
        "date",
        "timestamp",
        "timestamp_tz",
    ):
        return True
    if target.base == "time" and source.base in ("varchar", "time", "timestamp"):  # p <= 6 (times.py)
        return max(target.args[0], source.args[0] if source.base != "varchar" else 0) <= 6
    if source.base == "time" and target.base == "varchar":
        return True
    if source.base == target.base == "array":
        return castable(source.element, target.element)
    if source.base == target.base == "row" and len(source.args) == len(target.args):
        return all(castable(s[1], t[1]) for s, t in zip(source.args, target.args))
    return False


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
        a.unsupported("row subscript (use the field name)", node)
    a.fail(f"Cannot use subscript on {container}", node, "TYPE_MISMATCH")


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
    if unit in ("TIMEZONE_HOUR", "TIMEZONE_MINUTE") and t.base == "timestamp_tz":
        a.zone(t, node, f"EXTRACT({unit} FROM ...)")
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
    _set(inner, t)
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
    RANGE offsets: `_check_range_offset`. Not translated: EXCLUDE."""
    kind = spec.args.get("kind", "").upper()
    if spec.args.get("exclude"):
        a.unsupported("window frame EXCLUDE", spec)
    offsets = [b for b in (spec.args.get("start"), spec.args.get("end")) if isinstance(b, exp.Expression)]
    if kind == "GROUPS" and offsets and not order:
        a.fail("Window frame of type GROUPS PRECEDING or FOLLOWING requires ORDER BY", spec, "MISSING_ORDER_BY")
    for bound in offsets:
        bound_type = a.expr(bound, scope, env)
        if kind == "RANGE":
            _check_range_offset(a, order, bound, bound_type)
        elif not bound_type.is_integral:
            a.fail(f"Window frame offset must be an integer: {bound_type}", bound, "TYPE_MISMATCH")


def a_literal_number(node: exp.Expression) -> exp.Literal | None:
    """`node` when it is a number literal."""
    return node if isinstance(node, exp.Literal) and not node.is_string else None


@handles(exp.Grouping)
def _grouping(a: Analyzer, node, scope, env):
    """grouping(k1, ..., kn) -> bigint: bit i (from the right) is 1 when key k(n-i) is not grouped
    (docs/src/main/sphinx/functions/aggregate.md); the arguments are checked against the GROUP BY
    keys with the rest of the query (Analyzer.check_grouping)."""
    for argument in node.expressions:
        a.expr(argument, scope, env)
    a.groupings.append(node)
    if len(node.expressions) > 63:
        a.fail("GROUPING supports up to 63 column arguments", node, "TOO_MANY_ARGUMENTS")
    return tt.BIGINT


def _check_range_offset(a: Analyzer, keys: list, bound: exp.Expression, offset: TType) -> None:
    """A RANGE frame offset, as Trino's StatementAnalyzer checks it: one sort key, numeric with a
    numeric offset or date/timestamp with an interval. lakegate takes a non-negative literal offset
    over a double or integral key (an integer offset) or a date/timestamp key: what DuckDB frames alike."""
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
    literal = bound.this if isinstance(bound, exp.Interval) else bound
    if (
        not isinstance(literal, exp.Literal)
        or literal.this.strip().startswith("-")
        or key.base in ("decimal", "real", "timestamp_tz")
        or (key.is_integral and not offset.is_integral)
        or (key.base == "timestamp" and key.args[0] > 6)  # DuckDB's frame bound would be in microseconds
    ):
        a.unsupported(f"RANGE frame with offset {bound.sql(dialect='trino')} over a {key} sort key", bound)


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
    return _set(call, a.function(call, scope, env))


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
    if not (isinstance(zone, exp.Literal) and zone.is_string):
        a.unsupported("AT TIME ZONE with a non-literal zone", node)
    if t.base not in ("timestamp", "timestamp_tz"):
        a.fail(
            f"Type of value must be a time or timestamp with or without time zone (actual {t})", node, "TYPE_MISMATCH"
        )
    a.expr(zone, scope, env)
    return tt.timestamp(t.args[0], True, a.zone_literal(zone))


@handles(exp.Substring)
def _substring(a: Analyzer, node, scope, env):
    t = a.expr(node.this, scope, env)
    if t.base in ("varbinary", "char"):  # SUBSTRING(x FROM s [FOR n]) is the substr(x, ...) call
        args = [node.this] + [node.args[k] for k in ("start", "length") if node.args.get(k) is not None]
        call = exp.Anonymous(this="substr", expressions=args)
        node.replace(call)
        node.meta["replaced_by"] = call
        return _set(call, a.function(call, scope, env))
    for key in ("start", "length"):
        arg = node.args.get(key)
        if arg is not None and not (a.expr(arg, scope, env).is_integral or ttype(arg).is_unknown):
            a.fail("Unexpected parameters for function substr", node, "FUNCTION_NOT_FOUND")
    if t.base not in ("varchar", "unknown"):
        a.fail(f"Unexpected parameters ({t}) for function substr", node, "FUNCTION_NOT_FOUND")
    return t if t.base == "varchar" else tt.VARCHAR


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
        return _set(call, a.function(call, scope, env))
    if t.base not in ("varchar", "unknown"):
        a.fail(f"Unexpected parameters ({t}) for function trim", node, "FUNCTION_NOT_FOUND")
    return t if t.base == "varchar" else tt.VARCHAR


@handles(exp.StrPosition)
def _position(a: Analyzer, node, scope, env):
    for key in ("this", "substr"):
        t = a.expr(node.args[key], scope, env)
        if t.base not in ("varchar", "unknown"):
            a.fail("Unexpected parameters for function strpos", node, "FUNCTION_NOT_FOUND")
    if node.args.get("position") is not None or node.args.get("occurrence") is not None:
        a.unsupported("position with a start", node)
    return tt.BIGINT


def analyze(
    tree: exp.Expression, schema: dict[str, list[tuple[str, TType]]], sql: str, time_zone: str = zones.UTC
) -> list[OutCol]:
    """Resolve names and infer Trino types over the statement `tree` in the session zone `time_zone`;
    its output columns."""
    analyzer = Analyzer(schema, sql, time_zone)
    outputs = analyzer.query(tree, None)
    for name, _, t in outputs:
        _check_output_zone(analyzer, tree, name, t)
    return outputs


def _check_output_zone(a: Analyzer, tree: exp.Expression, name: str | None, t: TType) -> None:
    """A result column shows each timestamp with time zone in its zone: refuse one whose values do not all
    carry one zone, and zoned values other than UTC nested in an array, map or row (shown in UTC)."""
    if t.base == "timestamp_tz":
        a.zone(t, tree, f"the result column {name or ''}".rstrip())
    for inner in tt.inner_types(t):
        if inner.base == "timestamp_tz" and tt.zone_of(inner) != zones.UTC:
            a.unsupported(
                f"a result column of type {t} holding timestamps with time zone "
                f"{tt.zone_of(inner) or 'of several zones'} (lakegate shows nested ones in UTC only)",
                tree,
            )
