"""What is in the lake: branches, batches, jobs, and each branch's tables with columns and row counts.

The tables of a branch are the topics its configs declare (from the config registry:
the current version's topics, then topics only older versions declare that still have
files), the platform tables (`lake.platform_tables`: always, empty without files), `events`
and `metadata`. `view_sql` gives, per table, a DuckDB SELECT over the
table's Parquet files as the branch's record lists them, never a glob of the tree (the Hive
partition `batch_id` read as VARCHAR, never auto-cast; `job_id` is a column of the files, or in a
layout v1 branch a partition too) with the columns of `schema` in order; a file shared by many
jobs is read once, or filtered to the snapshot's jobs of it (`Snapshot.filtered`: a job's scope);
a table without files is an empty SELECT with the same columns and
types. Columns that a topic gained or changed across config versions are read with
`union_by_name` and cast to the current type (NULL in files written before the column
existed), and so is any table one of whose files lacks a column added to lakegate's layout
later (`project_id`, `run_counter`: NULL there); other tables are read without it (their files all
have the same columns, and DuckDB would otherwise read every file's footer at each query); the columns each file has
come from the record, so building views opens no file. `metric_results` (evaluated
metrics, one file per batch, written by the metrics engine) is a table once the branch has any.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import duckdb

from lakegate.lake import paths, platform_tables
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import Config, Topic
from lakegate.lake.record import FileEntry, Record, Snapshot
from lakegate.lake.schema import (
    EVENTS_COLUMNS,
    METADATA_COLUMNS,
    METRIC_LIST,
    METRIC_RESULTS_COLUMNS,
    duckdb_type,
    topic_columns,
)
from lakegate.lake.storage import LOCAL


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

    @property
    def by_name(self) -> bool:
        """Whether its files are read by column name and cast: its fields differ between config
        versions, or it has a metric[] column (files written before the metric's `extra` field
        hold a narrower struct, which read by position would drop `extra` of newer files)."""
        return self.varied or any(trino == METRIC_LIST for _, trino in self.columns)


def _lacks_columns(spec: _Spec, files: dict[str, list[FileEntry]]) -> bool:
    """Whether a file lacks a column of `spec` (written before the column was added, as `run_counter`)."""
    needed = {column for column, _ in spec.columns} - set(paths.PARTITION_KEYS) - set(paths.V1_KEYS)
    return any(not needed.issubset(entries[0].columns) for entries in files.values())


def _quote_ident(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def _quote_text(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def _in_scope(entry: FileEntry, batch_id: str | None, job_id: str | None) -> bool:
    """Whether a query of the scope (batch, job) reads `entry` (a batch-level file: every job of its batch)."""
    if batch_id is not None and entry.batch_id != batch_id:
        return False
    return job_id is None or entry.job_id in (job_id, "")


def _unreadable_sql(spec: _Spec, entry: FileEntry) -> str:
    """A SELECT standing for an unreadable file: it raises HIVE_BAD_DATA when a query reads its job."""
    keys = {"batch_id": entry.batch_id, "job_id": entry.job_id} if entry.job_id else {"batch_id": entry.batch_id}
    items = [
        _quote_ident(c) if c in keys else f"CAST(NULL AS {duckdb_type(t)}) AS {_quote_ident(c)}"
        for c, t in spec.columns
    ]
    constants = ", ".join(f"{_quote_text(value)} AS {_quote_ident(key)}" for key, value in keys.items())
    message = _quote_text(
        f"HIVE_BAD_DATA: Cannot read the Parquet file of {entry.where}: it is corrupt, truncated or "
        "missing (ingest the job again)"
    )
    return f"SELECT {', '.join(items)} FROM (SELECT {constants}) WHERE error({message}) IS NULL"


class Catalog:
    """Reads the lake at `lake`: each call reads the branch's record once (`lake.record`), or uses
    the `snapshot` it is given; nothing is cached between calls except loaded config versions.

    `pending` entries (staged, not yet committed) replace the record's files of their keys: the
    metrics engine shows a batch's new statuses to its batch metrics before committing them.
    """

    def __init__(self, lake: Path, pending: Sequence[FileEntry] = ()):
        self.lake = Path(lake)
        self.pending = {entry.key: entry for entry in pending}
        self._configs: dict[tuple[str, int], Config] = {}

    # -- listing --------------------------------------------------------------------------

    def branches(self) -> list[str]:
        """Every branch with a directory in the lake, sorted."""
        if not LOCAL.is_dir(self.lake):
            return []
        names = []
        for entry in LOCAL.list(self.lake):
            if entry.is_dir:
                try:
                    names.append(paths.decode_branch(entry.name))
                except paths.LakePathError:
                    continue
        return sorted(names)

    def snapshot(
        self,
        branch: str,
        record: Record | None = None,
        *,
        batch_id: str | None = None,
        job_id: str | None = None,
        files: bool = True,
    ) -> Snapshot:
        """The branch's files now, or only those of one scope, or none (`Record.snapshot`);
        `record`: an open record of the branch to read them from."""
        if record is None:
            record = Record(self.lake, branch)
            try:
                found = record.snapshot(batch_id, job_id, files=files)
            finally:
                record.close()
        else:
            found = record.snapshot(batch_id, job_id, files=files)
        if not self.pending:
            return found
        pending = {key: entry for key, entry in self.pending.items() if files and _in_scope(entry, batch_id, job_id)}
        current = {entry.key: entry for entry in found.files}
        merged = current | pending
        replaced = {current[key].path for key in pending if key in current}
        kept = {entry.path for entry in merged.values()}
        filtered = found.filtered | (replaced & kept)  # shared files some of whose jobs are pending
        if job_id is not None:
            filtered |= {entry.path for entry in pending.values() if entry.job_id}
        tables = found.tables | {entry.table for entry in self.pending.values()}
        return Snapshot(found.generation, tuple(merged.values()), tables, frozenset(filtered))

    def jobs(self, branch: str, batch_id: str | None = None) -> list[JobRef]:
        """The jobs (those with a metadata row) of a branch, or of one batch, sorted."""
        if batch_id is not None:
            paths.check_segment(batch_id, "batch id")
        return sorted(
            JobRef(e.batch_id, e.job_id) for e in self.snapshot(branch, batch_id=batch_id).of(paths.METADATA_TABLE)
        )

    def batches(self, branch: str) -> list[str]:
        """The batches of a branch that have at least one job, sorted (no file list is read)."""
        record = Record(self.lake, branch)
        try:
            found = set(record.batches())
        finally:
            record.close()
        return sorted(found | {e.batch_id for e in self.pending.values() if e.table == paths.METADATA_TABLE})

    # -- tables ---------------------------------------------------------------------------

    def _config(self, branch: str, version: int) -> Config:
        key = (branch, version)
        if key not in self._configs:
            self._configs[key] = BranchConfigs(self.lake, branch).load(version)
        return self._configs[key]

    def _specs(self, branch: str, snapshot: Snapshot) -> list[_Spec]:
        registry = BranchConfigs(self.lake, branch)
        versions = registry.versions()
        declared: dict[str, list[Topic]] = {}  # topic -> its declarations, newest first
        for version in reversed(versions):
            for topic in self._config(branch, version).topics.values():
                declared.setdefault(topic.name, []).append(topic)
        current = set(self._config(branch, versions[-1]).topics) if versions else set()
        with_files = snapshot.tables
        specs = []
        for name, topics in declared.items():
            if name not in current and name not in with_files:
                continue  # dropped from the config and never written
            varied = any(t.fields != topics[0].fields for t in topics[1:])
            specs.append(_Spec(name, "topic", topic_columns(topics[0]), varied))
        specs.sort(key=lambda s: s.name not in current)  # current topics first, in config order
        specs += [_Spec(name, "topic", topic_columns(topic)) for name, topic in platform_tables.TOPICS.items()]
        specs.append(_Spec(paths.EVENTS_TABLE, "events", list(EVENTS_COLUMNS)))
        specs.append(_Spec(paths.METADATA_TABLE, "metadata", list(METADATA_COLUMNS)))
        if paths.METRIC_RESULTS_TABLE in with_files:
            specs.append(_Spec(paths.METRIC_RESULTS_TABLE, "metric_results", list(METRIC_RESULTS_COLUMNS)))
        return specs

    def schema(self, branch: str, snapshot: Snapshot | None = None) -> dict[str, dict[str, str]]:
        """Table -> column -> Trino type name, for every table of the branch."""
        snapshot = snapshot or self.snapshot(branch)
        return {spec.name: dict(spec.columns) for spec in self._specs(branch, snapshot)}

    def tables(self, branch: str) -> list[TableInfo]:
        """Every table of the branch with its columns and row count (from the record: no file is read)."""
        snapshot = self.snapshot(branch)
        return [
            TableInfo(spec.name, spec.kind, list(spec.columns), sum(e.rows for e in snapshot.of(spec.name)))
            for spec in self._specs(branch, snapshot)
        ]

    def view_sql(
        self, branch: str, snapshot: Snapshot | None = None, unreadable: Collection[str] = ()
    ) -> dict[str, str]:
        """Table -> a DuckDB SELECT of its rows, columns as in `schema`, over exactly the files of
        `snapshot` (default: the record now, read through `paths.reader_path`; a scope's snapshot gives
        every table of the branch, over the scope's files only); no file is opened to
        build it. The `unreadable` files (absolute reader paths) are left out: a query that reads
        their job fails with HIVE_BAD_DATA naming table, batch and job; other jobs still read."""
        snapshot = snapshot or self.snapshot(branch)
        root = str(paths.branch_dir(self.lake, branch))
        views = {}
        for spec in self._specs(branch, snapshot):
            files: dict[str, list[FileEntry]] = {}
            bad = []
            for entry in snapshot.of(spec.name):
                reader = paths.reader_file(root, entry.path)
                if reader in unreadable:
                    bad.append(entry)
                else:
                    files.setdefault(reader, []).append(entry)
            if not spec.by_name and _lacks_columns(spec, files):
                spec = dataclasses.replace(spec, varied=True)
            selects = self._selects(spec, files, snapshot.filtered)
            selects += [_unreadable_sql(spec, entry) for entry in bad]
            if not selects:
                columns = ", ".join(f"CAST(NULL AS {duckdb_type(t)}) AS {_quote_ident(c)}" for c, t in spec.columns)
                selects = [f"SELECT {columns} WHERE false"]
            views[spec.name] = " UNION ALL ".join(selects)
        return views

    @classmethod
    def _selects(cls, spec: _Spec, files: dict[str, list[FileEntry]], filtered: Collection[str]) -> list[str]:
        """The SELECTs over `files` (reader path -> the entries naming it): one over the layout v2
        files, one over the layout v1 files (partitioned by job too), one per file in `filtered`
        (with only its listed jobs' rows)."""
        v2, v1, own = [], [], []
        for reader, entries in files.items():
            path = entries[0].path
            if paths.is_v1_path(path):
                v1.append((entries, reader))
            elif path in filtered:
                own.append((entries, reader))
            else:
                v2.append((entries, reader))
        selects = [cls._files_sql(spec, v2, paths.PARTITION_KEYS)] if v2 else []
        selects += [cls._files_sql(spec, v1, paths.V1_KEYS)] if v1 else []
        for entries, reader in own:
            jobs = ", ".join(_quote_text(entry.job_id) for entry in entries)
            where = f" WHERE {_quote_ident('job_id')} IN ({jobs})"
            selects.append(cls._files_sql(spec, [(entries, reader)], paths.PARTITION_KEYS) + where)
        return selects

    @staticmethod
    def _files_sql(spec: _Spec, files: Sequence[tuple[list[FileEntry], str]], keys: tuple[str, ...]) -> str:
        """A SELECT over `files` (entries, reader path) partitioned by `keys`, with the columns of `spec`."""
        hive_types = ", ".join(f"'{key}': VARCHAR" for key in keys)
        listed = ", ".join(_quote_text(reader) for _, reader in files)
        source = (
            f"read_parquet([{listed}], hive_partitioning = true, hive_types = {{{hive_types}}}"
            f"{', union_by_name = true' if spec.by_name else ''})"
        )
        present = None
        if spec.by_name:
            present = {column for entries, _ in files for column in entries[0].columns} | set(keys)
        items = []
        for column, trino in spec.columns:
            if present is None and trino != "timestamp(3)":
                items.append(_quote_ident(column))
            elif present is None:  # DuckDB reads Parquet milliseconds as TIMESTAMP (microseconds)
                items.append(f"CAST({_quote_ident(column)} AS {duckdb_type(trino)}) AS {_quote_ident(column)}")
            elif column in present:
                items.append(f"CAST({_quote_ident(column)} AS {duckdb_type(trino)}) AS {_quote_ident(column)}")
            else:
                items.append(f"CAST(NULL AS {duckdb_type(trino)}) AS {_quote_ident(column)}")
        return f"SELECT {', '.join(items)} FROM {source}"

    def unreadable(self, branch: str) -> list[tuple[FileEntry, str]]:
        """The branch's files that cannot be read whole, with why (reads every file whole:
        `LakeStorage.damage`, so corruption inside a file is found too)."""
        root = paths.branch_dir(self.lake, branch)
        found = []
        problems: dict[str, str | None] = {}  # path -> why (a shared file is read once)
        for entry in self.snapshot(branch).files:
            if entry.path not in problems:
                problems[entry.path] = LOCAL.damage(root / entry.path)
            if problems[entry.path] is not None:
                found.append((entry, problems[entry.path]))
        return found

    def connect(self, branch: str) -> duckdb.DuckDBPyConnection:
        """An in-memory DuckDB connection with one view per table of the branch."""
        con = duckdb.connect()
        for name, sql in self.view_sql(branch).items():
            con.execute(f"CREATE VIEW {_quote_ident(name)} AS {sql}")
        return con
