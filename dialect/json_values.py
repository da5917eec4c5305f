"""Trino's JSON values in DuckDB SQL: DuckDB holds a Trino `json` value as the exact JSON text
Trino holds (compact, keys as Trino orders them) in a VARCHAR. This module writes the SQL that reads such
texts (validity, element lists, casts to SQL types) and that writes SQL values as JSON text
(`CAST(x AS JSON)`), shared by the casts (transforms.py) and the JSON functions
(functions/json.py).

Facts followed (trinodb/trino 4xx, core/trino-main): io.trino.util.JsonUtil (JSON_FACTORY, the
canonical text of json_parse: Jackson with ORDER_MAP_ENTRIES_BY_KEYS), io.trino.type.JsonOperators
(CAST from json to scalars), io.trino.type.JsonToArrayCast, io.trino.type.ArrayToJsonCast and
docs/src/main/sphinx/functions/json.md ("Cast to JSON", "Cast from JSON").
"""

from __future__ import annotations

import json
from decimal import Decimal

from lakegate.dialect import registry
from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect import write_casts as casts
from lakegate.dialect.trino_types import TType


# --- Trino's canonical JSON text (json_parse, JSON literals), computed at translation -----------
class InvalidJson(ValueError):
    """Text Trino's json_parse refuses."""


def _no_constant(name: str):
    raise InvalidJson(name)


def java_double(value: float) -> str:
    """Java's Double.toString (what Jackson writes for a double): the shortest digits that round
    trip, plain for 1e-3 <= |v| < 1e7 (1.5, 100.0), else computerized scientific (1.0E20, 2.0E-5)."""
    if value == 0:
        return "-0.0" if str(value).startswith("-") else "0.0"
    sign, digits, exponent = Decimal(repr(value)).normalize().as_tuple()
    text = "".join(map(str, digits))
    point = len(text) + exponent  # position of the decimal point in `text`
    prefix = "-" if sign else ""
    if 1e-3 <= abs(value) < 1e7:
        if point <= 0:
            return f"{prefix}0.{'0' * -point}{text}"
        whole, fraction = text[:point].ljust(point, "0"), text[point:]
        return f"{prefix}{whole}.{fraction or '0'}"
    return f"{prefix}{text[0]}.{text[1:] or '0'}E{point - 1}"


def _write(value) -> str:
    if isinstance(value, dict):
        keys = sorted(value, key=lambda k: k.encode("utf-16-be"))  # Java's String order (UTF-16 units)
        return "{" + ",".join(f"{_write(k)}:{_write(value[k])}" for k in keys) + "}"
    if isinstance(value, list):
        return "[" + ",".join(_write(v) for v in value) + "]"
    if isinstance(value, float):
        if value != value or value in (float("inf"), float("-inf")):
            raise InvalidJson("a number out of the range of a double")
        return java_double(value)
    return json.dumps(value, ensure_ascii=False)  # str, int (exact), bool, None


def canonical(text: str) -> str:
    """The text of Trino's json_parse(text) (JsonUtil, Jackson with ORDER_MAP_ENTRIES_BY_KEYS):
    compact, object keys sorted (a repeated key keeps its last value), integers exact, other numbers
    as Java doubles. InvalidJson for text Jackson refuses (NaN, trailing commas, trailing text)."""
    try:
        value = json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError):
        raise InvalidJson(text) from None
    return _write(value)


# --- reading JSON text in DuckDB -----------------------------------------------------------------
def without_strings(sql: str) -> str:
    """The JSON text with each string token emptied (so that patterns see only structure and numbers)."""
    return f"regexp_replace({sql}, '\"([^\"\\\\]|\\\\.)*\"', '\"\"', 'g')"


def valid(sql: str) -> str:
    """Whether the text is JSON Trino's parser accepts: DuckDB's json_valid, less the extensions it
    allows (NaN and Infinity, trailing commas)."""
    bare = without_strings(sql)
    return (
        f"(json_valid({sql}) AND NOT regexp_matches({bare}, ',\\s*[\\]}}]') "
        f"AND NOT regexp_matches(regexp_replace({bare}, 'true|false|null', '', 'g'), '[A-DF-Za-df-z]'))"
    )


def kind(sql: str) -> str:
    """DuckDB's json_type of a valid text: OBJECT, ARRAY, VARCHAR, BIGINT, UBIGINT, DOUBLE, BOOLEAN, NULL."""
    return f"json_type({sql})"


def elements(sql: str) -> str:
    """The elements of a JSON array text, as a DuckDB list of JSON texts (VARCHAR, as json is held;
    a JSON null element is the text null)."""
    return f"CAST(json_extract({sql}, '$[*]') AS VARCHAR[])"


_UNSURE_NUMBER = "NOT_SUPPORTED: a non-integer JSON number whose text Trino and DuckDB may write differently"


def exact_numbers(sql: str) -> str:
    """The JSON text DuckDB wrote (re-serialising what it parsed), refused where a number in it may
    be written otherwise than by Trino's Jackson (Java's Double.toString): numbers with an exponent,
    and numbers outside 1e-3 <= |v| < 1e7 written with a fraction. Refused also inside try(): Trino
    answers there."""
    return f"CASE WHEN {unsure_numbers(sql)} THEN error({tf.string(_UNSURE_NUMBER)}) ELSE {sql} END"


def unsure_numbers(sql: str) -> str:
    """Whether the JSON text DuckDB wrote holds a number Trino's Jackson may write otherwise (see
    `exact_numbers`)."""
    unsure = "([0-9][eE])|([0-9]{8,}[.])|((^|[^0-9])0[.]000)"
    return f"regexp_matches({without_strings(sql)}, {tf.string(unsure)})"


def _is_float(sql: str) -> str:
    """Whether a JSON number text is a float token (with a fraction or exponent), as Jackson's
    VALUE_NUMBER_FLOAT; otherwise it is an integer token (VALUE_NUMBER_INT), of any size."""
    return f"regexp_matches(CAST({sql} AS VARCHAR), '[.eE]')"


# --- CAST(json AS type) ----------------------------------------------------------------------------
def from_json(g, sql: str, target: TType) -> str:
    """CAST(json AS target) for a JSON text `sql` (JsonOperators, JsonToArrayCast; TestJsonOperators):
    JSON null is NULL; a string converts as a varchar cast would; a float token as a double would;
    an integer token exactly (out of range: INVALID_CAST_ARGUMENT); true/false as 1/0; an array or
    object (or an array where a scalar is wanted, and back) fails with INVALID_CAST_ARGUMENT."""
    kind_ = kind(sql)
    bad = g.fail(f"'Cannot cast to {target}. ' || CAST({sql} AS VARCHAR)", "INVALID_CAST_ARGUMENT")
    if target.base == "json":
        return sql
    null = f"WHEN {kind_} IS NULL OR {kind_} = 'NULL' THEN NULL"
    if target.base == "array":
        inner = from_json(g, '"_j"', target.element)
        each = tf.cast(f'list_transform({elements(sql)}, lambda "_j": {inner})', target)
        present = f'len(list_filter({elements(sql)}, lambda "_j": json_type("_j") <> \'NULL\'))'
        each = casts.whole_in_try(g, present, each)
        return f"CASE {null} WHEN {kind_} = 'ARRAY' THEN {each} ELSE {bad} END"
    if target.base == "map":
        return f"CASE {null} WHEN {kind_} = 'OBJECT' THEN {_object_to_map(g, sql, target)} ELSE {bad} END"
    if target.base == "row":
        return (
            f"CASE {null} WHEN {kind_} = 'ARRAY' THEN {_array_to_row(g, sql, target, bad)} "
            f"WHEN {kind_} = 'OBJECT' THEN {_object_to_row(g, sql, target, bad)} ELSE {bad} END"
        )
    text = f"json_extract_string({sql}, '$')"
    double = f"TRY_CAST({text} AS DOUBLE)"
    if target.base == "varchar":
        integer, floating, boolean = text, casts.cast_value(g, double, tt.DOUBLE, target), text
    elif target.base == "boolean":
        integer, floating, boolean = f"{_exact(g, text, tt.BIGINT, bad)} <> 0", f"{double} <> 0", f"{text} = 'true'"
    else:
        integer = _exact(g, text, target, bad) if target.is_integral else tf.cast(double, target)
        floating = _rounded(g, double, target) if target.is_integral else tf.cast(double, target)
        boolean = tf.cast(f"{text} = 'true'", target)
    return (
        f"CASE {null} WHEN {kind_} = 'VARCHAR' THEN {casts.cast_value(g, text, tt.VARCHAR, target)} "
        f"WHEN {kind_} = 'BOOLEAN' THEN {boolean} WHEN {kind_} IN ('OBJECT', 'ARRAY') THEN {bad} "
        f"WHEN {_is_float(sql)} THEN {floating} ELSE {integer} END"
    )


def _object_to_map(g, sql: str, target: TType) -> str:
    """A JSON object as map(varchar, V) (JsonToMapCast): each value cast as V; a repeated key fails
    (Trino's map refuses duplicate keys; DuckDB's json_transform answers NULL for them)."""
    members = f"json_transform({sql}, '\"MAP(VARCHAR, JSON)\"')"
    value = from_json(g, _member("struct_extract(\"_e\", 'value')", target.args[1]), target.args[1])
    entry = f'struct_pack("key" := struct_extract("_e", \'key\'), "value" := {value})'
    each = tf.cast(f'map_from_entries(list_transform(map_entries({members}), lambda "_e": {entry}))', target)
    if g.in_try and target.args[1].base != "json":  # a value that fails makes the whole map NULL
        present = f'len(list_filter(map_values({members}), lambda "_v": "_v" IS NOT NULL))'
        each = f"CASE WHEN list_count(map_values({each})) = {present} THEN {each} END"
    duplicate = g.fail(f"'Duplicate keys are not allowed: ' || CAST({sql} AS VARCHAR)", "INVALID_CAST_ARGUMENT")
    return f"CASE WHEN {members} IS NULL THEN {duplicate} ELSE {each} END"


def _member(sql: str, t: TType) -> str:
    """A member's value of a JSON object split by json_transform, which reads a JSON null as SQL NULL:
    as a JSON value (type `t` json) it stays the JSON null (JsonToMapCast, JsonToRowCast)."""
    return f"coalesce({sql}, CAST('null' AS JSON))" if t.base == "json" else sql


def _row(g, values: list[str], target: TType) -> str:
    fields = [tf.quote(name or f"field{i}") for i, (name, _) in enumerate(target.args)]
    return "struct_pack(" + ", ".join(f"{f} := {v}" for f, v in zip(fields, values)) + ")"


def _array_to_row(g, sql: str, target: TType, bad: str) -> str:
    """A JSON array of exactly as many elements as the row has fields, field by field."""
    items = elements(sql)
    values = [from_json(g, f"{items}[{i + 1}]", t) for i, (_, t) in enumerate(target.args)]
    present = [f"json_type({items}[{i + 1}]) <> 'NULL'" for i in range(len(target.args))]
    row = casts.row_whole_in_try(g, present, _row(g, values, target), target)
    return f"CASE WHEN json_array_length({sql}) <> {len(target.args)} THEN {bad} ELSE {row} END"


_REPEATED_MEMBER = "NOT_SUPPORTED: CAST of a JSON object with a repeated key to a row"


def _object_to_row(g, sql: str, target: TType, bad: str) -> str:
    """A JSON object as a named row (JsonUtil.parseJsonToSingleRowBlock): members matched to fields
    by their lower-cased key, missing fields NULL, other members ignored, two members for one field
    an error; an anonymous row fails. An object with a repeated key is refused at run time."""
    if any(name is None for name, _ in target.args):
        return bad
    members = f"json_transform({sql}, '\"MAP(VARCHAR, JSON)\"')"
    values, present = [], []
    for name, t in target.args:
        named = f"lower(struct_extract(\"_e\", 'key')) = {tf.string(name)}"
        matching = (
            f'list_transform(list_filter(map_entries({members}), lambda "_e": {named}), '
            f'lambda "_e": struct_extract("_e", \'value\'))'
        )
        duplicate = g.fail(f"'Duplicate field: {name}'", "INVALID_CAST_ARGUMENT")
        value = from_json(g, f"CASE WHEN len({matching}) > 0 THEN {_member(f'{matching}[1]', t)} END", t)
        values.append(f"CASE WHEN len({matching}) > 1 THEN {duplicate} ELSE {value} END")
        present.append(f"len({matching}) > 0 AND json_type({matching}[1]) <> 'NULL'")
    row = casts.row_whole_in_try(g, present, _row(g, values, target), target)
    return f"CASE WHEN {members} IS NULL THEN error({tf.string(_REPEATED_MEMBER)}) ELSE {row} END"


def _exact(g, text: str, target: TType, bad: str) -> str:
    """An integer token as `target`, INVALID_CAST_ARGUMENT when out of its range (getLongValue)."""
    duck = tt.duckdb_type(target)
    return f"CASE WHEN TRY_CAST({text} AS {duck}) IS NULL THEN {bad} ELSE CAST({text} AS {duck}) END"


def _rounded(g, double: str, target: TType) -> str:
    """A float token as an integral type: rounded half away from zero, NUMERIC_VALUE_OUT_OF_RANGE
    when out of range (DoubleOperators.castToLong via JsonOperators)."""
    duck = tt.duckdb_type(target)
    message = f"'Out of range for {target}: ' || CAST({double} AS VARCHAR)"
    return (
        f"CASE WHEN TRY_CAST(round({double}) AS {duck}) IS NULL THEN {g.fail(message, 'NUMERIC_VALUE_OUT_OF_RANGE')} "
        f"ELSE CAST(round({double}) AS {duck}) END"
    )


# --- CAST(value AS json) ---------------------------------------------------------------------------
def to_json(g, sql: str, source: TType) -> str:
    """The JSON text of a SQL value (JsonUtil.JsonGeneratorWriter): numbers as Jackson writes them
    (doubles as Java's Double.toString, NaN and infinities as JSON strings, decimals as
    BigDecimal.toString), a varchar as a JSON string, an array element-wise with NULL as null. SQL
    NULL stays NULL (json.md, Cast to JSON; TestJsonOperators)."""
    return _json_text(g, sql, source)


def _json_text(g, sql: str, source: TType) -> str:
    if source.base in ("json", "unknown"):
        return f"CAST({sql} AS VARCHAR)"
    if source.base == "varchar":
        return f"CAST(to_json(CAST({sql} AS VARCHAR)) AS VARCHAR)"
    if source.base == "boolean":
        return f"CASE WHEN {sql} THEN 'true' WHEN NOT {sql} THEN 'false' END"
    if source.is_approx:
        value = f"CAST({sql} AS DOUBLE)" if source.base == "double" else f"CAST(CAST({sql} AS VARCHAR) AS DOUBLE)"
        return (
            f"CASE WHEN isnan({value}) THEN '\"NaN\"' "
            f"WHEN isinf({value}) THEN CASE WHEN {value} > 0 THEN '\"Infinity\"' ELSE '\"-Infinity\"' END "
            f"WHEN abs({value}) >= 0.001 AND abs({value}) < 10000000 OR {value} = 0 THEN CAST({value} AS VARCHAR) "
            f"{_subnormal_real(value) if source.base == 'real' else ''}"
            f"ELSE {casts.approx_text(value, tt.DOUBLE, json=True)} END"
        )
    if source.base == "map":
        return _map_json(g, sql, source)
    if source.base == "row":
        fields = [
            f"{tf.string(json.dumps(name, ensure_ascii=False) + ':')} || "
            f"coalesce({_json_text(g, f'struct_extract({sql}, {tf.string(name)})', t)}, 'null')"
            for name, t in source.args
        ]
        body = " || ',' || ".join(fields) if fields else "''"
        return f"CASE WHEN {sql} IS NOT NULL THEN '{{' || {body} || '}}' END"
    if source.base == "array":
        inner = _json_text(g, '"_v"', source.element)
        each = f"list_transform({sql}, lambda \"_v\": coalesce({inner}, 'null'))"
        return f"'[' || array_to_string({each}, ',') || ']'"
    return casts.varchar_of(g, sql, source)  # integers and decimals: their exact text


def _subnormal_real(value: str) -> str:
    """The WHEN clause refusing a subnormal real written as JSON (Java's Float.toString digits, which
    DuckDB's text of a float does not give)."""
    what = "unsupported in lakegate: the text of a subnormal real (JSON): Java's digits differ"
    return f"WHEN abs({value}) < {casts.MIN_NORMAL['real']} THEN error({tf.string('NOT_SUPPORTED: ' + what)}) "


#: Keys whose order differs between Java's String order (UTF-16 units) and DuckDB's (code points).
_OUTSIDE_UTF16_ORDER = "[\\x{E000}-\\x{10FFFF}]"


def _map_json(g, sql: str, source: TType) -> str:
    """A map as a JSON object with its keys sorted as text (JsonUtil.MapJsonGeneratorWriter, a
    TreeMap of the key texts); keys with characters from U+E000 up are refused at run time, where
    Java's UTF-16 order and DuckDB's differ."""
    key, value = source.args
    key_sql = "struct_extract(\"_m\", 'key')"
    key_text = (
        key_sql
        if key.base == "varchar"
        else f"CASE WHEN {key_sql} THEN 'true' ELSE 'false' END"
        if key.base == "boolean"
        else f"CAST({key_sql} AS VARCHAR)"
    )
    refuse = f"error({tf.string('NOT_SUPPORTED: a json object key from U+E000 up (Java orders them otherwise)')})"
    checked = f"CASE WHEN regexp_matches({key_text}, '{_OUTSIDE_UTF16_ORDER}') THEN {refuse} ELSE {key_text} END"
    value_text = _json_text(g, "struct_extract(\"_m\", 'value')", value)
    entry = f'struct_pack("k" := {checked}, "v" := {value_text})'
    pairs = (
        f'list_transform(list_sort(list_transform(map_entries({sql}), lambda "_m": {entry})), '
        f"lambda \"_p\": CAST(to_json(struct_extract(\"_p\", 'k')) AS VARCHAR) || ':' || "
        f"coalesce(struct_extract(\"_p\", 'v'), 'null'))"
    )
    return f"'{{' || array_to_string({pairs}, ',') || '}}'"


registry.JSON_CASTS.update(to_json=to_json, from_json=from_json)
