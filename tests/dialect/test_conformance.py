"""The Trino conformance suite: every case in cases/*.yaml is a Trino query with the answer Trino
gives (values and result types, or an error name), written from Trino's documented semantics. Each
case is translated with `lakegate.dialect.translate.translate` against the fixture schema, run in
real DuckDB over real Parquet files (conftest.py), and compared with the expected answer in the
Trino client-protocol JSON encoding.

Rows are compared in order when the query has a top-level ORDER BY (or the case says `ordered:
true`), otherwise as a multiset. Doubles compare exactly unless the case gives `tolerance:`.
A case whose query uses a function the registry lists in `registry.REJECTED`, and that is refused
naming that function, is reported as xfail (a documented gap), never as a pass.
"""

from __future__ import annotations

import base64
import datetime as dt
import math
import re
import uuid
from decimal import Context, Decimal
from zoneinfo import ZoneInfo

import duckdb
import pyarrow as pa
import pytest
from answer_compare import has_order_by, normalize_type, rows_match, same
from functions_doc import Case, called_names, load_cases

from lakegate.dialect import registry
from lakegate.dialect.errors import DialectError, runtime_error
from lakegate.dialect.translate import translate
from lakegate.gateway.engine.trino_values import ipaddress_text, shortest_float32

CASES = load_cases()
_INTEGRAL = {"tinyint", "smallint", "integer", "bigint"}
_SPECIAL_DOUBLES = {"NaN", "Infinity", "-Infinity"}
_GAP_ERRORS = {"NOT_SUPPORTED", "FUNCTION_NOT_FOUND"}


# --- Trino types -----------------------------------------------------------------------------------
def _split_top(text: str) -> list[str]:
    """Split on commas that are not inside parentheses or double quotes."""
    parts, depth, quoted, start = [], 0, False, 0
    for i, ch in enumerate(text):
        if ch == '"':
            quoted = not quoted
        elif not quoted and ch == "(":
            depth += 1
        elif not quoted and ch == ")":
            depth -= 1
        elif not quoted and depth == 0 and ch == ",":
            parts.append(text[start:i].strip())
            start = i + 1
    parts.append(text[start:].strip())
    return parts


_BASES = {
    "boolean",
    "tinyint",
    "smallint",
    "integer",
    "bigint",
    "real",
    "double",
    "decimal",
    "varchar",
    "char",
    "varbinary",
    "json",
    "date",
    "time",
    "timestamp",
    "interval",
    "array",
    "map",
    "row",
    "uuid",
    "unknown",
    "ipaddress",
}


def parse_type(text: str) -> tuple:
    """A Trino type name -> (base, args): decimal (p, s), varchar (n,) or (), timestamp (p,),
    array (T,), map (K, V), row (T, ...) (field names dropped); `with time zone` gives base
    'timestamp_tz'; the intervals are 'interval day to second' / 'interval year to month'."""
    text = text.strip()
    low = text.lower()
    if low.endswith(" with time zone"):
        base, args = parse_type(text[: -len(" with time zone")])
        return f"{base}_tz", args
    if low.startswith("interval"):
        return " ".join(low.split()), ()
    if "(" not in text:
        return low, ()
    base, rest = text.split("(", 1)
    base = base.strip().lower()
    inner = _split_top(rest[: rest.rindex(")")])
    if base in ("array", "map"):
        return base, tuple(parse_type(part) for part in inner)
    if base == "row":
        return base, tuple(parse_type(_field_type(part)) for part in inner)
    return base, tuple(int(part) for part in inner)


def _field_type(field: str) -> str:
    """The type of a row field spec: `name type`, `"name" type` or just `type`."""
    if field.startswith('"'):
        return field[field.index('"', 1) + 1 :].strip()
    head, _, tail = field.partition(" ")
    if tail and "(" not in head and head.lower() not in _BASES:
        return tail
    return field


# --- DuckDB values -> Trino client-protocol JSON encoding --------------------------------------------
def _zone_name(value: dt.datetime) -> str:
    """A zoned value's zone as Trino names it: the region, UTC, or the offset as +hh:mm."""
    key = getattr(value.tzinfo, "key", None)
    if key is not None and key not in ("UTC", "Etc/UTC"):
        return key
    minutes = int(value.utcoffset().total_seconds()) // 60
    sign = "-" if minutes < 0 else "+"
    return "UTC" if minutes == 0 else f"{sign}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"


def in_zone(value, zone: str | None):
    """A timestamp with time zone DuckDB gave (in UTC) in the zone its column's values carry; epoch
    nanoseconds (see _arrow_rows) as that timestamp to the second and its nanoseconds."""
    if isinstance(value, int) and not isinstance(value, bool) and zone is not None:
        seconds, nanos = divmod(value, 10**9)
        return in_zone(dt.datetime.fromtimestamp(seconds, dt.UTC), zone), nanos
    if not isinstance(value, dt.datetime) or zone in (None, "UTC"):
        return value
    if zone[0] in "+-":
        hours, minutes = int(zone[1:3]), int(zone[4:6])
        sign = -1 if zone[0] == "-" else 1
        return value.astimezone(dt.timezone(sign * dt.timedelta(hours=hours, minutes=minutes)))
    return value.astimezone(ZoneInfo(zone))


def to_protocol(value, ttype: tuple):
    """Encode a DuckDB Python value as the Trino protocol would for a column of type `ttype`. A value
    of an unexpected Python type is returned unchanged, so that it shows up as a mismatch."""
    if value is None:
        return None
    base, args = ttype
    if base in _INTEGRAL:
        return value if isinstance(value, int) and not isinstance(value, bool) else repr(value)
    if base in ("double", "real"):
        if not isinstance(value, (float, int)) or isinstance(value, bool):
            return repr(value)
        value = float(value)
        if math.isnan(value):
            return "NaN"
        if math.isinf(value):
            return "Infinity" if value > 0 else "-Infinity"
        return float(shortest_float32(value)) if base == "real" else value
    if base == "decimal":
        if isinstance(value, (Decimal, int)) and not isinstance(value, bool):
            return format(Decimal(value).quantize(Decimal(1).scaleb(-args[1]), context=Context(prec=80)), "f")
        return repr(value)
    if base == "date" and isinstance(value, dt.date):
        return value.isoformat()
    if base == "timestamp" and isinstance(value, int) and not isinstance(value, bool):  # epoch nanoseconds
        seconds, nanos = divmod(value, 10**9)
        text = (dt.datetime(1970, 1, 1) + dt.timedelta(seconds=seconds)).strftime("%Y-%m-%d %H:%M:%S")
        return text + ("." + f"{nanos:09d}"[: args[0]] if args[0] else "")
    if base in ("timestamp", "timestamp_tz") and isinstance(value, dict):  # wide_timestamps.shown
        wall = dt.datetime(1970, 1, 1) + dt.timedelta(microseconds=value["wall"])
        fraction = f"{wall.microsecond:06d}{value['ps']:06d}"[: args[0]]
        text = f"{wall:%Y-%m-%d %H:%M:%S}.{fraction}"
        return text if value["zone"] is None else f"{text} {value['zone']}"
    if base == "timestamp_tz" and isinstance(value, tuple):  # (timestamp to the second, nanoseconds)
        stamp, nanos = value
        fraction = "." + f"{nanos:09d}"[: args[0]] if args[0] else ""
        return stamp.strftime("%Y-%m-%d %H:%M:%S") + fraction + " " + _zone_name(stamp)
    if base in ("timestamp", "timestamp_tz") and isinstance(value, dt.datetime):
        text = value.strftime("%Y-%m-%d %H:%M:%S")
        precision = args[0] if args else 3
        if precision:
            text += "." + f"{value.microsecond:06d}".ljust(precision, "0")[:precision]
        if base == "timestamp_tz":
            text += " " + _zone_name(value)
        return text
    if base == "time_tz" and isinstance(value, dict):  # {utc_ps, offset_min} (dialect/zoned_times.py)
        minutes = value["offset_min"]
        seconds, picos = divmod((value["utc_ps"] + minutes * 60 * 10**12) % (86_400 * 10**12), 10**12)
        text = (dt.datetime(1970, 1, 1) + dt.timedelta(seconds=seconds)).strftime("%H:%M:%S")
        text += "." + f"{picos:012d}"[: args[0]] if args[0] else ""
        return f"{text}{'-' if minutes < 0 else '+'}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"
    if base == "time" and isinstance(value, int) and not isinstance(value, bool):  # picoseconds (pico_times.py)
        seconds, picos = divmod(value, 10**12)
        text = (dt.datetime(1970, 1, 1) + dt.timedelta(seconds=seconds)).strftime("%H:%M:%S")
        return text + ("." + f"{picos:012d}"[: args[0]] if args[0] else "")
    if base == "time" and isinstance(value, dt.time):
        precision = args[0] if args else 3
        text = value.strftime("%H:%M:%S")
        return text + ("." + f"{value.microsecond:06d}".ljust(precision, "0")[:precision] if precision else "")
    if base == "interval day to second" and isinstance(value, dt.timedelta):
        sign = "-" if value < dt.timedelta(0) else ""
        total_ms = abs(value) // dt.timedelta(milliseconds=1)
        days, ms = divmod(total_ms, 86_400_000)
        hours, ms = divmod(ms, 3_600_000)
        minutes, ms = divmod(ms, 60_000)
        return f"{sign}{days} {hours:02d}:{minutes:02d}:{ms // 1000:02d}.{ms % 1000:03d}"
    if base == "array" and isinstance(value, (list, tuple)):
        return [to_protocol(v, args[0]) for v in value]
    if base == "map" and isinstance(value, dict):
        pairs = value.items()
        if args[0][0] in ("array", "row"):  # DuckDB gives unhashable keys as {'key': [...], 'value': [...]}
            pairs = zip(value["key"], value["value"])
        return {_java_text(to_protocol(k, args[0])): to_protocol(v, args[1]) for k, v in pairs}
    if base == "row" and isinstance(value, (dict, tuple, list)):
        fields = list(value.values()) if isinstance(value, dict) else list(value)
        return [to_protocol(v, t) for v, t in zip(fields, args)] if len(fields) == len(args) else fields
    if base == "varbinary" and isinstance(value, (bytes, bytearray)):
        return base64.b64encode(bytes(value)).decode()
    if base == "uuid" and isinstance(value, uuid.UUID):
        return str(value)
    if base == "ipaddress" and isinstance(value, (bytes, bytearray)):
        return ipaddress_text(value)
    if base == "unknown":
        return repr(value)
    return value


# --- comparison ------------------------------------------------------------------------------------
def is_ordered(case: Case) -> bool:
    return case.ordered if case.ordered is not None else has_order_by(case.sql)


def _check_expected_values(case: Case, types: list[tuple]) -> None:
    """Catch typos in the case file: double columns hold numbers or the special strings."""
    for row in case.rows:
        for value, ttype in zip(row, types):
            if ttype[0] in ("double", "real") and isinstance(value, str) and value not in _SPECIAL_DOUBLES:
                raise AssertionError(f"case file: {value!r} is not a double (write 1.0e+10, not 1e10)")


# --- the suite -------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dialect():
    """The translator and the functions it refuses by name."""
    return translate, registry.REJECTED


def test_suite_size():
    """The issue asks for at least 300 cases, grouped by family."""
    assert len(CASES) >= 300
    assert len({case.family for case in CASES}) >= 15


@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_case(case: Case, dialect, fixture_lake):
    translate, rejected = dialect
    if case.errors:
        _run_error_case(case, translate, fixture_lake)
    else:
        _run_result_case(case, translate, rejected, fixture_lake)


def _translated(case: Case, translation) -> str:
    return f"\nTrino SQL:  {case.sql.strip()}\nDuckDB SQL: {translation.duckdb_sql}"


def _run_result_case(case: Case, translate, rejected: dict, lake) -> None:
    try:
        translation = translate(case.sql, lake.schema, time_zone=case.time_zone)
    except DialectError as e:
        gaps = [
            name
            for name in sorted(called_names(case.sql) & set(rejected))
            if re.search(rf"\b{re.escape(name)}\b", str(e), re.IGNORECASE)
        ]
        if e.error_name in _GAP_ERRORS and gaps:
            pytest.xfail(f"documented gap: {gaps[0]} ({rejected[gaps[0]]})")
        pytest.fail(f"refused with {e.error_name}: {e}\nTrino SQL: {case.sql.strip()}", pytrace=False)
    expected_types = [parse_type(t) for _, t in case.columns]
    _check_expected_values(case, expected_types)
    with lake.transaction() as con:
        try:
            if any(_nanoseconds(t) for t in expected_types):
                raw_rows = _arrow_rows(con.sql(translation.duckdb_sql).to_arrow_table())
                width = len(raw_rows[0]) if raw_rows else len(case.columns)
            else:
                cursor = con.execute(translation.duckdb_sql)
                raw_rows = cursor.fetchall()
                width = len(cursor.description)
        except duckdb.Error as e:
            pytest.fail(f"DuckDB failed: {e}{_translated(case, translation)}", pytrace=False)

    problems = []
    got_columns = [(name, str(t)) for name, t in translation.columns]
    want = [(n, normalize_type(t)) for n, t in case.columns]
    if [(n, normalize_type(t)) for n, t in got_columns] != want:
        problems.append(f"columns: expected {list(case.columns)}\n         got      {got_columns}")
    if width != len(case.columns):
        problems.append(f"DuckDB returned {width} columns, expected {len(case.columns)}")
    zones = translation.zones or (None,) * width
    rows = [[to_protocol(in_zone(v, z), t) for v, t, z in zip(row, expected_types, zones)] for row in raw_rows]
    expected = [list(row) for row in case.rows]
    if not rows_match(expected, rows, ordered=is_ordered(case), tolerance=case.tolerance):
        problems.append(f"rows: expected {expected}\n      got      {rows}")
    if problems:
        pytest.fail("\n".join(problems) + _translated(case, translation), pytrace=False)


def _java_text(value) -> str:
    """A map key as the protocol writes it: Java's toString of the key's value (`[1, null]`, `true`)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, list):
        return "[" + ", ".join(map(_java_text, value)) + "]"
    return str(value)


def _nanoseconds(ttype: tuple) -> bool:
    return ttype[0] in ("timestamp", "timestamp_tz") and bool(ttype[1]) and ttype[1][0] > 6


def _arrow_rows(table: pa.Table) -> list[tuple]:
    """The rows of a result with timestamp(7..9) columns, read through Arrow with nanosecond timestamps as
    epoch nanoseconds (ints, which to_protocol formats): DuckDB's Python values stop at microseconds."""
    columns = [
        c.cast(pa.timestamp("ns")).cast(pa.int64()).to_pylist()
        if pa.types.is_timestamp(c.type) and c.type.unit == "ns"
        else c.to_pylist()
        for c in table.columns
    ]
    return list(zip(*columns))


def _run_error_case(case: Case, translate, lake) -> None:
    names = " or ".join(case.errors)
    try:
        translation = translate(case.sql, lake.schema, time_zone=case.time_zone)
    except DialectError as e:
        problems = []
        if e.error_name not in case.errors:
            problems.append(f"error {e.error_name}, expected {names}")
        if case.line is not None and (e.line, e.column) != (case.line, case.column):
            problems.append(
                f"position line {e.line}, column {e.column}, expected line {case.line}, column {case.column}"
            )
        if case.message and case.message.lower() not in str(e).lower():
            problems.append(f"message does not mention {case.message!r}")
        if problems:
            pytest.fail("; ".join(problems) + f"\nerror: {e}\nTrino SQL: {case.sql.strip()}", pytrace=False)
        return
    if case.line is not None:
        pytest.fail(
            f"expected {names} at translation (line {case.line}, column {case.column}), but it "
            f"translated{_translated(case, translation)}",
            pytrace=False,
        )
    with lake.transaction() as con:
        try:
            rows = con.execute(translation.duckdb_sql).fetchall()
        except duckdb.Error as e:
            message = str(e)
            if (
                not any(name in message for name in case.errors)
                and runtime_error(message).error_name not in case.errors
            ):
                pytest.fail(
                    f"DuckDB error does not name {names}: {message}{_translated(case, translation)}", pytrace=False
                )
            told = f"{message} {runtime_error(message).message}"  # DuckDB's words and the client's
            if case.message and case.message.lower() not in told.lower():
                pytest.fail(f"error does not mention {case.message!r}: {message}", pytrace=False)
            return
    pytest.fail(f"expected {names}, but the query returned {rows}{_translated(case, translation)}", pytrace=False)


# --- the runner's own pieces -----------------------------------------------------------------------
def test_parse_type():
    assert parse_type("decimal(6,2)") == ("decimal", (6, 2))
    assert parse_type("varchar") == ("varchar", ())
    assert parse_type("timestamp(3) with time zone") == ("timestamp_tz", (3,))
    assert parse_type('array(row(x integer, "y z" varchar(3)))') == (
        "array",
        (("row", (("integer", ()), ("varchar", (3,)))),),
    )
    assert parse_type("row(integer, varchar(1))") == ("row", (("integer", ()), ("varchar", (1,))))
    assert parse_type("map(varchar(1), double)") == ("map", (("varchar", (1,)), ("double", ())))
    assert parse_type("interval day to second") == ("interval day to second", ())


def test_to_protocol_encodings():
    assert to_protocol(Decimal("150"), parse_type("decimal(6,2)")) == "150.00"
    assert to_protocol(Decimal("-0.5"), parse_type("decimal(1,1)")) == "-0.5"
    assert to_protocol(1.5, parse_type("decimal(2,1)")) == repr(1.5)  # a float is not a decimal value
    assert to_protocol(float("nan"), ("double", ())) == "NaN"
    assert to_protocol(float("-inf"), ("double", ())) == "-Infinity"
    assert (
        to_protocol(dt.datetime(2024, 1, 2, 3, 4, 5, 123456), parse_type("timestamp(3)")) == "2024-01-02 03:04:05.123"
    )
    assert to_protocol(dt.datetime(2024, 1, 2, 3, 4, 5), parse_type("timestamp(0)")) == "2024-01-02 03:04:05"
    assert (
        to_protocol(dt.datetime(1970, 1, 1, tzinfo=dt.UTC), parse_type("timestamp(3) with time zone"))
        == "1970-01-01 00:00:00.000 UTC"
    )
    assert to_protocol(dt.timedelta(days=2, seconds=3), ("interval day to second", ())) == "2 00:00:03.000"
    assert to_protocol({"x": 1, "y": "a"}, parse_type("row(x integer, y varchar)")) == [1, "a"]
    assert to_protocol([Decimal("1"), None], parse_type("array(decimal(3,1))")) == ["1.0", None]
    assert to_protocol(True, ("integer", ())) == "True"


def test_same_is_strict():
    assert same([1, "a"], [1, "a"], None)
    assert not same([True], [1], None)
    assert not same([2.45], [2.4500000000000006], None)
    assert same([2.45], [2.4500000000000006], 1e-12)
    assert not same(["1"], [1], None)
