"""Rewrites of the analyzed tree before it is written: `finalize` (the casts that give each
output column its Trino type) and `hoist_derived_order` (ORDER BY out of derived tables, a
Trino-level rewrite the forwarding backend sees too).
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import chars, pico_times, registry
from lakegate.dialect import trino_types as tt
from lakegate.dialect.transforms import DuckCast
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import ShownWide, ttype


# --- final shape ---------------------------------------------------------------------------------
def finalize(tree: exp.Expression, outputs: list) -> None:
    """Give every select item its DuckDB name (`_colN` for anonymous ones), cast set-operation
    branches to the common types, and cast the statement's output columns to the DuckDB types of
    their Trino types (so DuckDB's own choices, e.g. HUGEINT sums, never leak out)."""
    for select in tree.find_all(exp.Select):
        outs = select.meta.get("outputs")
        if outs is None:
            continue
        items = []
        for item, (_, duck_name, _) in zip(select.expressions, outs):
            inner = item.this if isinstance(item, exp.Alias) else item
            items.append(exp.Alias(this=inner, alias=exp.to_identifier(duck_name, quoted=True)))
        select.set("expressions", items)
    for operation in tree.find_all(exp.SetOperation):
        _cast_branches(operation, operation.meta["outputs"])
    _cast_outputs(tree, [t for _, _, t in outputs], top=True)


def _branches(node: exp.Expression):
    if isinstance(node, exp.SetOperation):
        yield from _branches(node.this)
        yield from _branches(node.expression)
    elif isinstance(node, exp.Subquery):
        yield from _branches(node.this)
    else:
        yield node


def _cast_branches(operation: exp.SetOperation, outputs: list) -> None:
    for branch in _branches(operation):
        if isinstance(branch, exp.Select):
            for item, (_, _, common) in zip(branch.expressions, outputs):
                if common.base == "char":
                    chars.cast_to(item.this, common)
                elif ttype(item.this) != common and tt.duckdb_type(common) in (tt.WIDE_TIMESTAMP_TZ, tt.WIDE_TIMESTAMP):
                    converted = exp.Cast(this=item.this, to=exp.DataType.build("VARCHAR"))  # Trino's CAST to `common`
                    converted.meta.update({"t": common, "from": ttype(item.this)})
                    item.set("this", converted)
                elif pico_times.is_wide(common) and ttype(item.this).base == "time":  # to picoseconds
                    pico_times.cast_to(item.this, common)
                elif ttype(item.this) != common and not ttype(item.this).base == common.base == "varchar":
                    _wrap(item, common)


def _cast_outputs(tree: exp.Expression, types: list[TType], top: bool) -> None:
    for branch in _branches(tree):
        if isinstance(branch, exp.Select):
            for item, t in zip(branch.expressions, types):
                _wrap(item, t)


def _wrap(item: exp.Alias, t: TType) -> None:
    duck = tt.duckdb_type(t)
    inner = item.this
    if duck is None or isinstance(inner, (DuckCast, ShownWide)):
        return
    if duck in (tt.WIDE_TIMESTAMP_TZ, tt.WIDE_TIMESTAMP):
        shown = ShownWide(this=inner)
        shown.meta["t"] = t
        item.set("this", shown)
        return
    wrapped = DuckCast(this=inner, to=duck)
    wrapped.meta["t"] = t
    item.set("this", wrapped)


# --- Trino-level rewrites (also seen by the forwarding backend) ----------------------------------
def _output_name(item: exp.Expression) -> str | None:
    if isinstance(item, exp.Alias):
        ident = item.args["alias"]
        return ident.name if ident.quoted else ident.name.lower()
    if isinstance(item, exp.Column) and not isinstance(item.this, exp.Star):
        return item.name.lower() if not item.this.quoted else item.name
    return None


def _first_select(node: exp.Expression) -> exp.Select | None:
    while isinstance(node, (exp.SetOperation, exp.Subquery)):
        node = node.this
    return node if isinstance(node, exp.Select) else None


def _aggregates_or_windows(select: exp.Select) -> bool:
    for item in select.expressions:
        for node in item.walk():
            if isinstance(node, exp.Window):
                return True
            if isinstance(node, exp.Anonymous):
                spec = registry.SUPPORTED.get(node.name.lower())
                if spec is not None and spec.kind != "scalar":
                    return True
    return False


def hoist_derived_order(tree: exp.Expression) -> bool:
    """An ORDER BY inside a derived table is kept for the outer query when that query has none and
    only projects and filters the derived table (`SELECT a, b FROM (... ORDER BY k)`): the rows
    come out in that order, which reports relying on it expect. Whether anything was hoisted."""
    hoisted_any = False
    for select in list(tree.find_all(exp.Select)):
        from_ = select.args.get("from_")
        if from_ is None or not isinstance(from_.this, exp.Subquery) or select.args.get("order") is not None:
            continue
        if any(select.args.get(k) for k in ("joins", "group", "having", "distinct", "laterals")):
            continue
        if _aggregates_or_windows(select) or any(isinstance(i, exp.Star) for i in select.expressions):
            continue
        derived = from_.this
        inner = derived.this
        order = inner.args.get("order")
        first = _first_select(inner)
        if order is None or first is None or any(isinstance(i, exp.Star) for i in first.expressions):
            continue
        alias = derived.args.get("alias")
        names = [_output_name(i) for i in first.expressions]
        if alias is not None and alias.columns:
            names = [c.name if c.quoted else c.name.lower() for c in alias.columns]
        hoisted = []
        for ordered in order.expressions:
            target = ordered.this
            if isinstance(target, exp.Literal) and not target.is_string and target.name.isdigit():
                index = int(target.name) - 1
                name = names[index] if 0 <= index < len(names) else None
            elif isinstance(target, exp.Column) and not target.table:
                wanted = target.name if target.this.quoted else target.name.lower()
                name = next((n for n in names if n is not None and n.lower() == wanted.lower()), None)
            else:
                name = None
            if name is None:
                break
            hoisted.append((name, ordered))
        else:
            if alias is None or not alias.name:
                alias = exp.TableAlias(this=exp.to_identifier("_ordered"))
                derived.set("alias", alias)
            select.set(
                "order",
                exp.Order(
                    expressions=[
                        exp.Ordered(
                            this=exp.column(exp.to_identifier(name, quoted=True), table=alias.this.copy()),
                            desc=ordered.args.get("desc"),
                            nulls_first=ordered.args.get("nulls_first"),
                        )
                        for name, ordered in hoisted
                    ]
                ),
            )
            if inner.args.get("limit") is None and inner.args.get("offset") is None:
                inner.set("order", None)
            hoisted_any = True
    return hoisted_any
