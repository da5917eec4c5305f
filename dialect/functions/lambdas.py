"""Trino's functions/lambda.md. The array functions that take a lambda: filter, transform, reduce, zip_with,
array_sort and the any / all / none matches (Trino's lambda.md shows them; array.md lists them).
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import write_operators as ops
from lakegate.dialect.functions.arguments import array_arg
from lakegate.dialect.functions.rendering import nested
from lakegate.dialect.registry import Render, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, ttype


def _array_sort(call: Call) -> TType:
    if not 1 <= len(call.args) <= 2:
        call.mismatch()
    arr = array_arg(call)
    if arr.element.base in ("map", "json"):
        call.mismatch()
    if len(call.args) == 1 and arr.element.base in ("array", "row") and nested(arr.element):
        call.fail(f"unsupported in lakegate: array_sort of {arr}: its elements hold arrays or rows", "NOT_SUPPORTED")
    if len(call.args) == 2:
        if not call.lam(1, [arr.element, arr.element]).is_integral:
            call.mismatch()
        call.node.meta["sort_key"] = _comparator_key(call)
    return arr


_RELATIONS = {exp.LT: "<", exp.LTE: "<=", exp.GT: ">", exp.GTE: ">=", exp.EQ: "=", exp.NEQ: "<>"}

_FLIP = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "=": "=", "<>": "<>"}

_HOLDS = {"<": {"lt"}, "<=": {"lt", "eq"}, ">": {"gt"}, ">=": {"gt", "eq"}, "=": {"eq"}, "<>": {"lt", "gt"}}


def _unparen(node):
    while isinstance(node, exp.Paren):
        node = node.this
    return node


def _uses(node: exp.Expression, name: str) -> bool:
    return any(
        isinstance(n, (exp.Identifier, exp.Column)) and n._meta and n.meta.get("lambda") and n.name.lower() == name
        for n in node.walk()
    )


def _renamed(node: exp.Expression, old: str, new: str) -> exp.Expression:
    copy = node.copy()
    for n in copy.walk():
        if isinstance(n, exp.Identifier) and n.name.lower() == old:
            n.set("this", new)
    return copy


def _comparator_key(call: Call) -> tuple[exp.Expression, bool]:
    """The sort key and direction of a comparator lambda that compares one expression of x with
    the same expression of y (IF / CASE returning -1, 0, 1); anything else is rejected."""
    lam = call.args[1]
    x, y = (p.name.lower() for p in lam.expressions)

    def reject():
        call.fail(
            "unsupported in lakegate: array_sort comparator other than IF/CASE comparisons of one "
            "expression of x with the same expression of y returning -1, 0, 1",
            "NOT_SUPPORTED",
        )

    branches, body = [], _unparen(lam.this)
    while True:
        if isinstance(body, exp.If):
            branches.append((body.this, body.args.get("true")))
            body = _unparen(body.args.get("false"))
        elif isinstance(body, exp.Case) and body.args.get("this") is None:
            branches.extend((b.this, b.args.get("true")) for b in body.args.get("ifs") or [])
            body = _unparen(body.args.get("default"))
        else:
            break
    branches, nulls_first = _null_branches(branches, x, y, reject)
    default, key, relations = body, None, []
    for cond, _ in branches:
        cond = _unparen(cond)
        if type(cond) not in _RELATIONS:
            reject()
        left, right, rel = _unparen(cond.this), _unparen(cond.expression), _RELATIONS[type(cond)]
        if _uses(left, y) and _uses(right, x):
            left, right, rel = right, left, _FLIP[rel]
        if _uses(left, y) or _uses(right, x) or not _uses(left, x) or _renamed(right, y, x) != left:
            reject()
        if key is not None and left != key:
            reject()
        key = left
        relations.append(rel)

    def value(node):
        node = _unparen(node) if node is not None else None
        literal = node.this if isinstance(node, exp.Neg) else node
        if not isinstance(literal, exp.Literal) or literal.is_string or not literal.name.isdigit():
            reject()
        return -int(literal.name) if isinstance(node, exp.Neg) else int(literal.name)

    outcome = []
    for order in ("lt", "eq", "gt"):
        chosen = next((result for rel, (_, result) in zip(relations, branches) if order in _HOLDS[rel]), default)
        number = value(chosen)
        outcome.append((number > 0) - (number < 0))
    if key is None or tuple(outcome) not in ((-1, 0, 1), (1, 0, -1)):
        reject()
    if nulls_first is not None and not (isinstance(key, (exp.Column, exp.Identifier)) and key.name.lower() == x):
        reject()  # the NULL branches test the elements, so the key must be the element itself
    return key, tuple(outcome) == (1, 0, -1), nulls_first


def _null_branches(branches: list, x: str, y: str, reject) -> tuple[list, bool | None]:
    """Leading `WHEN x IS NULL THEN -1 WHEN y IS NULL THEN 1` (NULLs first) or `... THEN 1 ... THEN -1`
    (NULLs last) of a comparator, as in Trino's docs (functions/array.md array_sort); the other branches
    and where NULLs go (None without such branches)."""
    tests = []
    for cond, result in branches[:2]:
        cond = _unparen(cond)
        if not (isinstance(cond, exp.Is) and isinstance(cond.expression, exp.Null)):
            break
        target = _unparen(cond.this)
        name = target.name.lower() if isinstance(target, (exp.Column, exp.Identifier)) else None
        literal = _unparen(result)
        sign = -1 if isinstance(literal, exp.Neg) else 1
        literal = literal.this if isinstance(literal, exp.Neg) else literal
        if name not in (x, y) or not isinstance(literal, exp.Literal) or literal.name != "1":
            reject()
        tests.append((name, sign))
    if not tests:
        return branches, None
    if tests not in ([(x, -1), (y, 1)], [(x, 1), (y, -1)]):
        reject()
    return branches[2:], tests[0][1] == -1


def _render_array_sort(g, node, args) -> str:
    arr = g.sql(args[0])
    if len(args) == 1:
        return _checked_order(f"list_sort({arr}, 'ASC', 'NULLS LAST')", ttype(node).element)
    key, descending, nulls_first = node.meta["sort_key"]
    x = tf.quote(args[1].expressions[0].name.lower())
    position = '-"_i"' if descending else '"_i"'
    null_flag = "" if nulls_first is None else f"n := {x} IS {'' if nulls_first == descending else 'NOT '}NULL, "
    keyed = (
        f'list_transform({arr}, lambda {x}, "_i": struct_pack({null_flag}k := {g.sql(key)}, i := {position}, v := {x}))'
    )
    direction = "'DESC'" if descending else "'ASC'"
    return f'list_transform(list_sort({keyed}, {direction}), lambda "_s": struct_extract("_s", \'v\'))'


def _checked_order(sorted_sql: str, element: TType) -> str:
    """A sorted array of arrays or rows, or Trino's error when sorting compares two elements that
    reach a NULL element: any comparison sort compares each adjacent pair of its result, and two
    elements whose comparison reaches a NULL have only such elements between them."""
    if element.base not in ("array", "row"):
        return sorted_sql
    pair = ('"_s"["_j"]', '"_s"["_j" + 1]')
    reached, failure = ops.null_reached(*pair, element)
    clash = (
        f'list_filter(range(1, len("_s")), lambda "_j": {pair[0]} IS NOT NULL AND {pair[1]} IS NOT NULL AND {reached})'
    )
    return f'list_transform([{sorted_sql}], lambda "_s": CASE WHEN len({clash}) > 0 THEN {failure} ELSE "_s" END)[1]'


def _filter(call: Call) -> TType:
    arr = array_arg(call)
    if len(call.args) != 2:
        call.mismatch()
    if call.lam(1, [arr.element]).base not in ("boolean", "unknown"):
        call.mismatch()
    return arr


def _transform(call: Call) -> TType:
    arr = array_arg(call)
    if len(call.args) != 2:
        call.mismatch()
    return tt.array(call.lam(1, [arr.element]))


def _render_lambda_call(duck: str) -> Render:
    def render(g, node, args):
        return f"{duck}({g.sql(args[0])}, {g.lambda_(args[1])})"

    return render


def _reduce(call: Call) -> TType:
    if len(call.args) != 4 or call.types[1] is None:
        call.mismatch()
    arr = array_arg(call)
    state = call.types[1]
    for _ in range(4):
        result = call.lam(2, [state, arr.element])
        widened = tt.common_super_type(state, result)
        if widened is None:
            call.mismatch()
        if widened == state:
            break
        state = widened
    call.node.meta["state"] = state
    return call.lam(3, [state])


def _render_reduce(g, node, args) -> str:
    arr = g.sql(args[0])
    state = node.meta["state"]
    merge, output = args[2], args[3]
    folded = f"list_reduce({arr}, {g.lambda_(merge)}, {g.coerce(args[1], state)})"
    out_param = output.expressions[0].name.lower()
    applied = f"list_transform([{folded}], lambda {tf.quote(out_param)}: {g.sql(output.this)})[1]"
    return f"CASE WHEN ({arr}) IS NULL THEN NULL ELSE {applied} END"


def _match(call: Call) -> TType:
    arr = array_arg(call)
    if len(call.args) != 2 or call.lam(1, [arr.element]).base not in ("boolean", "unknown"):
        call.mismatch()
    return tt.BOOLEAN


def _render_match(g, node, args) -> str:
    arr = g.sql(args[0])
    flags = f"list_transform({arr}, {g.lambda_(args[1])})"
    name = node.name.lower()
    has_null = f"list_count({flags}) < len({flags})"
    if name == "any_match":
        return (
            f"CASE WHEN ({arr}) IS NULL THEN NULL WHEN list_contains({flags}, true) THEN true "
            f"WHEN {has_null} THEN NULL ELSE false END"
        )
    if name == "all_match":
        return (
            f"CASE WHEN ({arr}) IS NULL THEN NULL WHEN list_contains({flags}, false) THEN false "
            f"WHEN {has_null} THEN NULL ELSE true END"
        )
    return (
        f"CASE WHEN ({arr}) IS NULL THEN NULL WHEN list_contains({flags}, true) THEN false "
        f"WHEN {has_null} THEN NULL ELSE true END"
    )


def _zip_with(call: Call) -> TType:
    if len(call.args) != 3:
        call.mismatch()
    a, b = array_arg(call, 0), array_arg(call, 1)
    return tt.array(call.lam(2, [a.element, b.element]))


def _render_zip_with(g, node, args) -> str:
    a, b = g.sql(args[0]), g.sql(args[1])
    fn = args[2]
    x, y = (p.name.lower() for p in fn.expressions)
    body = g.sql(fn.this)
    pair = '"_z"'
    inner = (
        f"list_transform([struct_extract({pair}, 1)], lambda {tf.quote(x)}: "
        f"list_transform([struct_extract({pair}, 2)], lambda {tf.quote(y)}: {body})[1])[1]"
    )
    return (
        f"CASE WHEN ({a}) IS NULL OR ({b}) IS NULL THEN NULL "
        f"ELSE list_transform(list_zip({a}, {b}), lambda {pair}: {inner}) END"
    )


def install() -> None:
    """Register the functions of this page (called by pages.py)."""
    register(
        "array_sort",
        "array",
        "array_sort(array[, function(T, T, integer)]) -> array",
        _array_sort,
        _render_array_sort,
        notes="NULLs last. A comparator is translated when it compares one expression of x "
        "with the same expression of y (a sort key, ascending or descending, stable); "
        "other comparators are rejected.",
    )
    register(
        "filter", "array", "filter(array, function(T, boolean)) -> array", _filter, _render_lambda_call("list_filter")
    )
    register(
        "transform",
        "array",
        "transform(array, function(T, U)) -> array(U)",
        _transform,
        _render_lambda_call("list_transform"),
    )
    register(
        "reduce",
        "array",
        "reduce(array, initialState, inputFunction, outputFunction) -> R",
        _reduce,
        _render_reduce,
        notes="The output function is applied to the final state.",
    )
    register("any_match", "array", "any_match(array, function(T, boolean)) -> boolean", _match, _render_match)
    register("all_match", "array", "all_match(array, function(T, boolean)) -> boolean", _match, _render_match)
    register("none_match", "array", "none_match(array, function(T, boolean)) -> boolean", _match, _render_match)
    register(
        "zip_with",
        "array",
        "zip_with(array(T), array(U), function(T, U, R)) -> array(R)",
        _zip_with,
        _render_zip_with,
        notes="The shorter array is padded with NULLs, as in Trino.",
    )
