"""upper() and lower() as Trino's Java maps each code point (Character.toUpperCase/toLowerCase, Unicode 16).

DuckDB's own mapping differs on a few code points, found by mapping every code point from U+0020 to
U+30D8F on both the real Trino 476 and DuckDB: ß stays ß in Java (DuckDB writes ẞ), and letters that
Unicode 16 paired (Latin additions, Garay) Java maps where DuckDB keeps them.
"""

from __future__ import annotations

from lakegate.dialect import transforms as tf

_GARAY = range(22)  # U+10D50..U+10D65 capital, U+10D70..U+10D85 small

#: Code points whose Java mapping DuckDB's differs from, and what Java maps them to.
UPPER: dict[str, str] = {
    "\u00df": "\u00df",
    "\u019b": "\ua7dc",
    "\u0264": "\ua7cb",
    "\u1c8a": "\u1c89",
    "\ua7cd": "\ua7cc",
    "\ua7db": "\ua7da",
    **{chr(0x10D70 + i): chr(0x10D50 + i) for i in _GARAY},
}
LOWER: dict[str, str] = {
    "\u1c89": "\u1c8a",
    "\ua7cb": "\u0264",
    "\ua7cc": "\ua7cd",
    "\ua7da": "\ua7db",
    "\ua7dc": "\u019b",
    **{chr(0x10D50 + i): chr(0x10D70 + i) for i in _GARAY},
}


def render(name: str, sql: str) -> str:
    """`name` (upper or lower) of the varchar `sql`: DuckDB's function, or code point by code point
    where the text holds one of the code points DuckDB maps otherwise."""
    table = UPPER if name == "upper" else LOWER
    pattern = tf.string("[" + "".join(table) + "]")
    cases = " ".join(f"WHEN {tf.string(source)} THEN {tf.string(target)}" for source, target in table.items())
    mapped = f'CASE "_c" {cases} ELSE {name}("_c") END'
    each = f"array_to_string(list_transform(string_split({sql}, ''), lambda \"_c\": {mapped}), '')"
    return f"CASE WHEN regexp_matches({sql}, {pattern}) THEN {each} ELSE {name}({sql}) END"
