"""Trino's type model: type values and names, their DuckDB equivalents, and Trino's typing rules
(literal types, implicit coercion, decimal arithmetic).

A `TType` is immutable and hashable. Its `str()` is the Trino type name exactly as Trino prints it
(`decimal(6,2)`, `varchar(3)`, `array(row(name varchar, x double))`, `timestamp(3) with time zone`).
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

from sqlglot import exp

from lakegate.dialect import zoned_times

MAX_PRECISION = 38
MAX_VARCHAR = 2147483647
CHAR_MAX_LENGTH = 65536  # io.trino.spi.type.CharType.MAX_LENGTH

#: Integral types by width, and the decimal precision each converts to (io.trino.type.TypeCoercion).
INTEGRAL = {"tinyint": 3, "smallint": 5, "integer": 10, "bigint": 19}
_INTEGRAL_ORDER = ("tinyint", "smallint", "integer", "bigint")


@dataclass(frozen=True, slots=True)
class TType:
    """A Trino type: `base` is one of the Trino base names (`timestamp_tz` for `timestamp(p) with
    time zone`, `interval_ds` / `interval_ym` for the intervals); `args` holds its parameters:
    decimal (p, s), varchar (n,) or () when unbounded, timestamp/time (p,), timestamp_tz (p, zone)
    with the zone all its values carry (None when they may carry different ones: `zone_of`), array (T,),
    map (K, V), row ((name or None, T), ...)."""

    base: str
    args: tuple = ()

    def __str__(self) -> str:
        base, args = self.base, self.args
        if base == "decimal":
            return f"decimal({args[0]},{args[1]})"
        if base in ("varchar", "char"):
            return f"{base}({args[0]})" if args else base
        if base in ("timestamp", "time"):
            return f"{base}({args[0]})"
        if base in ("timestamp_tz", "time_tz"):
            return f"{base[:-3]}({args[0]}) with time zone"
        if base == "interval_ds":
            return "interval day to second"
        if base == "interval_ym":
            return "interval year to month"
        if base == "array":
            return f"array({args[0]})"
        if base == "map":
            return f"map({args[0]}, {args[1]})"
        if base == "row":
            return "row(" + ", ".join(f"{_quote_field(n)} {t}" if n else str(t) for n, t in args) + ")"
        return base

    # --- classification -------------------------------------------------------------------
    @property
    def is_integral(self) -> bool:
        return self.base in INTEGRAL

    @property
    def is_decimal(self) -> bool:
        return self.base == "decimal"

    @property
    def is_approx(self) -> bool:
        return self.base in ("real", "double")

    @property
    def is_numeric(self) -> bool:
        return self.base in INTEGRAL or self.base in ("decimal", "real", "double")

    @property
    def is_string(self) -> bool:
        return self.base in ("varchar", "char")

    @property
    def is_unknown(self) -> bool:
        return self.base == "unknown"

    @property
    def is_temporal(self) -> bool:
        return self.base in ("date", "timestamp", "timestamp_tz", "time")

    @property
    def element(self) -> TType:
        """The element type of an array."""
        return self.args[0]


def _quote_field(name: str) -> str:
    return name if re.fullmatch(r"[a-z_][a-z0-9_]*", name) else '"' + name.replace('"', '""') + '"'


BOOLEAN = TType("boolean")
TINYINT = TType("tinyint")
SMALLINT = TType("smallint")
INTEGER = TType("integer")
BIGINT = TType("bigint")
REAL = TType("real")
DOUBLE = TType("double")
VARCHAR = TType("varchar")
DATE = TType("date")
JSON = TType("json")
VARBINARY = TType("varbinary")
UUID = TType("uuid")
IPADDRESS = TType("ipaddress")
UNKNOWN = TType("unknown")
INTERVAL_DS = TType("interval_ds")
INTERVAL_YM = TType("interval_ym")


def decimal(precision: int, scale: int) -> TType:
    return TType("decimal", (precision, scale))


def varchar(length: int | None = None) -> TType:
    return VARCHAR if length is None or length > MAX_VARCHAR else TType("varchar", (length,))


def array(element: TType) -> TType:
    return TType("array", (element,))


def row(fields: list[tuple[str | None, TType]]) -> TType:
    return TType("row", tuple(fields))


def map_of(key: TType, value: TType) -> TType:
    return TType("map", (key, value))


def timestamp(precision: int = 3, with_time_zone: bool = False, zone: str | None = None) -> TType:
    """timestamp(p), or timestamp(p) with time zone whose values all carry `zone` (dialect/zones.py)."""
    return TType("timestamp_tz", (precision, zone)) if with_time_zone else TType("timestamp", (precision,))


def zone_of(t: TType) -> str | None:
    """The zone every value of a timestamp with time zone type carries (None: not one zone)."""
    return t.args[1] if len(t.args) > 1 else None


def inner_types(t: TType):
    """The types inside an array, map or row type, at any depth."""
    if t.base not in ("array", "map", "row"):
        return
    for item in t.args if t.base != "row" else (f for _, f in t.args):
        yield item
        yield from inner_types(item)


def in_zone(t: TType, zone: str) -> TType:
    """`t` with every timestamp with time zone in it, nested ones too, carrying `zone`."""
    if t.base == "timestamp_tz":
        return timestamp(t.args[0], True, zone)
    if t.base in ("array", "map"):
        return TType(t.base, tuple(in_zone(a, zone) for a in t.args))
    if t.base == "row":
        return row([(name, in_zone(f, zone)) for name, f in t.args])
    return t


def with_precision(t: TType, precision: int) -> TType:
    """A timestamp type at another precision (a zone kept)."""
    return TType(t.base, (precision, *t.args[1:]))


def as_char(t: TType) -> TType:
    """The char type Trino 476 coerces `t` (char, varchar or unknown) to: varchar(x) is char(x), an
    unbounded varchar char(65536), NULL char(0) (io.trino.type.TypeCoercion.coerceTypeBase)."""
    if t.base == "char":
        return t
    if t.base != "varchar":
        return TType("char", (0,))
    length = varchar_length(t)
    return TType("char", (CHAR_MAX_LENGTH if length is None else min(length, CHAR_MAX_LENGTH),))


def varchar_length(t: TType) -> int | None:
    """The length of a bounded varchar, None when unbounded."""
    return t.args[0] if t.args else None


#: Trino's words when two overloads bind equally well.
AMBIGUOUS = "Could not choose a best candidate operator. Explicit type casts must be added."


def concat_with_null(types: list[TType]) -> TType | None:
    """The type of `concat(x, NULL)`, `NULL || x` and the like (two arguments, one a NULL literal): the
    real Trino 476 binds the element-to-array concat, array(x), unless x is NULL, an array (but
    array(unknown), which it keeps), varbinary,
    char or unbounded varchar, where two overloads fit equally and the call is AMBIGUOUS (None)."""
    (other,) = [t for t in types if not t.is_unknown] or [UNKNOWN]
    if other.base == "array" and other.element.is_unknown:  # ARRAY[] || NULL: every overload gives array(unknown)
        return other
    if other.base in ("unknown", "array", "varbinary", "char") or (other.base == "varchar" and not other.args):
        return None
    return array(other)


def as_decimal(t: TType) -> TType:
    """The decimal type an integral or decimal type converts to."""
    return t if t.is_decimal else decimal(INTEGRAL[t.base], 0)


# --- parsing type names -----------------------------------------------------------------------
_TOKEN = re.compile(r'\s*(?:("(?:[^"]|"")*")|([A-Za-z_][A-Za-z0-9_]*)|(\d+)|([(),]))')
_SIMPLE = {
    "boolean": BOOLEAN,
    "tinyint": TINYINT,
    "smallint": SMALLINT,
    "integer": INTEGER,
    "int": INTEGER,
    "bigint": BIGINT,
    "real": REAL,
    "double": DOUBLE,
    "date": DATE,
    "json": JSON,
    "varbinary": VARBINARY,
    "uuid": UUID,
    "ipaddress": IPADDRESS,
    "unknown": UNKNOWN,
}


@functools.lru_cache(maxsize=4096)
def parse_type(text: str) -> TType:
    """Parse a Trino type name (`bigint`, `array(row(name varchar, x double))`, `decimal(6,2)`,
    `timestamp(3) with time zone`, ...). Raises ValueError for anything else."""
    tokens = [next(g for g in m.groups() if g is not None) for m in _TOKEN.finditer(text)]
    if "".join(tokens).replace(" ", "") != re.sub(r"\s+", "", text):
        raise ValueError(f"invalid type name {text!r}")
    parsed, pos = _parse_tokens(tokens, 0, text)
    if pos != len(tokens):
        raise ValueError(f"invalid type name {text!r}")
    return parsed


def _parse_tokens(tokens: list[str], pos: int, text: str) -> tuple[TType, int]:
    def expect(token: str) -> None:
        nonlocal pos
        if pos >= len(tokens) or tokens[pos] != token:
            raise ValueError(f"invalid type name {text!r}")
        pos += 1

    def numbers() -> list[int]:
        nonlocal pos
        values = []
        expect("(")
        while True:
            if pos >= len(tokens) or not tokens[pos].isdigit():
                raise ValueError(f"invalid type name {text!r}")
            values.append(int(tokens[pos]))
            pos += 1
            if tokens[pos : pos + 1] == [","]:
                pos += 1
                continue
            expect(")")
            return values

    if pos >= len(tokens):
        raise ValueError(f"invalid type name {text!r}")
    word = tokens[pos].lower()
    pos += 1
    has_args = tokens[pos : pos + 1] == ["("]
    if word == "double" and tokens[pos : pos + 1] and tokens[pos].lower() == "precision":
        return DOUBLE, pos + 1
    if word in _SIMPLE and not has_args:
        return _SIMPLE[word], pos
    if word == "decimal":
        args = numbers() if has_args else [38, 0]
        precision, scale = (args + [0])[:2]
        if not 1 <= precision <= MAX_PRECISION or scale > precision:
            raise ValueError(f"invalid type name {text!r}")
        return decimal(precision, scale), pos
    if word in ("varchar", "char"):
        length = numbers()[0] if has_args else (None if word == "varchar" else 1)
        return (varchar(length) if word == "varchar" else TType("char", (length,))), pos
    if word in ("timestamp", "time"):
        precision = numbers()[0] if has_args else 3
        words = [t.lower() for t in tokens[pos : pos + 3]]
        if words == ["with", "time", "zone"]:
            return TType(f"{word}_tz" if word == "timestamp" else "time_tz", (precision,)), pos + 3
        if words == ["without", "time", "zone"]:
            pos += 3
        return TType(word, (precision,)), pos
    if word == "interval":
        words = [t.lower() for t in tokens[pos : pos + 3]]
        if words == ["day", "to", "second"]:
            return INTERVAL_DS, pos + 3
        if words == ["year", "to", "month"]:
            return INTERVAL_YM, pos + 3
    if word in ("array", "map", "row") and has_args:
        expect("(")
        items: list = []
        while True:
            name = None
            if (
                word == "row"
                and pos + 1 < len(tokens)
                and tokens[pos + 1] not in ("(", ",", ")")
                and tokens[pos].lower() not in ("double", "timestamp", "time", "interval")
            ):
                name = tokens[pos][1:-1].replace('""', '"') if tokens[pos].startswith('"') else tokens[pos].lower()
                pos += 1
            item, pos = _parse_tokens(tokens, pos, text)
            items.append((name, item) if word == "row" else item)
            if tokens[pos : pos + 1] == [","]:
                pos += 1
                continue
            expect(")")
            break
        if word == "array" and len(items) == 1:
            return array(items[0]), pos
        if word == "map" and len(items) == 2:
            return map_of(items[0], items[1]), pos
        if word == "row":
            return row(items), pos
    raise ValueError(f"invalid type name {text!r}")


# --- sqlglot data types (CAST targets) -----------------------------------------------------
_DTYPE = exp.DataType.Type
_FROM_DTYPE = {
    _DTYPE.BOOLEAN: BOOLEAN,
    _DTYPE.TINYINT: TINYINT,
    _DTYPE.SMALLINT: SMALLINT,
    _DTYPE.INT: INTEGER,
    _DTYPE.BIGINT: BIGINT,
    _DTYPE.FLOAT: REAL,
    _DTYPE.DOUBLE: DOUBLE,
    _DTYPE.DATE: DATE,
    _DTYPE.JSON: JSON,
    _DTYPE.VARBINARY: VARBINARY,
    _DTYPE.UUID: UUID,
    _DTYPE.IPADDRESS: IPADDRESS,
    _DTYPE.UNKNOWN: UNKNOWN,
}


def from_datatype(dt: exp.DataType) -> TType:
    """The Trino type of a CAST target parsed by sqlglot; ValueError when it has no Trino meaning here."""
    kind = dt.this
    if kind in _FROM_DTYPE:
        return _FROM_DTYPE[kind]
    params = [p.this for p in dt.expressions if isinstance(p, exp.DataTypeParam)]
    numbers = [int(p.name) for p in params if isinstance(p, exp.Literal)]
    if kind == _DTYPE.DECIMAL:
        precision, scale = (numbers + [38, 0])[:2] if numbers else (38, 0)
        if len(numbers) == 1:
            scale = 0
        if not 1 <= precision <= MAX_PRECISION or scale > precision:
            raise ValueError(
                f"DECIMAL precision must be in range [1, 38] and scale at most the precision: {dt.sql('trino')}"
            )
        return decimal(precision, scale)
    if kind in (_DTYPE.VARCHAR, _DTYPE.TEXT):
        return varchar(numbers[0] if numbers else None)
    if kind in (_DTYPE.CHAR, _DTYPE.NCHAR):
        return TType("char", (numbers[0] if numbers else 1,))
    if kind in (_DTYPE.TIMESTAMP, _DTYPE.DATETIME):
        return timestamp(numbers[0] if numbers else 3)
    if kind in (_DTYPE.TIMESTAMPTZ, _DTYPE.TIMESTAMPLTZ):
        return timestamp(numbers[0] if numbers else 3, with_time_zone=True)
    if kind == _DTYPE.TIME:
        return TType("time", (numbers[0] if numbers else 3,))
    if kind == _DTYPE.TIMETZ:
        return TType("time_tz", (numbers[0] if numbers else 3,))
    if kind == _DTYPE.ARRAY and dt.expressions:
        return array(from_datatype(dt.expressions[0]))
    if kind == _DTYPE.MAP and len(dt.expressions) == 2:
        return map_of(from_datatype(dt.expressions[0]), from_datatype(dt.expressions[1]))
    if kind == _DTYPE.STRUCT and dt.expressions:
        fields = []
        for field in dt.expressions:
            if isinstance(field, exp.ColumnDef):
                fields.append(
                    (field.name.lower() if not field.this.quoted else field.name, from_datatype(field.args["kind"]))
                )
            else:
                fields.append((None, from_datatype(field)))
        return row(fields)
    if kind == _DTYPE.INTERVAL:
        unit = dt.args.get("expressions") and dt.expressions[0]
        text = unit.sql().upper() if unit is not None else ""
        return INTERVAL_YM if text.startswith(("YEAR", "MONTH")) else INTERVAL_DS
    raise ValueError(f"type {dt.sql('trino')}")


# --- DuckDB equivalents ------------------------------------------------------------------------
_DUCK = {
    "boolean": "BOOLEAN",
    "tinyint": "TINYINT",
    "smallint": "SMALLINT",
    "integer": "INTEGER",
    "bigint": "BIGINT",
    "real": "FLOAT",
    "double": "DOUBLE",
    "varchar": "VARCHAR",
    "char": "VARCHAR",
    "date": "DATE",
    "json": "VARCHAR",  # the JSON text Trino holds, which DuckDB's JSON type would re-validate
    "varbinary": "BLOB",
    "uuid": "UUID",
    "ipaddress": "BLOB",  # its 16-byte IPv6 form (dialect/ipaddresses.py)
    "interval_ds": "INTERVAL",
    "interval_ym": "INTERVAL",
    "time": "TIME",
    "timestamp_tz": "TIMESTAMPTZ",
}


#: The DuckDB types of a timestamp(7..12) with time zone and a timestamp(10..12) (dialect/wide_timestamps.py).
WIDE_TIMESTAMP_TZ = 'STRUCT("us" TIMESTAMPTZ, "ps" INTEGER)'
WIDE_TIMESTAMP = 'STRUCT("us" TIMESTAMP, "ps" INTEGER)'


def duckdb_type(t: TType) -> str | None:
    """The DuckDB type holding values of Trino type `t`; None for `unknown` (NULL) and rows with
    unnamed fields, which DuckDB cannot name in a CAST."""
    base = t.base
    if base == "timestamp_tz" and t.args[0] > 6:
        return WIDE_TIMESTAMP_TZ
    if base == "time_tz":
        return zoned_times.DUCKDB_TYPE
    if base == "time" and t.args[0] > 6:
        return "BIGINT"  # picoseconds of the day (dialect/pico_times.py)
    if base in _DUCK:
        return _DUCK[base]
    if base == "decimal":
        return f"DECIMAL({t.args[0]},{t.args[1]})"
    if base == "timestamp":
        return WIDE_TIMESTAMP if t.args[0] > 9 else "TIMESTAMP_NS" if t.args[0] > 6 else "TIMESTAMP"
    if base == "array":
        inner = duckdb_type(t.args[0])
        return None if inner is None else f"{inner}[]"
    if base == "map":
        key, value = duckdb_type(t.args[0]), duckdb_type(t.args[1])
        return None if key is None or value is None else f"MAP({key}, {value})"
    if base == "row":
        parts = []
        for name, field in t.args:
            inner = duckdb_type(field)
            if name is None or inner is None:
                return None
            parts.append('"' + name.replace('"', '""') + '" ' + inner)
        return "STRUCT(" + ", ".join(parts) + ")"
    return None


# --- literal types -------------------------------------------------------------------------------
def integer_literal_type(text: str) -> TType:
    """`integer` when the literal fits 32 bits, else `bigint`; ValueError beyond 64 bits."""
    value = int(text)
    if -(2**31) <= value < 2**31:
        return INTEGER
    if -(2**63) <= value < 2**63:
        return BIGINT
    raise ValueError(f"Invalid numeric literal: {text}")


def decimal_literal_type(text: str) -> TType:
    """Trino's type of a decimal literal such as `1.5` (decimal(2,1)) or `0.50` (decimal(2,2)):
    leading zeros of the integral part do not count (io.trino.spi.type.Decimals.parse)."""
    integral, _, fraction = text.lstrip("+-").partition(".")
    integral = integral.lstrip("0")
    precision = max(len(integral) + len(fraction), 1)
    if precision > MAX_PRECISION:
        raise ValueError(f"Invalid numeric literal: {text}")
    return decimal(precision, len(fraction))


# --- coercion -------------------------------------------------------------------------------------
def common_super_type(a: TType, b: TType) -> TType | None:
    """The type both `a` and `b` implicitly coerce to in Trino, or None when there is none."""
    if a == b:
        return a
    if a.is_unknown:
        return b
    if b.is_unknown:
        return a
    if a.is_integral and b.is_integral:
        return a if _INTEGRAL_ORDER.index(a.base) >= _INTEGRAL_ORDER.index(b.base) else b
    if (a.is_integral or a.is_decimal) and (b.is_integral or b.is_decimal):
        da, db = as_decimal(a), as_decimal(b)
        scale = max(da.args[1], db.args[1])
        digits = max(da.args[0] - da.args[1], db.args[0] - db.args[1])
        return decimal(min(MAX_PRECISION, digits + scale), scale)
    if a.is_numeric and b.is_numeric:
        return DOUBLE if DOUBLE in (a, b) else REAL
    if {a.base, b.base} <= {"char", "varchar"} and "char" in (a.base, b.base):  # varchar(x) -> char(x), chars.py
        return TType("char", (max(as_char(a).args[0], as_char(b).args[0]),))
    if a.base == "varchar" and b.base == "varchar":
        la, lb = varchar_length(a), varchar_length(b)
        return VARCHAR if la is None or lb is None else varchar(max(la, lb))
    if a.base == b.base == "timestamp":
        return TType(a.base, (max(a.args[0], b.args[0]),))
    if a.base == b.base == "time":
        return TType("time", (max(a.args[0], b.args[0]),))
    if {a.base, b.base} <= {"time", "time_tz"}:  # a time takes the session zone's offset
        return TType("time_tz", (max(a.args[0], b.args[0]),))
    if a.base == b.base == "timestamp_tz":  # values of two zones: no one zone
        return timestamp(max(a.args[0], b.args[0]), True, zone_of(a) if zone_of(a) == zone_of(b) else None)
    if {a.base, b.base} == {"timestamp", "timestamp_tz"}:  # the timestamps take the session zone
        return timestamp(max(a.args[0], b.args[0]), with_time_zone=True)
    if {a.base, b.base} == {"date", "timestamp"}:
        return a if a.base == "timestamp" else b
    if {a.base, b.base} == {"date", "timestamp_tz"}:  # the dates take the session zone
        return timestamp((a if a.base == "timestamp_tz" else b).args[0], with_time_zone=True)
    if a.base == b.base == "array":
        inner = common_super_type(a.element, b.element)
        return None if inner is None else array(inner)
    if a.base == b.base == "map":
        key, value = common_super_type(a.args[0], b.args[0]), common_super_type(a.args[1], b.args[1])
        return None if key is None or value is None else map_of(key, value)
    if a.base == b.base == "row" and len(a.args) == len(b.args):
        fields = []
        for (na, ta), (nb, tb) in zip(a.args, b.args):
            inner = common_super_type(ta, tb)
            if inner is None:
                return None
            fields.append((na if na == nb else None, inner))
        return row(fields)
    if a.base == "varchar" and b.base == "json" or a.base == "json" and b.base == "varchar":
        return None
    return None


def common_super_type_of(types: list[TType]) -> TType | None:
    """The common super type of several types (UNKNOWN for none)."""
    result = UNKNOWN
    for t in types:
        result = common_super_type(result, t)
        if result is None:
            return None
    return result


def coercible(source: TType, target: TType) -> bool:
    """Whether Trino implicitly coerces a value of `source` to `target`."""
    if source == target or source.is_unknown:
        return True
    if source.base == "varchar" and target.base == "varchar":
        return True
    if source.base == "decimal" and target.base == "decimal":
        ps, ss = source.args
        pt, st = target.args
        return ss <= st and ps - ss <= pt - st
    return common_super_type(source, target) == target


# --- arithmetic ----------------------------------------------------------------------------------
def arithmetic_type(op: str, a: TType, b: TType) -> TType | None:
    """The result type of `a op b` for op in + - * / %, following Trino's operators; None when
    Trino has no such operator for these types."""
    if a.is_unknown and b.is_unknown:
        return UNKNOWN
    if a.is_unknown:
        a = b
    if b.is_unknown:
        b = a
    if not (a.is_numeric and b.is_numeric):
        return None
    if a.is_approx or b.is_approx:
        return DOUBLE if DOUBLE in (a, b) else REAL
    if a.is_integral and b.is_integral:
        return common_super_type(a, b)
    (p1, s1), (p2, s2) = as_decimal(a).args, as_decimal(b).args
    if op in "+-":
        scale = max(s1, s2)
        return decimal(min(MAX_PRECISION, max(p1 - s1, p2 - s2) + scale + 1), scale)
    if op == "*":
        if s1 + s2 > MAX_PRECISION:
            return None
        return decimal(min(MAX_PRECISION, p1 + p2), s1 + s2)
    if op == "/":
        return decimal(min(MAX_PRECISION, p1 + s2 + max(s2 - s1, 0)), max(s1, s2))
    if op == "%":
        scale = max(s1, s2)
        return decimal(min(p2 - s2, p1 - s1) + scale, scale)
    return None


# --- JSON casts ------------------------------------------------------------------------------
def castable_from_json(target: TType) -> bool:
    """The targets lakegate translates from json (JsonUtil.canCastFromJson, less decimal and maps
    with other than varchar keys)."""
    if target.base == "array":
        return castable_from_json(target.element)
    if target.base == "map":
        return target.args[0].base == "varchar" and castable_from_json(target.args[1])
    if target.base == "row":
        return all(castable_from_json(t) for _, t in target.args)
    return target.is_integral or target.is_approx or target.base in ("boolean", "varchar", "json")


def castable_to_json(source: TType) -> bool:
    """The sources lakegate writes as JSON (JsonUtil.canCastToJson, less timestamp, date, maps with
    other than varchar, integer or boolean keys, and rows with unnamed fields)."""
    if source.base == "array":
        return castable_to_json(source.element)
    if source.base == "map":
        key = source.args[0]
        return (key.base in ("varchar", "boolean") or key.is_integral) and castable_to_json(source.args[1])
    if source.base == "row":
        return all(name is not None and castable_to_json(t) for name, t in source.args)
    return source.is_numeric or source.base in ("boolean", "varchar", "json", "unknown")
