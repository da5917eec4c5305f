"""Trino's functions/datetime.md, continued: the overloads for time(p) with time zone of hour, minute,
second, millisecond, timezone_hour, timezone_minute, timezone, date_trunc, date_add and date_diff
(io.trino.operator.scalar.timetz: ExtractHour, ..., DateTrunc, DateAdd, DateDiff, TimeZoneHour,
TimeZoneMinute), on values held as dialect/zoned_times.py describes. The local time gives the
fields, truncation and addition (modulo a day, the offset kept); date_diff counts on the times at
+00:00. Cases in tests/dialect/cases/datetime.yaml.
"""

from __future__ import annotations

from lakegate.dialect import trino_types as tt
from lakegate.dialect import zoned_times
from lakegate.dialect.functions.arguments import literal_str
from lakegate.dialect.registry import overload
from lakegate.dialect.type_rules import Call, ttype

_FIELDS = ("hour", "minute", "second", "millisecond", "timezone_hour", "timezone_minute")


def _zoned(t: tt.TType | None) -> bool:
    return t is not None and t.base == "time_tz"


def _unit(call: Call) -> str:
    """The unit: a literal, millisecond to hour ('day' is not a valid TIME field, at analysis)."""
    unit = literal_str(call, 0)
    if unit is None:
        call.fail("the unit must be a literal string in lakegate", "NOT_SUPPORTED")
    if unit.lower() not in zoned_times.UNIT_PICOS:
        call.fail(f"'{unit}' is not a valid TIME field", "INVALID_FUNCTION_ARGUMENT")
    return unit.lower()


def _field(call: Call) -> tt.TType | None:
    if len(call.types) != 1 or not _zoned(call.types[0]):
        return None
    return tt.VARCHAR if call.name == "timezone" else tt.BIGINT


def _date_trunc(call: Call) -> tt.TType | None:
    if len(call.types) != 2 or not _zoned(call.types[1]):
        return None
    _unit(call)
    return call.types[1]


def _date_add(call: Call) -> tt.TType | None:
    if len(call.types) != 3 or not _zoned(call.types[2]):
        return None
    amount = call.types[1]
    if amount is None or not (amount.is_integral or amount.is_unknown):
        call.mismatch()
    _unit(call)
    return call.types[2]


def _date_diff(call: Call) -> tt.TType | None:
    if len(call.types) != 3 or not (_zoned(call.types[1]) and _zoned(call.types[2])):
        return None
    _unit(call)
    return tt.BIGINT


def _render_date_add(g, node, args) -> str:
    """The amount of units modulo a day added to the local time, modulo a day (DateAdd)."""
    size = zoned_times.UNIT_PICOS[args[0].name.lower()]
    delta = f"((CAST({g.sql(args[1])} AS BIGINT) % {zoned_times.PICOS_PER_DAY // size}) * {size})"
    return zoned_times.add_picos(g.sql(args[2]), delta, ttype(node).args[0])


def _render_date_diff(g, node, args) -> str:
    """Whole units from the first time to the second at +00:00, truncated toward zero (DateDiff)."""
    size = zoned_times.UNIT_PICOS[args[0].name.lower()]
    return f"CAST({zoned_times.difference_picos(g.sql(args[2]), g.sql(args[1]))} // {size} AS BIGINT)"


def install() -> None:
    for name in _FIELDS:
        overload(
            name,
            _field,
            lambda g, node, args, name=name: zoned_times.field(g.sql(args[0]), name),
            f"{name}(time(p) with time zone) -> bigint",
        )
    overload(
        "timezone",
        _field,
        lambda g, node, args: zoned_times.offset_text(zoned_times.offset(g.sql(args[0]))),
        "timezone(time(p) with time zone) -> varchar",
    )
    overload(
        "date_trunc",
        _date_trunc,
        lambda g, node, args: zoned_times.truncate(args[0].name.lower(), g.sql(args[1])),
        "date_trunc(unit, time(p) with time zone) -> same",
    )
    overload("date_add", _date_add, _render_date_add, "date_add(unit, value, time(p) with time zone) -> same")
    overload("date_diff", _date_diff, _render_date_diff, "date_diff(unit, time(p) with time zone, same) -> bigint")
