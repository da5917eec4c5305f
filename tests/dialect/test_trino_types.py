"""Trino's type model and typing rules (lakegate.dialect.trino_types), checked against the rules in
Trino's sources: io.trino.spi.type.Decimals.parse (literal types), io.trino.type.DecimalOperators
(decimal arithmetic), io.trino.type.TypeCoercion (common super types)."""

from __future__ import annotations

import pytest
import sqlglot

from lakegate.dialect import trino_types as tt


@pytest.mark.parametrize(
    "name",
    [
        "bigint",
        "integer",
        "double",
        "real",
        "boolean",
        "varchar",
        "varchar(3)",
        "decimal(6,2)",
        "date",
        "timestamp(3)",
        "timestamp(6) with time zone",
        "array(varchar)",
        "array(array(bigint))",
        "map(varchar, double)",
        "row(name varchar, x double)",
        "row(bigint, varchar(1))",
        "array(row(name varchar, description varchar, status varchar, type varchar, value varchar))",
        "interval day to second",
        "interval year to month",
        "json",
        "unknown",
    ],
)
def test_type_names_round_trip(name):
    assert str(tt.parse_type(name)) == name


def test_parse_type_aliases_and_defaults():
    assert tt.parse_type("INT") == tt.INTEGER
    assert tt.parse_type("decimal") == tt.decimal(38, 0)
    assert tt.parse_type("timestamp") == tt.timestamp(3)
    assert tt.parse_type("double precision") == tt.DOUBLE
    assert str(tt.parse_type('row("my field" bigint)')) == 'row("my field" bigint)'


@pytest.mark.parametrize("text", ["", "decimal(39,0)", "decimal(2,3)", "array(", "frobnicate", "array(bigint, x)"])
def test_parse_type_rejects_invalid_names(text):
    with pytest.raises(ValueError):
        tt.parse_type(text)


@pytest.mark.parametrize(
    "literal, expected",
    [
        ("1.5", "decimal(2,1)"),
        ("0.5", "decimal(1,1)"),
        ("100.0", "decimal(4,1)"),
        ("00.50", "decimal(2,2)"),
        ("12345678901234567890.5", "decimal(21,1)"),
        ("0.0", "decimal(1,1)"),
        ("7.", "decimal(1,0)"),
    ],
)
def test_decimal_literal_types_strip_leading_zeros(literal, expected):
    assert str(tt.decimal_literal_type(literal)) == expected


def test_integer_literal_types():
    assert tt.integer_literal_type("1") == tt.INTEGER
    assert tt.integer_literal_type("2147483647") == tt.INTEGER
    assert tt.integer_literal_type("2147483648") == tt.BIGINT
    assert tt.integer_literal_type("10000000000") == tt.BIGINT
    with pytest.raises(ValueError):
        tt.integer_literal_type("9223372036854775808")


@pytest.mark.parametrize(
    "op, left, right, expected",
    [
        ("+", "decimal(2,1)", "decimal(4,3)", "decimal(5,3)"),  # max(1, 1) + 3 + 1
        ("-", "decimal(38,0)", "decimal(38,0)", "decimal(38,0)"),  # capped at 38
        ("*", "decimal(4,1)", "decimal(2,1)", "decimal(6,2)"),  # the product guide's 100.0 * avg(...)
        ("/", "decimal(4,1)", "decimal(2,1)", "decimal(5,1)"),  # p1 + s2 + max(s2 - s1, 0), max(s1, s2)
        ("/", "decimal(3,2)", "decimal(5,4)", "decimal(9,4)"),
        ("%", "decimal(5,2)", "decimal(3,1)", "decimal(4,2)"),
        ("+", "integer", "decimal(2,1)", "decimal(12,1)"),  # integer -> decimal(10,0)
        ("*", "bigint", "decimal(2,1)", "decimal(21,1)"),  # bigint -> decimal(19,0)
        ("/", "integer", "integer", "integer"),
        ("+", "integer", "bigint", "bigint"),
        ("+", "tinyint", "smallint", "smallint"),
        ("*", "decimal(2,1)", "double", "double"),
        ("+", "real", "decimal(2,1)", "real"),
        ("+", "real", "double", "double"),
    ],
)
def test_arithmetic_result_types(op, left, right, expected):
    assert str(tt.arithmetic_type(op, tt.parse_type(left), tt.parse_type(right))) == expected


def test_arithmetic_on_non_numbers_has_no_operator():
    assert tt.arithmetic_type("+", tt.VARCHAR, tt.INTEGER) is None
    assert tt.arithmetic_type("*", tt.decimal(38, 20), tt.decimal(38, 20)) is None  # scale 40 > 38


@pytest.mark.parametrize(
    "a, b, expected",
    [
        ("varchar(3)", "varchar(5)", "varchar(5)"),
        ("varchar(3)", "varchar", "varchar"),
        ("integer", "decimal(2,1)", "decimal(11,1)"),
        ("bigint", "double", "double"),
        ("integer", "bigint", "bigint"),
        ("unknown", "date", "date"),
        ("date", "timestamp(3)", "timestamp(3)"),
        ("timestamp(3)", "timestamp(6)", "timestamp(6)"),
        ("array(integer)", "array(decimal(2,1))", "array(decimal(11,1))"),
    ],
)
def test_common_super_types(a, b, expected):
    assert str(tt.common_super_type(tt.parse_type(a), tt.parse_type(b))) == expected
    assert str(tt.common_super_type(tt.parse_type(b), tt.parse_type(a))) == expected


@pytest.mark.parametrize(
    "a, b", [("varchar", "integer"), ("boolean", "bigint"), ("date", "varchar"), ("array(bigint)", "bigint")]
)
def test_no_common_super_type_between_unrelated_types(a, b):
    assert tt.common_super_type(tt.parse_type(a), tt.parse_type(b)) is None


def test_coercible_widens_but_never_narrows():
    assert tt.coercible(tt.INTEGER, tt.BIGINT)
    assert not tt.coercible(tt.BIGINT, tt.INTEGER)
    assert tt.coercible(tt.decimal(2, 1), tt.decimal(5, 2))
    assert not tt.coercible(tt.decimal(5, 2), tt.decimal(2, 1))
    assert tt.coercible(tt.UNKNOWN, tt.VARCHAR)


@pytest.mark.parametrize(
    "trino, duck",
    [
        ("bigint", "BIGINT"),
        ("real", "FLOAT"),
        ("decimal(6,2)", "DECIMAL(6,2)"),
        ("varchar(3)", "VARCHAR"),
        ("timestamp(3)", "TIMESTAMP"),
        ("timestamp(9)", "TIMESTAMP_NS"),
        ("timestamp(3) with time zone", "TIMESTAMPTZ"),
        ("array(row(name varchar, x double))", 'STRUCT("name" VARCHAR, "x" DOUBLE)[]'),
        ("map(varchar, bigint)", "MAP(VARCHAR, BIGINT)"),
    ],
)
def test_duckdb_equivalents(trino, duck):
    assert tt.duckdb_type(tt.parse_type(trino)) == duck


def test_no_duckdb_cast_for_unknown_or_anonymous_rows():
    assert tt.duckdb_type(tt.UNKNOWN) is None
    assert tt.duckdb_type(tt.parse_type("row(bigint, varchar)")) is None


@pytest.mark.parametrize(
    "cast_sql, expected",
    [
        ("CAST(x AS decimal(10, 2))", "decimal(10,2)"),
        ("CAST(x AS decimal)", "decimal(38,0)"),
        ("CAST(x AS varchar)", "varchar"),
        ("CAST(x AS varchar(4))", "varchar(4)"),
        ("CAST(x AS timestamp)", "timestamp(3)"),
        ("CAST(x AS timestamp(6) with time zone)", "timestamp(6) with time zone"),
        ("CAST(x AS array(bigint))", "array(bigint)"),
        ("CAST(x AS row(a integer, b double))", "row(a integer, b double)"),
        ("CAST(x AS real)", "real"),
        ("CAST(x AS integer)", "integer"),
    ],
)
def test_cast_targets(cast_sql, expected):
    target = sqlglot.parse_one(f"SELECT {cast_sql}", read="trino").expressions[0].args["to"]
    assert str(tt.from_datatype(target)) == expected
