"""Trino client-protocol encoding of result types and values (notes/trino-protocol.md, sections 5-6).

`type_signature` turns a Trino type name into the `typeSignature` tree clients read; `arrow_type` gives
the Arrow type carrying a Trino type's values (any Trino type; the lake's own columns: `lake.schema`); `encoder`
gives the JSON encoding of one Python value of a type; `encode_rows` encodes a whole Arrow record
batch column by column, with Arrow's vectorised casts for the common types (the server's hot path).
"""

from __future__ import annotations

import base64
import datetime as dt
import math
import re
import struct
import uuid
from collections.abc import Callable, Sequence
from decimal import Decimal
from functools import lru_cache
from typing import Any

import pyarrow as pa
import pyarrow.compute as pc

from lakegate.dialect.trino_types import MAX_VARCHAR, TType, parse_type

Encoder = Callable[[Any], Any]

_RAW_TYPES = {
    "timestamp_tz": "timestamp with time zone",
    "time_tz": "time with time zone",
    "interval_ds": "interval day to second",
    "interval_ym": "interval year to month",
}
_UTC_NAMES = {
    "UTC",
    "Etc/UTC",
    "Etc/UCT",
    "UCT",
    "Etc/Universal",
    "Universal",
    "Etc/Zulu",
    "Zulu",
    "Z",
    "GMT",
    "Etc/GMT",
    "+00:00",
    "+0000",
}


def _long(value: int) -> dict:
    return {"kind": "LONG", "value": value}


def _signature(t: TType) -> dict:
    base, args = t.base, t.args
    raw = _RAW_TYPES.get(base, base)
    if base == "varchar":
        arguments = [_long(args[0] if args else MAX_VARCHAR)]
    elif base in ("char", "decimal", "timestamp", "timestamp_tz", "time", "time_tz"):
        arguments = [_long(a) for a in args]
    elif base in ("array", "map"):
        arguments = [{"kind": "TYPE", "value": _signature(a)} for a in args]
    elif base == "row":
        arguments = []
        for name, field in args:
            value = {"typeSignature": _signature(field)}
            if name is not None:
                value["fieldName"] = {"name": name}
            arguments.append({"kind": "NAMED_TYPE", "value": value})
    else:
        arguments = []
    return {"rawType": raw, "arguments": arguments}


def protocol_type(trino_type: str) -> str:
    """A column's `type` text in the client protocol: the type name with the interval types in
    capitals, at any depth (`array(INTERVAL DAY TO SECOND)`), as Trino 476 writes it; typeof()
    and the typeSignature keep the lower-case name."""
    return re.sub(r"\binterval (day to second|year to month)\b", lambda m: m.group(0).upper(), trino_type)


def type_signature(trino_type: str) -> dict:
    """The client protocol's `typeSignature` of a Trino type name (`varchar` carries its length
    2147483647, `decimal(p,s)` both numbers, `timestamp(p)` its precision, nested types their
    element, key/value or named field signatures). ValueError for an unknown type name."""
    return _signature(parse_type(trino_type))


def arrow_type(t: TType) -> pa.DataType:
    """The Arrow type that carries values of a Trino type (as the DuckDB backend's batches do)."""
    base, args = t.base, t.args
    simple = {
        "boolean": pa.bool_(),
        "tinyint": pa.int8(),
        "smallint": pa.int16(),
        "integer": pa.int32(),
        "bigint": pa.int64(),
        "real": pa.float32(),
        "double": pa.float64(),
        "varchar": pa.string(),
        "char": pa.string(),
        "json": pa.string(),
        "uuid": pa.string(),
        "ipaddress": pa.binary(),
        "varbinary": pa.binary(),
        "date": pa.date32(),
        "unknown": pa.null(),
        "interval_ds": pa.month_day_nano_interval(),
        "interval_ym": pa.month_day_nano_interval(),
    }
    if base in simple:
        return simple[base]
    if base == "decimal":
        return pa.decimal128(args[0], args[1])
    if base in ("timestamp", "timestamp_tz") and args[0] > (9 if base == "timestamp" else 6):  # wide_timestamps.py
        zone = "UTC" if base == "timestamp_tz" else None
        fields = [("us", pa.timestamp("us", tz=zone)), ("ps", pa.int32()), ("wall", pa.int64()), ("zone", pa.string())]
        return pa.struct(fields)
    if base == "timestamp":
        return pa.timestamp("ms" if args[0] <= 3 else "us")
    if base == "timestamp_tz":
        return pa.timestamp("ms" if args[0] <= 3 else "us", tz="UTC")
    if base == "time":
        return pa.time64("us") if args[0] <= 6 else pa.int64()  # dialect/pico_times.py
    if base == "time_tz":  # dialect/zoned_times.py
        return pa.struct([("utc_ps", pa.int64()), ("offset_min", pa.int16())])
    if base == "array":
        return pa.list_(arrow_type(args[0]))
    if base == "map":
        return pa.map_(arrow_type(args[0]), arrow_type(args[1]))
    if base == "row":
        return pa.struct([(name or f"field{i}", arrow_type(f)) for i, (name, f) in enumerate(args)])
    raise ValueError(f"type {t} has no Arrow equivalent in lakegate")


# --- per-value encoders --------------------------------------------------------------------------


def _double(value: Any) -> Any:
    if value is None or math.isfinite(value):
        return value
    return "NaN" if value != value else ("Infinity" if value > 0 else "-Infinity")


def _real(value: Any) -> Any:
    """A REAL as Trino writes it: the shortest digits that read back as the same float32 (128.9, not
    the widened double 128.89999389648438)."""
    if value is None or not math.isfinite(value) or _as_float32(value) != value:
        return _double(value)
    return float(shortest_float32(value))


def shortest_float32(value: float) -> str:
    """Java's Float.toString digits of the float32 `value` as `%g` text: the shortest that read back as
    it, or when one digit does, the two nearest it (1.4e-45, not 1e-45: Java's at least two digits)."""
    n = next(n for n in range(1, 10) if _as_float32(float(f"{value:.{n}g}")) == value)
    return f"{value:.{max(n, 2)}g}"


def _decimal(scale: int) -> Encoder:
    quantum = Decimal(1).scaleb(-scale)

    def encode(value: Any) -> Any:
        if value is None:
            return None
        number = value if isinstance(value, Decimal) else Decimal(value)
        if number.as_tuple().exponent != -scale:
            number = number.quantize(quantum)
        return format(number, "f")

    return encode


def _fraction(micros: int, nanos: int, precision: int) -> str:
    if precision == 0:
        return ""
    digits = f"{micros:06d}{nanos:03d}"
    return "." + digits[:precision] if precision <= 9 else "." + digits + "0" * (precision - 9)


def _zone(value: dt.datetime | dt.time) -> str:
    tz = value.tzinfo
    key = getattr(tz, "key", None) or getattr(tz, "zone", None)
    if key:
        return "UTC" if key in _UTC_NAMES else key
    offset = value.utcoffset() or dt.timedelta(0)
    minutes = int(offset.total_seconds() // 60)
    if minutes == 0:
        return "UTC"
    return f"{'+' if minutes >= 0 else '-'}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"


def _timestamp(precision: int, with_zone: bool) -> Encoder:
    def encode(value: Any) -> Any:
        if value is None:
            return None
        text = value.strftime("%Y-%m-%d %H:%M:%S") + _fraction(
            value.microsecond, getattr(value, "nanosecond", 0), precision
        )
        return f"{text} {_zone(value)}" if with_zone else text

    return encode


def _time(precision: int) -> Encoder:
    """A time(p <= 6) held as DuckDB's TIME; a time(p > 6) as picoseconds of the day (dialect/pico_times.py)."""

    def encode(value: Any) -> Any:
        if value is None:
            return None
        if isinstance(value, int):
            return _picos_text(value, precision)
        return value.strftime("%H:%M:%S") + _fraction(value.microsecond, 0, precision)

    return encode


_PICOS_PER_DAY = 86_400 * 10**12


def _picos_text(local: int, precision: int) -> str:
    """HH:MM:SS and p fraction digits (truncated) of a time of day in picoseconds."""
    seconds, picos = divmod(local, 10**12)
    text = f"{seconds // 3600:02d}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"
    return text + "." + f"{picos:012d}"[:precision] if precision else text


def _time_with_time_zone(precision: int) -> Encoder:
    """A time with time zone held as DuckDB's {utc_ps, offset_min} (dialect/zoned_times.py):
    HH:MM:SS, p fraction digits, then the offset as +hh:mm (TimeWithTimeZoneOperators.castToVarchar)."""

    def encode(value: Any) -> Any:
        if value is None:
            return None
        minutes = value["offset_min"]
        text = _picos_text((value["utc_ps"] + minutes * 60 * 10**12) % _PICOS_PER_DAY, precision)
        sign = "-" if minutes < 0 else "+"
        return f"{text}{sign}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"

    return encode


def _interval_day_to_second(value: Any) -> Any:
    if value is None:
        return None
    if isinstance(value, dt.timedelta):
        micros = (value.days * 86_400 + value.seconds) * 1_000_000 + value.microseconds
    else:  # Arrow's MonthDayNano
        micros = (value.months * 30 + value.days) * 86_400_000_000 + value.nanoseconds // 1000
    sign = "-" if micros < 0 else ""
    seconds, micros = divmod(abs(micros), 1_000_000)
    days, seconds = divmod(seconds, 86_400)
    return f"{sign}{days} {seconds // 3600:02d}:{seconds // 60 % 60:02d}:{seconds % 60:02d}.{micros // 1000:03d}"


def _interval_year_to_month(value: Any) -> Any:
    if value is None:
        return None
    months = value.months if hasattr(value, "months") else int(value)
    sign = "-" if months < 0 else ""
    return f"{sign}{abs(months) // 12}-{abs(months) % 12}"


def _varbinary(value: Any) -> Any:
    return None if value is None else base64.b64encode(bytes(value)).decode("ascii")


def _uuid(value: Any) -> Any:
    if value is None or isinstance(value, str):
        return value
    return str(uuid.UUID(bytes=bytes(value)) if isinstance(value, (bytes, bytearray)) else value)


#: The first twelve bytes of an IPv4 address in its IPv6 form (::ffff:0:0/96).
_IPV4_MAPPED = bytes(10) + b"\xff\xff"


def ipaddress_text(value: Any) -> Any:
    """An IPADDRESS (its 16 bytes, dialect/ipaddresses.py) as Trino writes it (Guava's
    InetAddresses.toAddrString): an IPv4-mapped address dotted, any other as lower-case hex groups, the
    longest run of two or more zero groups (the first of equal runs) written `::`."""
    if value is None:
        return None
    data = bytes(value)
    if data[:12] == _IPV4_MAPPED:
        return ".".join(str(b) for b in data[12:])
    groups = [int.from_bytes(data[i : i + 2], "big") for i in range(0, 16, 2)]
    start, length = -1, 0
    for i in range(8):
        run = next((n for n in range(8 - i) if groups[i + n]), 8 - i) if not groups[i] else 0
        if run > length and (i == 0 or groups[i - 1]):
            start, length = i, run
    words = [f"{g:x}" for g in groups]
    if length < 2:
        return ":".join(words)
    return ":".join(words[:start]) + "::" + ":".join(words[start + length :])


def _date(value: Any) -> Any:
    return None if value is None else value.isoformat()


def _identity(value: Any) -> Any:
    return value


def _java_text(value: Any, t: TType) -> str:
    """An encoded value of type `t` as Java's toString of Trino's object value, which is how Trino writes
    a map key (server/protocol/JsonEncodingUtils.MapEncoder: getObjectValue(...).toString()): arrays and
    rows as `[a, b]`, NULL as `null`, booleans in lower case, doubles and reals as Java prints them."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if t.base in ("array", "row"):
        types = [t.element] * len(value) if t.base == "array" else [field for _, field in t.args]
        return "[" + ", ".join(_java_text(v, field) for v, field in zip(value, types)) + "]"
    if t.base in ("double", "real") and isinstance(value, float):
        return _java_float(value, single=t.base == "real")
    return str(value)


def _java_float(value: float, single: bool) -> str:
    """Java's Double.toString (Float.toString when `single`): the shortest digits that read back,
    as d.ddd within [1e-3, 1e7) and as d.dddEn outside it."""
    if value == 0:
        return "-0.0" if math.copysign(1.0, value) < 0 else "0.0"
    text = repr(value)
    if single:
        text = shortest_float32(value)
    number = Decimal(text)
    if 1e-3 <= abs(value) < 1e7:
        plain = format(number, "f")
        return plain if "." in plain else plain + ".0"
    _, digits, exponent = number.as_tuple()
    power = len(digits) + exponent - 1
    figures = "".join(map(str, digits)).rstrip("0") or "0"
    return f"{'-' if value < 0 else ''}{figures[0]}.{figures[1:] or '0'}E{power}"


def _as_float32(value: float) -> float:
    return struct.unpack("f", struct.pack("f", value))[0]


def _make_encoder(t: TType) -> Encoder:
    base, args = t.base, t.args
    if base in ("real", "double"):
        return _real if base == "real" else _double
    if base == "decimal":
        return _decimal(args[1])
    if base in ("timestamp", "timestamp_tz"):
        return _timestamp(args[0], base == "timestamp_tz")
    if base == "time":
        return _time(args[0])
    if base == "time_tz":
        return _time_with_time_zone(args[0])
    if base == "date":
        return _date
    if base == "varbinary":
        return _varbinary
    if base == "uuid":
        return _uuid
    if base == "ipaddress":
        return ipaddress_text
    if base == "interval_ds":
        return _interval_day_to_second
    if base == "interval_ym":
        return _interval_year_to_month
    if base == "array":
        element = _make_encoder(args[0])
        if element is _identity:
            return _identity
        return lambda value: None if value is None else [element(v) for v in value]
    if base == "map":
        key_encoder, value_encoder = _make_encoder(args[0]), _make_encoder(args[1])

        def encode_map(value: Any) -> Any:
            if value is None:
                return None
            pairs = value.items() if isinstance(value, dict) else value
            return {_java_text(key_encoder(k), args[0]): value_encoder(v) for k, v in pairs}

        return encode_map
    if base == "row":
        fields = [_make_encoder(field) for _, field in args]

        def encode_row(value: Any) -> Any:
            if value is None:
                return None
            values = value.values() if isinstance(value, dict) else value
            return [encode(v) for encode, v in zip(fields, values)]

        return encode_row
    return _identity  # boolean, integers, varchar, char, json, unknown


@lru_cache(maxsize=512)
def encoder(trino_type: str) -> Encoder:
    """The function that encodes one Python value of `trino_type` (None -> None) for a client:
    decimals as strings with the type's scale, non-finite doubles as "NaN"/"Infinity"/"-Infinity",
    timestamps with exactly p fraction digits (and the zone), dates ISO, varbinary base64, uuid
    text, arrays as lists, maps as objects with string keys, rows as lists of field values."""
    return _make_encoder(parse_type(trino_type))


# --- whole record batches ------------------------------------------------------------------------


def _fit_fraction(texts: list, precision: int) -> list:
    """Make every `...HH:MM:SS[.fff...]` text carry exactly `precision` fraction digits."""
    out = []
    for text in texts:
        if text is None:
            out.append(None)
            continue
        head, _, fraction = text.partition(".")
        fraction = (fraction + "0" * precision)[:precision]
        out.append(f"{head}.{fraction}" if precision else head)
    return out


#: Arrow time units whose text form has exactly p fraction digits.
_UNITS = {0: "s", 3: "ms", 6: "us", 9: "ns"}


def _temporal_texts(
    column: pa.Array, precision: int, to_text: Callable[[pa.Array], pa.Array], suffix: str = ""
) -> list:
    """Timestamps or times as text with exactly `precision` fraction digits (then `suffix`): by Arrow,
    after a cast to the unit with that many digits (which truncates: the SQL already rounded), when
    there is one."""
    unit = _UNITS.get(precision)
    if unit is None:
        texts = _fit_fraction(_signed_years(to_text(column)).to_pylist(), precision)
        return [None if text is None else text + suffix for text in texts] if suffix else texts
    if column.type.unit != unit:
        if pa.types.is_timestamp(column.type):
            target = pa.timestamp(unit, column.type.tz)
        else:
            target = pa.time32(unit) if unit in ("s", "ms") else pa.time64(unit)
        column = column.cast(target, safe=False)
    texts = _signed_years(to_text(column))
    if suffix:
        texts = pc.binary_join_element_wise(texts, pa.scalar(suffix), "")
    return texts.to_pylist()


#: Epoch seconds of 0001-01-01 and 10000-01-01: Arrow writes the text of the instants between them
#: right (past them it writes a wrong year or "<value out of range>"), the others are written here.
_NEAR = (-62135596800, 253402300800)
_PER_SECOND = {"s": 1, "ms": 10**3, "us": 10**6, "ns": 10**9}


def _civil(days: int) -> tuple[int, int, int]:
    """The proleptic Gregorian (year, month, day) of a day number from 1970-01-01 (H. Hinnant's
    civil_from_days)."""
    z = days + 719468
    era, doe = divmod(z, 146097)
    yoe = (doe - doe // 1460 + doe // 36524 - doe // 146096) // 365
    doy = doe - (365 * yoe + yoe // 4 - yoe // 100)
    mp = (5 * doy + 2) // 153
    month = mp + 3 if mp < 10 else mp - 9
    return yoe + era * 400 + (month <= 2), month, doy - (153 * mp + 2) // 5 + 1


def _day_text(days: int) -> str:
    """A date as Trino writes it, ISO 8601's expanded years included (+12025-07-01, -9999-01-01)."""
    year, month, day = _civil(days)
    sign = "+" if year > 9999 else "-" if year < 0 else ""
    return f"{sign}{abs(year):04d}-{month:02d}-{day:02d}"


def _wide_timestamp(value: Any, precision: int) -> str | None:
    """A timestamp(7..12) with time zone or timestamp(10..12) result (dialect/wide_timestamps.shown): its
    wall time in epoch microseconds and the picoseconds below it, then its zone, as Trino writes it."""
    if value is None:
        return None
    seconds, micros = divmod(value["wall"], 1_000_000)
    days, second = divmod(seconds, 86400)
    clock = f"{second // 3600:02d}:{second // 60 % 60:02d}:{second % 60:02d}"
    fraction = f"{micros:06d}{value['ps']:06d}"[:precision]
    text = f"{_day_text(days)} {clock}.{fraction}"
    return text if value["zone"] is None else f"{text} {value['zone']}"


def _is_far(values: pa.Array, low: int, high: int) -> bool:
    """Whether a value of `values` is outside [low, high)."""
    least, most = (v.as_py() for v in pc.min_max(values).values())
    return least is not None and (least < low or most >= high)


def _far_timestamps(column: pa.Array, texts: list, precision: int, suffix: str = "") -> list:
    """`texts` with the timestamps outside years 1..9999 written here (Arrow writes them wrong)."""
    per_second = _PER_SECOND[column.type.unit]
    values = column.cast(pa.int64())
    low, high = _NEAR[0] * per_second, _NEAR[1] * per_second
    if not len(column) or not _is_far(values, low, high):
        return texts
    out = []
    for value, text in zip(values.to_pylist(), texts):
        if value is None or low <= value < high:
            out.append(text)
            continue
        seconds, fraction = divmod(value, per_second)
        days, second = divmod(seconds, 86400)
        digits = f".{fraction * 10**precision // per_second:0{precision}d}" if precision else ""
        clock = f"{second // 3600:02d}:{second // 60 % 60:02d}:{second % 60:02d}"
        out.append(f"{_day_text(days)} {clock}{digits}{suffix}")
    return out


def _signed_years(texts: pa.Array) -> pa.Array:
    """Dates and timestamps as Trino writes them past year 9999: with a `+` (`+12025-07-01`)."""
    return pc.replace_substring_regex(texts, pattern=r"^(\d{5,})", replacement=r"+\1")


def _as_string(column: pa.Array) -> pa.Array:
    return column.cast(pa.string())


def _zone_name(arrow_zone: str) -> str:
    return "UTC" if arrow_zone in _UTC_NAMES else arrow_zone


def _column(t: TType, column: pa.Array) -> list:
    """One column of a batch as encoded values, vectorised where Arrow can do it exactly."""
    arrow_type = column.type
    base = t.base
    if t.is_integral and not pa.types.is_integer(arrow_type):  # e.g. a HUGEINT arriving as decimal
        return [None if v is None else int(v) for v in column.to_pylist()]
    if base == "real" and pa.types.is_floating(arrow_type):
        return [_real(v) for v in column.to_pylist()]
    if base == "double" and pa.types.is_floating(arrow_type):
        values = column.to_pylist()
        if pc.all(pc.is_finite(column)).as_py() is not False:
            return values
        return [_double(v) for v in values]
    if base == "decimal" and pa.types.is_decimal(arrow_type) and arrow_type.scale == t.args[1]:
        texts = column.cast(pa.string())
        if not pc.any(pc.match_substring(texts, "E")).as_py():
            return texts.to_pylist()
        return [format(Decimal(s), "f") if s is not None and "E" in s else s for s in texts.to_pylist()]
    if base == "timestamp" and pa.types.is_timestamp(arrow_type) and arrow_type.tz is None:
        texts = _temporal_texts(column, t.args[0], _as_string)
        return _far_timestamps(column, texts, t.args[0])
    if base in ("timestamp", "timestamp_tz") and pa.types.is_struct(arrow_type):  # dialect/wide_timestamps.py
        return [_wide_timestamp(value, t.args[0]) for value in column.to_pylist()]
    if base == "timestamp_tz" and pa.types.is_timestamp(arrow_type):
        zone = arrow_type.tz or "UTC"
        texts = _temporal_texts(
            column,
            t.args[0],
            lambda c: pc.strftime(c, format="%Y-%m-%d %H:%M:%S"),
            " " + _zone_name(zone),
        )
        return _far_timestamps(column, texts, t.args[0], " UTC") if _zone_name(zone) == "UTC" else texts
    if base == "date" and pa.types.is_date(arrow_type):
        texts = _signed_years(column.cast(pa.string())).to_pylist()
        low, high = _NEAR[0] // 86400, _NEAR[1] // 86400
        if len(column) and _is_far(column.cast(pa.int32()), low, high):
            days = column.cast(pa.int32()).to_pylist()
            return [text if d is None or low <= d < high else _day_text(d) for d, text in zip(days, texts)]
        return texts
    if base == "time" and pa.types.is_time(arrow_type):
        return _temporal_texts(column, t.args[0], _as_string)
    encode = encoder(str(t))
    values = column.to_pylist()
    return values if encode is _identity else [encode(v) for v in values]


@lru_cache(maxsize=512)
def _parsed(trino_type: str) -> TType:
    return parse_type(trino_type)


def encode_columns(columns: Sequence[tuple[str, str]], batch: pa.RecordBatch) -> list[list]:
    """The encoded values of `batch` column by column (`encode_rows` gives them as rows)."""
    if batch.num_columns != len(columns):
        raise ValueError(f"the batch has {batch.num_columns} columns, the result {len(columns)}")
    return [_column(_parsed(trino_type), batch.column(i)) for i, (_, trino_type) in enumerate(columns)]


def encode_rows(columns: Sequence[tuple[str, str]], batch: pa.RecordBatch) -> list[list]:
    """The rows of `batch` as the client protocol's `data`: a list of rows, each a list of the
    encoded values of `columns` ((name, Trino type) in the batch's column order)."""
    encoded = encode_columns(columns, batch)
    if len(encoded) == 1:
        return [[v] for v in encoded[0]]
    return [list(row) for row in zip(*encoded)]
