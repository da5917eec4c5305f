"""The named WINDOW clause (`SELECT rank() OVER w ... WINDOW w AS (PARTITION BY g ORDER BY x)`),
resolved as Trino's StatementAnalyzer does (analyzeWindowDefinitions, resolveWindowSpecification;
cases of io.trino.sql.analyzer.TestAnalyzer testWindowDefinition, testWindowInFunctionCall,
testNamedWindowScope): each `OVER w` or `OVER (w ORDER BY ...)` of the query is replaced by the
window it names, so the rest of the dialect sees plain `OVER (...)` windows.

Names follow Trino's identifier rules (`w` and `"W"` are the same name, `"w"` another); a
definition sees the definitions before it, a reference sees those of its own query only.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NoReturn

from sqlglot import exp

Fail = Callable[[str, exp.Expression, str], NoReturn]


def _key(name: exp.Identifier) -> str:
    return name.name if name.quoted else name.name.upper()


def _copy(node: exp.Expression | None) -> exp.Expression | None:
    return node.copy() if node is not None else None


def _parenthesized(window: exp.Window, sql: str) -> bool:
    """`OVER (w ...)` rather than `OVER w`: sqlglot parses both alike when nothing follows the name."""
    start = (window.args["alias"]._meta or {}).get("start")
    return start is None or sql[:start].rstrip().endswith("(")


def _resolve(window: exp.Window, defined: dict[str, exp.Window], sql: str, fail: Fail) -> None:
    """Fill `window`, which names an existing window in `alias`, from that window (in place)."""
    name = window.args["alias"]
    base = defined.get(_key(name))
    if base is None:
        fail(f"Cannot resolve WINDOW name {name.name}", name, "INVALID_WINDOW_REFERENCE")
    own = {key: window.args.get(key) for key in ("partition_by", "order", "spec")}
    if any(own.values()) or _parenthesized(window, sql):
        if own["partition_by"]:
            fail(
                "WINDOW specification with named WINDOW reference cannot specify PARTITION BY",
                own["partition_by"][0],
                "INVALID_PARTITION_BY",
            )
        if own["order"] is not None and base.args.get("order") is not None:
            message = "Cannot specify ORDER BY if referenced named WINDOW specifies ORDER BY"
            fail(message, own["order"], "INVALID_ORDER_BY")
        if base.args.get("spec") is not None:
            fail("Cannot reference named WINDOW containing frame specification", name, "INVALID_WINDOW_REFERENCE")
    window.set("alias", None)
    window.set("partition_by", [p.copy() for p in base.args.get("partition_by") or []] or None)
    window.set("order", own["order"] or _copy(base.args.get("order")))
    window.set("spec", own["spec"] or _copy(base.args.get("spec")))


def resolve_named_windows(select: exp.Select, sql: str, fail: Fail) -> list[exp.Window]:
    """Replace every window reference of `select` (not of its subqueries) by the window it names and
    drop the WINDOW clause; the definitions, resolved, for analysing their expressions (Trino
    analyzes every definition, used or not)."""
    definitions = select.args.get("windows") or []
    if not definitions:  # a reference then names nothing: the analyzer's window handler says so
        return []
    defined: dict[str, exp.Window] = {}
    for definition in definitions:
        key = _key(definition.this)
        if key in defined:
            fail(f"WINDOW name '{definition.this.name}' specified more than once", definition, "DUPLICATE_WINDOW_NAME")
        if definition.args.get("alias") is not None:
            _resolve(definition, defined, sql, fail)
        defined[key] = definition
    select.set("windows", None)
    references = [
        w
        for w in select.find_all(exp.Window)
        if w.args.get("alias") is not None and w.find_ancestor(exp.Select) is select
    ]
    order = select.args.get("order")
    shadowing = {
        item.alias.lower()
        for item in select.expressions
        if isinstance(item, exp.Alias) and not (isinstance(item.this, exp.Column) and item.this.name == item.alias)
    }
    for reference in references:
        base = defined.get(_key(reference.args["alias"]))
        in_order_by = order is not None and reference.find_ancestor(exp.Order) is order
        if in_order_by and base is not None and any(c.name.lower() in shadowing for c in base.find_all(exp.Column)):
            # a definition's columns are source columns; ORDER BY sees the output columns first
            fail(
                "unsupported in lakegate: a named WINDOW in ORDER BY whose definition names an output column alias",
                reference,
                "NOT_SUPPORTED",
            )
        _resolve(reference, defined, sql, fail)
    return definitions


def window_keys(window: exp.Window) -> list[exp.Expression]:
    """The expressions of a window: its PARTITION BY and ORDER BY keys and its frame offsets."""
    order = window.args.get("order")
    spec = window.args.get("spec")
    bounds = [spec.args.get(b) for b in ("start", "end")] if spec is not None else []
    return [
        *(window.args.get("partition_by") or []),
        *(o.this for o in (order.expressions if order is not None else [])),
        *(b for b in bounds if isinstance(b, exp.Expression)),
    ]
