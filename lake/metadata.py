"""The `metadata` table: one row per job, with the columns of the product guide plus `build_version`.

A job's row comes from a metadata file (`--metadata job.yaml`: a YAML mapping from column
names to values), flags of the command, or a dict; `build_metadata_row` fills in what is
missing: ids (uuid5 of the matching name, so re-ingesting a job gives the same ids, else a
random uuid4), `branch_name` (the branch), `job_status` ('SUCCEEDED'), and
`job_conflated_status` ('ERROR' for a FAILED job, else NULL until metrics run).
`write_metadata_row` replaces a job's row atomically (`update_metadata_row` changes some
columns with it); `stage_metadata_rows` adds new rows of a batch's jobs, in one file, to a larger
record change (`metrics run` switches every job's statuses and the batch's results at once).
"""

from __future__ import annotations

import datetime as dt
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
from ruamel.yaml import YAML
from ruamel.yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from lakegate.lake import paths
from lakegate.lake.batch_files import job_id_position, jobs_table, write_jobs
from lakegate.lake.config_yaml import FileReader, RawProblem, describe, did_you_mean
from lakegate.lake.record import Change, Record
from lakegate.lake.schema import METADATA_COLUMNS, file_schema
from lakegate.lake.storage import LOCAL

#: Column names in table order; batch_id lives only in the partition directories.
COLUMN_NAMES = tuple(name for name, _ in METADATA_COLUMNS)
#: The Arrow schema of the Parquet file (all columns but the partition key; a file may hold many jobs).
FILE_SCHEMA = file_schema(paths.METADATA_TABLE, METADATA_COLUMNS)
_TYPES = dict(METADATA_COLUMNS)
_YAML = YAML(typ="safe", pure=True).constructor  # the config loader's library (YAML 1.2)

#: Namespace of the deterministic ids (uuid5) generated for names.
ID_NAMESPACE = uuid.UUID("6f1e7c1a-3b9d-5d43-9a57-2c1f0e6b8a41")
#: id column -> the name columns it is derived from.
_ID_SOURCES = {
    "build_id": ("build_name", "build_version"),
    "experience_id": ("experience_name",),
    "test_suite_id": ("test_suite_name",),
}


class MetadataError(ValueError):
    """Invalid job metadata; `problems` lists every error, each saying where (file:line:column)."""

    def __init__(self, problems: list[str]):
        self.problems = problems
        super().__init__("\n".join(problems))


# -- checking values ---------------------------------------------------------------------


def _check(column: str, value: Any) -> Any:
    """The stored form of `value` for `column`, or ValueError saying what was expected."""
    if value is None:
        return [] if _TYPES[column] == "array(varchar)" else None
    kind = _TYPES[column]
    if kind == "varchar":
        if not isinstance(value, str):
            raise ValueError(f"expected a string, got {type(value).__name__} {value!r}")
        return value
    if kind == "bigint":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"expected an integer, got {type(value).__name__} {value!r}")
        if not -(2**63) <= value < 2**63:
            raise ValueError(f"integer {value} is out of range (64-bit)")
        return value
    if kind == "timestamp(3)":
        return _timestamp(value)
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        raise ValueError(f"expected a list of strings, got {value!r}")
    return list(value)


def _timestamp(value: Any) -> dt.datetime:
    if isinstance(value, dt.datetime):
        moment = value
    elif isinstance(value, dt.date):
        moment = dt.datetime(value.year, value.month, value.day)
    elif isinstance(value, str):
        try:
            moment = dt.datetime.fromisoformat(value.strip())
        except ValueError:
            raise ValueError(f"expected an ISO 8601 timestamp like 2025-01-31T12:00:00Z, got {value!r}") from None
    else:
        raise ValueError(f"expected an ISO 8601 timestamp, got {type(value).__name__} {value!r}")
    if moment.tzinfo is not None:
        moment = moment.astimezone(dt.UTC).replace(tzinfo=None)
    return moment.replace(microsecond=moment.microsecond // 1000 * 1000)


def check_metadata(values: dict[str, Any]) -> dict[str, Any]:
    """Check a dict of column values (any subset); MetadataError for unknown keys or bad values."""
    problems = []
    result = {}
    for key, value in values.items():
        if key not in _TYPES:
            problems.append(f"unknown metadata column {key!r}{did_you_mean(str(key), COLUMN_NAMES)}")
            continue
        try:
            result[key] = _check(key, value)
        except ValueError as exc:
            problems.append(f"metadata column {key!r}: {exc}")
    if problems:
        raise MetadataError(problems)
    return result


# -- the metadata file ---------------------------------------------------------------------


def load_metadata_file(path: str | Path) -> dict[str, Any]:
    """Read a job's metadata YAML file: a mapping from column names to values (any subset).

    Strings are taken as written (`build_version: 1.10` is '1.10'), arrays are lists,
    timestamps ISO 8601. MetadataError lists every problem as `file:line:column: message`.
    """
    raw: list[RawProblem] = []
    reader = FileReader(str(path), raw)
    root = reader.compose()
    values: dict[str, Any] = {}
    if root is not None and not isinstance(root, MappingNode):
        reader.error(root, f"expected a mapping of metadata columns to values, got {describe(root)}")
    elif root is not None:
        for key, node in reader.items(root, "metadata column", " in the metadata file", string_keys=False):
            name = key.value
            if name not in _TYPES:
                reader.error(key, f"unknown metadata column {name!r}{did_you_mean(name, COLUMN_NAMES)}")
                continue
            try:
                values[name] = _check(name, _node_value(_TYPES[name], node))
            except ValueError as exc:
                reader.error(node, f"{name}: {exc}")
    if root is None and len(raw) == 1 and "empty" in raw[0][3]:
        return {}  # an empty metadata file sets nothing
    if raw:
        raise MetadataError([f"{p}:{line}:{column}: {message}" for p, line, column, message in raw])
    return values


def _node_value(kind: str, node: Node) -> Any:
    """The Python value of a YAML node for a column of Trino type `kind`."""
    if isinstance(node, ScalarNode) and node.tag.endswith(":null"):
        return None
    if kind == "array(varchar)":
        if not isinstance(node, SequenceNode):
            raise ValueError(f"expected a list of strings, got {describe(node)}")
        items = []
        for item in node.value:
            if not isinstance(item, ScalarNode) or item.tag.endswith(":null"):
                raise ValueError(f"expected a list of strings, got {describe(item)} in it")
            items.append(item.value)
        return items
    if not isinstance(node, ScalarNode):
        raise ValueError(f"expected a single value, got {describe(node)}")
    if kind == "bigint":
        if not node.tag.endswith(":int"):
            raise ValueError(f"expected an integer, got {describe(node)}")
        return _YAML.construct_yaml_int(node)
    return node.value  # varchar and timestamps: the text as written


# -- building and writing rows -----------------------------------------------------------------


def _name_id(kind: str, *names: Any) -> str:
    return str(uuid.uuid5(ID_NAMESPACE, kind + ":" + "\0".join("" if n is None else str(n) for n in names)))


def build_metadata_row(
    values: dict[str, Any], *, lake: Path, branch: str, batch_id: str, job_id: str, now: dt.datetime | None = None
) -> dict[str, Any]:
    """A complete metadata row for one job: `values` (checked) plus defaults and generated ids.

    org_id and project_id default to ids derived from the lake's location, so every job of
    a lake shares them; the other ids derive from their names within the project; run_counter
    defaults to 0.
    """
    row = check_metadata(values)
    problems = []
    for key, given in (("batch_id", batch_id), ("job_id", job_id)):
        if row.get(key) not in (None, given):
            problems.append(f"metadata says {key} {row[key]!r} but the job is ingested as {key} {given!r}")
    if problems:
        raise MetadataError(problems)
    row["batch_id"], row["job_id"] = batch_id, job_id
    where = str(Path(lake).resolve())
    row.setdefault("org_id", None)
    row["org_id"] = row["org_id"] or _name_id("org", where)
    row["project_id"] = row.get("project_id") or _name_id("project", where)
    if row.get("run_counter") is None:
        row["run_counter"] = 0  # the job's first run; ReSim counts a batch's reruns up from it
    project = row["project_id"]
    row["branch_name"] = row.get("branch_name") or branch
    row["branch_id"] = row.get("branch_id") or _name_id("branch", project, row["branch_name"])
    for id_column, name_columns in _ID_SOURCES.items():
        names = [row.get(c) for c in name_columns]
        if not row.get(id_column):
            row[id_column] = (
                _name_id(id_column, project, *names) if any(n is not None for n in names) else str(uuid.uuid4())
            )
    tag_names = row.setdefault("experience_tag_names", [])
    if "experience_tag_ids" not in row or (not row["experience_tag_ids"] and tag_names):
        row["experience_tag_ids"] = [_name_id("tag", project, name) for name in tag_names]
    if len(row["experience_tag_ids"]) != len(tag_names):
        problems.append(
            f"experience_tag_ids has {len(row['experience_tag_ids'])} ids but experience_tag_names "
            f"has {len(tag_names)} names; they are parallel lists"
        )
    keys, custom_values = row.setdefault("custom_field_keys", []), row.setdefault("custom_field_values", [])
    if len(keys) != len(custom_values):
        problems.append(
            f"custom_field_keys has {len(keys)} keys but custom_field_values has {len(custom_values)} "
            "values; they are parallel lists"
        )
    if problems:
        raise MetadataError(problems)
    row["job_status"] = row.get("job_status") or "SUCCEEDED"
    if "job_conflated_status" not in row:
        row["job_conflated_status"] = "ERROR" if row["job_status"].upper() == "FAILED" else None
    if row.get("time") is None:
        row["time"] = _timestamp(now or dt.datetime.now(dt.UTC))
    return {name: row.get(name) for name in COLUMN_NAMES}


def metadata_table(row: dict[str, Any]) -> pa.Table:
    """The one-row Arrow table stored for `row` (a complete row; partition columns are left out)."""
    missing = [name for name in FILE_SCHEMA.names if name not in row]
    if missing:
        raise MetadataError([f"metadata row lacks column(s) {', '.join(missing)}"])
    checked = check_metadata({name: row[name] for name in FILE_SCHEMA.names})
    return pa.Table.from_pylist([checked], schema=FILE_SCHEMA)


def write_metadata_row(lake: Path, branch: str, batch_id: str, job_id: str, row: dict[str, Any]) -> Path:
    """Replace the metadata row of one job atomically; returns the data file's path.

    `row` has every column (batch_id/job_id may be left out; if present they must match).
    The caller holds the job's lock (`paths.job_lock`).
    """
    change = Change(lake, branch)
    with paths.staging(lake, branch) as scratch:
        stage_metadata_row(change, scratch, batch_id, job_id, row)
    return change.commit(f"metadata {batch_id}/{job_id}")[0]


def stage_metadata_row(change: Change, scratch: Path, batch_id: str, job_id: str, row: dict[str, Any]) -> None:
    """Add a job's new metadata row to `change` (written via `scratch`); it shows once `change` commits."""
    _check_ids(row, batch_id, job_id)
    staged = scratch / "metadata.parquet"
    write_metadata_file(metadata_table(row), staged)
    change.add(paths.METADATA_TABLE, batch_id, job_id, staged)


def stage_metadata_rows(change: Change, scratch: Path, batch_id: str, rows: dict[str, dict[str, Any]]) -> None:
    """Add new metadata rows of jobs of one batch (job id -> row) to `change` as ONE file, sorted by job
    (one row group each); they show once `change` commits."""
    for job_id, row in rows.items():
        _check_ids(row, batch_id, job_id)
    staged = scratch / "metadata.parquet"
    write_jobs(staged, [(job_id, metadata_table(row)) for job_id, row in rows.items()])
    change.add_jobs(paths.METADATA_TABLE, batch_id, staged, sorted(rows))


def _check_ids(row: dict[str, Any], batch_id: str, job_id: str) -> None:
    for key, given in (("batch_id", batch_id), ("job_id", job_id)):
        if row.get(key, given) != given:
            raise MetadataError([f"row has {key} {row[key]!r} but is written for {key} {given!r}"])


def write_metadata_file(table: pa.Table, path: Path) -> None:
    LOCAL.write_parquet(table, path, compression="zstd")


def read_metadata_row(lake: Path, branch: str, batch_id: str, job_id: str) -> dict[str, Any] | None:
    """The metadata row of one job (every column, timestamps as naive UTC datetimes), or None."""
    return read_metadata_rows(lake, branch, batch_id, [job_id]).get(job_id)


def read_metadata_rows(lake: Path, branch: str, batch_id: str, job_ids: Sequence[str]) -> dict[str, dict[str, Any]]:
    """The metadata rows of jobs of one batch, as `read_metadata_row` reads each (job id -> row; a job
    without one is left out), each file read once (a compacted batch has one for every job)."""
    record = Record(lake, branch)
    try:
        entries = {job_id: record.find(paths.METADATA_TABLE, batch_id, job_id) for job_id in job_ids}
    finally:
        record.close()
    files: dict[Path, list[str]] = {}
    for job_id, entry in entries.items():
        if entry is not None:
            files.setdefault(record.root / entry.path, []).append(job_id)
    rows: dict[str, dict[str, Any]] = {}
    for target, jobs in files.items():
        v1 = paths.is_v1_path(target.as_posix())
        table = jobs_table(target, jobs, v1=v1, position=job_id_position(paths.METADATA_TABLE, ()))
        ids = table.column("job_id").to_pylist()
        for field in FILE_SCHEMA:  # a file written before a column existed reads it as NULL, as the SQL side does
            if field.name not in table.column_names:
                table = table.append_column(field, pa.nulls(table.num_rows, field.type))
        for job_id, stored in zip(ids, table.select(FILE_SCHEMA.names).cast(FILE_SCHEMA).to_pylist()):
            if job_id not in rows:  # the first row of a job, as its one row
                stored.update(batch_id=batch_id, job_id=job_id)
                rows[job_id] = {name: stored.get(name) for name in COLUMN_NAMES}
    return {job_id: rows[job_id] for job_id in job_ids if job_id in rows}


def update_metadata_row(lake: Path, branch: str, batch_id: str, job_id: str, **changes: Any) -> dict[str, Any]:
    """Change some columns of a job's row (e.g. job_metrics_status) atomically; returns the new row."""
    with paths.job_lock(lake, branch, batch_id, job_id):
        row = read_metadata_row(lake, branch, batch_id, job_id)
        if row is None:
            raise FileNotFoundError(f"no metadata row for batch {batch_id!r}, job {job_id!r} on branch {branch!r}")
        row.update(check_metadata(changes))
        write_metadata_row(lake, branch, batch_id, job_id, row)
        return row
