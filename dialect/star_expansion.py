"""Star expansion: the select list of a query with `*`, `t.*` and `row.*` expanded, with
Trino's output names (the StarExpansion mixin of the Analyzer).
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import row_star
from lakegate.dialect.name_resolution import ident_name
from lakegate.dialect.type_rules import NameScope, OutCol, set


class StarExpansion:
    """The select list with `*`, `t.*` and `row.*` expanded (a mixin of analyzer.Analyzer)."""

    def projection(self, node: exp.Select, scope: NameScope) -> list[OutCol]:
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
                name = ident_name(item.args["alias"])
            elif isinstance(item, exp.Column):
                name = item.meta["ref"][1] if item.meta.get("resolved") else item.parts[-1].name
            elif isinstance(item, exp.Dot):
                name = item.name
            else:
                name = None
            outputs.append((name, name if name is not None else f"_col{index}", t))
            item.meta["t"] = t
        return outputs

    def expand_star(self, star: exp.Expression, scope: NameScope) -> list[exp.Expression]:
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
                set(ref, col[2])
                ref.meta["resolved"] = True
        return expanded
