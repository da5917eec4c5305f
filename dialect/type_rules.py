"""What a type rule of the analysis sees: a node's Trino type (`ttype`), a function call under
analysis (`Call`) and the names it can see (NameScope, Source), the FloorMicros node, and the table of
rules by expression kind (`handles`), which the infer_* modules and the function pages fill.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NoReturn, Protocol

from sqlglot import exp

from lakegate.dialect import trino_types as tt
from lakegate.dialect.trino_types import TType


class Analysis(Protocol):
    """What the type rules, the checks and the mixins ask of the Analyzer (lakegate.dialect.analyzer,
    which imports them); `time_zone` is the session zone."""

    time_zone: str

    def fail(self, message: str, node: exp.Expression, error_name: str = ...) -> NoReturn: ...

    def unsupported(self, what: str, node: exp.Expression) -> NoReturn: ...

    def expr(self, node: exp.Expression, scope: NameScope, env: dict[str, TType]) -> TType: ...

    def zone(self, t: TType, node: exp.Expression, what: str) -> str: ...

    def zone_literal(self, node: exp.Literal) -> str: ...

    def query(self, node: exp.Expression, outer: NameScope | None) -> list[OutCol]: ...


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
class NameScope:
    """The names visible to an expression: FROM sources, then enclosing queries' (correlation)."""

    sources: list[Source] = field(default_factory=list)
    outer: NameScope | None = None
    ctes: dict[str, list[OutCol]] = field(default_factory=dict)
    outputs: list[OutCol] | None = None  # select outputs, visible in ORDER BY

    def derived(self) -> NameScope:
        """The scope of a derived table in this FROM: this query's CTEs, not its other sources."""
        return NameScope(outer=self.outer, ctes=self.ctes)

    def cte(self, name: str) -> list[OutCol] | None:
        scope: NameScope | None = self
        while scope is not None:
            if name in scope.ctes:
                return scope.ctes[name]
            scope = scope.outer
        return None


def ttype(node: exp.Expression) -> TType:
    """The Trino type the analysis attached to an expression."""
    return node.meta["t"]


def set(node: exp.Expression, t: TType) -> TType:
    node.meta["t"] = t
    return t


class Call:
    """What a function's type rule sees: the call, its arguments and their types."""

    def __init__(
        self,
        analyzer: Analysis,
        node: exp.Expression,
        name: str,
        args: list[exp.Expression],
        scope: NameScope,
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
        return set(node, self.analyzer.expr(node.this, self.scope, {**self.env, **dict(zip(names, params))}))

    def fail(self, message: str, error_name: str = "TYPE_MISMATCH") -> NoReturn:
        self.analyzer.fail(message, self.node, error_name)

    def mismatch(self) -> NoReturn:
        types = ", ".join("<function>" if t is None else str(t) for t in self.types)
        self.fail(f"Unexpected parameters ({types}) for function {self.name}", "FUNCTION_NOT_FOUND")

    def literal(self, index: int) -> exp.Literal | None:
        """The argument at `index` when it is a literal (a parameter bound as a literal counts)."""
        node = self.args[index]
        while isinstance(node, exp.Paren):
            node = node.this
        if isinstance(node, exp.Neg) and isinstance(node.this, exp.Literal) and not node.this.is_string:
            return exp.Literal.number("-" + node.this.name)
        return node if isinstance(node, exp.Literal) else None


COMPARISONS = (exp.EQ, exp.NEQ, exp.GT, exp.GTE, exp.LT, exp.LTE, exp.NullSafeEQ, exp.NullSafeNEQ)
#: The expressions written for operands of every time type held in more than DuckDB's own types
#: (casts, comparisons, conditions, arithmetic, ordering, fields); each such type adds its own.
WIDE_TIME_OPERATIONS = (
    exp.Cast,
    exp.TryCast,
    *COMPARISONS,
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
)


class FloorMicros(exp.Expression):
    """A timestamp(7..9) argument floored to a microsecond timestamp(6) (a zoned one to timestamp(6) with
    time zone): what Trino's date and time functions read of a LongTimestamp (getEpochMicros). Added by
    the analysis, never written by users."""

    arg_types = {"this": True}


class ShownWide(exp.Expression):
    """A result column of timestamp(7..12) with time zone: its value and Trino's text of it (added by
    `finalize`, never written by users)."""

    arg_types = {"this": True}


def floor_micros(node: exp.Expression) -> exp.Expression:
    """`node` read as Trino's functions read a timestamp(7..9) or a timestamp(7..12) with time zone:
    floored to microseconds (the zone kept)."""
    t = node.meta.get("t") if node._meta else None
    if t is None or t.base not in ("timestamp", "timestamp_tz") or t.args[0] <= 6:
        return node
    floored = FloorMicros(this=node)
    set(floored, tt.with_precision(t, 6) if t.base == "timestamp_tz" else tt.timestamp(6))
    return floored


ARITHMETIC = {exp.Add: "+", exp.Sub: "-", exp.Mul: "*", exp.Div: "/", exp.Mod: "%"}

UNORDERABLE = ("json", "map", "varbinary", "unknown")


# --- expression handlers ---------------------------------------------------------------------------
Handler = Callable[[Analysis, exp.Expression, NameScope, dict], TType]

HANDLERS: dict[type, Handler] = {}


def handles(*types: type) -> Callable[[Handler], Handler]:
    def register(fn: Handler) -> Handler:
        for t in types:
            HANDLERS[t] = fn
        return fn

    return register
