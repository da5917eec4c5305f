"""Registering a lake in a running Trino's Hive catalog (`lakegate trino-ddl --apply`), and the
record of that registration that `--backend trino` reads.

`register` runs what `trino_ddl` prints, through a `TrinoBackend` connection, checking first what
the catalog already holds: a schema or table of that name at another location, or a table
registered by an earlier lakegate (partitioned by `batch_id` and `job_id`), is an error naming it;
columns a topic gained since are added (`ALTER TABLE ... ADD COLUMN`); a table whose column changed
type is an error. Every table's partitions are then synced with `sync_partition_metadata(...,
'FULL')` (new batches added, vanished ones dropped), so running it again after ingests is all that
keeps the cluster current. A table without data files yet gets its (empty) directory when the
lake is registered where it is, so Trino has every table lakegate has; for a copy it is left out
until a later run.
`unregister` drops what a registration made (the files stay).

The registration is recorded in the lake, `<lake>/_trino.json`, one entry per Trino URL: catalog,
schema prefix, location and the schema of each branch. `read_registration` finds the entry of a
URL (scheme, host and port compared), which `--backend trino` uses when no `--trino-catalog`,
`--trino-schema-prefix` or `--trino-schema-map` is given.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from urllib.parse import urlparse

from lakegate.dialect.errors import DialectError
from lakegate.dialect.trino_types import parse_type
from lakegate.gateway.engine.trino_backend import RemoteQueryError, TrinoBackend
from lakegate.gateway.engine.trino_ddl import (
    TableDDL,
    branch_location,
    branch_tables,
    check_location,
    chosen_branches,
    create_schema,
    create_table,
    quote_ident,
    quote_text,
    schema_name,
    sync_partitions,
)
from lakegate.lake import paths
from lakegate.lake.catalog import Catalog
from lakegate.lake.storage import LOCAL

#: The file, in the lake's directory, that records its registrations in Trino clusters.
RECORD = "_trino.json"


class RegistrationError(ValueError):
    """The lake cannot be registered in the cluster; the message says which schema, table or
    column, and what to do."""


@dataclass(frozen=True)
class Registration:
    """Where one Trino cluster has the lake: `schemas` maps each registered branch to its schema."""

    trino_url: str
    catalog: str
    location: str
    schema_prefix: str
    schemas: dict[str, str]


@dataclass
class BranchReport:
    """What `register` did for one branch."""

    branch: str
    schema: str
    created: list[str] = field(default_factory=list)
    kept: list[str] = field(default_factory=list)
    added_columns: list[str] = field(default_factory=list)  # table.column
    left_out: list[str] = field(default_factory=list)  # tables without data files yet
    jobs_in_lake: int = 0
    jobs_in_trino: int = 0


def url_key(url: str) -> str:
    """A Trino URL as registrations are keyed: scheme://host:port, lower case, default port filled in."""
    parsed = urlparse(url)
    port = parsed.port or (443 if parsed.scheme == "https" else 8080)
    return f"{parsed.scheme}://{(parsed.hostname or '').lower()}:{port}"


def local_location(lake: Path) -> str:
    """The URI a Trino on this machine reads the lake at (Trino's native local file system rooted at /)."""
    return "local://" + str(lake.resolve())


def _registrations(lake: Path) -> list[dict]:
    path = lake / RECORD
    if not LOCAL.is_file(path):
        return []
    try:
        found = json.loads(LOCAL.read_text(path))
        return [entry for entry in found["registrations"] if isinstance(entry, dict)]
    except (ValueError, KeyError, TypeError):
        raise RegistrationError(
            f"{path}: not a registration record (delete it and run 'lakegate trino-ddl --apply')"
        ) from None


def read_registration(lake: Path, url: str) -> Registration | None:
    """The lake's registration in the cluster at `url`, if `lakegate trino-ddl --apply` made one."""
    for entry in _registrations(lake):
        if url_key(str(entry.get("trino_url", ""))) == url_key(url):
            try:
                return Registration(**entry)
            except TypeError:
                raise RegistrationError(f"{lake / RECORD}: a malformed entry for {url}") from None
    return None


def _record(lake: Path, url: str, registration: Registration | None) -> None:
    """Set (None: remove) the registration of `url` in the lake's record (written under a fresh
    name, then moved into place)."""
    kept = [e for e in _registrations(lake) if url_key(str(e.get("trino_url", ""))) != url_key(url)]
    entries = kept if registration is None else [*kept, asdict(registration)]
    text = json.dumps({"registrations": entries}, indent=2, sort_keys=True) + "\n"
    scratch = lake / f".{RECORD}.{os.getpid()}"
    LOCAL.write_text(scratch, text)
    LOCAL.move(scratch, lake / RECORD)


class _Cluster:
    """The statements `register` sends, with the cluster's errors as RegistrationErrors."""

    def __init__(self, connection: TrinoBackend):
        self.connection = connection

    def run(self, sql: str) -> list[list]:
        try:
            return self.connection.run(sql)
        except DialectError as error:
            if error.error_name == "GENERIC_INTERNAL_ERROR" and not isinstance(error, RemoteQueryError):
                raise RegistrationError(f"{error.message} (is Trino running there?)") from None
            raise RegistrationError(f"Trino at {self.connection.url}: {error.message}") from None


def _property(text: str, name: str) -> str | None:
    """A property's value in SHOW CREATE output (`name = 'value'` or `name = ARRAY[...]`)."""
    found = re.search(rf"\b{name} = ('(?:[^']|'')*'|ARRAY\[[^\]]*\])", text)
    return found.group(1) if found else None


def _check_catalog(cluster: _Cluster, catalog: str) -> None:
    rows = cluster.run("SELECT catalog_name, connector_name FROM system.metadata.catalogs ORDER BY 1")
    connectors = dict((name, connector) for name, connector in rows)
    if catalog not in connectors:
        raise RegistrationError(
            f"Trino at {cluster.connection.url} has no catalog {catalog!r} (its catalogs: {', '.join(connectors)}); "
            "give the Hive catalog with --catalog"
        )
    if connectors[catalog] != "hive":
        raise RegistrationError(
            f"catalog {catalog!r} of Trino at {cluster.connection.url} is a {connectors[catalog]} catalog, "
            "not a Hive one (connector.name=hive)"
        )


def _ensure_schema(cluster: _Cluster, catalog: str, schema: str, location: str, existing: set[str]) -> bool:
    """Create the schema, or check that the existing one is at `location`; whether it was created."""
    name = f"{quote_ident(catalog)}.{quote_ident(schema)}"
    if schema not in existing:
        cluster.run(create_schema(catalog, schema, location))
        return True
    shown = _property(cluster.run(f"SHOW CREATE SCHEMA {name}")[0][0], "location")
    if shown != quote_text(location):
        raise RegistrationError(
            f"schema {catalog}.{schema} already exists at {shown or 'no location'}, not at {quote_text(location)}: "
            "register this lake under another --schema-prefix, or drop that schema"
        )
    return False


def _ensure_table(cluster: _Cluster, catalog: str, table: TableDDL, columns: list[tuple[str, str]] | None) -> list[str]:
    """Create the table, or check the existing one and add the columns it lacks; the added columns."""
    if columns is None:
        cluster.run(create_table(catalog, table))
        return []
    name = f"{quote_ident(catalog)}.{quote_ident(table.schema)}.{quote_ident(table.name)}"
    where = f"table {catalog}.{table.schema}.{table.name}"
    shown = cluster.run(f"SHOW CREATE TABLE {name}")[0][0]
    location = _property(shown, "external_location")
    if location != quote_text(table.location):
        raise RegistrationError(
            f"{where} already exists at {location or 'no external location'}, not at {quote_text(table.location)}: "
            "register this lake under another --schema-prefix, or drop that table (dropping an external "
            "table leaves its files)"
        )
    keys = "ARRAY[" + ", ".join(quote_text(key) for key in table.partition_keys) + "]"
    if _property(shown, "partitioned_by") != keys:
        raise RegistrationError(
            f"{where} is partitioned by {_property(shown, 'partitioned_by')}, as an earlier lakegate registered "
            f"it; this lake's layout is partitioned by {keys}: drop it (DROP TABLE {name} leaves its files) "
            "and run this again"
        )
    registered = dict(columns)
    added = []
    for column, hive in table.columns:
        if column not in registered:
            cluster.run(f"ALTER TABLE {name} ADD COLUMN {quote_ident(column)} {hive}")
            added.append(f"{table.name}.{column}")
        elif str(parse_type(registered[column])) != str(parse_type(hive)):
            raise RegistrationError(
                f"{where}: column {column!r} is registered as {registered[column]}, the lake has {hive}: "
                "drop the table (its files stay) and run this again"
            )
    return added


def register(
    lake: Path,
    connection: TrinoBackend,
    *,
    location: str | None = None,
    catalog: str = "hive",
    schema_prefix: str = "",
    branches: Iterable[str] | None = None,
) -> list[BranchReport]:
    """Register `branches` (default: every branch) of the lake at `lake` in the Hive catalog `catalog`
    of the cluster `connection` talks to, reading the lake at `location` (default: the lake itself,
    `local:///abs/path`), and record the registration in the lake. Idempotent: a second run syncs
    the partitions of new batches. RegistrationError (or DDLError) says what stands in the way."""
    location = location or local_location(lake)
    check_location(location)
    lake_catalog = Catalog(lake)
    chosen = chosen_branches(lake_catalog, branches)
    schema_name("main", schema_prefix)  # checks the prefix
    cluster = _Cluster(connection)
    _check_catalog(cluster, catalog)
    existing = {row[0] for row in cluster.run(f"SHOW SCHEMAS FROM {quote_ident(catalog)}")}
    reports = []
    for branch in chosen:
        schema = schema_name(branch, schema_prefix)
        report = BranchReport(branch, schema)
        _ensure_schema(cluster, catalog, schema, branch_location(location, branch), existing)
        registered: dict[str, list[tuple[str, str]]] = {}
        for table, column, data_type in cluster.run(
            "SELECT table_name, column_name, data_type "
            f"FROM {quote_ident(catalog)}.information_schema.columns "
            f"WHERE table_schema = {quote_text(schema)} ORDER BY table_name, ordinal_position"
        ):
            registered.setdefault(table, []).append((column, data_type))
        for table in branch_tables(lake_catalog, branch, location, schema_prefix):
            if not table.has_files and table.name not in registered:
                if location != local_location(lake):  # a copy: its location may not exist yet
                    report.left_out.append(table.name)
                    continue
                LOCAL.make_dirs(paths.table_dir(lake, branch, table.name))  # an empty table, as lakegate has it
            (report.kept if table.name in registered else report.created).append(table.name)
            report.added_columns += _ensure_table(cluster, catalog, table, registered.get(table.name))
            cluster.run(sync_partitions(catalog, table, "FULL"))
        report.jobs_in_lake = len(lake_catalog.jobs(branch))
        if "metadata" in report.created + report.kept:
            rows = cluster.run(
                f"SELECT count(*) FROM {quote_ident(catalog)}.{quote_ident(schema)}.{quote_ident('metadata')}"
            )
            report.jobs_in_trino = rows[0][0]
        reports.append(report)
    previous = read_registration(lake, connection.url)
    same = previous is not None and (previous.catalog, previous.location, previous.schema_prefix) == (
        catalog,
        location,
        schema_prefix,
    )
    schemas = dict(previous.schemas) if same else {}
    schemas.update({report.branch: report.schema for report in reports})
    _record(lake, connection.url, Registration(url_key(connection.url), catalog, location, schema_prefix, schemas))
    return reports


def jobs_seen(connection: TrinoBackend, branch: str, batch_id: str) -> int:
    """How many jobs of the batch the cluster's `metadata` table of `branch` has (0 when it has no
    such table): fewer than the lake means its partitions need syncing (`trino-ddl --apply`)."""
    table = f"{quote_ident(connection.catalog)}.{quote_ident(connection.schema_for(branch))}.{quote_ident('metadata')}"
    try:
        return connection.run(f"SELECT count(*) FROM {table} WHERE batch_id = {quote_text(batch_id)}")[0][0]
    except RemoteQueryError as error:
        if error.error_name in ("TABLE_NOT_FOUND", "SCHEMA_NOT_FOUND"):
            return 0
        raise


def unregister(lake: Path, connection: TrinoBackend) -> list[str]:
    """Drop the schemas and tables the lake's registration in the cluster at `connection` made
    (dropping an external table leaves its files; a schema that holds other tables stays) and
    forget the registration; the schemas dropped."""
    registration = read_registration(lake, connection.url)
    if registration is None:
        raise RegistrationError(f"the lake {lake} has no registration in Trino at {connection.url}")
    cluster = _Cluster(connection)
    existing = {row[0] for row in cluster.run(f"SHOW SCHEMAS FROM {quote_ident(registration.catalog)}")}
    dropped = []
    for schema in sorted(set(registration.schemas.values()) & existing):
        name = f"{quote_ident(registration.catalog)}.{quote_ident(schema)}"
        location = _property(cluster.run(f"SHOW CREATE SCHEMA {name}")[0][0], "location") or ""
        for (table,) in cluster.run(f"SHOW TABLES FROM {name}"):
            shown = cluster.run(f"SHOW CREATE TABLE {name}.{quote_ident(table)}")[0][0]
            if (_property(shown, "external_location") or "").startswith(location[:-1] + "/"):
                cluster.run(f"DROP TABLE {name}.{quote_ident(table)}")
        if not cluster.run(f"SHOW TABLES FROM {name}"):
            cluster.run(f"DROP SCHEMA {name}")
            dropped.append(schema)
    _record(lake, connection.url, None)
    return dropped


def sync_local(lake: Path, connection: TrinoBackend, branch: str) -> bool:
    """Register `branch` again (new tables, columns and partitions) when the lake's registration in
    the cluster at `connection` reads the lake where it is (`local:///...`, never a copy, whose
    files may lag) in the catalog the connection uses; whether it did."""
    registration = read_registration(lake, connection.url)
    if registration is None or registration.location != local_location(lake):
        return False
    if registration.catalog != connection.catalog or connection.schema_for(branch) != schema_name(
        branch, registration.schema_prefix
    ):
        return False
    register(
        lake,
        connection,
        location=registration.location,
        catalog=registration.catalog,
        schema_prefix=registration.schema_prefix,
        branches=[branch],
    )
    return True
