"""Every lake table's columns, as Trino and Arrow types: the one place for table schemas and type maps.

A table's columns are (name, Trino type) pairs in table order, partition keys included
(`paths.partition_keys`: they live in the directory names, not in the Parquet files). Each Trino
type a lake column can have is listed once here with its Arrow type (`arrow_type`) and the DuckDB
type the catalog's views cast to (`duckdb_type`). A topic field's Trino type comes from its config
type (`types.trino_type`).
"""

from __future__ import annotations

from collections.abc import Iterable

import pyarrow as pa

from lakegate.lake import paths, platform_tables
from lakegate.lake.config import Topic
from lakegate.lake.types import METRIC_FIELDS, trino_type

#: Columns lakegate adds to every topic and events row (besides the batch_id/job_id partitions), with
#: their Trino types: one value per job, from its `metadata` row. SignalFlag names `project_id`,
#: `build_version` and `run_counter` as columns of metadata and of every topic.
TIMESTAMP = "timestamp"
JOB_COLUMNS: tuple[tuple[str, str], ...] = (
    ("experience_name", "varchar"),
    ("build_version", "varchar"),
    ("project_id", "varchar"),
    ("run_counter", "bigint"),
)
PARTITIONS = ("batch_id", "job_id")
RESERVED_FIELDS = frozenset({TIMESTAMP, *(name for name, _ in JOB_COLUMNS), *PARTITIONS})

METRIC_STRUCT = pa.struct([(name, pa.string()) for name in METRIC_FIELDS])
#: The Trino type of a `metric[]` column.
METRIC_LIST = trino_type("metric[]")
_METRIC_DUCKDB = "STRUCT(" + ", ".join(f'"{f.name}" VARCHAR' for f in METRIC_STRUCT) + ")[]"
#: Trino type -> (Arrow type as stored in Parquet, DuckDB type the catalog's views cast to), for
#: every type a lake column can have (tests check DuckDB reads each Arrow type as this DuckDB type).
_TYPES = {
    "bigint": (pa.int64(), "BIGINT"),
    "double": (pa.float64(), "DOUBLE"),
    "boolean": (pa.bool_(), "BOOLEAN"),
    "varchar": (pa.string(), "VARCHAR"),
    "timestamp(3)": (pa.timestamp("ms"), "TIMESTAMP_MS"),
    "array(varchar)": (pa.list_(pa.string()), "VARCHAR[]"),
    METRIC_LIST: (pa.list_(METRIC_STRUCT), _METRIC_DUCKDB),
}
#: Trino type -> Arrow type of every lake column type.
ARROW_TYPES = {trino: arrow for trino, (arrow, _) in _TYPES.items()}

Columns = list[tuple[str, str]]

EVENTS_COLUMNS: Columns = [
    (TIMESTAMP, "bigint"),
    ("topic", "varchar"),
    ("name", "varchar"),
    ("description", "varchar"),
    ("status", "varchar"),
    ("tags", "array(varchar)"),
    ("metrics", METRIC_LIST),
    *JOB_COLUMNS,
    *[(c, "varchar") for c in PARTITIONS],
]

#: The `metadata` table (one row per job): the columns of the product guide plus `build_version`.
METADATA_COLUMNS: Columns = [
    ("org_id", "varchar"),
    ("batch_id", "varchar"),
    ("job_id", "varchar"),
    ("run_counter", "bigint"),
    ("project_id", "varchar"),
    ("branch_id", "varchar"),
    ("branch_name", "varchar"),
    ("build_id", "varchar"),
    ("build_name", "varchar"),
    ("build_version", "varchar"),
    ("build_creation_timestamp", "timestamp(3)"),
    ("experience_id", "varchar"),
    ("experience_name", "varchar"),
    ("experience_tag_ids", "array(varchar)"),
    ("experience_tag_names", "array(varchar)"),
    ("test_suite_id", "varchar"),
    ("test_suite_name", "varchar"),
    ("test_suite_revision", "bigint"),
    ("job_status", "varchar"),
    ("job_metrics_status", "varchar"),
    ("job_conflated_status", "varchar"),
    ("custom_field_keys", "array(varchar)"),
    ("custom_field_values", "array(varchar)"),
    ("time", "timestamp(3)"),
]

#: `metric_results`: one row per evaluated metric (job_id NULL for batch metrics).
METRIC_RESULTS_COLUMNS: Columns = [
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


def arrow_type(trino: str) -> pa.DataType:
    """The Arrow type a lake column of Trino type `trino` is stored as."""
    return ARROW_TYPES[trino]


def field_arrow_type(field_type: str) -> pa.DataType:
    """The Arrow type a topic field of config type `field_type` is stored as."""
    return ARROW_TYPES[trino_type(field_type)]


def duckdb_type(trino: str) -> str:
    """The DuckDB type of a lake column of Trino type `trino` (`timestamp(3)`: TIMESTAMP_MS)."""
    return _TYPES[trino][1]


def job_columns(topic: Topic) -> Columns:
    """The columns of a topic table that hold one value per job (its `metadata` row's), partitions aside:
    `JOB_COLUMNS`, and `org_id` first in a platform table (`lake.platform_tables`)."""
    extra = platform_tables.EXTRA_JOB_COLUMNS if topic.name in platform_tables.TOPICS else ()
    return [*extra, *JOB_COLUMNS]


def topic_columns(topic: Topic) -> Columns:
    """A topic table's columns (name, Trino type) in order."""
    return [
        (TIMESTAMP, "bigint"),
        *[(f, trino_type(t)) for f, t in topic.fields.items()],
        *job_columns(topic),
        *[(c, "varchar") for c in PARTITIONS],
    ]


def file_schema(table: str, columns: Iterable[tuple[str, str]]) -> pa.Schema:
    """The Arrow schema of `table`'s Parquet files: its columns but the partition keys."""
    keys = paths.partition_keys(table)
    return pa.schema([(name, arrow_type(trino)) for name, trino in columns if name not in keys])
