"""What the SQL endpoint shows of the lake, in Trino's words: catalogs, schemas, tables, the
`information_schema` and `system` tables, and the SHOW / DESCRIBE statements.

Two catalogs: the lake (named `lake` by default) with one schema per branch plus
`information_schema`, and `system` with `information_schema`, `jdbc`, `metadata` and `runtime`.
A schema is named exactly like its branch (`main`, `feature/x`); a name that is not a plain
identifier is written quoted (`"feature/x".odom`). Unquoted names are lower-cased as Trino does,
and a schema name that matches no branch exactly matches the one branch equal to it ignoring case.

System tables are small: a query over them runs on an in-memory DuckDB database (one thread,
`memory_limit`: `system_queries.SystemDatabase`) in which the referenced tables are materialised
from the lake's catalog (as Arrow tables) for that query, after the same Trino-to-DuckDB translation
as any query; in a query worker process when the backend runs queries in them (`IsolatedBackend`).
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import pyarrow as pa

from lakegate.dialect import trino_types as tt
from lakegate.dialect.errors import DialectError
from lakegate.dialect.session_functions import SessionNames
from lakegate.dialect.statements import Reader, Statement
from lakegate.dialect.translate import translate
from lakegate.gateway.engine.backend import Backend, QueryResult
from lakegate.gateway.engine.catalog_name import CATALOG
from lakegate.gateway.engine.session import PROPERTIES, Answer, Session
from lakegate.gateway.engine.system_queries import SystemDatabase
from lakegate.gateway.engine.trino_values import arrow_type

INFORMATION_SCHEMA = "information_schema"
SYSTEM = "system"
V, B = "varchar", "bigint"

#: information_schema tables (in every catalog): name -> (column, Trino type).
INFORMATION_SCHEMA_TABLES: dict[str, list[tuple[str, str]]] = {
    "columns": [
        ("table_catalog", V),
        ("table_schema", V),
        ("table_name", V),
        ("column_name", V),
        ("ordinal_position", B),
        ("column_default", V),
        ("is_nullable", V),
        ("data_type", V),
        ("comment", V),
        ("extra_info", V),
        ("column_comment", V),
    ],
    "tables": [
        ("table_catalog", V),
        ("table_schema", V),
        ("table_name", V),
        ("table_type", V),
        ("trino_relation_type", V),
        ("table_comment", V),
    ],
    "views": [("table_catalog", V), ("table_schema", V), ("table_name", V), ("view_definition", V)],
    "schemata": [("catalog_name", V), ("schema_name", V)],
    "table_privileges": [
        ("grantor", V),
        ("grantor_type", V),
        ("grantee", V),
        ("grantee_type", V),
        ("table_catalog", V),
        ("table_schema", V),
        ("table_name", V),
        ("privilege_type", V),
        ("is_grantable", V),
        ("with_hierarchy", V),
    ],
    "roles": [("role_name", V)],
    "applicable_roles": [("grantee", V), ("grantee_type", V), ("role_name", V), ("is_grantable", V)],
    "enabled_roles": [("role_name", V)],
}
_TS = "timestamp(3) with time zone"
#: The system catalog's other schemas: schema -> table -> (column, Trino type).
SYSTEM_SCHEMAS: dict[str, dict[str, list[tuple[str, str]]]] = {
    "jdbc": {
        "catalogs": [("table_cat", V)],
        "schemas": [("table_schem", V), ("table_catalog", V)],
        "tables": [
            ("table_cat", V),
            ("table_schem", V),
            ("table_name", V),
            ("table_type", V),
            ("remarks", V),
            ("type_cat", V),
            ("type_schem", V),
            ("type_name", V),
            ("self_referencing_col_name", V),
            ("ref_generation", V),
        ],
        "columns": [
            ("table_cat", V),
            ("table_schem", V),
            ("table_name", V),
            ("column_name", V),
            ("data_type", B),
            ("type_name", V),
            ("column_size", B),
            ("buffer_length", B),
            ("decimal_digits", B),
            ("num_prec_radix", B),
            ("nullable", B),
            ("remarks", V),
            ("column_def", V),
            ("sql_data_type", B),
            ("sql_datetime_sub", B),
            ("char_octet_length", B),
            ("ordinal_position", B),
            ("is_nullable", V),
            ("scope_catalog", V),
            ("scope_schema", V),
            ("scope_table", V),
            ("source_data_type", B),
            ("is_autoincrement", V),
            ("is_generatedcolumn", V),
        ],
        "table_types": [("table_type", V)],
        "types": [
            ("type_name", V),
            ("data_type", B),
            ("precision", B),
            ("literal_prefix", V),
            ("literal_suffix", V),
            ("create_params", V),
            ("nullable", B),
            ("case_sensitive", "boolean"),
            ("searchable", B),
            ("unsigned_attribute", "boolean"),
            ("fixed_prec_scale", "boolean"),
            ("auto_increment", "boolean"),
            ("local_type_name", V),
            ("minimum_scale", B),
            ("maximum_scale", B),
            ("sql_data_type", B),
            ("sql_datetime_sub", B),
            ("num_prec_radix", B),
        ],
        # Tables the JDBC driver reads for procedures, user-defined types, attributes, super
        # tables and types and pseudo columns: lakegate has none of them, so they are empty.
        "attributes": [
            ("type_cat", V),
            ("type_schem", V),
            ("type_name", V),
            ("attr_name", V),
            ("data_type", B),
            ("attr_type_name", V),
            ("attr_size", B),
            ("decimal_digits", B),
            ("num_prec_radix", B),
            ("nullable", B),
            ("remarks", V),
            ("attr_def", V),
            ("sql_data_type", B),
            ("sql_datetime_sub", B),
            ("char_octet_length", B),
            ("ordinal_position", B),
            ("is_nullable", V),
            ("scope_catalog", V),
            ("scope_schema", V),
            ("scope_table", V),
            ("source_data_type", B),
        ],
        "procedure_columns": [
            ("procedure_cat", V),
            ("procedure_schem", V),
            ("procedure_name", V),
            ("column_name", V),
            ("column_type", B),
            ("data_type", B),
            ("type_name", V),
            ("precision", B),
            ("length", B),
            ("scale", B),
            ("radix", B),
            ("nullable", B),
            ("remarks", V),
            ("column_def", V),
            ("sql_data_type", B),
            ("sql_datetime_sub", B),
            ("char_octet_length", B),
            ("ordinal_position", B),
            ("is_nullable", V),
            ("specific_name", V),
        ],
        "procedures": [
            ("procedure_cat", V),
            ("procedure_schem", V),
            ("procedure_name", V),
            ("remarks", V),
            ("procedure_type", B),
            ("specific_name", V),
        ],
        "pseudo_columns": [
            ("table_cat", V),
            ("table_schem", V),
            ("table_name", V),
            ("column_name", V),
            ("data_type", B),
            ("column_size", B),
            ("decimal_digits", B),
            ("num_prec_radix", B),
            ("column_usage", V),
            ("remarks", V),
            ("char_octet_length", B),
            ("is_nullable", B),
        ],
        "super_tables": [("table_cat", V), ("table_schem", V), ("table_name", V), ("supertable_name", V)],
        "super_types": [
            ("type_cat", V),
            ("type_schem", V),
            ("type_name", V),
            ("supertype_cat", V),
            ("supertype_schem", V),
            ("supertype_name", V),
        ],
        "udts": [
            ("type_cat", V),
            ("type_schem", V),
            ("type_name", V),
            ("class_name", V),
            ("data_type", V),
            ("remarks", V),
            ("base_type", V),
        ],
    },
    "metadata": {
        "catalogs": [("catalog_name", V), ("connector_id", V), ("connector_name", V)],
        "table_comments": [("catalog_name", V), ("schema_name", V), ("table_name", V), ("comment", V)],
    },
    "runtime": {
        "queries": [
            ("query_id", V),
            ("state", V),
            ("user", V),
            ("source", V),
            ("query", V),
            ("resource_group_id", "array(varchar)"),
            ("queued_time_ms", B),
            ("analysis_time_ms", B),
            ("planning_time_ms", B),
            ("created", _TS),
            ("started", _TS),
            ("last_heartbeat", _TS),
            ("end", _TS),
            ("error_type", V),
            ("error_code", V),
        ],
    },
}
#: java.sql.Types of Trino base types (system.jdbc.columns.data_type; JAVA_OBJECT otherwise).
_JDBC_TYPES = {
    "boolean": 16,
    "bigint": -5,
    "integer": 4,
    "smallint": 5,
    "tinyint": -6,
    "real": 7,
    "double": 8,
    "decimal": 3,
    "varchar": 12,
    "char": 1,
    "varbinary": -3,
    "date": 91,
    "time": 92,
    "time_tz": 2013,
    "timestamp": 93,
    "timestamp_tz": 2014,
    "array": 2003,
}
#: system.jdbc.types (DatabaseMetaData.getTypeInfo): the types lakegate reads and answers with, as
#: Trino 476 lists them: name -> (java.sql.Types, precision, radix, searchable). Types with
#: parameters are listed by their base name, as Trino lists them: JAVA_OBJECT (ARRAY for array),
#: no precision, not searchable.
_TYPE_INFO: dict[str, tuple[int, int | None, int | None, int]] = {
    "tinyint": (-6, 3, 10, 3),
    "bigint": (-5, 19, 10, 3),
    "varbinary": (-3, 2147483647, None, 3),
    "integer": (4, 10, 10, 3),
    "smallint": (5, 5, 10, 3),
    "real": (7, 24, 2, 3),
    "double": (8, 53, 2, 3),
    "boolean": (16, None, None, 3),
    "date": (91, 14, None, 3),
    "json": (2000, None, None, 3),
    "unknown": (2000, None, None, 3),
    "interval year to month": (2000, None, None, 3),
    "interval day to second": (2000, None, None, 3),
    "uuid": (2000, None, None, 3),
    **{
        name: (2000, None, None, 0)
        for name in (
            "char",
            "varchar",
            "decimal",
            "time",
            "time with time zone",
            "timestamp",
            "timestamp with time zone",
            "row",
            "map",
        )
    },
    "array": (2003, None, None, 0),
}
_FIXED_SIZE = {
    "bigint": 19,
    "integer": 10,
    "smallint": 5,
    "tinyint": 3,
    "real": 24,
    "double": 53,
    "date": 14,
    "varbinary": 2147483647,
}


@dataclass(frozen=True)
class TableRef:
    """A resolved table: catalog, schema (a branch name for lake tables) and table name."""

    catalog: str
    schema: str
    table: str
    system: bool  # an information_schema or system table, not a lake table

    def __str__(self) -> str:
        return f"{self.catalog}.{self.schema}.{self.table}"


class SystemCatalog:
    """The catalogs, schemas and tables the server shows over `backend` (its branches and schemas),
    and the system tables. `queries(user)` lists the server's queries that `user` (the session's
    user) may see, as rows of system.runtime.queries."""

    def __init__(
        self,
        backend: Backend,
        *,
        catalog: str = CATALOG,
        queries: Callable[[str | None], list[tuple]] = lambda user: [],
        memory_limit: str = "1GB",
    ):
        self.backend, self.catalog, self.queries = backend, catalog, queries
        self._memory_limit = memory_limit
        self._db: SystemDatabase | None = None  # made on first use, when the backend runs no such query
        self._lock = threading.Lock()

    # -- names ----------------------------------------------------------------------------

    def catalogs(self) -> list[str]:
        return sorted([self.catalog, SYSTEM])

    def branches(self) -> list[str]:
        return list(self.backend.branches())

    def schemas(self, catalog: str) -> list[str]:
        if catalog == SYSTEM:
            return sorted([INFORMATION_SCHEMA, *SYSTEM_SCHEMAS])
        return sorted([*self.branches(), INFORMATION_SCHEMA])

    def tables(self, catalog: str, schema: str) -> dict[str, list[tuple[str, str]]]:
        """Table -> (column, Trino type) of one existing schema."""
        if schema == INFORMATION_SCHEMA:
            return INFORMATION_SCHEMA_TABLES
        if catalog == SYSTEM:
            return SYSTEM_SCHEMAS[schema]
        return {table: list(columns.items()) for table, columns in self.backend.schema(schema).items()}

    def check_catalog(self, catalog: str | None, *, line: int | None = None, column: int | None = None) -> str:
        if catalog is None:
            raise DialectError(
                "Catalog must be specified when session catalog is not set",
                line=line,
                column=column,
                error_name="MISSING_CATALOG_NAME",
            )
        name = catalog.lower()
        if name not in (self.catalog, SYSTEM):
            raise DialectError(
                f"Catalog '{catalog}' not found", line=line, column=column, error_name="CATALOG_NOT_FOUND"
            )
        return name

    def schema_name(
        self, catalog: str, schema: str | None, *, line: int | None = None, column: int | None = None
    ) -> str:
        """The existing schema `schema` of `catalog` names (the branch's exact name), else DialectError."""
        if schema is None:
            raise DialectError(
                "Schema must be specified when session schema is not set",
                line=line,
                column=column,
                error_name="MISSING_SCHEMA_NAME",
            )
        names = self.schemas(catalog)
        if schema in names:
            return schema
        matches = [name for name in names if name.lower() == schema.lower()]
        if len(matches) == 1:
            return matches[0]
        raise DialectError(f"Schema '{schema}' does not exist", line=line, column=column, error_name="SCHEMA_NOT_FOUND")

    def resolve_schema(self, catalog: str | None, schema: tuple[str, bool]) -> tuple[str, str]:
        """USE's target: the (catalog, schema) names to set."""
        catalog = self.check_catalog(catalog)
        return catalog, self.schema_name(catalog, schema[0])

    def resolve(
        self, parts: Sequence[str], session: Session, *, line: int | None = None, column: int | None = None
    ) -> TableRef:
        """The table `parts` ([[catalog.]schema.]table) names in `session`; DialectError (at
        line/column) when its catalog, schema or table does not exist."""
        table = parts[-1].lower()
        if len(parts) > 3:
            raise DialectError(
                f"Too many dots in table name: {'.'.join(parts)}", line=line, column=column, error_name="SYNTAX_ERROR"
            )
        catalog = self.check_catalog(parts[0] if len(parts) == 3 else session.catalog, line=line, column=column)
        if len(parts) == 1 and session.schema is None:
            self.schema_name(catalog, None, line=line, column=column)
        schema = self.schema_name(catalog, parts[-2] if len(parts) > 1 else session.schema, line=line, column=column)
        tables = self.tables(catalog, schema)
        name = next((t for t in tables if t.lower() == table), None)
        if name is None:
            raise DialectError(
                f"Table '{catalog}.{schema}.{table}' does not exist",
                line=line,
                column=column,
                error_name="TABLE_NOT_FOUND",
            )
        return TableRef(catalog, schema, name, system=catalog == SYSTEM or schema == INFORMATION_SCHEMA)

    # -- system table rows ----------------------------------------------------------------

    def _all_tables(self, catalogs: Iterable[str]) -> Iterable[tuple[str, str, str, list[tuple[str, str]]]]:
        for catalog in catalogs:
            for schema in self.schemas(catalog):
                for table, columns in self.tables(catalog, schema).items():
                    yield catalog, schema, table, columns

    def rows(self, ref: TableRef, user: str | None = None) -> list[tuple]:
        """The rows of a system table, as `user` sees them."""
        catalog, schema, table = ref.catalog, ref.schema, ref.table
        if schema == INFORMATION_SCHEMA:
            if table == "schemata":
                return [(catalog, s) for s in self.schemas(catalog)]
            if table == "tables":
                return [(c, s, t, "BASE TABLE", "TABLE", None) for c, s, t, _ in self._all_tables([catalog])]
            if table == "columns":
                return [
                    (c, s, t, name, i, None, "YES", trino_type, None, None, None)
                    for c, s, t, cols in self._all_tables([catalog])
                    for i, (name, trino_type) in enumerate(cols, 1)
                ]
            return []  # views, privileges and roles: none
        everything = self.catalogs()
        if (schema, table) == ("jdbc", "catalogs"):
            return [(c,) for c in everything]
        if (schema, table) == ("jdbc", "schemas"):
            return [(s, c) for c in everything for s in self.schemas(c)]
        if (schema, table) == ("jdbc", "tables"):
            return [
                (c, s, t, "TABLE", None, None, None, None, None, None) for c, s, t, _ in self._all_tables(everything)
            ]
        if (schema, table) == ("jdbc", "columns"):
            return [
                _jdbc_column(c, s, t, name, trino_type, i)
                for c, s, t, cols in self._all_tables(everything)
                for i, (name, trino_type) in enumerate(cols, 1)
            ]
        if (schema, table) == ("jdbc", "table_types"):
            return [("TABLE",), ("VIEW",)]
        if (schema, table) == ("jdbc", "types"):
            return [
                (name, jdbc, precision, None, None, None, 1, False, searchable, None, False, None, None, 0, 0)
                + (None, None, radix)
                for name, (jdbc, precision, radix, searchable) in _TYPE_INFO.items()
            ]
        if schema == "jdbc":
            return []  # attributes, procedures, procedure_columns, pseudo_columns, super_*, udts
        if (schema, table) == ("metadata", "catalogs"):
            return [(c, c, "system" if c == SYSTEM else "lakegate") for c in everything]
        if (schema, table) == ("metadata", "table_comments"):
            return [(c, s, t, None) for c, s, t, _ in self._all_tables(everything)]
        if (schema, table) == ("runtime", "queries"):
            return self.queries(user)
        raise DialectError(f"Table '{ref}' does not exist", error_name="TABLE_NOT_FOUND")

    def arrow(self, ref: TableRef, user: str | None = None) -> pa.Table:
        columns = self.tables(ref.catalog, ref.schema)[ref.table]
        rows = self.rows(ref, user)
        return pa.table(
            {
                name: pa.array([row[i] for row in rows], arrow_type(tt.parse_type(trino_type)))
                for i, (name, trino_type) in enumerate(columns)
            }
        )

    # -- queries over system tables -------------------------------------------------------

    def run(
        self,
        statement: Statement,
        refs: Sequence[TableRef],
        params: Sequence[object] = (),
        user: str | None = None,
        time_zone: str = "UTC",
        session: SessionNames | None = None,
    ) -> QueryResult:
        """Start one Trino query (as the planner read it, its table names unqualified) whose table
        names are the `refs`' table names, over those system tables as `user` sees them, in the
        session zone `time_zone`, its session functions answered from `session`. Raises DialectError;
        the result streams and can be canceled."""
        schema = {ref.table: dict(self.tables(ref.catalog, ref.schema)[ref.table]) for ref in refs}
        translation = translate(
            statement.text,
            schema,
            params=params,
            time_zone=time_zone,
            session=session,
            tree=statement.tree,
            rewrite=statement.edits,
        )
        tables = {ref.table: self.arrow(ref, user) for ref in refs}
        columns, zones = list(translation.columns), list(translation.zones)
        in_worker = getattr(self.backend, "run_over_tables", None)  # an isolated backend: in a query worker
        if in_worker is not None:
            return in_worker(translation.duckdb_sql, tables, columns, zones)
        with self._lock:
            if self._db is None:
                self._db = SystemDatabase(self._memory_limit)
        return self._db.run(translation.duckdb_sql, tables, columns, zones)

    def close(self) -> None:
        if self._db is not None:
            self._db.close()

    # -- SHOW and DESCRIBE ------------------------------------------------------------------

    def show(self, statement: Statement, session: Session) -> Answer:
        """Answer SHOW CATALOGS / SCHEMAS / TABLES / COLUMNS / SESSION and DESCRIBE t (a statement
        of kind show or describe, its refusal raised), with Trino's result columns, sorted as Trino
        sorts them."""
        reader = Reader(statement.text)
        if reader.take("DESCRIBE", "DESC"):
            parts = reader.parts()
            reader.end()
            return self._columns(parts, session, None)
        reader.take("SHOW")
        if reader.take("CATALOGS"):
            pattern = reader.like()
            reader.end()
            catalogs = self.catalogs()  # Trino's rewrite lists them as literals: varchar(longest name)
            return Answer([("Catalog", f"varchar({max(map(len, catalogs))})")], _matching(catalogs, pattern))
        if reader.take("SCHEMAS"):
            catalog = reader.parts()[0] if reader.take("FROM", "IN") else session.catalog
            pattern = reader.like()
            reader.end()
            return Answer([("Schema", V)], _matching(self.schemas(self.check_catalog(catalog)), pattern))
        if reader.take("TABLES"):
            parts = reader.parts() if reader.take("FROM", "IN") else []
            pattern = reader.like()
            reader.end()
            if len(parts) > 2:
                raise DialectError(f"Too many parts in schema name: {'.'.join(parts)}", error_name="SYNTAX_ERROR")
            catalog = self.check_catalog(parts[0] if len(parts) == 2 else session.catalog)
            schema = self.schema_name(catalog, parts[-1] if parts else session.schema)
            return Answer([("Table", V)], _matching(self.tables(catalog, schema), pattern))
        if reader.take("COLUMNS"):
            if not reader.take("FROM", "IN"):
                reader.fail("FROM")
            parts = reader.parts()
            pattern = reader.like()
            reader.end()
            return self._columns(parts, session, pattern)
        if reader.take("SESSION"):
            pattern = reader.like()
            reader.end()
            rows = [
                (name, session.properties.get(name, ""), "", V, description)
                for name, description in PROPERTIES.items()
                if pattern is None or pattern.fullmatch(name)
            ]
            return Answer([("Name", V), ("Value", V), ("Default", V), ("Type", V), ("Description", V)], rows)
        raise DialectError(
            f"unsupported in lakegate: SHOW {reader.word()}".rstrip(), line=1, column=1, error_name="NOT_SUPPORTED"
        )

    def _columns(self, parts: list[str], session: Session, pattern: re.Pattern | None) -> Answer:
        ref = self.resolve(parts, session)
        rows = [
            (name, trino_type, "", "")
            for name, trino_type in self.tables(ref.catalog, ref.schema)[ref.table]
            if pattern is None or pattern.fullmatch(name)
        ]
        return Answer([("Column", V), ("Type", V), ("Extra", V), ("Comment", V)], rows)


def _matching(names: Iterable[str], pattern: re.Pattern | None) -> list[tuple]:
    return [(name,) for name in sorted(names) if pattern is None or pattern.fullmatch(name)]


def _jdbc_column(catalog: str, schema: str, table: str, name: str, trino_type: str, position: int) -> tuple:
    """One row of system.jdbc.columns, as Trino's ColumnJdbcTable computes it."""
    t = tt.parse_type(trino_type)
    base, args = t.base, t.args
    size = _FIXED_SIZE.get(base)
    digits = None
    if base == "decimal":
        size, digits = args[0], args[1]
    elif base in ("varchar", "char"):
        size = args[0] if args else tt.MAX_VARCHAR
    elif base in ("time", "time_tz"):
        size, digits = 8 + min(args[0], 1) + args[0] + (6 if base == "time_tz" else 0), args[0]
    elif base == "timestamp":
        size, digits = 21 + min(args[0], 1) + args[0], args[0]
    elif base == "timestamp_tz":
        size, digits = 23 + min(args[0], 1) + args[0] + 32, args[0]
    radix = 10 if t.is_integral or base == "decimal" else 2 if base in ("real", "double") else None
    octets = (
        (args[0] if args else tt.MAX_VARCHAR)
        if base in ("varchar", "char")
        else 2147483647
        if base == "varbinary"
        else None
    )
    return (
        catalog,
        schema,
        table,
        name,
        _JDBC_TYPES.get(base, 2000),
        trino_type,
        size,
        0,
        digits,
        radix,
        1,  # columnNullable: every lake column may hold NULL
        None,
        None,
        None,
        None,
        octets,
        position,
        "YES",
        None,
        None,
        None,
        None,
        None,
        None,
    )
