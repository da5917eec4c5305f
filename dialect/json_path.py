"""The SQL/JSON path language of json_exists, json_value and json_query, translated to DuckDB SQL
that computes the path's result sequence.

A sequence is a DuckDB VARCHAR[] of JSON texts; an item that is the marker ERROR makes the whole
sequence an error (the input is not JSON, or a structural error in strict mode). Translated:
`lax` / `strict` mode; member accessors `.key`, `."key"`, the wildcard member accessor `.*`, array
accessors with subscripts (`[1]`, `[1, 3 to 5]`, `[last]`, `[last - 1]`) and the wildcard `[*]`;
filters `?(...)` of comparisons (`==`, `!=`, `<>`, `<`, `<=`, `>`, `>=`) between `@`-paths and
literals, `exists(...)`, `starts with`, `is unknown`, `&&`, `||`, `!`; the item methods `size()`,
`type()`, `abs()`, `floor()`, `ceiling()` and (once per path, outside filters) `keyvalue()`. Others
are refused, named. Facts: trinodb/trino
docs/src/main/sphinx/functions/json.md ("JSON path language"), io.trino.json.PathEvaluationVisitor
and PathPredicateEvaluationVisitor.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass

from lakegate.dialect import transforms as tf

#: The item that marks an error sequence (not valid JSON, so never a real item).
ERROR = "'\\u0000error'"

_REPEATED_KEY = "NOT_SUPPORTED: a JSON path member accessor on an object with a repeated key is not translated"
_BIG_NUMBER = "NOT_SUPPORTED: a JSON path comparison of a number of magnitude 2^53 or more is not translated"


class PathNotSupported(ValueError):
    """A path (or a part of it) lakegate does not translate; the message names it."""


# --- parsing -------------------------------------------------------------------------------------
_TOKEN = re.compile(
    r'\s*(?:(?P<string>"(?:[^"\\]|\\.)*")|(?P<number>\d+(?:\.\d*)?(?:[eE][+-]?\d+)?)'
    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*)|(?P<op>==|!=|<>|<=|>=|&&|\|\||\.\.|[$@.*\[\],()?!<>+-]))"
)


@dataclass(frozen=True)
class Literal:
    kind: str  # number, string, boolean, null
    value: object


@dataclass(frozen=True)
class Compare:
    op: str
    left: object  # a relative path (list of steps) or a Literal
    right: object


@dataclass(frozen=True)
class Logic:
    op: str  # &&, ||, !, exists
    args: tuple


class _Parser:
    def __init__(self, text: str):
        self.tokens, at = [], 0
        while at < len(text.rstrip()):
            match = _TOKEN.match(text, at)
            if match is None:
                raise PathNotSupported(f"JSON path syntax at {text[at : at + 10]!r}")
            self.tokens.append((match.lastgroup, match.group(match.lastgroup)))
            at = match.end()
        self.at = 0

    def peek(self, value: str | None = None) -> bool:
        return self.at < len(self.tokens) and (value is None or self.tokens[self.at][1] == value)

    def take(self, value: str | None = None) -> tuple[str, str]:
        if not self.peek(value):
            found = self.tokens[self.at][1] if self.at < len(self.tokens) else "the end"
            raise PathNotSupported(f"JSON path: expected {value or 'more'} at {found}")
        self.at += 1
        return self.tokens[self.at - 1]

    def steps(self, relative: bool) -> list:
        """Accessors after `$` (or `@` in a filter) up to the end of the path or predicate operand."""
        steps = []
        while self.peek():
            if self.peek("."):
                self.take()
                kind, value = self.take()
                if value == "*":
                    steps.append(("members",))
                elif kind == "string":
                    if json.loads(value) == "*":  # DuckDB's JSON path reads $."*" as the wildcard
                        raise PathNotSupported('JSON path member accessor ."*"')
                    steps.append(("key", json.loads(value)))
                elif kind == "name" and self.peek("("):
                    self.take("(")
                    self.take(")")
                    if value == "keyvalue" and not relative and all(s != ("keyvalue",) for s in steps):
                        steps.append(("keyvalue",))  # its "id" counts objects: one keyvalue() per path, outside filters
                        continue
                    if value not in ("size", "type", "abs", "floor", "ceiling"):
                        raise PathNotSupported(f"JSON path item method {value}()")
                    steps.append(("method", value))
                elif kind == "name":
                    steps.append(("key", value))
                else:
                    raise PathNotSupported(f"JSON path accessor .{value}")
            elif self.peek("["):
                self.take()
                if self.peek("*"):
                    self.take()
                    steps.append(("elements", None))
                else:
                    subscripts = [self.subscript()]
                    while self.peek(","):
                        self.take()
                        subscripts.append(self.subscript())
                    steps.append(("elements", subscripts))
                self.take("]")
            elif self.peek("?") and not relative:
                self.take()
                self.take("(")
                steps.append(("filter", self.disjunction()))
                self.take(")")
            elif self.peek(".."):
                raise PathNotSupported("JSON path descendant member accessor ..")
            else:
                break
        return steps

    def subscript(self) -> tuple:
        start = self.index()
        return (start, self.index()) if self.peek("to") and self.take() else (start, start)

    def index(self) -> tuple[bool, int]:
        """(from the last index, offset)."""
        if self.peek("last"):
            self.take()
            if self.peek("-") or self.peek("+"):
                sign = -1 if self.take()[1] == "-" else 1
                return True, sign * self.integer()
            return True, 0
        sign = -1 if self.peek("-") and self.take() else 1
        return False, sign * self.integer()

    def integer(self) -> int:
        kind, value = self.take()
        if kind != "number" or not value.isdigit():
            raise PathNotSupported(f"JSON path array subscript {value}")
        return int(value)

    def disjunction(self):
        left = self.conjunction()
        while self.peek("||"):
            self.take()
            left = Logic("||", (left, self.conjunction()))
        return left

    def conjunction(self):
        left = self.unary()
        while self.peek("&&"):
            self.take()
            left = Logic("&&", (left, self.unary()))
        return left

    def unary(self):
        if self.peek("!"):
            self.take()
            return Logic("!", (self.unary(),))
        if self.peek("("):
            self.take()
            inner = self.disjunction()
            self.take(")")
            if self.peek("is"):
                self.take()
                self.take("unknown")
                return Logic("is unknown", (inner,))
            return inner
        if self.peek("exists"):
            self.take()
            self.take("(")
            path = self.operand()
            self.take(")")
            if isinstance(path, Literal):
                raise PathNotSupported("JSON path exists() of a literal")
            return Logic("exists", (path,))
        left = self.operand()
        if self.peek("starts") and not isinstance(left, Literal):
            self.take()
            self.take("with")
            prefix = self.operand()
            if not (isinstance(prefix, Literal) and prefix.kind == "string"):
                raise PathNotSupported("JSON path starts with other than a string literal")
            return Logic("starts with", (left, prefix.value))
        if not any(self.peek(op) for op in ("==", "!=", "<>", "<", "<=", ">", ">=")):
            found = self.tokens[self.at][1] if self.peek() else "the end"
            raise PathNotSupported(f"JSON path predicate at {found}")
        op = self.take()[1]
        right = self.operand()
        if isinstance(left, Literal) == isinstance(right, Literal):
            raise PathNotSupported("JSON path comparison other than of an @ path and a literal")
        if isinstance(left, Literal):  # a literal on the left: mirror the comparison
            left, right, op = right, left, {"<": ">", ">": "<", "<=": ">=", ">=": "<="}.get(op, op)
        return Compare("!=" if op == "<>" else op, left, right)

    def operand(self):
        kind, value = self.take()
        if value == "@":
            return self.steps(relative=True)
        if kind == "string":
            return Literal("string", json.loads(value))
        if kind == "number" or (value == "-" and self.peek() and self.tokens[self.at][0] == "number"):
            text = value if kind == "number" else "-" + self.take()[1]
            digits = re.sub(r"[eE].*|[-.]", "", text).strip("0")
            if len(digits) > 15:
                raise PathNotSupported(f"JSON path numeric literal {text} (more than 15 significant digits)")
            return Literal("number", text)
        if value in ("true", "false"):
            return Literal("boolean", value)
        if value == "null":
            return Literal("null", None)
        raise PathNotSupported(f"JSON path operand {value}")


def parse(text: str) -> tuple[str, list]:
    """The mode ("lax" or "strict") and steps of a path text; PathNotSupported naming what is not
    translated (Trino's own syntax errors included: lakegate refuses what it does not read)."""
    match = re.match(r"\s*(lax|strict)\s+\$", text)
    if match is None:
        raise PathNotSupported("JSON path other than lax $... or strict $...")
    parser = _Parser(text[match.end() :])
    steps = parser.steps(relative=False)
    if parser.peek():
        raise PathNotSupported(f"JSON path at {parser.tokens[parser.at][1]!r}")
    return match.group(1), steps


# --- DuckDB SQL ------------------------------------------------------------------------------------
class _Writer:
    def __init__(self, lax: bool):
        self.lax, self.depth = lax, 0

    def var(self) -> str:
        self.depth += 1
        return f'"_p{self.depth}"'

    def each(self, sequence: str, body) -> str:
        """flatten(each item -> body(item) as a list); an error item stays an error item."""
        x = self.var()
        return f"flatten(list_transform({sequence}, lambda {x}: CASE WHEN {x} = {ERROR} THEN [{x}] ELSE {body(x)} END))"

    def unwrap(self, sequence: str) -> str:
        """Lax mode: each array replaced by its elements."""
        if not self.lax:
            return sequence
        return self.each(sequence, lambda x: f"CASE WHEN json_type({x}) = 'ARRAY' THEN {_elements(x)} ELSE [{x}] END")

    def steps(self, sequence: str, steps: list) -> str:
        for step in steps:
            sequence = getattr(self, "_" + step[0])(sequence, *step[1:])
        return sequence

    def _not_object(self) -> str:
        return "[]" if self.lax else f"[{ERROR}]"

    def _key(self, sequence: str, key: str) -> str:
        path = tf.string("$." + json.dumps(key, ensure_ascii=False))
        missing = self._not_object()

        def member(x):
            value = f"CAST(json_extract({x}, {path}) AS VARCHAR)"
            return (
                f"CASE WHEN json_type({x}) <> 'OBJECT' THEN {missing} WHEN {_repeated(x)} "
                f"THEN [error({tf.string(_REPEATED_KEY)})] WHEN {value} IS NULL THEN {missing} ELSE [{value}] END"
            )

        return self.each(self.unwrap(sequence), member)

    def _members(self, sequence: str) -> str:
        def members(x):
            return (
                f"CASE WHEN json_type({x}) <> 'OBJECT' THEN {self._not_object()} WHEN {_repeated(x)} "
                f"THEN [error({tf.string(_REPEATED_KEY)})] ELSE CAST(json_extract({x}, '$.*') AS VARCHAR[]) END"
            )

        return self.each(self.unwrap(sequence), members)

    def _elements(self, sequence: str, subscripts) -> str:
        def elements(x):
            items = f"CASE WHEN json_type({x}) = 'ARRAY' THEN {_elements(x)} ELSE [{x}] END"
            if not self.lax:
                items = f"CASE WHEN json_type({x}) = 'ARRAY' THEN {_elements(x)} ELSE [{ERROR}] END"
            if subscripts is None:
                return items
            e = self.var()
            picks = [self._subscript(e, start, end) for start, end in subscripts]
            empty = "[]" if self.lax else f"[{ERROR}]"
            body = f"CASE WHEN len({e}) = 0 THEN {empty} ELSE flatten([{', '.join(picks)}]) END"
            return f"list_transform([{items}], lambda {e}: {body})[1]"

        return self.each(sequence, elements)

    def _subscript(self, e: str, start, end) -> str:
        """The elements of the array `e` from index `start` to `end` (each (from last, offset)),
        clipped to the array in lax mode, an error when outside it in strict mode."""
        last = f"(len({e}) - 1)"
        a, b = ((f"({last} + {off})" if from_last else str(off)) for from_last, off in (start, end))
        taken = f"list_slice({e}, greatest({a}, 0) + 1, least({b}, {last}) + 1)"
        if self.lax:  # (DuckDB's list_slice would count a negative end from the end of the list)
            return f"CASE WHEN {a} <= {b} AND {b} >= 0 AND {a} <= {last} THEN {taken} ELSE [] END"
        return f"CASE WHEN {a} < 0 OR {b} > {last} OR {a} > {b} THEN [{ERROR}] ELSE {taken} END"

    def _method(self, sequence: str, name: str) -> str:
        if name == "size":  # no unwrapping; lax: a non-array is a one-element array
            other = "'1'" if self.lax else ERROR
            size = "CAST(json_array_length({}) AS VARCHAR)".format
            return self.each(
                sequence, lambda x: f"[CASE WHEN json_type({x}) = 'ARRAY' THEN {size(x)} ELSE {other} END]"
            )
        if name == "type":  # no unwrapping
            kinds = {"OBJECT": "object", "ARRAY": "array", "VARCHAR": "string", "BOOLEAN": "boolean", "NULL": "null"}
            cases = " ".join(f"WHEN '{k}' THEN '\"{v}\"'" for k, v in kinds.items())
            return self.each(sequence, lambda x: f"[CASE json_type({x}) {cases} ELSE '\"number\"' END]")
        return self.each(self.unwrap(sequence), lambda x: f"[{_number_method(name, x)}]")

    def _keyvalue(self, sequence: str) -> str:
        """Each member of each object as {"name": key, "value": value, "id": the object's position}
        (visitIrKeyValueMethod, a new visitor, so ids from 0, per evaluation); a non-object is an error."""
        items, i, k = self.var(), self.var(), self.var()
        x = f"{items}[{i} + 1]"
        keys, values = f"json_keys({x})", f"CAST(json_extract({x}, '$.*') AS VARCHAR[])"
        member = (
            f"'{{\"name\":' || CAST(to_json({keys}[{k} + 1]) AS VARCHAR) || ',\"value\":' || {values}[{k} + 1] "
            f"|| ',\"id\":' || {i} || '}}'"
        )
        each = (
            f"CASE WHEN {x} = {ERROR} THEN [{x}] WHEN json_type({x}) <> 'OBJECT' THEN [{ERROR}] "
            f"WHEN {_repeated(x)} THEN [error({tf.string(_REPEATED_KEY)})] "
            f"ELSE list_transform(range(len({keys})), lambda {k}: {member}) END"
        )
        per_item = f"flatten(list_transform(range(len({items})), lambda {i}: {each}))"
        return f"list_transform([{self.unwrap(sequence)}], lambda {items}: {per_item})[1]"

    def _filter(self, sequence: str, predicate) -> str:
        x = self.var()
        keep = self.predicate(predicate, x)
        return self.each(self.unwrap(sequence), lambda y: f"list_filter([{y}], lambda {x}: ({keep}) IS TRUE)")

    # --- predicates: a DuckDB BOOLEAN, NULL for unknown ---------------------------------------------
    def predicate(self, node, current: str) -> str:
        if isinstance(node, Logic):
            if node.op == "!":
                return f"(NOT {self.predicate(node.args[0], current)})"
            if node.op == "is unknown":
                return f"({self.predicate(node.args[0], current)} IS NULL)"
            if node.op == "starts with":
                return self.starts_with(node.args[0], node.args[1], current)
            if node.op == "exists":
                seq = self.steps(f"[{current}]", node.args[0])
                return f"CASE WHEN list_contains({seq}, {ERROR}) THEN NULL ELSE len({seq}) > 0 END"
            sql_op = "AND" if node.op == "&&" else "OR"
            return f"({self.predicate(node.args[0], current)} {sql_op} {self.predicate(node.args[1], current)})"
        return self.compare(node, current)

    def compare(self, node: Compare, current: str) -> str:
        """PathPredicateEvaluationVisitor.visitIrComparisonPredicate for a path and a literal."""
        raw = self.steps(f"[{current}]", node.left)
        seq = self.unwrap(raw)
        y = self.var()
        kind = f"json_type({y})"
        has = {
            "null": f"list_bool_or(list_transform({seq}, lambda {y}: {kind} = 'NULL'))",
            "nonscalar": f"list_bool_or(list_transform({seq}, lambda {y}: {kind} IN ('ARRAY', 'OBJECT')))",
            "scalar": f"list_bool_or(list_transform({seq}, lambda {y}: {kind} NOT IN ('ARRAY', 'OBJECT', 'NULL')))",
        }
        right = node.right
        if right.kind == "null":
            result = {"==": has["null"], "!=": f"({has['scalar']} OR {has['nonscalar']})"}.get(node.op, "false")
        else:
            scalars = f"list_filter({seq}, lambda {y}: {kind} <> 'NULL')"
            codes = f"list_transform({scalars}, lambda {y}: {self._scalar(y, node.op, right)})"
            found_null = has["null"] if node.op == "!=" else "false"
            if self.lax:
                result = f"CASE WHEN {found_null} THEN true ELSE {self._any(codes)} END"
            else:
                result = f"({self._any(codes)} OR {found_null})"
            result = f"CASE WHEN {has['nonscalar']} THEN NULL ELSE {result} END"
        return f"CASE WHEN list_contains({raw}, {ERROR}) THEN NULL WHEN len({seq}) = 0 THEN false ELSE {result} END"

    def _any(self, codes: str) -> str:
        """Whether any of the codes (1 true, 0 false, 2 error) is true: unknown on an error, in lax
        mode only on an error before the first true (PathPredicateEvaluationVisitor stops early)."""
        if not self.lax:
            return f"CASE WHEN list_contains({codes}, 2) THEN NULL ELSE list_contains({codes}, 1) END"
        first_error, first_true = f"list_position({codes}, 2)", f"list_position({codes}, 1)"
        return (
            f"CASE WHEN {first_error} IS NOT NULL AND ({first_true} IS NULL OR {first_error} < {first_true}) "
            f"THEN NULL ELSE list_contains({codes}, 1) END"
        )

    def starts_with(self, path: list, prefix: str, current: str) -> str:
        """visitIrStartsWithPredicate: every item must be text; true when one starts with the prefix."""
        raw = self.steps(f"[{current}]", path)
        seq = self.unwrap(raw)
        y = self.var()
        test = f"CAST(starts_with(json_extract_string({y}, '$'), {tf.string(prefix)}) AS INTEGER)"
        codes = f"list_transform({seq}, lambda {y}: CASE WHEN json_type({y}) = 'VARCHAR' THEN {test} ELSE 2 END)"
        answer = f"CASE WHEN len({seq}) = 0 THEN false ELSE {self._any(codes)} END"
        return f"CASE WHEN list_contains({raw}, {ERROR}) THEN NULL ELSE {answer} END"

    def _scalar(self, y: str, op: str, right: Literal) -> str:
        """1 (true), 0 (false) or 2 (the types do not compare: an error) for one scalar item."""
        sql_op = "=" if op == "==" else "<>" if op == "!=" else op
        kind = f"json_type({y})"
        if right.kind == "number":
            number = f"CAST({y} AS DOUBLE)"
            big = f"error({tf.string(_BIG_NUMBER)})"
            literal = f"CAST({right.value} AS DOUBLE)"
            compared = f"CASE WHEN abs({number}) >= 9007199254740992 THEN {big} ELSE ({number} {sql_op} {literal}) END"
            accepts = "IN ('BIGINT', 'UBIGINT', 'DOUBLE')"
        elif right.kind == "string":
            compared = f"json_extract_string({y}, '$') {sql_op} {tf.string(right.value)}"
            accepts = "= 'VARCHAR'"
        else:
            compared = f"CAST({y} AS BOOLEAN) {sql_op} {right.value}"
            accepts = "= 'BOOLEAN'"
        return f"CASE WHEN {kind} {accepts} THEN CAST({compared} AS INTEGER) ELSE 2 END"


def _number_method(name: str, x: str) -> str:
    """abs(), floor() or ceiling() of a JSON number (an integer stays an integer, a double a double:
    DuckDB writes it with a fraction, which the functions' output checks refuse as text); another
    item is an error (the method requires a number)."""
    integer = x
    if name == "abs":  # the negative bound of int and of bigint (Jackson's IntNode, LongNode) overflows
        integer = f"CASE WHEN {x} IN ('-2147483648', '-9223372036854775808') THEN {ERROR} ELSE ltrim({x}, '-') END"
    double = f"CAST({name.replace('ceiling', 'ceil')}(CAST({x} AS DOUBLE)) AS VARCHAR)"
    return (
        f"CASE json_type({x}) WHEN 'DOUBLE' THEN {double} "
        f"WHEN 'BIGINT' THEN {integer} WHEN 'UBIGINT' THEN {integer} ELSE {ERROR} END"
    )


def _elements(x: str) -> str:
    return f"CAST(json_extract({x}, '$[*]') AS VARCHAR[])"


def _repeated(x: str) -> str:
    return f"len(json_keys({x})) <> len(list_distinct(json_keys({x})))"


def sequence(mode: str, steps: list, input_sql: str) -> str:
    """DuckDB SQL for the path's result sequence over `input_sql` (a JSON text, the ERROR marker
    when it is not JSON, or NULL for a NULL input, which gives NULL)."""
    start = f"CASE WHEN {input_sql} IS NOT NULL THEN [{input_sql}] END"
    return _Writer(mode == "lax").steps(start, steps)
