"""What is in the lake: branches, batches, jobs, and each branch's tables with columns and row counts.

The tables of a branch are the topics its configs declare (from the config registry:
the current version's topics, then topics only older versions declare that still have
files), `events` and `metadata`. `view_sql` gives, per table, a DuckDB SELECT over the
table's Parquet files (Hive partitions `batch_id`/`job_id` read as VARCHAR, never
auto-cast) with the columns of `schema` in order; a table without files is an empty
SELECT with the same columns and types. Columns that a topic gained or changed across
config versions are read with `union_by_name` and cast to the current type (NULL in
files written before the column existed); other tables are read without it (their files all
have the same columns, and DuckDB would otherwise read every file's footer at each query).
`metric_results` (evaluated metrics, one file per batch, written by the metrics engine) is a
table once the branch has any.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import duckdb

from lakegate.lake import paths
from lakegate.lake.config import Config, Topic
from lakegate.lake.ingest import JOB_COLUMNS, TIMESTAMP
from lakegate.lake.metadata import COLUMNS as METADATA_COLUMNS
from lakegate.lake.registry import BranchConfigs
from lakegate.lake.types import trino_type

_METRIC_DUCKDB = 'STRUCT("name" VARCHAR, "description" VARCHAR, "status" VARCHAR, "type" VARCHAR, "value" VARCHAR)[]'
#: Trino type -> DuckDB type, for every type a lake column can have.
DUCKDB_TYPES = {
    "bigint": "BIGINT",
    "double": "DOUBLE",
    "boolean": "BOOLEAN",
    "varchar": "VARCHAR",
    "timestamp(3)": "TIMESTAMP_MS",
    "array(varchar)": "VARCHAR[]",
    trino_type("metric[]"): _METRIC_DUCKDB,
}
PARTITIONS = ("batch_id", "job_id")
_EVENTS_COLUMNS = [
    (TIMESTAMP, "bigint"),
    ("topic", "varchar"),
    ("name", "varchar"),
    ("description", "varchar"),
    ("status", "varchar"),
    ("tags", "array(varchar)"),
    ("metrics", trino_type("metric[]")),
    *[(c, "varchar") for c in JOB_COLUMNS],
    *[(c, "varchar") for c in PARTITIONS],
]
#: Columns of `metric_results`: one row per evaluated metric (job_id NULL for batch metrics).
METRIC_RESULTS_COLUMNS = [
    ("batch_id", "varchar"),
    ("job_id", "varchar"),
    ("metric_name", "varchar"),
    ("metric_type", "varchar"),
    ("template", "varchar"),
    ("status", "varchar"),
    ("scalar_value", "double"),
    ("value_text", "varchar"),
    ("units", "varchar"),
    ("figure_json", "varchar"),
    ("details_json", "varchar"),
    ("error_message", "varchar"),
    ("error_line", "bigint"),
    ("error_column", "bigint"),
    ("error_location", "varchar"),
    ("metrics_set", "varchar"),
    ("config_version", "bigint"),
    ("evaluated_at", "timestamp(3)"),
]


@dataclass
class TableInfo:
    """One table of a branch: `kind` is 'topic', 'metadata' or 'events'; columns are (name, Trino type)."""

    name: str
    kind: str
    columns: list[tuple[str, str]]
    row_count: int


class JobRef(NamedTuple):
    batch_id: str
    job_id: str


@dataclass
class _Spec:
    name: str
    kind: str
    columns: list[tuple[str, str]]
    varied: bool = False  # the topic's fields differ between config versions


def _quote_ident(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def _quote_text(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def topic_columns(topic: Topic) -> list[tuple[str, str]]:
    """A topic table's columns (name, Trino type) in order."""
    return [(TIMESTAMP, "bigint"), *[(f, trino_type(t)) for f, t in topic.fields.items()],
            *[(c, "varchar") for c in JOB_COLUMNS], *[(c, "varchar") for c in PARTITIONS]]


class Catalog:
    """Reads the lake at `lake`; nothing is cached between calls except loaded config versions."""

    def __init__(self, lake: Path):
        self.lake = Path(lake)
        self._configs: dict[tuple[str, int], Config] = {}

    # -- listing --------------------------------------------------------------------------

    def branches(self) -> list[str]:
        """Every branch with a directory in the lake, sorted."""
        if not self.lake.is_dir():
            return []
        names = []
        for entry in self.lake.iterdir():
            if entry.is_dir():
                try:
                    names.append(paths.decode_branch(entry.name))
                except paths.LakePathError:
                    continue
        return sorted(names)

    def jobs(self, branch: str, batch_id: str | None = None) -> list[JobRef]:
        """The jobs (those with a metadata row) of a branch, or of one batch, sorted."""
        root = paths.table_dir(self.lake, branch, paths.METADATA_TABLE)
        if batch_id is not None:
            paths.check_segment(batch_id, "batch id")
        found = []
        for batch_dir in sorted(root.glob(f"batch_id={'*' if batch_id is None else batch_id}")):
            batch = paths.partition_value(batch_dir, "batch_id")
            for job_dir in sorted(batch_dir.glob("job_id=*")):
                if (job_dir / paths.DATA_FILE).is_file():
                    found.append(JobRef(batch, paths.partition_value(job_dir, "job_id")))
        return sorted(found)

    def batches(self, branch: str) -> list[str]:
        """The batches of a branch that have at least one job, sorted."""
        return sorted({job.batch_id for job in self.jobs(branch)})

    # -- tables ---------------------------------------------------------------------------

    def _config(self, branch: str, version: int) -> Config:
        key = (branch, version)
        if key not in self._configs:
            self._configs[key] = BranchConfigs(self.lake, branch).load(version)
        return self._configs[key]

    def _specs(self, branch: str) -> list[_Spec]:
        registry = BranchConfigs(self.lake, branch)
        versions = registry.versions()
        declared: dict[str, list[Topic]] = {}  # topic -> its declarations, newest first
        for version in reversed(versions):
            for topic in self._config(branch, version).topics.values():
                declared.setdefault(topic.name, []).append(topic)
        current = set(self._config(branch, versions[-1]).topics) if versions else set()
        specs = []
        for name, topics in declared.items():
            if name not in current and not self._has_files(branch, name):
                continue  # dropped from the config and never written
            varied = any(t.fields != topics[0].fields for t in topics[1:])
            specs.append(_Spec(name, "topic", topic_columns(topics[0]), varied))
        specs.sort(key=lambda s: s.name not in current)  # current topics first, in config order
        specs.append(_Spec(paths.EVENTS_TABLE, "events", list(_EVENTS_COLUMNS)))
        specs.append(_Spec(paths.METADATA_TABLE, "metadata", list(METADATA_COLUMNS)))
        if self._has_files(branch, paths.METRIC_RESULTS_TABLE):
            specs.append(_Spec(paths.METRIC_RESULTS_TABLE, "metric_results", list(METRIC_RESULTS_COLUMNS)))
        return specs

    def _has_files(self, branch: str, table: str) -> bool:
        return next(paths.data_files(self.lake, branch, table), None) is not None

    def schema(self, branch: str) -> dict[str, dict[str, str]]:
        """Table -> column -> Trino type name, for every table of the branch."""
        return {spec.name: dict(spec.columns) for spec in self._specs(branch)}

    def tables(self, branch: str) -> list[TableInfo]:
        """Every table of the branch with its columns and row count."""
        con = duckdb.connect()
        try:
            infos = []
            for spec in self._specs(branch):
                count = 0
                if self._has_files(branch, spec.name):
                    glob = _quote_text(paths.table_glob(self.lake, branch, spec.name))
                    count = con.execute(f"SELECT count(*) FROM read_parquet({glob})").fetchone()[0]
                infos.append(TableInfo(spec.name, spec.kind, list(spec.columns), count))
            return infos
        finally:
            con.close()

    def view_sql(self, branch: str) -> dict[str, str]:
        """Table -> a DuckDB SELECT of its rows, columns as in `schema` (reflects the files at call time)."""
        views = {}
        con: duckdb.DuckDBPyConnection | None = None
        try:
            for spec in self._specs(branch):
                if not self._has_files(branch, spec.name):
                    columns = ", ".join(f"CAST(NULL AS {DUCKDB_TYPES[t]}) AS {_quote_ident(c)}" for c, t in spec.columns)
                    views[spec.name] = f"SELECT {columns} WHERE false"
                    continue
                hive_types = ", ".join(f"'{key}': VARCHAR" for key in paths.partition_keys(spec.name))
                source = (f"read_parquet({_quote_text(paths.table_glob(self.lake, branch, spec.name))}, "
                          f"hive_partitioning = true, hive_types = {{{hive_types}}}"
                          f"{', union_by_name = true' if spec.varied else ''})")
                present = None
                if spec.varied:
                    con = con or duckdb.connect()
                    present = {row[0] for row in con.execute(f"DESCRIBE SELECT * FROM {source}").fetchall()}
                items = []
                for column, trino in spec.columns:
                    if present is None and trino != "timestamp(3)":
                        items.append(_quote_ident(column))
                    elif present is None:  # DuckDB reads Parquet milliseconds as TIMESTAMP (microseconds)
                        items.append(f"CAST({_quote_ident(column)} AS TIMESTAMP_MS) AS {_quote_ident(column)}")
                    elif column in present:
                        items.append(f"CAST({_quote_ident(column)} AS {DUCKDB_TYPES[trino]}) AS {_quote_ident(column)}")
                    else:
                        items.append(f"CAST(NULL AS {DUCKDB_TYPES[trino]}) AS {_quote_ident(column)}")
                views[spec.name] = f"SELECT {', '.join(items)} FROM {source}"
        finally:
            if con is not None:
                con.close()
        return views

    def connect(self, branch: str) -> duckdb.DuckDBPyConnection:
        """An in-memory DuckDB connection with one view per table of the branch."""
        con = duckdb.connect()
        for name, sql in self.view_sql(branch).items():
            con.execute(f"CREATE VIEW {_quote_ident(name)} AS {sql}")
        return con
