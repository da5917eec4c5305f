"""Trino's all-fields reference `row_expression.* [AS (column_alias, ...)]` (docs/src/main/sphinx/sql/
select.md "Select expressions"; io.trino.sql.analyzer.StatementAnalyzer analyzeAllFieldsFromRowTypeExpression),
expanded to one select item per field of the row: field i of `r` is `struct_extract_at(r, i)` in DuckDB.

Output names as Trino gives them: the alias when AS (...) is given, else the field's name, else
`_colN` (N the output position). A NULL row gives NULL in every field. `t.*` with AS (...) renames
the columns of table `t` (analyzeAllColumnsFromTable).
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect.type_rules import Analysis, NameScope

#: Functions whose value differs per call: Trino computes the row once, the expansion once per field.
_NON_DETERMINISTIC = frozenset({"rand", "random", "uuid", "shuffle"})


def target(item: exp.Expression, scope: NameScope) -> exp.Expression | None:
    """The row expression `item` expands (`(expr).*`, `t.col.*`, with or without AS (...)), if any;
    `schema.t.*` naming a table of the FROM clause is that table's columns, as in Trino."""
    star = item.this if isinstance(item, exp.Aliases) else item
    if isinstance(star, exp.Dot) and isinstance(star.expression, exp.Star):
        return star.this
    if (
        isinstance(star, exp.Column)
        and isinstance(star.this, exp.Star)
        and star.args.get("db") is not None
        and not any(source.name == star.table.lower() for source in scope.sources)
    ):
        parts = star.parts[:-1]  # catalog.db.table.* : a table alias, a row column, then fields
        column: exp.Expression = exp.Column(this=parts[1].copy(), table=parts[0].copy())
        for part in parts[2:]:
            column = exp.Dot(this=column, expression=part.copy())
        return column
    return None


def aliases(item: exp.Expression) -> list[exp.Identifier]:
    """The AS (column_alias, ...) list of a select item (empty without one)."""
    return list(item.expressions) if isinstance(item, exp.Aliases) else []


def check_aliases(a: Analysis, item: exp.Expression, count: int) -> None:
    """Trino's MISMATCHED_COLUMN_ALIASES when AS (...) does not name every column (validateColumnAliasesCount)."""
    names = aliases(item)
    if names and len(names) != count:
        a.fail(
            f"Column alias list has {len(names)} entries but relation has {count} columns",
            names[0],
            "MISMATCHED_COLUMN_ALIASES",
        )


def expand(
    a: Analysis, item: exp.Expression, row: exp.Expression, scope: NameScope, first: int
) -> list[exp.Expression]:
    """One aliased select item per field of `row`; `first` is the output position of the first one."""
    if any(f.name.lower() in _NON_DETERMINISTIC for f in row.find_all(exp.Anonymous)):
        a.unsupported("row_expression.* over a non-deterministic expression", item)
    t = a.expr(row.copy(), scope, {})
    if t.base != "row":
        select = item.find_ancestor(exp.Select)
        a.fail("expected expression of type Row", select if select is not None else item, "TYPE_MISMATCH")
    check_aliases(a, item, len(t.args))
    names = aliases(item)
    expanded: list[exp.Expression] = []
    for i, (name, _) in enumerate(t.args):
        field = exp.Dot(this=row.copy(), expression=exp.to_identifier(name or f"_col{first + i}", quoted=True))
        field.meta["row_position"] = i + 1
        alias = names[i].copy() if names else exp.to_identifier(name or f"_col{first + i}", quoted=True)
        expanded.append(exp.Alias(this=field, alias=alias))
    return expanded


def rename(a: Analysis, item: exp.Aliases, columns: list[exp.Expression]) -> list[exp.Expression]:
    """`t.* AS (column_alias, ...)`: the expanded columns of `t`, renamed."""
    check_aliases(a, item, len(columns))
    for column, name in zip(columns, item.expressions, strict=True):
        column.set("alias", name.copy())
    return columns
