"""Trino Hive-connector DDL that registers the lake's tables in a Trino cluster (`lakegate trino-ddl`).

Per branch, one schema at `<location>/<branch-dir>`; per table, an external Parquet table at
`<location>/<branch-dir>/<table>` partitioned by its Hive partition key `batch_id` (last, as the
Hive connector requires; `job_id` is a column of the files: a compacted file holds many jobs),
then a `sync_partition_metadata` call that registers the partitions already on storage. A branch
still in layout v1 (`job_id=<J>/` directories) is refused: `lakegate lake compact` migrates it.

Schema names: Hive metastores keep lower-case `[a-z0-9_]` names, so a branch name is lower-cased
and every other character becomes `_`; a name that changed gets a short hash of the branch name
(`feature/x` -> `feature_x_45239254`) so that two branches never share a schema. The forwarding
backend (`trino_backend`) maps branches to schemas with the same `schema_name`.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from lakegate.dialect.trino_types import TType, parse_type
from lakegate.lake import paths
from lakegate.lake.catalog import Catalog

#: The longest schema name emitted (Hive metastores allow 128 characters).
MAX_SCHEMA = 100
#: Scalar Trino types the Hive connector stores in Parquet (timestamps at the connector's default
#: precision, `hive.timestamp-precision=MILLISECONDS`).
HIVE_SCALARS = frozenset(
    {
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
        "date",
    }
)
#: Characters Hive escapes in partition directory names (FileUtils.escapePathName); a lake directory
#: with one of them unescaped can break `sync_partition_metadata` (a ':' even Hadoop paths).
_HIVE_ESCAPED = frozenset("\"#%'*/:=?\\\x7f{[]^")
_PREFIX = re.compile(r"[a-z0-9_]*")


class DDLError(ValueError):
    """The lake cannot be registered as asked; the message says which table, column or name."""


def quote_ident(name: str) -> str:
    """A Trino delimited identifier."""
    return '"' + name.replace('"', '""') + '"'


def quote_text(text: str) -> str:
    """A Trino string literal."""
    return "'" + text.replace("'", "''") + "'"


def schema_name(branch: str, prefix: str = "") -> str:
    """The Trino schema of `branch`: `prefix` + the lower-cased name with every character outside
    `[a-z0-9_]` as `_`, plus `_` and 8 hex digits of the name's SHA-1 when that changed it."""
    if not _PREFIX.fullmatch(prefix):
        raise DDLError(f"schema prefix {prefix!r} may only contain a-z, 0-9 and '_'")
    clean = re.sub(r"[^a-z0-9_]", "_", branch.lower())
    if clean != branch or len(prefix + clean) > MAX_SCHEMA:
        digest = hashlib.sha1(branch.encode("utf-8")).hexdigest()[:8]
        clean = f"{clean[: MAX_SCHEMA - len(prefix) - 9]}_{digest}"
    return prefix + clean


def hive_type(trino_type: str, where: str) -> str:
    """The column type of a Hive-connector Parquet table for a lake column of `trino_type`, with
    row field names quoted. DDLError naming `where` for a type the connector cannot store."""
    try:
        parsed = parse_type(trino_type)
    except ValueError:
        raise DDLError(f"{where}: unknown type {trino_type!r}") from None
    return _hive(parsed, where)


def _hive(t: TType, where: str) -> str:
    if t.base in HIVE_SCALARS:
        return str(t)
    if t.base == "timestamp" and t.args == (3,):
        return "timestamp(3)"
    if t.base == "array":
        return f"array({_hive(t.args[0], where)})"
    if t.base == "map":
        return f"map({_hive(t.args[0], where)}, {_hive(t.args[1], where)})"
    if t.base == "row" and all(name for name, _ in t.args):
        return "row(" + ", ".join(f"{quote_ident(name)} {_hive(field, where)}" for name, field in t.args) + ")"
    raise DDLError(f"{where}: type {t} cannot be a Hive-connector Parquet column")


@dataclass(frozen=True)
class TableDDL:
    """One lake table as a Hive external table: data columns, then the partition columns."""

    schema: str
    name: str
    columns: list[tuple[str, str]]  # (name, Hive column type), partition columns last
    partition_keys: tuple[str, ...]
    location: str
    has_files: bool


def _check_unique(names: Iterable[str], what: str) -> None:
    seen: dict[str, str] = {}
    for name in names:
        other = seen.setdefault(name.lower(), name)
        if other != name:
            raise DDLError(
                f"{what} {other!r} and {name!r} would be the same name in Trino (names are case-insensitive there)"
            )


def branch_tables(catalog: Catalog, branch: str, location: str, prefix: str = "") -> list[TableDDL]:
    """The tables of one branch of the lake `catalog` reads, as registered at `location` (a URI)."""
    schema = schema_name(branch, prefix)
    located = branch_location(location, branch)
    tables = catalog.schema(branch)
    _check_unique(tables, f"on branch {branch!r}, tables")
    found = []
    for table, columns in tables.items():
        keys = paths.partition_keys(table)
        missing = [key for key in keys if key not in columns]
        if missing:
            raise DDLError(f"table {table!r} of branch {branch!r} has no partition column {missing[0]!r}")
        _check_unique(columns, f"table {table!r} of branch {branch!r}: columns")
        where = f"branch {branch!r}, table {table!r}"
        data = [(name, hive_type(t, f"{where}, column {name!r}")) for name, t in columns.items() if name not in keys]
        partitions = [(key, hive_type(columns[key], f"{where}, column {key!r}")) for key in keys]
        if any(t != "varchar" for _, t in partitions):
            raise DDLError(f"{where}: partition columns must be varchar")
        has_files = bool(paths.data_files(catalog.lake, branch, table))
        found.append(TableDDL(schema, table, data + partitions, keys, f"{located}/{table}", has_files))
    return found


def _escaped_ids(catalog: Catalog, branch: str) -> list[str]:
    """Batch ids of the branch that Hive would escape in a directory name."""
    return [batch for batch in catalog.batches(branch) if any(c in _HIVE_ESCAPED for c in batch)]


def _check_layout(catalog: Catalog, branch: str) -> None:
    """DDLError for a branch with files in layout v1 (`job_id=<J>/` directories, no job_id column)."""
    if any(paths.is_v1_path(entry.path) for entry in catalog.snapshot(branch).files):
        raise DDLError(
            f"branch {branch!r} is in the layout of earlier lakegate versions (a job_id=<J>/ directory per "
            f"job, which Trino would read without job_id): run 'lakegate lake compact --lake {catalog.lake} "
            f"--branch {branch}' first; it moves job_id into the files"
        )


def check_location(location: str) -> None:
    """DDLError unless `location` is a URI."""
    if not re.match(r"[A-Za-z][A-Za-z0-9+.-]*://", location):
        raise DDLError(f"--location {location!r} is not a URI (expected e.g. s3://bucket/lake or hdfs://host/lake)")


def chosen_branches(lake_catalog: Catalog, branches: Iterable[str] | None) -> list[str]:
    """`branches` (default: every branch of the lake), each checked to exist and to be in layout v2."""
    known = lake_catalog.branches()
    chosen = list(branches) if branches else known
    for branch in chosen:
        if branch not in known:
            raise DDLError(
                f"no branch {branch!r} in the lake {lake_catalog.lake} (branches: {', '.join(known) or 'none'})"
            )
        _check_layout(lake_catalog, branch)
    return chosen


def create_schema(catalog: str, schema: str, location: str) -> str:
    """The CREATE SCHEMA IF NOT EXISTS statement of a branch's schema at `location`."""
    name = f"{quote_ident(catalog)}.{quote_ident(schema)}"
    return f"CREATE SCHEMA IF NOT EXISTS {name} WITH (location = {quote_text(location)})"


def create_table(catalog: str, table: TableDDL) -> str:
    """The CREATE TABLE IF NOT EXISTS statement of one lake table (an external Parquet table)."""
    columns = ",\n".join(f"  {quote_ident(name)} {t}" for name, t in table.columns)
    keys = ", ".join(quote_text(key) for key in table.partition_keys)
    return (
        f"CREATE TABLE IF NOT EXISTS {quote_ident(catalog)}.{quote_ident(table.schema)}.{quote_ident(table.name)} "
        f"(\n{columns}\n)\nWITH (\n  external_location = {quote_text(table.location)},\n  format = 'PARQUET',\n"
        f"  partitioned_by = ARRAY[{keys}]\n)"
    )


def sync_partitions(catalog: str, table: TableDDL, mode: str = "ADD") -> str:
    """The call that registers the table's partitions on storage (`mode` ADD, DROP or FULL)."""
    return (
        f"CALL {quote_ident(catalog)}.system.sync_partition_metadata("
        f"{quote_text(table.schema)}, {quote_text(table.name)}, {quote_text(mode)})"
    )


def branch_location(location: str, branch: str) -> str:
    """The URI of a branch's directory in the lake at `location`."""
    return f"{location.rstrip('/')}/{paths.encode_branch(branch)}"


def ddl(
    lake: Path,
    location: str,
    *,
    catalog: str = "hive",
    schema_prefix: str = "",
    branches: Iterable[str] | None = None,
    skip_empty: bool = False,
) -> str:
    """The DDL script (statements ending in `;`, `--` comments) that registers `branches` (default:
    every branch) of the lake at `lake`, copied to `location`, in the Trino Hive catalog `catalog`."""
    check_location(location)
    lake_catalog = Catalog(lake)
    chosen = chosen_branches(lake_catalog, branches)
    schemas = {branch: schema_name(branch, schema_prefix) for branch in chosen}
    lines = [
        f"-- Trino Hive-connector DDL for the lakegate lake {lake}, copied to {location}.",
        "-- Run it again after ingesting: CREATE ... IF NOT EXISTS keeps what exists, the calls add new partitions.",
        "-- Tables registered before lakegate's layout v2 (partitioned by batch_id and job_id) must be dropped",
        "-- first (DROP TABLE of an external table leaves its files).",
    ]
    for branch in chosen:
        schema = quote_ident(catalog) + "." + quote_ident(schemas[branch])
        lines += ["", f"-- branch {branch!r} -> schema {schema}"]
        for bad in _escaped_ids(lake_catalog, branch):
            lines.append(
                f"-- warning: id {bad!r} has a character Hive escapes in directory names; "
                "sync_partition_metadata may fail on its partitions or register them wrongly"
            )
        lines.append(create_schema(catalog, schemas[branch], branch_location(location, branch)) + ";")
        for table in branch_tables(lake_catalog, branch, location, schema_prefix):
            if not table.has_files:
                if skip_empty:
                    lines.append(f"-- table {table.name!r} has no data files yet: left out (--skip-empty)")
                    continue
                lines.append(
                    f"-- table {table.name!r} has no data files yet: its location must exist as a "
                    "directory for CREATE TABLE on HDFS or local storage"
                )
            lines.append(create_table(catalog, table) + ";")
            lines.append(sync_partitions(catalog, table) + ";")
    return "\n".join(lines) + "\n"
