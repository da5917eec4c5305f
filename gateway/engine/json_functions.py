"""Trino 476's JSONPath and JSON array functions over JSON text, reading it as Trino does with
Jackson's streaming parser (json_stream.py): io.trino.operator.scalar.JsonExtract (json_extract_scalar,
json_extract, json_size: one ObjectFieldJsonExtractor per path step) and JsonFunctions
(json_array_length, json_array_contains, json_array_get). Each answers as soon as it has read what
it needs, NULL where the text is malformed before that. lakegate.gateway.engine.udfs registers them;
the translation (lakegate.dialect.functions.json) calls them where DuckDB's own JSON functions cannot
give Trino's answer (text that is not JSON, numbers as written, ...).

A path arrives as the JSON array of its steps' names (`["a","0"]` for `$.a[0]`): each step is an
object's member of that name, or an array's element when the name is a Java int (Integer.parseInt).
"""

from __future__ import annotations

import functools
import json
import re

from lakegate.dialect.json_values import java_double
from lakegate.dialect.jsonpath_steps import index
from lakegate.gateway.engine.json_stream import (
    END_ARRAY,
    END_OBJECT,
    FLOAT,
    INT,
    NAME,
    NULL,
    SCALARS,
    START_ARRAY,
    START_OBJECT,
    STRING,
    TRUE,
    MalformedJson,
    Parser,
    utf8_text,
)


@functools.lru_cache(maxsize=256)
def _steps(path: str) -> tuple[tuple[str, int], ...]:
    """Each step's name and the array index it reads (-1: none)."""
    return tuple((name, -1 if (position := index(name)) is None else position) for name in json.loads(path))


def _walk(parser: Parser, path: str) -> bool:
    """Read up to the value at `path` (its first token current); False when there is none."""
    if parser.next_token() is None:
        return False
    for name, wanted in _steps(path):
        if parser.token == START_OBJECT:
            while parser.next_token() != END_OBJECT:
                found = parser.name == name
                parser.next_token()
                if found:
                    break
                parser.skip_children()
            else:
                return False
        elif parser.token == START_ARRAY:
            position = 0
            while True:
                if parser.next_token() == END_ARRAY:
                    return False
                if position == wanted:
                    break
                position += 1
                parser.skip_children()
        else:
            return False
    return True


def _answer(function):
    """`function` answering NULL (None) for a NULL argument, and where the text is malformed at the
    point it reads."""

    @functools.wraps(function)
    def answer(*args):
        if any(arg is None for arg in args):
            return None
        try:
            return function(*args)
        except MalformedJson:
            return None

    return answer


# --- writing JSON as Jackson does ----------------------------------------------------------------
_CONTROL = {"\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r", '"': '\\"', "\\": "\\\\"}
_GENERATOR_ESCAPED = re.compile('["\\\\\x00-\x1f\ud800-\udfff\U00010000-\U0010ffff]')
_TREE_ESCAPED = re.compile('["\\\\\x00-\x1f]')


def _escape(ch: str) -> str:
    if ch in _CONTROL:
        return _CONTROL[ch]
    code = ord(ch)
    if code > 0xFFFF:  # a pair of UTF-16 surrogates, each escaped
        code -= 0x10000
        return f"\\u{0xD800 + (code >> 10):04X}\\u{0xDC00 + (code & 0x3FF):04X}"
    return f"\\u{code:04X}"


def generator_string(text: str) -> str:
    """A JSON string as Trino's UTF-8 JsonGenerator writes it (json_extract): quote, backslash and
    control characters escaped (\\n, \\t, ... or \\u00XX), and every UTF-16 surrogate as \\uXXXX."""
    return '"' + _GENERATOR_ESCAPED.sub(lambda m: _escape(m.group()), text) + '"'


def _tree_string(text: str) -> str:
    """A JSON string as a Jackson tree's toString writes it (json_array_get): quote, backslash and
    control characters escaped, other characters as they are."""
    return '"' + _TREE_ESCAPED.sub(lambda m: _escape(m.group()), text) + '"'


def _number(parser: Parser) -> str:
    """A number as Jackson writes the value it read: an integer exactly (-0 is 0), a float as a
    double (Java's Double.toString; out of range, the string "Infinity")."""
    if parser.token == INT:
        return "0" if parser.raw == "-0" else parser.raw
    value = float(parser.raw)
    if value in (float("inf"), float("-inf")):
        return '"Infinity"' if value > 0 else '"-Infinity"'
    return java_double(value)


def _scalar(parser: Parser, string) -> str:
    if parser.token == STRING:
        return string(parser.text())
    if parser.token in (INT, FLOAT):
        return _number(parser)
    return parser.raw


def _copy(parser: Parser) -> str:
    """The current value as Trino's json_extract writes it (JsonGenerator.copyCurrentStructure):
    compact, members in the order written (a repeated key kept)."""
    out: list[str] = []
    comma = [False]  # per open container: whether the next entry follows another
    depth = 0
    token = parser.token
    while True:
        if token in (END_ARRAY, END_OBJECT):
            out.append(token)
            comma.pop()
            comma[-1] = True
            depth -= 1
        elif token == NAME:
            out.append(("," if comma[-1] else "") + generator_string(parser.name) + ":")
            comma[-1] = False
        else:
            out.append("," if comma[-1] else "")
            comma[-1] = True
            if token in (START_ARRAY, START_OBJECT):
                out.append(token)
                comma.append(False)
                depth += 1
            else:
                out.append(_scalar(parser, generator_string))
        if depth == 0:
            return "".join(out)
        token = parser.next_token()


def _tree(parser: Parser):
    """The current value as a Jackson tree (readValueAsTree): objects as dicts (a repeated key keeps
    its first place and its last value), scalars as their JSON text."""
    if parser.token == START_ARRAY:
        items = []
        while parser.next_token() != END_ARRAY:
            items.append(_tree(parser))
        return items
    if parser.token == START_OBJECT:
        members = {}
        while parser.next_token() != END_OBJECT:
            name = parser.name
            parser.next_token()
            members[name] = _tree(parser)
        return members
    return _scalar(parser, _tree_string)


def _tree_text(value) -> str:
    if isinstance(value, list):
        return "[" + ",".join(map(_tree_text, value)) + "]"
    if isinstance(value, dict):
        return "{" + ",".join(f"{_tree_string(k)}:{_tree_text(v)}" for k, v in value.items()) + "}"
    return value


# --- the functions --------------------------------------------------------------------------------
@_answer
def json_extract_scalar(text: str, path: str) -> str | None:
    """The scalar at `path` (a string unescaped, a number as written); NULL for null, arrays, objects."""
    parser = Parser(text)
    if not _walk(parser, path) or parser.token not in SCALARS:
        return None
    return utf8_text(parser.text())


@_answer
def json_extract(text: str, path: str) -> str | None:
    """The JSON text of the value at `path`."""
    parser = Parser(text)
    return _copy(parser) if _walk(parser, path) else None


@_answer
def json_size(text: str, path: str) -> int | None:
    """The number of elements or members of the value at `path`; 0 for a scalar."""
    parser = Parser(text)
    if not _walk(parser, path):
        return None
    if parser.token not in (START_ARRAY, START_OBJECT):
        return 0
    end, size = (END_ARRAY if parser.token == START_ARRAY else END_OBJECT), 0
    while parser.next_token() != end:  # an object's names are counted, an array's values
        if parser.token == NAME or end == END_ARRAY:
            size += 1
        parser.skip_children()
    return size


def _array(parser: Parser) -> bool:
    return parser.next_token() == START_ARRAY


@_answer
def json_array_length(text: str) -> int | None:
    parser = Parser(text)
    if not _array(parser):
        return None
    length = 0
    while parser.next_token() != END_ARRAY:
        parser.skip_children()
        length += 1
    return length


def _contains(matches):
    """json_array_contains for one type of needle: whether an element `matches(parser, needle)`,
    each element read (and skipped) in turn (JsonFunctions.varcharJsonArrayContains)."""

    @_answer
    def contains(text: str, needle) -> bool | None:
        parser = Parser(text)
        if not _array(parser):
            return None
        while parser.next_token() != END_ARRAY:
            parser.skip_children()
            if matches(parser, needle):
                return True
        return False

    return contains


def _long(parser: Parser) -> int | None:
    value = int(parser.raw) if parser.token == INT and len(parser.raw) < 21 else None
    return value if value is not None and -(2**63) <= value < 2**63 else None


json_array_contains_boolean = _contains(lambda p, needle: p.token == (TRUE if needle else "false"))
json_array_contains_bigint = _contains(lambda p, needle: _long(p) == needle)
json_array_contains_double = _contains(lambda p, needle: p.token == FLOAT and float(p.raw) == needle)
json_array_contains_varchar = _contains(lambda p, needle: p.token == STRING and p.text() == needle)


def _element(parser: Parser) -> str | None:
    """An element as json_array_get gives it: a string unescaped, a number as written, an array or
    object as its Jackson tree's text; NULL for null."""
    if parser.token in (START_ARRAY, START_OBJECT):
        try:
            return utf8_text(_tree_text(_tree(parser)))
        except RecursionError:
            raise RuntimeError("NOT_SUPPORTED: json_array_get of an element nested too deeply") from None
    if parser.token == NULL:
        return None
    return utf8_text(parser.text())


_NULL_ELEMENT = "GENERIC_INTERNAL_ERROR: string is null"


@_answer
def json_array_get(text: str, index: int) -> str | None:
    """The element at `index` (negative: from the end, which reads the whole array)."""
    if index == -(2**63):
        return None
    parser = Parser(text)
    if not _array(parser):
        return None
    last: list[str | None] = []
    position = 0
    while parser.next_token() != END_ARRAY:
        element = _element(parser)
        if position == index:
            return element
        if index < 0:
            last.append(element)
            if len(last) > -index:
                last.pop(0)
        position += 1
    if index < 0 and len(last) == -index:
        if last[0] is None:
            raise RuntimeError(_NULL_ELEMENT)
        return last[0]
    return None
