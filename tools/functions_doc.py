"""Generate docs/functions.md: which Trino functions and operators lakegate answers, from the function
registry (filled by the modules of `lakegate.dialect.functions`) and the conformance cases (tests/dialect/cases/*.yaml).

    python tools/functions_doc.py           # write docs/functions.md
    python tools/functions_doc.py --check   # exit 1 if docs/functions.md is stale

The case files are also loaded from here by the conformance runner (`load_cases`), so the runner and
the page read them the same way. A repository tool: it reads tests/ and writes docs/, so it is not
part of the installed package (pytest finds it through `pythonpath` in pyproject.toml).
"""

from __future__ import annotations

import argparse
import logging
import re
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import sqlglot
import yaml
from sqlglot.dialects.trino import Trino
from sqlglot.tokens import TokenType

REPO = Path(__file__).resolve().parent.parent
CASES_DIR = REPO / "tests" / "dialect" / "cases"
OUTPUT = REPO / "docs" / "functions.md"

#: PyYAML's libyaml-backed safe loader when it is built in (the same documents, several times faster:
#: every conformance module loads the case files at collection), else the pure-Python one.
_CASE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

_CASE_KEYS = {
    "name",
    "sql",
    "columns",
    "rows",
    "error",
    "message",
    "line",
    "column",
    "ordered",
    "tolerance",
    "note",
    "session",
    "not_on_trino",
}
_FILE_KEYS = {"family", "title", "description", "cases"}


class CaseFileError(ValueError):
    """A case file is malformed (the message names the file and the case)."""


#: The decision on the time types lakegate refuses by name, with the figures it rests on.
PRECISION = [
    "Answered exactly: timestamp(p) for every p = 0..12 (DuckDB's TIMESTAMP_NS for 7-9, within its range "
    "1677-2262; a struct for 10-12), timestamp(p) with time zone for every p = 0..12, and time(p) and time(p) "
    "with time zone for every p = 0..12. Refused by name (NOT_SUPPORTED): timestamp(7-9) outside the "
    "nanosecond range.",
    "Time with time zone (dialect/zoned_times.py): held in DuckDB as `STRUCT(utc_ps BIGINT, offset_min SMALLINT)`, "
    "the time of day at offset +00:00 in picoseconds (Trino's TimeWithTimeZoneTypes.normalize: what it compares, "
    "orders and subtracts) and the offset in minutes. Answered: literals of every precision, CAST to and from "
    "varchar, time(p <= 6) and itself, from timestamp(p <= 6) and timestamp(p <= 6) with time zone (a time, "
    "timestamp or text without an offset takes the session zone's, when the session zone has one offset), "
    "=, <>, <, <=, >, >=, BETWEEN, IN a list, IS [NOT] DISTINCT FROM, ORDER BY, min, max, min_by, max_by, hour, "
    "minute, second, millisecond, timezone_hour, timezone_minute, timezone, EXTRACT, date_trunc, date_add, "
    "date_diff, ± interval day to second, the difference of two, AT TIME ZONE an offset or an interval of whole "
    "minutes; the protocol's JSON shows Trino's text (`01:02:03.456-00:35`). Refused by name: GROUP BY, "
    "DISTINCT, UNION / INTERSECT / EXCEPT, IN a subquery, PARTITION BY and greatest / least of it (DuckDB would "
    "tell apart one instant in two offsets, which Trino takes as one value), arrays, maps and rows of it, AT "
    "TIME ZONE a region, the casts of a value that is not a literal to timestamp with time zone (each value's "
    "offset would be its zone), current_time, Arrow and "
    "Parquet output (no such Arrow type). CAST of a timestamp(p <= 6) with time zone to time goes through it "
    "(the time of day in the value's zone).",
    "time(7-12) (dialect/pico_times.py): held in DuckDB as a BIGINT of picoseconds of the day (the unit of "
    "time with time zone; time(p <= 6) stays DuckDB's TIME), so comparisons, ORDER BY, GROUP BY, DISTINCT, set "
    "operations, min and max need nothing more. Answered: literals, CAST to and from varchar, between "
    "precisions (HALF_UP, wrapping at midnight), to and from time(p <= 6), time with time zone and "
    "timestamp(p <= 9), hour, minute, second, millisecond, EXTRACT, date_trunc, date_add, date_diff, ± "
    "interval day to second, the difference of two times (of every precision: an interval rounded HALF_UP to "
    "milliseconds), AT TIME ZONE, and Trino's text through the protocol. Refused by name: the other functions "
    "of it (DuckDB would read the number) and arrays, maps and rows of it. Cost: none for time(p <= 6).",
    "The casts of time and time with time zone to timestamp (dialect/time_casts.py) take the session's date, "
    "the date the query starts on in the session zone, as the real Trino 476 does (asked in UTC, "
    "Pacific/Kiritimati, Etc/GMT+12 and America/New_York): a time, or a time with time zone's local time, on "
    "that date, rounded HALF_UP (24:00 is the next day); to timestamp with time zone a time is read in the "
    "session zone, and a time with time zone literal is the instant of its time at +00:00 on that date, in its "
    "own offset. Answered for the timestamps lakegate holds (timestamp(p <= 9), timestamp(p <= 6) with time "
    "zone); the rest refused by name. Figures (2026-11-29, `python3 dev.py corpus --refusals 40` and "
    "`--sample 3000`): the translator refuses 4,420 of the 19,450 corpus queries (6,299 before); time(7-12) "
    "1,176 -> 0, the casts of times to timestamps 744 -> 282 (all to timestamps lakegate does not hold); "
    "functions and types of the sample 75.5 % equal (64.9 % before).",
    "Why a struct and not DuckDB's TIMETZ (microseconds and an offset in seconds, compared with the offset): of "
    "the 3,559 corpus queries of time with time zone the translator answers 2,038 now, 1,005 of them with p > 6, "
    "which TIMETZ cannot hold, and its equality would still have to be rewritten. Cost: every comparison "
    "reads one struct field (translation cold median below; no lake column has this type).",
    "Timestamp(7..12) with time zone (dialect/wide_timestamps.py): held as `STRUCT(us TIMESTAMPTZ, ps INTEGER)`, "
    "the instant floored to the microsecond (what every zone-dependent operation of timestamp(p <= 6) with time "
    "zone reads, so those apply unchanged) and the picoseconds below it; the zone stays static in the "
    "expression's type, as for every zoned timestamp, and DuckDB orders the struct field by field, as Trino "
    "orders the instants. Timestamp(10..12) is the same struct of the wall time (`us TIMESTAMP`). Answered: "
    "literals (their instant computed at translation), CAST to and from varchar "
    "(literals), timestamp(p), date and every precision (HALF_UP), =, <>, <, <=, >, >=, BETWEEN, IN, IS [NOT] "
    "DISTINCT FROM, ORDER BY, GROUP BY, DISTINCT, min, max, count, arbitrary, coalesce, CASE, the date and time "
    "functions that read the microseconds (fields, EXTRACT, date_trunc, date_add, which keeps the picoseconds, "
    "date_diff, date_format), ± intervals, AT TIME ZONE, to_unixtime and from_unixtime_nanos; results show "
    "Trino's text. Refused by name: the other functions of it, arrays, maps and rows of it, the difference of "
    "two and casts to time (casts to time with time zone are answered). Why a struct: the epoch picoseconds "
    "need 80 bits (no DuckDB integer type but "
    "HUGEINT, whose every zone-dependent operation would have to be rewritten), DuckDB's TIMESTAMP_NS cannot "
    "hold the zone's instant past 1677-2262 nor past nine digits, and the struct keeps the TIMESTAMPTZ code. "
    "Cost: a literal with a zone translates to a constant; a column value's SQL reads one struct field per "
    "use. Figures (`python3 dev.py corpus --refusals 40`, 19,450 queries, 2026-11-29): the translator refused "
    "6,299 before, 5,215 with timestamp(7..12) with time zone, 4,584 with timestamp(10..12) too, 4,134 with "
    "their casts to time with time zone.",
    "Figures (`python3 dev.py corpus --refusals 40`, Trino 476's own function, type and query tests, 19,450 "
    "queries, 2026-11-29): the translator refused 8,389 before time with time zone (2,844 of them time with "
    "time zone), 6,299 after. The next families: timestamp(7-12) with time zone 1,503, time(7-12) 1,176, "
    "timestamp past nanoseconds 851, and the casts of times to timestamps that take the session's date (744); "
    "representing them means the same kind of two-part value (epoch microseconds and picoseconds of the "
    "microsecond), family by family with the corpus run as the judge. Dates and timestamps of years past 9999 or "
    "before year 0 are answered and written as Trino writes them (+10000-06-01, -0500-06-01).",
]

#: How lakegate holds Trino's IPADDRESS (dialect/ipaddresses.py).
IP_ADDRESSES = [
    "IPADDRESS is held in DuckDB as a BLOB of 16 bytes, the address's IPv6 form (an IPv4 address as "
    "::ffff:a.b.c.d), as Trino holds it: DuckDB orders and compares BLOBs byte by byte, which is Trino's order "
    "(ORDER BY, min, max, comparisons, DISTINCT, GROUP BY), and CAST to varbinary is the BLOB itself. Text is read "
    "as Guava's InetAddresses.forString reads it (literals at translation, CAST from varchar in DuckDB SQL) and "
    "written as InetAddresses.toAddrString writes it (CAST to varchar in DuckDB SQL; the protocol's JSON by "
    "gateway/engine/trino_values.py): an IPv4-mapped address dotted, any other in lower-case hex with the longest "
    "run of zero groups as `::`. A scope after `%` is dropped when it is a number; one naming a network interface "
    "(Trino resolves it on its server) is refused as an invalid address. contains(network, address) as the real "
    "Trino 476 answers it (tests/dialect/cases/ipaddress.yaml). IPPREFIX is not a type of Trino 476.",
]


@dataclass(frozen=True)
class Case:
    """One conformance case: a Trino query and the answer Trino gives (result or error)."""

    family: str
    name: str
    sql: str
    columns: tuple[tuple[str, str], ...] | None = None  # (output name, Trino type) per column
    rows: tuple[tuple, ...] | None = None  # values in the client-protocol JSON encoding
    errors: tuple[str, ...] = ()  # accepted Trino error names
    message: str | None = None  # substring of the error message
    line: int | None = None
    column: int | None = None
    ordered: bool | None = None  # None: ordered iff a top-level ORDER BY
    tolerance: float | None = None
    note: str | None = None
    time_zone: str = "UTC"  # the session zone (`session: {time_zone: ...}`)
    not_on_trino: str | None = None  # why the differential run does not ask the real Trino

    @property
    def id(self) -> str:
        return f"{self.family}/{self.name}"


@dataclass(frozen=True)
class Family:
    """One case file: a function family with its cases."""

    name: str
    title: str
    description: str
    cases: tuple[Case, ...]


def parse_column(spec: str) -> tuple[str, str]:
    """`'name type'` or `'"quoted name" type'` -> (name, type)."""
    spec = spec.strip()
    if spec.startswith('"'):
        match = re.match(r'"((?:[^"]|"")*)"\s+(.+)$', spec)
        if not match:
            raise ValueError(f"bad column spec {spec!r}")
        return match.group(1).replace('""', '"'), match.group(2).strip()
    name, _, type_name = spec.partition(" ")
    if not type_name.strip():
        raise ValueError(f"column spec {spec!r} has no type")
    return name, type_name.strip()


def _case(family: str, raw: dict, where: str) -> Case:
    unknown = set(raw) - _CASE_KEYS
    if unknown:
        raise CaseFileError(f"{where}: unknown keys {sorted(unknown)}")
    if not isinstance(raw.get("name"), str) or not isinstance(raw.get("sql"), str):
        raise CaseFileError(f"{where}: a case needs a name and an sql text")
    has_result = "rows" in raw or "columns" in raw
    if has_result == ("error" in raw):
        raise CaseFileError(f"{where}: give either columns and rows, or error")
    columns = rows = None
    if has_result:
        if "rows" not in raw or "columns" not in raw:
            raise CaseFileError(f"{where}: a result needs both columns and rows")
        try:
            columns = tuple(parse_column(c) for c in raw["columns"])
        except (ValueError, AttributeError) as e:
            raise CaseFileError(f"{where}: {e}") from None
        rows = tuple(tuple(r) for r in raw["rows"])
        for row in rows:
            if len(row) != len(columns):
                raise CaseFileError(f"{where}: row {list(row)} does not have {len(columns)} values")
    session = raw.get("session") or {}
    if not isinstance(session, dict) or set(session) - {"time_zone"}:
        raise CaseFileError(f"{where}: session takes only time_zone")
    errors = raw.get("error", ())
    errors = (errors,) if isinstance(errors, str) else tuple(errors)
    return Case(
        family=family,
        name=raw["name"],
        sql=raw["sql"],
        columns=columns,
        rows=rows,
        errors=errors,
        message=raw.get("message"),
        line=raw.get("line"),
        column=raw.get("column"),
        ordered=raw.get("ordered"),
        tolerance=float(raw["tolerance"]) if "tolerance" in raw else None,
        note=raw.get("note"),
        time_zone=session.get("time_zone", "UTC"),
        not_on_trino=raw.get("not_on_trino"),
    )


def load_family(path: Path) -> Family:
    data = yaml.load(path.read_text(encoding="utf-8"), Loader=_CASE_LOADER)
    if not isinstance(data, dict) or set(data) - _FILE_KEYS or "family" not in data:
        raise CaseFileError(f"{path.name}: expected keys {sorted(_FILE_KEYS)}")
    family = data["family"]
    cases, seen = [], set()
    for index, raw in enumerate(data.get("cases") or []):
        where = f"{path.name}: case {index + 1} ({raw.get('name', '?') if isinstance(raw, dict) else '?'})"
        if not isinstance(raw, dict):
            raise CaseFileError(f"{where}: a case is a mapping")
        case = _case(family, raw, where)
        if case.name in seen:
            raise CaseFileError(f"{where}: duplicate case name")
        seen.add(case.name)
        cases.append(case)
    return Family(family, data.get("title", family), " ".join(str(data.get("description", "")).split()), tuple(cases))


def load_families(directory: Path = CASES_DIR) -> list[Family]:
    """Every case file in `directory`, in file-name order."""
    return [load_family(path) for path in sorted(directory.glob("*.yaml"))]


def load_cases(directory: Path = CASES_DIR) -> list[Case]:
    """Every conformance case, family by family."""
    return [case for family in load_families(directory) for case in family.cases]


# --- which functions and operators a query uses ---------------------------------------------------
_NOT_NAMES = {
    TokenType.STRING,
    TokenType.NUMBER,
    TokenType.IDENTIFIER,
    TokenType.L_PAREN,
    TokenType.R_PAREN,
    TokenType.L_BRACKET,
    TokenType.R_BRACKET,
    TokenType.COMMA,
}


def called_names(sql: str) -> set[str]:
    """Lower-cased names written as calls (`name(`) in `sql`, from sqlglot's Trino tokenizer; a name
    after `)` (FILTER, OVER) or `.` is not a call."""
    try:
        tokens = Trino().tokenize(sql)
    except sqlglot.errors.TokenError:
        return set()
    names = set()
    for prev, tok, nxt in zip([None, *tokens], tokens, [*tokens[1:], None]):
        if nxt is None or nxt.token_type != TokenType.L_PAREN or tok.token_type in _NOT_NAMES:
            continue
        if prev is not None and prev.token_type in (TokenType.R_PAREN, TokenType.DOT):
            continue
        names.add(tok.text.lower())
    return names


def used_constructs(sql: str, constructs: dict) -> set[str]:
    """The names of `constructs` (lakegate.dialect.constructs.CONSTRUCTS) a query uses (none if it
    does not parse)."""
    logger = logging.getLogger("sqlglot")
    level = logger.level
    logger.setLevel(logging.ERROR)  # no "falling back to parsing as a Command" warnings
    try:
        trees = sqlglot.parse(sql, read="trino")
    except sqlglot.errors.SqlglotError:
        return set()
    finally:
        logger.setLevel(level)
    return {
        name
        for tree in trees
        if tree is not None
        for node in tree.walk()
        for name, construct in constructs.items()
        if construct.used_by(node, sql)
    }


# --- Trino's function catalogue ----------------------------------------------------------------------
#: Major Trino functions per family (from Trino's function reference), so that functions lakegate
#: neither translates nor explicitly rejects are listed too. The registry's family wins when a
#: function is registered.
CATALOGUE: dict[str, str] = {
    "math": "abs acos asin atan atan2 cbrt ceil ceiling cos cosh cosine_similarity degrees e exp floor "
    "from_base infinity is_finite is_infinite is_nan ln log log10 log2 mod nan pi pow power "
    "radians rand random round sign sin sinh sqrt tan tanh to_base truncate width_bucket "
    "beta_cdf inverse_beta_cdf normal_cdf inverse_normal_cdf wilson_interval_lower "
    "wilson_interval_upper bit_count bitwise_and bitwise_not bitwise_or bitwise_xor "
    "bitwise_left_shift bitwise_right_shift bitwise_right_shift_arithmetic",
    "comparison": "greatest least",
    "conditional": "coalesce if nullif try",
    "conversion": "cast try_cast typeof format format_number parse_data_size",
    "string": "chr codepoint concat concat_ws hamming_distance length levenshtein_distance lower lpad "
    "ltrim luhn_check normalize position replace reverse rpad rtrim soundex split split_part "
    "split_to_map split_to_multimap starts_with strpos substr substring translate trim upper "
    "word_stem to_utf8 from_utf8 url_extract_fragment url_extract_host url_extract_parameter "
    "url_extract_path url_extract_port url_extract_protocol url_extract_query url_encode "
    "url_decode md5 sha1 sha256 sha512 to_hex from_hex to_base64 from_base64 crc32 xxhash64",
    "regexp": "regexp_count regexp_extract regexp_extract_all regexp_like regexp_position regexp_replace regexp_split",
    "json": "is_json_scalar json_array_contains json_array_get json_array_length json_extract "
    "json_extract_scalar json_format json_parse json_size json_exists json_object json_array",
    "datetime": "current_date current_time current_timestamp current_timezone date date_add date_diff "
    "date_format date_parse date_trunc day day_of_month day_of_week day_of_year dow doy "
    "extract format_datetime from_iso8601_date from_iso8601_timestamp from_unixtime "
    "from_unixtime_nanos hour human_readable_seconds last_day_of_month localtime "
    "localtimestamp millisecond minute month now parse_datetime parse_duration quarter "
    "second timezone_hour timezone_minute to_iso8601 to_milliseconds to_unixtime week "
    "week_of_year with_timezone at_timezone year year_of_week yow",
    "array": "all_match any_match array_distinct array_except array_histogram array_intersect "
    "array_join array_max array_min array_position array_remove array_sort array_union "
    "arrays_overlap cardinality combinations contains contains_sequence element_at filter "
    "flatten ngrams none_match reduce repeat reverse sequence shuffle slice transform "
    "trim_array zip zip_with",
    "map": "map map_concat map_entries map_filter map_from_entries map_keys map_values map_zip_with "
    "multimap_from_entries transform_keys transform_values",
    "aggregate": "any_value approx_distinct approx_most_frequent approx_percentile approx_set arbitrary "
    "array_agg avg bitwise_and_agg bitwise_or_agg bool_and bool_or checksum corr count "
    "count_if covar_pop covar_samp every geometric_mean histogram kurtosis listagg map_agg "
    "map_union max max_by min min_by multimap_agg numeric_histogram reduce_agg "
    "regr_intercept regr_slope skewness stddev stddev_pop stddev_samp sum var_pop var_samp "
    "variance",
    "window": "cume_dist dense_rank first_value lag last_value lead nth_value ntile percent_rank rank row_number",
}

#: Trino's function reference pages, in the order of this document: page -> its title.
PAGES = {
    "aggregate": "Aggregate functions",
    "array": "Array functions and operators",
    "binary": "Binary functions and operators",
    "bitwise": "Bitwise functions",
    "comparison": "Comparison functions and operators",
    "conditional": "Conditional expressions",
    "conversion": "Conversion functions",
    "datetime": "Date and time functions and operators",
    "json": "JSON functions and operators",
    "lambda": "Lambda expressions",
    "map": "Map functions and operators",
    "math": "Mathematical functions and operators",
    "regexp": "Regular expression functions",
    "string": "String functions and operators",
    "teradata": "Teradata functions",
    "url": "URL functions",
    "window": "Window functions",
}
#: Module of lakegate.dialect.functions -> the page it mirrors, where the names differ.
MODULE_PAGE = {"lambdas": "lambda", "datetime_formats": "datetime", "json_constructors": "json"}
#: Catalogue functions lakegate does not register, on another page than their CATALOGUE family.
_CATALOGUE_PAGE = re.compile(
    r"^(?:(?P<url>url_)|(?P<binary>md5|sha\d+|to_hex|from_hex|to_base64|from_base64|crc32|xxhash64)$"
    r"|(?P<bitwise>bit_count|bitwise_(?!.*_agg)))"
)


def _catalogue_family() -> dict[str, str]:
    return {name: family for family, names in CATALOGUE.items() for name in names.split()}


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def generate(
    families: list[Family],
    supported: dict,
    rejected: dict[str, str],
    constructs: dict | None = None,
    module_of: dict[str, str] | None = None,
) -> str:
    """The Markdown of docs/functions.md for these case families, this function registry, these
    constructs (name -> lakegate.dialect.constructs.Construct) and `module_of` (function -> the module
    of lakegate.dialect.functions that registers or refuses it)."""
    from lakegate.dialect import zones  # the zone rules, listed as the dialect applies them

    constructs = constructs or {}
    cases = [case for family in families for case in family.cases]
    module_of = module_of or {}
    calls = defaultdict(int)
    files = defaultdict(set)  # function -> the case files (families) calling it
    uses = defaultdict(int)
    for case in cases:
        for name in called_names(case.sql):
            calls[name] += 1
            files[name].add(case.family)
        for name in used_constructs(case.sql, constructs):
            uses[name] += 1

    page_of = {}
    for name, family in _catalogue_family().items():
        match = _CATALOGUE_PAGE.match(name)
        page_of[name] = next((page for page, hit in match.groupdict().items() if hit), family) if match else family
    construct_of = {n: (row, c) for row, c in constructs.items() for n in c.names}
    for name, spec in supported.items():
        module = module_of.get(name)
        page_of[name] = MODULE_PAGE.get(module, module) if module else spec.family
    for name in rejected:
        page_of.setdefault(name, "other")
    by_page = defaultdict(list)
    for name, page in page_of.items():
        by_page[page].append(name)

    out = [
        "# Trino functions and operators in lakegate",
        "",
        "<!-- Generated by `python tools/functions_doc.py` from lakegate.dialect.functions and "
        "tests/dialect/cases/*.yaml. Do not edit by hand. -->",
        "",
        "lakegate answers Trino-dialect SQL with DuckDB. A query either answers exactly as Trino "
        "would (same values, same result types) or is refused with an error that names the "
        "unsupported construct and its position. This page lists what is translated.",
        "",
        "How to read the tables:",
        "",
        "- **supported**: translated so that it answers as Trino does; the signature is Trino's.",
        "- **rejected (reason)**: refused before execution with an error naming the function "
        "(`NOT_SUPPORTED`); the reason says why.",
        "- **rejected (not implemented)**: a Trino function that lakegate does not know; a query "
        "using it is refused (`FUNCTION_NOT_FOUND`).",
        "- **construct**: not a function but syntax (CAST, EXTRACT, IF, current_date, ...): its status "
        "is that of its row in the SQL constructs table at the end of the page.",
        "- **module**: the module of dialect/functions/ that translates (or refuses) the function, one "
        "per page of Trino's function reference.",
        "- **cases**: how many conformance cases (`tests/dialect/cases/*.yaml`) call the function, and "
        "the case files holding them; "
        "each case is a Trino query with the result (values and types) or error Trino gives, run "
        "end to end through translation and DuckDB. Functions are found with sqlglot's Trino "
        "tokenizer (a name followed by `(`), operators by parsing the query.",
        "",
        f"## Conformance cases ({len(cases)})",
        "",
        "| file | cases | what it pins |",
        "|---|---:|---|",
    ]
    for family in families:
        out.append(
            f"| [{family.name}](../tests/dialect/cases/{family.name}.yaml) | {len(family.cases)} "
            f"| {_cell(family.title)}: {_cell(family.description)} |"
        )
    out += ["", "## Time zones", "", *(f"- {rule}" for rule in zones.RULES)]
    out += ["", "## Fractional seconds past microseconds, and time with time zone", "", *PRECISION]
    out += ["", "## IP addresses", "", *IP_ADDRESSES]

    counts = {"supported": 0, "rejected": 0, "not implemented": 0, "construct": 0}
    sections = []
    order = [p for p in PAGES if p in by_page] + sorted(set(by_page) - set(PAGES))
    for page in order:
        title = f"{PAGES[page]} (Trino's functions/{page}.md)" if page in PAGES else page.capitalize()
        if page == "other":
            title = "Other functions of Trino's reference, refused by name"
        sections += [
            "",
            f"## {title}",
            "",
            "| function | status | module | cases | signature / notes |",
            "|---|---|---|---|---|",
        ]
        for name in sorted(by_page[page]):
            if name in supported:
                spec = supported[name]
                status, detail = (
                    "supported",
                    " ".join(
                        part for part in (f"`{spec.signature}`" if spec.signature else "", _cell(spec.notes)) if part
                    ),
                )
                counts["supported"] += 1
            elif name in rejected:
                status, detail = f"rejected ({_cell(rejected[name])})", ""
                counts["rejected"] += 1
            elif name in construct_of:
                row, construct = construct_of[name]
                refused = f"rejected ({_cell(construct.refused)})" if construct.refused else "supported"
                status, detail = f"{refused} as a construct", f"see the construct {_cell(row)}"
                counts["construct"] += 1
            else:
                status, detail = "rejected (not implemented)", ""
                counts["not implemented"] += 1
            module = module_of.get(name)
            module_link = f"[{module}.py](../dialect/functions/{module}.py)" if module else ""
            case_links = ", ".join(f"[{f}](../tests/dialect/cases/{f}.yaml)" for f in sorted(files.get(name, ())))
            cases_cell = f"{calls.get(name, 0)}" + (f" ({case_links})" if case_links else "")
            sections.append(f"| `{name}` | {status} | {module_link} | {cases_cell} | {detail} |")

    supported_constructs = sum(1 for c in constructs.values() if not c.refused)
    out += [
        "",
        f"Functions: {counts['supported']} supported, {counts['rejected']} rejected with a "
        f"reason, {counts['not implemented']} not implemented, {counts['construct']} constructs. "
        f"Constructs: {supported_constructs} supported, {len(constructs) - supported_constructs} rejected "
        f"with a reason. Functions and constructs supported: {counts['supported'] + supported_constructs}.",
    ]
    out += sections
    out += [
        "",
        "## SQL constructs",
        "",
        "Operators and syntax, handled by the translator itself rather than the function registry "
        "(lakegate.dialect.constructs). Each has an example query that tests/dialect/test_constructs.py "
        "translates; **cases** counts the conformance cases that use it.",
        "",
        "| construct | family | status | cases |",
        "|---|---|---|---:|",
    ]
    for name, construct in constructs.items():
        status = f"rejected ({_cell(construct.refused)})" if construct.refused else "supported"
        out.append(f"| {_cell(name)} | {construct.family} | {status} | {uses.get(name, 0)} |")
    return "\n".join(out) + "\n"


def render_current(cases_dir: Path = CASES_DIR) -> str:
    """generate() with the installed registry and the case files in `cases_dir`."""
    # imported here, as load_cases needs no registry
    from lakegate.dialect import constructs, registry
    from lakegate.dialect.functions import pages

    pages.install()  # the registry, from the one list of function modules

    return generate(
        load_families(cases_dir), registry.SUPPORTED, registry.REJECTED, constructs.CONSTRUCTS, pages.PAGE_OF
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python tools/functions_doc.py", description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--check", action="store_true", help="do not write; exit 1 if the file differs from what would be generated"
    )
    parser.add_argument("--cases", type=Path, default=CASES_DIR, help="directory of the case files")
    parser.add_argument("--output", type=Path, default=OUTPUT, help="the Markdown file to write or check")
    args = parser.parse_args(argv)
    text = render_current(args.cases)
    if args.check:
        current = args.output.read_text(encoding="utf-8") if args.output.exists() else None
        if current != text:
            print(f"{args.output} is stale: run `python tools/functions_doc.py`", file=sys.stderr)
            return 1
        print(f"{args.output} is up to date")
        return 0
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text, encoding="utf-8")
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
