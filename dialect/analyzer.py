"""The Analyzer: one walk over a parsed Trino query (its mixins resolve names, expand stars and
check what Trino checks), the Trino type of every expression by the rule of its kind (type_rules),
failures with their position in the SQL text, and the session zone.
"""

from __future__ import annotations

from typing import NoReturn

from sqlglot import exp

from lakegate.dialect import pico_times, registry, wide_timestamps, zones
from lakegate.dialect import trino_types as tt
from lakegate.dialect.analysis_checks import CHAR_TYPE, MICROS_READERS, Checks, check_char_use
from lakegate.dialect.errors import DialectError
from lakegate.dialect.guard import trino_name
from lakegate.dialect.name_resolution import Relations
from lakegate.dialect.star_expansion import StarExpansion
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import HANDLERS, Call, NameScope, floor_micros, position, set

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


class Analyzer(Relations, StarExpansion, Checks):
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
        if error_name in ("TYPE_MISMATCH", "FUNCTION_NOT_FOUND") and CHAR_TYPE.search(message):
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

    # --- expressions ----------------------------------------------------------------------------
    def expr(self, node: exp.Expression, scope: NameScope, env: dict[str, TType]) -> TType:
        """The Trino type of expression `node` (stored on it), analyzing its children."""
        handler = HANDLERS.get(type(node))
        if type(node) in _DUCKDB_SYNTAX:
            self.fail(f"mismatched input: {_DUCKDB_SYNTAX[type(node)]} is not Trino syntax", node, "SYNTAX_ERROR")
        if handler is None:
            self.unsupported(trino_name(node), node)
        t = handler(self, node, scope, env)
        wide_timestamps.check_use(self, node, MICROS_READERS)
        self._check_nanosecond_use(node)
        self.check_time_tz_use(node, t)
        pico_times.check_use(self, node, t)
        check_char_use(self, node)
        return set(node, t)

    def function(self, node: exp.Anonymous, scope: NameScope, env: dict[str, TType], window: bool = False) -> TType:
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
        call = Call(self, node, name, args, scope, env)
        try:
            t = spec.infer(call)
        except IndexError:  # the rule read an argument the call does not have: Trino finds no signature
            call.mismatch()
        if any(isinstance(a, exp.Lambda) and not (a._meta and "params" in a._meta) for a in args):
            call.mismatch()  # a lambda where the signature takes none
        if name in MICROS_READERS or name in wide_timestamps.ZONE_READERS:
            args[:] = [floor_micros(arg) for arg in args]
        return t
