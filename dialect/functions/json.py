"""Trino's functions/json.md. JSON functions and operators: the `json` type, `JSON '...'` literals, the JSONPath
and SQL/JSON path functions (the json_array / json_object constructors are in json_constructors.py). A json
value is held in DuckDB as the exact JSON text Trino holds (dialect/json_values.py).
"""

from __future__ import annotations

import re

from sqlglot import exp

from lakegate.dialect import json_path as jp
from lakegate.dialect import json_values as jv
from lakegate.dialect import jsonpath_steps as jps
from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.arguments import fixed, literal_str, need
from lakegate.dialect.functions.binary import UDF_PREFIX
from lakegate.dialect.registry import register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call, handles, ttype


# --- JSON literals and json_parse -----------------------------------------------------------------
def _invalid_json(text: str) -> str:
    return f"Cannot convert value to JSON: '{text}'"


@handles(exp.ParseJSON)
def _json_literal(a, node, scope, env) -> TType:
    """JSON '...' is json_parse of the text (JsonUtil.jsonParse), computed at translation."""
    if not (node.args.get("is_literal") and isinstance(node.this, exp.Literal)):
        a.unsupported("JSON literal", node)
    try:
        node.meta["json"] = jv.canonical(node.this.name)
    except jv.InvalidJson:
        a.fail(f"Cannot convert '{node.this.name}' to JSON", node, "INVALID_LITERAL")
    return tt.JSON


@tf.transform(exp.ParseJSON)
def json_literal(g, node: exp.ParseJSON) -> str:
    return tf.string(node.meta["json"])


#: Consumers of json_parse(non-constant text) whose answer does not depend on the key order or
#: repeated keys of objects (which Trino's json_parse sorts and folds and DuckDB keeps).
_ORDER_BLIND = ("json_array_length", "json_array_contains", "is_json_scalar")


def _json_parse(call: Call) -> TType:
    need(call, "string")
    text = literal_str(call, 0)
    if text is not None:
        try:
            call.node.meta["json"] = jv.canonical(text)
        except jv.InvalidJson:
            call.node.meta["json"] = None
        return tt.JSON
    parent = call.node.parent
    cast_target = tt.from_datatype(parent.to) if isinstance(parent, (exp.Cast, exp.TryCast)) else None
    blind = (
        isinstance(parent, exp.Anonymous) and parent.name.lower() in _ORDER_BLIND and parent.expressions[0] is call.node
    ) or (cast_target is not None and "json" not in str(cast_target) and tt.castable_from_json(cast_target))
    if not blind:
        call.fail(
            "unsupported in lakegate: json_parse of a non-constant text whose JSON value is used as a whole "
            "(Trino sorts object keys; use json_extract_scalar or json_extract on the text itself)",
            "NOT_SUPPORTED",
        )
    return tt.JSON


def _render_json_parse(g, node, args) -> str:
    if "json" in node.meta:
        text = node.meta["json"]
        if text is None:
            # typed: DuckDB folds a function of an untyped error() to NULL without raising it
            return f"CAST({g.fail(tf.string(_invalid_json(args[0].name)))} AS VARCHAR)"
        return tf.string(text)
    value = g.sql(args[0])
    bad = g.fail(f"'Cannot convert value to JSON: ''' || {value} || ''''")
    return f"CASE WHEN {jv.valid(value)} THEN {value} WHEN {value} IS NOT NULL THEN {bad} END"


def _json_format(call: Call) -> TType:
    if len(call.args) != 1 or call.types[0] is None or call.types[0].base not in ("json", "unknown"):
        call.mismatch()
    return tt.VARCHAR


# --- JSONPath functions (JsonExtract) and JSON array functions (JsonFunctions) ---------------------
#: The Python functions (lakegate.gateway.engine.json_functions, each registered as UDF_PREFIX + its
#: name) that read JSON text as Trino does, with Jackson's streaming parser: each stops once it has
#: read what it needs, so text malformed after that still answers. They answer for the text that is
#: not JSON and where DuckDB's JSON functions do not give Trino's answer (numbers as written, ...).
STREAMED = (
    "json_extract_scalar",
    "json_extract",
    "json_size",
    "json_array_length",
    "json_array_get",
    "json_array_contains_boolean",
    "json_array_contains_bigint",
    "json_array_contains_double",
    "json_array_contains_varchar",
)


def _streamed(name: str, text: str, *args: str) -> str:
    return f"{UDF_PREFIX}{name}({', '.join((f'CAST({text} AS VARCHAR)', *args))})"


def _valid_else(text: str, fast: str, streamed: str) -> str:
    """`fast` for a text that is JSON, `streamed` for another (DuckDB runs a CASE branch only on
    the rows that take it). A json value is checked too: json_array_get gives a string element's
    text unquoted, as json."""
    return f"CASE WHEN {jv.valid(text)} THEN {fast} ELSE {streamed} END"


def _located(node: exp.Expression, text: str) -> tuple[str, str] | None:
    """The JSON document and DuckDB path that reach the value at the call's JSONPath (several paths
    when a step may be an index or a name: the value one of them finds), None where DuckDB cannot."""
    paths = jps.duckdb_paths(node.meta["steps"])
    if paths is None:
        return None
    if len(paths) == 1:
        return text, tf.string(paths[0])
    found = f"json_extract({text}, [{', '.join(map(tf.string, paths))}])"
    return f'list_filter({found}, lambda "_jp": "_jp" IS NOT NULL)[1]', "'$'"


def _path_call(name: str, g, node: exp.Expression, args) -> tuple[str, str, tuple[str, str] | None]:
    """The JSON text's SQL, the streamed function `name` at the call's JSONPath, and `_located`."""
    value = g.sql(args[0])
    return value, _streamed(name, value, tf.string(jps.udf_path(node.meta["steps"]))), _located(node, value)


_EXACT_NUMBER_TARGETS = {
    exp.DataType.Type.TINYINT,
    exp.DataType.Type.SMALLINT,
    exp.DataType.Type.INT,
    exp.DataType.Type.BIGINT,
    exp.DataType.Type.FLOAT,
    exp.DataType.Type.DOUBLE,
}


def _render_json_extract_scalar(g, node, args) -> str:
    """Trino returns a number's text as written; DuckDB re-prints numbers it parsed (2.50 -> 2.5,
    1e3 -> 1000.0, -0 -> 0): where that can differ, the streamed function answers."""
    value, streamed, located = _path_call("json_extract_scalar", g, node, args)
    if located is None:
        return streamed
    kind, text = f"json_type({located[0]}, {located[1]})", f"json_extract_string({located[0]}, {located[1]})"
    parent = node.parent
    if isinstance(parent, (exp.Cast, exp.TryCast)) and parent.to.this in _EXACT_NUMBER_TARGETS:
        # Any spelling of a number casts to the same integer (or the same error) and the same double.
        fast = f"CASE WHEN {kind} IN ('OBJECT', 'ARRAY') THEN NULL ELSE {text} END"
    else:
        fast = (
            f"CASE WHEN {kind} IN ('OBJECT', 'ARRAY') THEN NULL "
            f"WHEN {kind} = 'DOUBLE' OR ({kind} IN ('BIGINT', 'UBIGINT') AND {text} = '0' AND contains({value}, '-0')) "
            f"THEN {streamed} ELSE {text} END"
        )
    return _valid_else(value, fast, streamed)


def _json_path(call: Call, result: TType | None = None) -> TType:
    need(call, "json", "string")
    path = literal_str(call, 1)
    names = None if path is None else jps.steps(path)
    if names is None:
        call.fail("unsupported in lakegate: JSON path other than a literal $.key / [index] path", "NOT_SUPPORTED")
    call.node.meta["steps"] = names
    if result is not None:
        return result
    source = call.types[0]
    return source if source.base == "varchar" else tt.VARCHAR


def _render_json_extract(g, node, args) -> str:
    """DuckDB's JSON text of the value, unless it may differ from what Trino's Jackson writes (a
    number Java writes otherwise, a character outside the BMP, which Jackson escapes)."""
    value, streamed, located = _path_call("json_extract", g, node, args)
    if located is None:
        return streamed
    found = f"CAST(json_extract({located[0]}, {located[1]}) AS VARCHAR)"
    unsure = f"{jv.unsure_numbers(found)} OR regexp_matches({found}, '[\\x{{10000}}-\\x{{10FFFF}}]')"
    return _valid_else(value, f"CASE WHEN {unsure} THEN {streamed} ELSE {found} END", streamed)


def _render_json_size(g, node, args) -> str:
    value, streamed, located = _path_call("json_size", g, node, args)
    if located is None:
        return streamed
    kind = f"json_type({located[0]}, {located[1]})"
    fast = (
        f"CASE WHEN {kind} IS NULL THEN NULL "
        f"WHEN {kind} = 'ARRAY' THEN CAST(json_array_length({located[0]}, {located[1]}) AS BIGINT) "
        f"WHEN {kind} = 'OBJECT' THEN CAST(len(json_keys({located[0]}, {located[1]})) AS BIGINT) "
        "ELSE CAST(0 AS BIGINT) END"
    )
    return _valid_else(value, fast, streamed)


def _render_json_array_length(g, node, args) -> str:
    value = g.sql(args[0])
    fast = f"CASE WHEN json_type({value}) = 'ARRAY' THEN CAST(json_array_length({value}) AS BIGINT) END"
    return _valid_else(value, fast, _streamed("json_array_length", value))


def _json_array_contains(call: Call) -> TType:
    need(call, "json", "any")
    value = call.types[1]
    if not (value.is_numeric or value.base in ("boolean", "varchar", "unknown")):
        call.mismatch()
    return tt.BOOLEAN


def _element_matches(value: TType, element: str, needle: str) -> str:
    """Whether one array element (a JSON text) is `needle`: a JSON boolean for a boolean, an integer
    token in bigint range for an integral number, a token with a fraction or exponent for another
    number (compared as doubles, finite only), a JSON string for a varchar (jsonArrayContains)."""
    kind = f"json_type({element})"
    if value.base == "boolean":
        return f"{kind} = 'BOOLEAN' AND TRY_CAST({element} AS BOOLEAN) = {needle}"
    if value.is_integral:
        return f"{kind} IN ('BIGINT', 'UBIGINT') AND TRY_CAST(CAST({element} AS VARCHAR) AS BIGINT) = {needle}"
    if value.is_numeric:
        return (
            f"{kind} = 'DOUBLE' AND regexp_matches(CAST({element} AS VARCHAR), '[.eE]') "
            f"AND TRY_CAST({element} AS DOUBLE) = {needle} AND NOT isinf(TRY_CAST({element} AS DOUBLE))"
        )
    return f"{kind} = 'VARCHAR' AND json_extract_string({element}, '$') = {needle}"


def _needle_kind(value: TType) -> str:
    """Which streamed json_array_contains compares with a needle of this type."""
    if value.base == "boolean":
        return "boolean"
    return "bigint" if value.is_integral else "double" if value.is_numeric else "varchar"


def _render_json_array_contains(g, node, args) -> str:
    value = ttype(args[1])
    if value.is_unknown:
        return "CAST(NULL AS BOOLEAN)"
    text = g.sql(args[0])
    needle = g.sql(args[1]) if value.is_integral or not value.is_numeric else f"CAST({g.sql(args[1])} AS DOUBLE)"
    matches = _element_matches(value, '"_e"', needle)
    kind = _needle_kind(value)
    needle_sql = f"CAST({needle} AS {'VARCHAR' if kind == 'varchar' else kind.upper()})"
    fast = (
        f"CASE WHEN json_type({text}) = 'ARRAY' THEN "
        f'len(list_filter({jv.elements(text)}, lambda "_e": {matches})) > 0 END'
    )
    # a NaN or infinite double is in no JSON value, array or not (false before the JSON is read)
    infinite = "" if value.is_integral or not value.is_numeric else f"WHEN NOT isfinite({needle}) THEN false "
    answer = _valid_else(text, fast, _streamed(f"json_array_contains_{kind}", text, needle_sql))
    return f"CASE WHEN ({needle}) IS NULL OR ({text}) IS NULL THEN NULL {infinite}ELSE {answer} END"


def _render_json_array_get(g, node, args) -> str:
    """The element at a 0-based index (negative: from the end); NULL outside the array and for a
    JSON null element (reached from the end, Trino fails: "string is null"). A string element comes
    back unquoted, as Trino documents ("broken"). DuckDB's answer is taken for a string, boolean or
    integer element of a text that is JSON; otherwise the streamed function answers (a number as
    written, an array or object as Jackson's tree writes it, text that is not JSON)."""
    text, index = g.sql(args[0]), g.sql(args[1])
    streamed = _streamed("json_array_get", text, f"CAST({index} AS BIGINT)")
    items = jv.elements(text)
    position = f"CASE WHEN {index} >= 0 THEN {index} + 1 ELSE len({items}) + {index} + 1 END"
    element = f"CASE WHEN {position} >= 1 THEN {items}[{position}] END"
    kind = f"json_type({element})"
    # a JSON null reached from the end fails as in the real Trino 476 (not caught by try())
    null_from_end = f"error({tf.string('GENERIC_INTERNAL_ERROR: string is null')})"
    fast = (
        f"CASE WHEN json_type({text}) <> 'ARRAY' THEN NULL WHEN {kind} IS NULL THEN NULL WHEN {kind} = 'NULL' THEN "
        f"CASE WHEN {index} < 0 THEN {null_from_end} END "
        f"WHEN {kind} = 'VARCHAR' THEN json_extract_string({element}, '$') "
        f"WHEN {kind} = 'BOOLEAN' OR {kind} IN ('BIGINT', 'UBIGINT') AND NOT contains({text}, '-0') THEN {element} "
        f"ELSE {streamed} END"
    )
    return _valid_else(text, fast, streamed)


# --- SQL/JSON path functions (json_exists, json_value, json_query) ---------------------------------
_ERROR = jp.ERROR


def _sql_json_path(a, node: exp.Expression, function: str, path: exp.Expression) -> tuple[str, list]:
    """The mode and steps of a path literal (json_path.parse), or a refusal naming the function,
    the path and what in it is not translated."""
    text = path.name if isinstance(path, exp.Literal) and path.is_string else None
    if text is None:
        a.unsupported(f"JSON path {path.sql(dialect='trino')} in function '{function}' (a path literal only)", node)
    if not re.match(r"\s*(lax|strict)\b", text):  # JsonPath.g4: the mode is required
        token = re.match(r"\s*(\w+|\S)", text)
        first = token.group(1) if token else "<EOF>"
        a.fail(f"mismatched input '{first}' expecting {{'lax', 'strict'}}", path, "SYNTAX_ERROR")
    try:
        return jp.parse(text)
    except jp.PathNotSupported as error:
        a.unsupported(f"JSON path {path.sql(dialect='trino')} in function '{function}': {error}", node)


def _path_sequence(g, input_node: exp.Expression, mode: str, steps: list) -> str:
    """The path's result sequence (json_path.sequence) over the input; input that is not JSON is
    the error sequence, a NULL input NULL."""
    value = g.sql(input_node)
    if ttype(input_node).base != "json":  # the text compacted, as Trino writes the item it read
        compact = f"CAST(json({value}) AS VARCHAR)"
        value = f"CASE WHEN {jv.valid(value)} THEN {compact} WHEN {value} IS NOT NULL THEN {_ERROR} END"
    return jp.sequence(mode, steps, value)


def _check_input(a, node, input_node: exp.Expression, scope, env, function: str) -> None:
    _check_input_type(a, input_node, a.expr(input_node, scope, env), function)


def _check_input_type(a, input_node: exp.Expression, t: TType, function: str) -> None:
    """The input of json_exists, json_value and json_query is text (or bytes) to read as JSON: a
    value of type json or any other type is Trino's TYPE_MISMATCH."""
    if t.base == "varbinary":
        a.unsupported(f"{function} of varbinary input", input_node)
    if t.base not in ("varchar", "unknown"):
        a.fail(f"Cannot read input of type {t} as JSON using formatting JSON", input_node, "TYPE_MISMATCH")


def _json_exists(call: Call) -> TType:
    for clause in ("passing", "encoding"):
        if call.node.meta.get(clause):
            call.fail(f"unsupported in lakegate: json_exists ... {clause.upper()}", "NOT_SUPPORTED")
    if call.node.meta.get("on_error") == "ERROR":
        call.fail("unsupported in lakegate: json_exists ... ERROR ON ERROR", "NOT_SUPPORTED")
    _check_input_type(call.analyzer, call.args[0], call.types[0], "json_exists")
    need(call, "string", "string")
    call.node.meta["path"] = _sql_json_path(call.analyzer, call.node, "json_exists", call.args[1])
    return tt.BOOLEAN


def _render_json_exists(g, node, args) -> str:
    """true for an item, false for none; an error is as the ON ERROR clause says: FALSE (the
    default), TRUE or UNKNOWN (NULL) (json.md json_exists)."""
    mode, steps = node.meta["path"]
    result = _path_sequence(g, args[0], mode, steps)
    on_error = {"TRUE": "true", "UNKNOWN": "NULL"}.get(node.meta.get("on_error"), "false")
    body = f'CASE WHEN "_r" IS NULL THEN NULL WHEN list_contains("_r", {_ERROR}) THEN {on_error} ELSE len("_r") > 0 END'
    return f'list_transform([{result}], lambda "_r": {body})[1]'


def _bind(sql: str, name: str, body: str) -> str:
    """`body` with `sql` computed once and named `name` (a DuckDB lambda over a one-element list)."""
    return f"list_transform([{sql}], lambda {name}: {body})[1]"


def _on(a, node, clause, what: str, allowed: tuple[str, ...]):
    """An ON EMPTY / ON ERROR behaviour: NULL (the default), EMPTY ARRAY, EMPTY OBJECT, or a DEFAULT
    expression; ERROR and the others are refused naming the clause."""
    if clause is None or clause is False:
        return "NULL"
    text = clause if isinstance(clause, str) else clause.name if isinstance(clause, exp.Var) else None
    if text is None:
        if "DEFAULT" not in allowed:
            a.unsupported(f"DEFAULT ... ON {what}", node)
        return clause
    behaviour = text.upper().rsplit(" ON ", 1)[0].strip()
    if behaviour not in allowed:
        a.unsupported(f"{behaviour} ON {what}", node)
    return behaviour


_VALUE_TARGETS = ("varchar", "bigint", "integer", "smallint", "tinyint", "double", "real", "boolean")


@handles(exp.JSONValue)
def _json_value(a, node, scope, env) -> TType:
    """json_value(input, path [RETURNING type] [NULL | DEFAULT x ON EMPTY] [NULL | DEFAULT x ON ERROR])."""
    for key in set(node.args) - {"this", "path", "returning", "on_condition"}:
        if node.args.get(key):
            a.unsupported(f"json_value ... {key.upper()}", node)
    _check_input(a, node, node.this, scope, env, "json_value")
    node.meta["path"] = _sql_json_path(a, node, "json_value", node.args["path"])
    returning = node.args.get("returning")
    target = tt.from_datatype(returning) if returning else tt.VARCHAR
    if target.base not in _VALUE_TARGETS:
        a.unsupported(f"json_value ... RETURNING {target}", node)
    condition = node.args.get("on_condition")
    on = condition.args if condition is not None else {}
    allowed = ("NULL", "DEFAULT")
    node.meta["on"] = {what: _on(a, node, on.get(what.lower()), what, allowed) for what in ("EMPTY", "ERROR")}
    for default in node.meta["on"].values():
        if isinstance(default, exp.Expression) and tt.common_super_type(a.expr(default, scope, env), target) is None:
            a.fail(f"Function json_value default value type does not match {target}", default, "TYPE_MISMATCH")
    return target


def _behaviour(g, choice, target: TType) -> str:
    if isinstance(choice, exp.Expression):
        return g.coerce(choice, target)
    return {"NULL": "NULL", "EMPTY ARRAY": "'[]'", "EMPTY OBJECT": "'{}'"}[choice]


_UNSURE_VALUE = "NOT_SUPPORTED: json_value of a non-integer JSON number as varchar (its text is not kept)"


@tf.transform(exp.JSONValue)
def json_value(g, node: exp.JSONValue) -> str:
    """The scalar item as the RETURNING type (json.md json_value): an empty result is ON EMPTY, a
    structural error, a non-scalar item, input that is not JSON or a failed conversion is ON ERROR
    (NULL unless DEFAULT); a JSON null is NULL."""
    target = ttype(node)
    mode, steps = node.meta["path"]
    empty, error = (_behaviour(g, node.meta["on"][w], target) for w in ("EMPTY", "ERROR"))
    item = '"_r"'
    kind = f"json_type({item})"
    g.in_try += 1  # a conversion that fails is NULL here, then ON ERROR
    try:
        if target.base == "varchar":
            converted = (
                f"CASE WHEN {kind} = 'VARCHAR' THEN json_extract_string({item}, '$') "
                f"WHEN {kind} = 'BOOLEAN' OR NOT regexp_matches({item}, '[.eE]') THEN {item} "
                f"ELSE error({tf.string(_UNSURE_VALUE)}) END"
            )
        else:
            converted = jv.from_json(g, item, target)
    finally:
        g.in_try -= 1
    body = (
        f"CASE WHEN {item} IS NULL THEN {empty} WHEN {item} = {_ERROR} THEN {error} "
        f"WHEN {kind} = 'NULL' THEN NULL WHEN {kind} IN ('OBJECT', 'ARRAY') THEN {error} "
        f"ELSE coalesce({converted}, {error}) END"
    )
    # the one item of the sequence: a JSON text, NULL (empty) or the error marker (also for more than one item)
    single = f'CASE WHEN list_contains("_s", {_ERROR}) OR len("_s") > 1 THEN {_ERROR} ELSE "_s"[1] END'
    value = f'CASE WHEN "_s" IS NULL THEN NULL ELSE {_bind(single, item, body)} END'  # NULL input: NULL
    return _bind(_path_sequence(g, node.this, mode, steps), '"_s"', value)


_WRAPPERS = {
    None: "WITHOUT",
    "WITHOUT WRAPPER": "WITHOUT",
    "WITHOUT ARRAY WRAPPER": "WITHOUT",
    "WITH WRAPPER": "UNCONDITIONAL",
    "WITH ARRAY WRAPPER": "UNCONDITIONAL",
    "WITH UNCONDITIONAL WRAPPER": "UNCONDITIONAL",
    "WITH UNCONDITIONAL ARRAY WRAPPER": "UNCONDITIONAL",
    "WITH CONDITIONAL WRAPPER": "CONDITIONAL",
    "WITH CONDITIONAL ARRAY WRAPPER": "CONDITIONAL",
}


@handles(exp.JSONExtract)
def _json_query(a, node, scope, env) -> TType:
    """json_query(input, path [WITH | WITHOUT ... WRAPPER] [KEEP | OMIT QUOTES] [ON EMPTY] [ON ERROR])."""
    if not node.args.get("json_query"):
        a.unsupported("JSON path operator", node)
    returning = node.args.get("returning")  # RETURNING varchar: the default for text, json's text for json
    varchar = isinstance(returning, exp.DataType) and returning.is_type("varchar") and not returning.expressions
    node.meta["varchar"] = varchar
    for key in (
        set(node.args)
        - {"this", "expression", "json_query", "option", "quote", "on_condition"}
        - ({"returning"} if node.meta["varchar"] else set())
    ):
        if node.args.get(key):
            a.unsupported(f"json_query ... {key.upper()}", node)
    _check_input(a, node, node.this, scope, env, "json_query")
    node.meta["path"] = _sql_json_path(a, node, "json_query", node.args["expression"])
    option = node.args.get("option")
    wrapper = " ".join((option.name if option is not None else "").upper().split()) or None
    if wrapper not in _WRAPPERS:
        a.unsupported(f"json_query ... {wrapper}", node)
    quote = node.args.get("quote")
    omit = quote is not None and quote.args.get("option", "").upper() == "OMIT"
    if omit and quote.args.get("scalar") is False and _WRAPPERS[wrapper] != "WITHOUT":
        a.fail("OMIT QUOTES behavior is not specified for WITH ARRAY WRAPPER", node, "INVALID_FUNCTION_ARGUMENT")
    condition = node.args.get("on_condition")
    on = condition.args if condition is not None else {}
    allowed = ("NULL", "EMPTY ARRAY", "EMPTY OBJECT")
    node.meta["on"] = {what: _on(a, node, on.get(what.lower()), what, allowed) for what in ("EMPTY", "ERROR")}
    node.meta["wrapper"], node.meta["omit"] = _WRAPPERS[wrapper], omit
    return tt.VARCHAR


_UNSURE_ITEM = "NOT_SUPPORTED: json_query of a value holding a non-integer JSON number (its text is not kept)"

_REPEATED_ITEM_KEY = (
    "NOT_SUPPORTED: json_query of a value holding an object with a repeated key (Trino keeps its last member)"
)


def _repeated_key(item: str) -> str:
    """Whether the JSON text `item` holds, at any depth, an object with a key twice: Trino's path
    engine reads the input into a tree (the last member of a key wins), DuckDB keeps the text."""
    values = f"list_concat([CAST({item} AS JSON)], json_extract(CAST({item} AS JSON), '$..*'))"
    repeated = 'json_type("_v") = \'OBJECT\' AND len(json_keys("_v")) <> len(list_distinct(json_keys("_v")))'
    return f'coalesce(list_bool_or(list_transform({values}, lambda "_v": {repeated})), false)'


@tf.transform(exp.JSONExtract)
def json_query(g, node: exp.JSONExtract) -> str:
    """The item as JSON text (json.md json_query): wrapped in an array as the WRAPPER clause says,
    a string unquoted with OMIT QUOTES; empty is ON EMPTY, an error ON ERROR (both NULL unless
    EMPTY ARRAY / EMPTY OBJECT). An item holding a non-integer number or an object with a repeated
    key is refused at run time."""
    mode, steps = node.meta["path"]
    empty, error = (_behaviour(g, node.meta["on"][w], tt.VARCHAR) for w in ("EMPTY", "ERROR"))
    items, first = '"_s"', '"_s"[1]'

    def checked(text: str) -> str:
        return (
            f"CASE WHEN regexp_matches({jv.without_strings(text)}, '[0-9][.eE]') "
            f"THEN error({tf.string(_UNSURE_ITEM)}) "
            f"WHEN {_repeated_key(text)} THEN error({tf.string(_REPEATED_ITEM_KEY)}) ELSE {text} END"
        )

    wrapped = checked(f"'[' || array_to_string({items}, ',') || ']'")
    wrapper = node.meta["wrapper"]
    if wrapper == "UNCONDITIONAL":
        text = wrapped
    elif wrapper == "CONDITIONAL":
        one_structure = f"len({items}) = 1 AND json_type({first}) IN ('ARRAY', 'OBJECT')"
        text = f"CASE WHEN {one_structure} THEN {checked(first)} ELSE {wrapped} END"
    else:
        single = checked(first)
        if node.meta["omit"]:
            single = (
                f"CASE WHEN json_type({first}) = 'VARCHAR' THEN json_extract_string({first}, '$') ELSE {single} END"
            )
        text = f"CASE WHEN len({items}) > 1 THEN {error} ELSE {single} END"
    body = (
        f"CASE WHEN {items} IS NULL THEN NULL WHEN list_contains({items}, {_ERROR}) THEN {error} "
        f"WHEN len({items}) = 0 THEN {empty} ELSE {text} END"
    )
    return _bind(_path_sequence(g, node.this, mode, steps), items, body)


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "json_parse",
        "json",
        "json_parse(string) -> json",
        _json_parse,
        _render_json_parse,
        notes="Of a non-constant text only where the value's object key order cannot matter "
        "(json_array_length, json_array_contains, is_json_scalar, CAST to SQL types).",
    )

    register(
        "json_format",
        "json",
        "json_format(json) -> varchar",
        _json_format,
        lambda g, node, args: f"CAST({g.sql(args[0])} AS VARCHAR)",
    )

    register(
        "is_json_scalar",
        "json",
        "is_json_scalar(json) -> boolean",
        fixed(tt.BOOLEAN, "json"),
        lambda g, node, args: (
            f"CASE WHEN NOT {jv.valid(g.sql(args[0]))} THEN "
            f"{g.fail(tf.string('Invalid JSON value: ') + ' || ' + g.sql(args[0]))} "
            f"ELSE json_type({g.sql(args[0])}) NOT IN ('OBJECT', 'ARRAY') END"
        ),
    )
    register(
        "json_extract_scalar",
        "json",
        "json_extract_scalar(json, json_path) -> varchar",
        _json_path,
        _render_json_extract_scalar,
        notes="NULL for objects, arrays and missing keys; a number's text as written (2.50). Text that is "
        "not JSON is read as Trino's streaming parser reads it: the value is found if the text is "
        "well-formed up to it ('[1,]' -> '1').",
    )
    register(
        "json_extract",
        "json",
        "json_extract(json, json_path) -> json",
        lambda call: _json_path(call, tt.JSON),
        _render_json_extract,
        notes="NULL for missing paths; numbers written as Jackson writes them (1e3 -> 1000.0). Text that is "
        "not JSON is read as Trino's streaming parser reads it: the value is found if the text is "
        "well-formed up to its end.",
    )

    register(
        "json_size",
        "json",
        "json_size(json, json_path) -> bigint",
        lambda call: _json_path(call, tt.BIGINT),
        _render_json_size,
    )

    register(
        "json_array_length",
        "json",
        "json_array_length(json) -> bigint",
        fixed(tt.BIGINT, "json"),
        _render_json_array_length,
    )

    register(
        "json_array_contains",
        "json",
        "json_array_contains(json, value) -> boolean",
        _json_array_contains,
        _render_json_array_contains,
    )

    register(
        "json_array_get",
        "json",
        "json_array_get(json_array, index) -> json",
        fixed(tt.JSON, "json", "integral"),
        _render_json_array_get,
    )

    register(
        "json_exists",
        "json",
        "json_exists(json_input, json_path) -> boolean",
        _json_exists,
        _render_json_exists,
        notes="Paths in lax or strict mode as json_path.py translates them (accessors, wildcards, subscripts, last, "
        "filters, size(), type(), abs(), floor(), ceiling()); FALSE (the default), TRUE and UNKNOWN ON ERROR. "
        "Other path features, PASSING and ERROR ON ERROR are refused (NOT_SUPPORTED).",
    )
