"""FETCH FIRST n ROWS WITH TIES (Trino: docs/src/main/sphinx/sql/select.md, "LIMIT or FETCH FIRST
clause"): the first n rows in ORDER BY order and every row in the peer group of the last of them.

DuckDB has no WITH TIES. The same rows are those whose rank() over the ORDER BY keys is at most n
(a row's rank is one more than the number of rows before its peer group), and after OFFSET m those
of rank at most m + n, of which OFFSET then drops the first m. So the SELECT keeps its ORDER BY and
OFFSET and gets `QUALIFY rank() OVER (ORDER BY keys) <= m + n` instead of the FETCH clause. The
keys are the ORDER BY items with the output columns they name (by alias or position) replaced by
the select items' expressions, copied before the query is analyzed.
"""

from __future__ import annotations

from sqlglot import exp


def with_ties(fetch: exp.Expression | None) -> bool:
    """Whether a query's `limit` clause is FETCH ... WITH TIES."""
    if not isinstance(fetch, exp.Fetch):
        return False
    options = fetch.args.get("limit_options")
    return bool(fetch.args.get("with_ties") or options is not None and options.args.get("with_ties"))


def rank_keys(select: exp.Select) -> list[exp.Ordered]:
    """The ORDER BY items of `select` as source expressions (copies, before analysis)."""
    items = select.expressions
    named = {item.alias.lower(): item.this for item in items if isinstance(item, exp.Alias)}
    keys = []
    for ordered in select.args["order"].expressions:
        key = ordered.copy()
        target = key.this
        if isinstance(target, exp.Literal) and not target.is_string and target.name.isdigit():
            index = int(target.name) - 1
            if 0 <= index < len(items):
                item = items[index]
                key.set("this", (item.this if isinstance(item, exp.Alias) else item).copy())
        else:
            for column in list(key.find_all(exp.Column)):
                if not column.table and column.name.lower() in named and not column.find_ancestor(exp.Subquery):
                    replacement = named[column.name.lower()].copy()
                    if column is key.this:
                        key.set("this", replacement)
                    else:
                        column.replace(replacement)
        keys.append(key)
    return keys


def rank_filter(keys: list[exp.Ordered], rows: int) -> exp.Expression:
    """`rank() OVER (ORDER BY keys) <= rows`, to be analyzed in the SELECT's scope."""
    rank = exp.Window(this=exp.Anonymous(this="rank", expressions=[]), order=exp.Order(expressions=keys))
    return exp.LTE(this=rank, expression=exp.Literal.number(rows))
