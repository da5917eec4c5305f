"""Scopes: restrict every lake table a query reads to one batch, one job, or a list of batches.

The rewrite works on the Trino AST, so its result serves both backends: each reference to a lake
table becomes a filtered derived table with the reference's alias,

    FROM odom o   ->   FROM (SELECT * FROM odom WHERE batch_id = 'B' AND job_id = 'J') AS o

in every part of the query (joins, subqueries, set operations, CTE bodies), except where a CTE
of the same name is visible: a CTE shadows a table in the rest of its WITH (later CTEs and the
query body, including nested subqueries), not in its own body or earlier CTEs, unless the WITH is
RECURSIVE. Names compare case-insensitively, as Trino's do.

A dashboard or report metric's scope is a list of batches (`Scope.batches`): every lake table,
`metadata` and `metric_results` included, shows the rows of every job of those batches and nothing
else (`WHERE batch_id IN (...)`), so `JOIN metadata m ON t.batch_id = m.batch_id AND t.job_id =
m.job_id` finds each row's build; an empty list shows no rows. Which batches (a window of the
branch's, or a list given) is the caller's choice (`gateway/metrics/trends.py`).

A scope may also carry job statuses a dashboard session computed without writing them
(`Scope.statuses`): `metadata` then shows those statuses in place of the stored ones, so batch
metrics that count them agree with `lakegate metrics run` while the lake stays untouched.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from sqlglot import exp


@dataclass(frozen=True)
class Scope:
    """Which rows of the lake a query sees: one batch, one job of it, every job of `batches`, or
    everything (all None)."""

    batch_id: str | None = None
    job_id: str | None = None
    #: (job_id, job_metrics_status, job_conflated_status) that `metadata` shows instead of its own.
    statuses: tuple[tuple[str, str, str], ...] = ()
    #: The batches of a dashboard or report metric (with `batch_id` and `job_id` None).
    batches: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if self.batches is not None and (self.batch_id is not None or self.job_id is not None):
            raise ValueError("a scope is one batch or job, or a list of batches, not both")

    def conditions(self) -> list[tuple[str, str]]:
        """(column, value) pairs every lake row in one batch's or job's scope satisfies."""
        return [
            (column, value)
            for column, value in (("batch_id", self.batch_id), ("job_id", self.job_id))
            if value is not None
        ]

    def columns(self) -> list[str]:
        """The lake columns the scope filters on."""
        return ["batch_id"] if self.batches is not None else [column for column, _ in self.conditions()]

    def predicate(self) -> exp.Expression | None:
        """The condition every lake row in scope satisfies (values are string literal nodes, never
        pasted text); None when the scope is everything."""
        if self.batches is not None:
            if not self.batches:
                return exp.false()
            values = [exp.Literal.string(batch) for batch in self.batches]
            return exp.In(this=exp.column("batch_id"), expressions=values)
        if not self.conditions():
            return None
        return exp.and_(
            *(
                exp.EQ(this=exp.column(column), expression=exp.Literal.string(value))
                for column, value in self.conditions()
            ),
            copy=False,
        )


def _references(expression: exp.Expression, tables: set[str]) -> list[exp.Table]:
    """The Table nodes that name a lake table and are not shadowed by a visible CTE (iterative, so
    deep queries cannot exhaust the Python stack)."""
    found = []
    stack: list[tuple[exp.Expression, frozenset[str]]] = [(expression, frozenset())]
    while stack:
        node, visible = stack.pop()
        with_ = node.args.get("with_")
        if isinstance(with_, exp.With):
            ctes = list(with_.expressions)
            names = [cte.alias_or_name.lower() for cte in ctes]
            if with_.args.get("recursive"):
                visible = visible | set(names)
                stack.extend((cte.this, visible) for cte in ctes)
            else:
                for cte, name in zip(ctes, names):
                    stack.append((cte.this, visible))
                    visible = visible | {name}
        if isinstance(node, exp.Table):
            name = node.name.lower()
            qualified = bool(node.args.get("db"))
            if isinstance(node.this, exp.Identifier) and name in tables and (qualified or name not in visible):
                found.append(node)
            continue
        for key, value in node.args.items():
            if key == "with_":
                continue
            for child in value if isinstance(value, list) else (value,):
                if isinstance(child, exp.Expression):
                    stack.append((child, visible))
    return found


def _status_overlay(columns: Iterable[str], statuses: tuple[tuple[str, str, str], ...]) -> list[exp.Expression]:
    """`metadata`'s columns in order, its two job statuses replaced by `CASE job_id WHEN ... END`."""
    overlaid = {"job_metrics_status": 1, "job_conflated_status": 2}
    out: list[exp.Expression] = []
    for column in columns:
        if column not in overlaid:
            out.append(exp.column(column, quoted=True))
            continue
        case = exp.Case(this=exp.column("job_id"), default=exp.column(column, quoted=True))
        for status in statuses:
            case = case.when(exp.Literal.string(status[0]), exp.Literal.string(status[overlaid[column]]), copy=False)
        out.append(exp.alias_(case, column, quoted=True))
    return out


def _filtered(table: exp.Table, scope: Scope, condition: exp.Expression, columns: Iterable[str] | None) -> exp.Subquery:
    source = table.copy()
    source.set("alias", None)
    overlay = scope.statuses and columns and table.name.lower() == "metadata"
    shown = _status_overlay(columns, scope.statuses) if overlay else [exp.Star()]
    select = exp.Select(expressions=shown, from_=exp.From(this=source), where=exp.Where(this=condition.copy()))
    alias = table.args.get("alias")
    if alias is None:
        alias = exp.TableAlias(this=exp.Identifier(this=table.name, quoted=table.this.args.get("quoted", False)))
    return exp.Subquery(this=select, alias=alias.copy())


def restrict(
    expression: exp.Expression, scope: Scope, tables: Iterable[str] | Mapping[str, Mapping[str, str]]
) -> exp.Expression:
    """Rewrite (in place, and return) `expression` so that every lake table in `tables` it reads
    shows only the rows of `scope`. Values are string literal nodes, never pasted text. `tables`
    with their columns (table -> column -> type) lets `metadata` show `scope.statuses`."""
    condition = scope.predicate()
    if condition is None:
        return expression
    columns = {t.lower(): list(c) for t, c in tables.items()} if isinstance(tables, Mapping) else {}
    names = {t.lower() for t in tables}
    for table in _references(expression, names):
        table.replace(_filtered(table, scope, condition, columns.get(table.name.lower())))
    return expression
