"""Trino type inference of CAST and TRY_CAST, typed literals, and which casts Trino allows."""

from __future__ import annotations

import datetime as dt
import re
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

from sqlglot import exp

from lakegate.dialect import ipaddresses, pico_times, times, zoned_times, zones
from lakegate.dialect import trino_types as tt
from lakegate.dialect.analysis_checks import has_char
from lakegate.dialect.analyzer import Analyzer
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import handles


def _typed_literal(a: Analyzer, node: exp.Cast) -> bool:
    """Whether a Cast is Trino's typed literal (`DECIMAL '1.50'`, `TIMESTAMP '...'`): sqlglot parses
    both the same way; the source text tells them apart."""
    literal = node.this
    if not (isinstance(node, exp.Cast) and isinstance(literal, exp.Literal) and literal.is_string and literal._meta):
        return False
    before = a.sql[: literal._meta.get("start", 0)].rstrip()
    return bool(before) and (before[-1].isalnum() or before[-1] in ")_")


@handles(exp.Cast, exp.TryCast)
def _cast(a: Analyzer, node, scope, env):
    source = a.expr(node.this, scope, env)
    try:
        target = tt.from_datatype(node.args["to"])
    except ValueError as error:
        a.unsupported(f"cast to {error}", node)
    if _typed_literal(a, node):
        text = node.this.name.strip()
        if target.base == "char":  # CHAR 'abc ': char(4), of the literal's characters (spaces included)
            target = TType("char", (len(node.this.name),))
        if target.is_decimal:
            try:
                target = tt.decimal_literal_type(text)
            except ValueError:
                a.fail(f"'{text}' is not a valid decimal literal", node, "INVALID_LITERAL")
        if target.base in ("timestamp", "timestamp_tz") and target.args[0] > 12:
            name = "TIMESTAMP WITH TIME ZONE" if target.base == "timestamp_tz" else "TIMESTAMP"
            a.fail(f"{name} precision must be in range [0, 12]: {target.args[0]}", node, "NUMERIC_VALUE_OUT_OF_RANGE")
        elif target.base == "timestamp" and re.search(
            r"[0-9]:[0-9]{2}(:[0-9]{2}([.][0-9]*)?)?\s*([A-Za-z]|[+-][0-9])", text
        ):
            a.unsupported("timestamp literal with a time zone", node)
        elif target.base == "time":
            target = _time_literal_type(a, node, text)
        elif target.base == "time_tz":
            target = _time_tz_literal_type(a, node)
        elif target.base == "ipaddress":  # computed here (node.meta["ip"])
            node.meta["ip"] = ipaddresses.parse(node.this.name)
            if node.meta["ip"] is None:
                a.fail(f"'{node.this.name}' is not a valid IPADDRESS literal", node, "INVALID_LITERAL")
    if "ipaddress" in (source.base, target.base) and not castable(source, target):
        a.fail(f"Cannot cast {source} to {target}", node, "TYPE_MISMATCH")
    if source.base == "char" and target.base == "varchar":
        node.meta["from"] = source
        return target  # the padded text, cut to the varchar's length (CharacterStringCasts.charToVarcharCast)
    if has_char(source) or has_char(target):
        if source.base not in ("varchar", "char", "unknown") or target.base != "char":
            a.unsupported(f"CAST({source} AS {target})", node)
        if target.args[0] > 65536:  # CharType.MAX_LENGTH
            a.unsupported(f"{target} (Trino's char holds at most 65536 characters)", node)
        node.meta["from"] = source
        return target  # truncated or padded with spaces to the length (CharacterStringCasts.varcharToCharCast)
    if target.base == "varbinary" and source.base in ("varchar", "varbinary", "unknown"):
        node.meta["from"] = source
        return target  # the UTF-8 bytes of the text (VarcharOperators.castToVarbinary)
    if "json" in (source.base, target.base) and source != target:
        _check_json_cast(a, node, source, target)
    elif "time" in (source.base, target.base) or "time_tz" in (source.base, target.base):
        _check_time_cast(a, node, source, target)
    elif target.base in ("uuid", "varbinary", "map") and source.base != "ipaddress":
        a.unsupported(f"cast to {target}", node)
    if target.base == "timestamp_tz":
        target = tt.timestamp(target.args[0], True, _cast_zone(a, node, source))
        if _typed_literal(a, node) and "local" in node.meta:
            _check_wall_time_exists(a, node, node.meta["local"], tt.zone_of(target))
    else:
        a.zones(source, node, f"CAST to {target}")
    if source.base in ("interval_ds", "interval_ym") and target.base == "varchar" and target.args:
        a.unsupported(f"CAST({source} AS {target}) (to a bounded varchar)", node)
    if not castable(source, target) and any(t.base == "time" for t in tt.inner_types(target)):
        a.unsupported(f"CAST({source} AS {target})", node)  # nested time(p > 6) or timestamp(p > 6)
    if not castable(source, target):
        a.fail(f"Cannot cast {source} to {target}", node, "TYPE_MISMATCH")
    flat_array = source.base == target.base == "array" and target.args[0].base not in ("array", "map", "row")
    if isinstance(node, exp.TryCast) and target.base in ("array", "map", "row") and source != target and not flat_array:
        # Trino's TRY_CAST is NULL when any element fails; lakegate's casts would give NULL elements
        a.unsupported(f"TRY_CAST({source} AS {target})", node)
    node.meta["from"] = source
    return target


def _time_literal_type(a: Analyzer, node: exp.Cast, text: str) -> TType:
    """TIME '01:02:03.456' is time(p), p its fraction digits (DateTimes.extractTimePrecision)."""
    digits = re.fullmatch(r"\s*[0-9]{1,2}:[0-9]{1,2}:[0-9]{1,2}[.]([0-9]{13,})\s*", node.this.name)
    if digits is not None:
        message = f"TIME precision must be in range [0, 12]: {len(digits[1])}"
        a.fail(message, node, "NUMERIC_VALUE_OUT_OF_RANGE")
    match = re.fullmatch(times.TIME_TEXT[1:-1], node.this.name)
    if match is None or int(match[1]) > 23 or int(match[2]) > 59 or int(match[4] or 0) > 59:
        a.fail(f"'{text}' is not a valid TIME literal", node, "INVALID_LITERAL")
    precision = len(match[6] or "")
    if precision > 6:  # its picoseconds, computed here (pico_times.py)
        node.meta["time_ps"] = pico_times.literal(node.this.name)
    return TType("time", (precision,))


def _time_tz_literal_type(a: Analyzer, node: exp.Cast) -> TType:
    """TIME '01:02:03.456 +05:45' is time(p) with time zone, p its fraction digits
    (DateTimes.extractTimePrecision); its value is computed here (node.meta["time_tz"])."""
    text = node.this.name
    precision = zoned_times.literal_precision(text)
    if precision is not None and precision > zoned_times.MAX_PRECISION:
        a.fail(
            f"TIME WITH TIME ZONE precision must be in range [0, 12]: {precision}", node, "NUMERIC_VALUE_OUT_OF_RANGE"
        )
    value = None if precision is None else zoned_times.literal(text, precision, None)
    if value is None:
        a.fail(f"'{text}' is not a valid TIME literal", node, "INVALID_LITERAL")
    node.meta["time_tz"] = value
    return TType("time_tz", (precision,))


def _check_time_cast(a: Analyzer, node: exp.Cast, source: TType, target: TType) -> None:
    """time(p <= 6) from varchar, time and timestamp(p <= 6), and to varchar (TimeOperators,
    TimestampToTimeCast); time(p) with time zone from and to varchar, time and itself
    (TimeWithTimeZoneOperators); the casts that need the session's date, or its zone's offset when
    that changes, are refused."""
    for t in (source, target):
        if t.base in ("time", "time_tz") and t.args[0] > zoned_times.MAX_PRECISION:
            a.fail(f"Unknown type: {t}", node, "TYPE_MISMATCH")
    if (
        source.base == "timestamp"
        and source.args[0] > 6
        and not (target.base == "time_tz" or target.base == "time" and source.args[0] <= 9)
    ):
        a.unsupported(f"CAST({source} AS {target}) (more than microsecond precision)", node)
    if source.base in ("time", "time_tz") and target.base in ("timestamp", "timestamp_tz"):
        _check_time_to_timestamp(a, node, source, target)
    if source.base == "date":
        a.unsupported(f"CAST({source} AS {target})", node)
    if target.base in ("time", "time_tz") and source.base == "timestamp_tz":  # its zone's offset at the instant
        a.zone(source, node, f"CAST to {target}")
        if source.args[0] > 6 and target.base != "time_tz":
            a.unsupported(f"CAST({source} AS {target}) (more than microsecond precision)", node)
    if (
        target.base == "time_tz"
        and source.base in ("time", "varchar", "timestamp")
        and zoned_times.offset_of(a.time_zone) is None
        and not _names_its_offset(node)
    ):
        a.unsupported(f"CAST({source} AS {target}) in the session zone {a.time_zone} (its offset changes)", node)


def _check_time_to_timestamp(a: Analyzer, node: exp.Cast, source: TType, target: TType) -> None:
    """A time on the session's date (dialect/time_casts.py): to the timestamps lakegate holds, and to
    timestamp with time zone from a time with time zone literal only (its offset is the value's zone)."""
    if target.base == "timestamp_tz" and target.args[0] > 6 or target.args[0] > 9:
        a.unsupported(f"CAST({source} AS {target}) (more than lakegate's timestamps hold)", node)
    if target.base == "timestamp_tz" and source.base == "time_tz" and "time_tz" not in node.this.meta:
        a.unsupported(f"CAST({source} AS {target}) of a value that is not a literal (its offset is its zone)", node)


def _names_its_offset(node: exp.Cast) -> bool:
    """A TIME literal with an offset, or a text literal whose time names its offset: no session offset needed."""
    literal = node.this
    if "time_tz" in node.meta:
        return True
    return (
        isinstance(literal, exp.Literal)
        and literal.is_string
        and bool(re.search(r"[+-][0-9]{2}:[0-9]{2}\s*$", literal.name))
    )


def _check_json_cast(a: Analyzer, node: exp.Cast, source: TType, target: TType) -> None:
    """Casts to and from json (JsonUtil.canCastToJson / canCastFromJson): Trino's, less those
    lakegate does not translate (trino_types.castable_to_json / castable_from_json), refused."""
    if target.base == "json":
        if not tt.castable_to_json(source):
            a.unsupported(f"CAST({source} AS json)", node)
    elif not tt.castable_from_json(target):
        a.unsupported(f"CAST(json AS {target})", node)


#: The zone at the end of a timestamp text: a region name or an offset.
_ZONE_SUFFIX = re.compile(
    r"[0-9]:[0-9]{2}(?::[0-9]{2}(?:[.][0-9]*)?)?\s*([A-Za-z][A-Za-z0-9_/+-]*|[+-][0-9]{1,2}(?::?[0-9]{2})?)\s*$"
)


def _cast_zone(a: Analyzer, node: exp.Cast, source: TType) -> str | None:
    """The zone of a value cast to timestamp with time zone: a timestamp with time zone keeps its own,
    a text literal has the zone it names (its wall time is kept in node.meta["local"]), anything else
    takes the session zone (io.trino.type.TimestampToTimestampWithTimeZoneCast,
    DateTimes.parseTimestampWithTimeZone)."""
    if source.base == "timestamp_tz":
        return tt.zone_of(source)
    if source.base == "time_tz" and "time_tz" in node.this.meta:  # a literal's offset (time_casts.py)
        return zones.canonical(zoned_times.offset_text_of(node.this.meta["time_tz"][1]))
    if source.base != "varchar":
        return a.time_zone
    if not (isinstance(node.this, exp.Literal) and node.this.is_string):
        a.unsupported(
            "CAST of a non-literal varchar to timestamp with time zone (each value's zone would be lost)", node
        )
    text = node.this.name.strip()
    suffix = _ZONE_SUFFIX.search(text)
    if suffix is None:
        node.meta["local"] = text
        return a.time_zone
    try:
        zone = zones.canonical(suffix.group(1))
    except ValueError as error:
        a.fail(str(error), node, "NOT_SUPPORTED")
    node.meta["local"] = text[: suffix.start(1)].strip()
    return zone


_WALL_TIME = re.compile(r"\s*([0-9]{4})-([0-9]{1,2})-([0-9]{1,2})(?:[ T]([0-9]{1,2}):([0-9]{1,2})(?::([0-9]{1,2}))?)?")


def _check_wall_time_exists(a: Analyzer, node: exp.Cast, local: str, zone: str | None) -> None:
    """A TIMESTAMP literal whose wall time falls in a daylight-saving gap of its zone is Trino's
    INVALID_LITERAL (a CAST of the same text moves it forward by the gap)."""
    match = _WALL_TIME.match(local)
    if zone is None or zone == zones.UTC or zones.is_offset(zone) or match is None:
        return
    try:
        wall = dt.datetime(*(int(part or 0) for part in match.groups()))
        region = ZoneInfo(zone)
    except (ValueError, ZoneInfoNotFoundError):
        return
    instant = wall.replace(tzinfo=region).astimezone(dt.UTC)
    if instant.astimezone(region).replace(tzinfo=None) != wall:
        a.fail(f"'{node.this.name.strip()}' is not a valid TIMESTAMP literal", node, "INVALID_LITERAL")


def castable(source: TType, target: TType) -> bool:
    """Whether Trino has a CAST from `source` to `target` (the subset lakegate translates)."""
    if source == target or source.is_unknown:
        return True
    if "json" in (source.base, target.base):
        return tt.castable_to_json(source) if target.base == "json" else tt.castable_from_json(target)
    scalar = ("boolean", "varchar")
    if source.is_numeric or source.base in scalar:
        if target.is_numeric or target.base in scalar:
            return True
    if source.base in ("varchar", "date", "timestamp", "timestamp_tz") and target.base in (
        "varchar",
        "date",
        "timestamp",
        "timestamp_tz",
    ):
        return True
    if target.base == "time" and source.base in ("varchar", "time", "timestamp"):  # times.py, pico_times.py
        return source.base != "timestamp" or source.args[0] <= 9
    if source.base in ("time", "time_tz") and target.base in ("timestamp", "timestamp_tz"):  # time_casts.py
        return True
    if source.base in ("time", "time_tz", "interval_ds", "interval_ym") and target.base == "varchar":
        return True
    if target.base == "time_tz" and source.base in ("varchar", "time", "time_tz", "timestamp", "timestamp_tz"):
        return True  # time(p <= 12) (pico_times.py), timestamp(p <= 9) (time_casts.py) and past (wide_timestamps.py)
    if target.base == "time" and source.base in ("time_tz", "timestamp_tz"):
        return source.args[0] <= 6 or source.base == "time_tz"
    if "ipaddress" in (source.base, target.base):  # from varchar and varbinary, to varchar and varbinary
        sources = ("varchar", "varbinary") if target.base == "ipaddress" else ()
        return source.base in sources or source.base == "ipaddress" and target in (tt.VARCHAR, tt.VARBINARY)
    if source.base == target.base == "array":
        return castable(source.element, target.element)
    if source.base == target.base == "row" and len(source.args) == len(target.args):
        return all(castable(s[1], t[1]) for s, t in zip(source.args, target.args))
    return False
