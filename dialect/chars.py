"""Trino's char(n) in DuckDB's VARCHAR: a char(n) value is kept as its text padded with spaces to n
characters, which is the value Trino's client gets (io.trino.spi.type.CharType.getObjectValue pads).

Trino (476) keeps a char value without its trailing spaces and compares char values as if padded
with spaces to a common length (io.trino.spi.type.Chars.compareChars); padded texts of one length
compare the same way, byte by byte. Mixed operands are coerced the way Trino 476 coerces them
(io.trino.type.TypeCoercion.coerceTypeBase): varchar(x) becomes char(x) (unbounded varchar
char(65536), CharType.MAX_LENGTH), and char(x) with char(y) becomes char(max(x, y)); char never
becomes varchar implicitly (that direction came with trinodb/trino#29939, after 476).
The coercions here are explicit casts put into the tree, so every writer of a comparison, CASE or
set operation sees operands of one char type.
"""

from __future__ import annotations

from typing import Any

from sqlglot import exp

from lakegate.dialect import trino_types as tt
from lakegate.dialect.trino_types import TType


def pad(sql: str, length: int) -> str:
    """DuckDB text `sql` as a char(length): truncated to `length` characters or padded with spaces
    (CharacterStringCasts.varcharToCharCast and charToCharCast, then the padding the client sees)."""
    return f"rpad({sql}, {length}, ' ')"


def concat_type(left: TType, right: TType) -> TType | None:
    """The type of `left || right` and concat(left, right) when one side is char and the other char,
    varchar or NULL: char(x + y) (io.trino.operator.scalar.StringFunctions.concat(char(x), char(y)),
    two arguments only); None when that passes CharType.MAX_LENGTH."""
    length = tt.as_char(left).args[0] + tt.as_char(right).args[0]
    return TType("char", (length,)) if length <= tt.CHAR_MAX_LENGTH else None


def cast_to(node: exp.Expression, target: TType, trimmed: bool = False) -> None:
    """Put an explicit cast of the analyzed `node` to char type `target` in its place (written by
    transforms.cast_value as the padded text), unless `node` already has that type. A `trimmed` cast
    is written as the value without trailing spaces instead, which only equality may compare."""
    source = node.meta.get("t")
    if source is None or source == target and not trimmed:
        return
    cast = exp.Cast(to=exp.DataType.build(f"char({target.args[0]})"))
    node.replace(cast)
    cast.set("this", node)
    cast.meta.update({"from": source, "t": target, "trimmed": trimmed})


def coerce(nodes: list[exp.Expression], common: TType, equality: bool = False) -> None:
    """Cast the operands of a comparison, IN or BETWEEN to their common type when it is char(n). At
    char(65536) (a char with an unbounded varchar) the operands of `equality` (=, <>, IS DISTINCT
    FROM, IN) are compared without their trailing spaces, as equal padded values are equal unpadded."""
    if common.base == "char":
        trimmed = equality and common.args[0] == tt.CHAR_MAX_LENGTH
        for node in nodes:
            cast_to(node, common, trimmed)


def trimmed(g: Any, node: exp.Cast) -> str:
    """A `trimmed` cast (see cast_to): its operand without trailing spaces, cut to 65536 characters."""
    if node.meta["from"].is_unknown:
        return "CAST(NULL AS VARCHAR)"
    return f"rtrim({_unpadded(g, node)}, ' ')"


def compare(g: Any, op: str, left: exp.Expression, right: exp.Expression) -> str:
    """`left op right` for an ordering `op` at char(65536), the common type of a char and an unbounded
    varchar, without writing 65536-character values: padded values order alike at any common length
    at least both lengths (Chars.compareChars)."""
    a, b = _padded_alike(g, [left, right])
    return f"{a} {op} {b}"


def between(g: Any, value: exp.Expression, low: exp.Expression, high: exp.Expression) -> str:
    """`value BETWEEN low AND high` at char(65536), padded alike as in `compare`."""
    v, lo, hi = _padded_alike(g, [value, low, high])
    return f"{v} BETWEEN {lo} AND {hi}"


def _padded_alike(g: Any, nodes: list[exp.Expression]) -> list[str]:
    """The char(65536) operands padded to the longest of their unpadded lengths."""
    texts = [_unpadded(g, node) for node in nodes]
    length = f"CAST(greatest({', '.join(f'length({t})' for t in texts)}) AS INTEGER)"
    return [f"rpad({t}, {length}, ' ')" for t in texts]


def _unpadded(g: Any, node: exp.Expression) -> str:
    """DuckDB text of a char(65536) operand before its padding: a cast's char operand, or its varchar
    operand cut to 65536 characters (CharacterStringCasts.varcharToCharCast)."""
    source = node.meta.get("from") if isinstance(node, exp.Cast) else None
    if source is not None and source.base == "char":
        return g.sql(node.this)
    if source is not None and source.base == "varchar":
        return f"left({g.sql(node.this)}, {tt.CHAR_MAX_LENGTH})"
    return g.sql(node)
