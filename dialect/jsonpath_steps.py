"""The JSONPath of Trino's json_extract, json_extract_scalar and json_size
(io.trino.operator.scalar.JsonPathTokenizer): `$`, then steps `.name`, `[name]` or `["name"]` (in
quotes, `\\"` and `\\\\` escaped). Each step is an object's member of that name or, when the name
is a Java int (`0`, `01`, `+1`), an array's element: `$[0]` reads `{"0": 5}` and `$["1"]` reads
`[5, 6]`. lakegate reads unquoted names of ASCII letters, digits and '_' (and ':' after a dot).
"""

from __future__ import annotations

import itertools
import json
import re

_STEP = re.compile(r'\.([A-Za-z0-9_:]+)|\[([A-Za-z0-9_]+)\]|\["((?:[^"\\]|\\["\\])*)"\]')
_INDEX = re.compile(r"[+-]?[0-9]+")
#: At most this many steps that may be an index or a name (2**n DuckDB paths are tried).
_AMBIGUOUS = 3


def steps(path: str) -> list[str] | None:
    """The names of the path's steps, None for a path lakegate does not read."""
    if not path.startswith("$"):
        return None
    names, at = [], 1
    while at < len(path):
        match = _STEP.match(path, at)
        if match is None:
            return None
        dotted, bare, quoted = match.groups()
        names.append(dotted or bare or re.sub(r"\\(.)", r"\1", quoted))
        at = match.end()
    return names


def index(name: str) -> int | None:
    """The array index a step's name reads (Integer.parseInt), None when it reads none."""
    if not _INDEX.fullmatch(name) or len(name.lstrip("+-").lstrip("0")) > 10:
        return None
    value = int(name)
    return value if 0 <= value < 2**31 else None


def udf_path(names: list[str]) -> str:
    """The path as the streaming functions take it (gateway/engine/json_functions.py): its names as a
    JSON array."""
    return json.dumps(names, ensure_ascii=False)


def duckdb_paths(names: list[str]) -> list[str] | None:
    """DuckDB JSON paths that together read the path: one per choice of index or name for each step
    that may be either (at most one of them finds a value). None when DuckDB cannot write a name
    (empty, or holding a quote or backslash) or too many steps may be either."""
    choices = []
    for name in names:
        if not name or '"' in name or "\\" in name:
            return None
        position = index(name)
        choices.append([f'."{name}"'] + ([f"[{position}]"] if position is not None else []))
    if sum(len(c) > 1 for c in choices) > _AMBIGUOUS:
        return None
    return ["$" + "".join(combination) for combination in itertools.product(*choices)]
