"""The branch's file record: which Parquet file holds each table's rows of each job, switched atomically.

`<lake>/<branch-dir>/_lake.sqlite` (SQLite, rollback journal) keeps one row per (table, batch, job) in `files`
(path relative to the branch directory, row count, min/max `timestamp`, the file's columns, the
commit that wrote it) and a `commits` log whose last id is the branch's *generation*. Writers
put every new file in its partition directory under a fresh name (`paths.new_data_file`), with
a hard link under `_readers/` (`paths.reader_path`), then `Change.commit` replaces the rows of
everything they rewrite in ONE transaction, bumping the generation, and only then deletes the
superseded files' visible names; their reader links stay `GRACE_SECONDS` (listed in `trash`), so
a query that listed them still reads them. Readers take one `snapshot` per generation and read
the reader links, so they see a job's tables all old or all new, and never list the tree. A
writer killed before its commit leaves only files no row references: lakegate never reads them,
and the next writer of that batch removes them. See docs/lake-format.md.

Layout v2 (`PRAGMA user_version` 2): every table is partitioned by batch only and `job_id` is a
column, so a file may hold many jobs of one batch (compaction, `lake.compaction`); each job keeps
its own row, all of them with the file's path. A file holds exactly the rows of the jobs whose rows
name it: a commit that replaces some of its jobs rewrites it for the others (`Change`), under the
batch's `paths.batch_files_lock`. A branch still in layout v1 (`job_id=<J>/` directories) is read as
it is and migrated by its first writer, in one commit.

A lake written before the record existed (`data.parquet` files, no record) is recorded when the
record is first opened: its files are listed once, inside the record's first write transaction.
"""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import functools
import json
import os
import sqlite3
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa
from tqdm import tqdm

from lakegate.lake import batch_files, paths
from lakegate.lake.storage import LOCAL

RECORD = "_lake.sqlite"
#: How long a superseded file stays readable by lakegate's queries that listed it (its hidden link).
GRACE_SECONDS = 120
#: Test hook: `<point>:<marker file>` makes a writer touch the marker and stop for a minute at that
#: point, or until the marker is removed (`added`: after its first file is published; `commit`: just
#: before its record commit).
PAUSE_ENV = "LAKEGATE_TEST_PAUSE"
#: How long a writer or reader waits for another's transaction before giving up (ms).
BUSY_TIMEOUT_MS = 60_000
_SCHEMA = """
CREATE TABLE IF NOT EXISTS commits (commit_id INTEGER PRIMARY KEY AUTOINCREMENT, what TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS files (
    table_name TEXT NOT NULL, batch_id TEXT NOT NULL, job_id TEXT NOT NULL, path TEXT NOT NULL,
    rows INTEGER NOT NULL, min_ts INTEGER, max_ts INTEGER, columns TEXT NOT NULL, commit_id INTEGER NOT NULL,
    PRIMARY KEY (table_name, batch_id, job_id));
CREATE INDEX IF NOT EXISTS files_of_job ON files (batch_id, job_id);
CREATE TABLE IF NOT EXISTS trash (path TEXT PRIMARY KEY, superseded_at REAL NOT NULL);
"""
#: Which folder holds each job's logs (made by the first commit that records logs: older records lack it).
_LOGS_TABLE = """CREATE TABLE IF NOT EXISTS logs (
    batch_id TEXT NOT NULL, job_id TEXT NOT NULL, path TEXT NOT NULL, PRIMARY KEY (batch_id, job_id))"""
#: The index a layout v2 record has besides `_SCHEMA`'s (a file may be shared by many rows).
_PATH_INDEX = "CREATE INDEX IF NOT EXISTS files_by_path ON files (path)"
#: The layout of a branch whose record says so (`PRAGMA user_version`; 0 and 1 are layout v1).
LAYOUT = 2


@dataclass(frozen=True)
class FileEntry:
    """One published file: `job_id` is '' for batch tables; `path` is relative to the branch directory."""

    table: str
    batch_id: str
    job_id: str
    path: str
    rows: int
    min_ts: int | None = None
    max_ts: int | None = None
    columns: tuple[str, ...] = ()

    @property
    def key(self) -> tuple[str, str, str]:
        return self.table, self.batch_id, self.job_id

    @property
    def where(self) -> str:
        """How messages name the file: `table T, batch B, job J` (never its path)."""
        return f"table {self.table}, batch {self.batch_id}" + (f", job {self.job_id}" if self.job_id else "")


@dataclass(frozen=True)
class Snapshot:
    """The files of a branch at one generation: all of them, or those of one scope (`Record.snapshot`);
    `tables` are the tables that have files anywhere in the branch."""

    generation: int
    files: tuple[FileEntry, ...]
    tables: frozenset[str] = frozenset()
    #: Paths (shared files) whose rows a reader keeps only for the jobs this snapshot lists with them.
    filtered: frozenset[str] = frozenset()

    def of(self, table: str) -> list[FileEntry]:
        return self._by_table.get(table, [])

    @functools.cached_property
    def _by_table(self) -> dict[str, list[FileEntry]]:
        found: dict[str, list[FileEntry]] = {}
        for entry in self.files:
            found.setdefault(entry.table, []).append(entry)
        return found


def describe_file(root: Path, table: str, batch_id: str, job_id: str, path: Path) -> FileEntry:
    """The record entry of a Parquet file (read from its footer) under branch directory `root`."""
    meta = LOCAL.parquet_file(path).metadata
    names = tuple(meta.schema.to_arrow_schema().names)
    low = high = None
    if paths.TIMESTAMP_COLUMN in names:
        index = names.index(paths.TIMESTAMP_COLUMN)
        for group in range(meta.num_row_groups):
            stats = meta.row_group(group).column(index).statistics
            if stats is not None and stats.has_min_max:
                low = stats.min if low is None else min(low, stats.min)
                high = stats.max if high is None else max(high, stats.max)
    return FileEntry(table, batch_id, job_id, path.relative_to(root).as_posix(), meta.num_rows, low, high, names)


@dataclass
class JobVersions:
    """The versions of a batch's jobs (`Record.job_versions`) a commit was computed for."""

    batch_id: str
    versions: dict[str, int]


class StaleJobsError(RuntimeError):
    """A commit made for some versions of a batch's jobs found others: a job was re-ingested,
    rewritten (its file shared with a re-ingested or compacted job), added or dropped since those
    versions were read (`jobs`: the jobs that differ)."""

    def __init__(self, batch_id: str, jobs: Sequence[str], *, attempts: int = 1):
        self.batch_id, self.jobs = batch_id, list(jobs)
        shown = ", ".join(repr(job) for job in self.jobs)
        message = (
            f"job(s) {shown} of batch {batch_id!r} changed during the evaluation "
            "(re-ingested, rewritten, added or removed)"
        )
        if attempts > 1:
            message += f", in each of {attempts} attempts: nothing was written"
        super().__init__(message)


_VERSIONS = (
    "SELECT job_id, max(commit_id) FROM files WHERE batch_id = ? AND job_id != '' AND table_name != ? GROUP BY job_id"
)


class Record:
    """The file record of one branch (the connection is opened lazily, and may serve several threads)."""

    def __init__(self, lake: Path, branch: str):
        self.root = paths.branch_dir(lake, branch)
        self._db: sqlite3.Connection | None = None

    def _connect(self) -> sqlite3.Connection:
        """The record's connection. SQLite's rollback journal (not WAL), so that a reader writes
        nothing: a read-only mount or a full disk can still be read."""
        if self._db is None:
            path = self.root / RECORD
            if LOCAL.is_file(path) and not os.access(self.root, os.W_OK):  # a read-only lake
                db = sqlite3.connect(
                    f"{path.resolve().as_uri()}?mode=ro",
                    uri=True,
                    timeout=BUSY_TIMEOUT_MS / 1000,
                    isolation_level=None,
                    check_same_thread=False,
                )
            else:
                LOCAL.make_dirs(self.root)
                db = sqlite3.connect(
                    path, timeout=BUSY_TIMEOUT_MS / 1000, isolation_level=None, check_same_thread=False
                )
            db.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
            if not _created(db):
                with _transaction(db, immediate=True):
                    for statement in _SCHEMA.split(";")[:-1]:
                        db.execute(statement)
                    if db.execute("SELECT count(*) FROM commits").fetchone()[0] == 0:
                        if not _migrate(db, self.root):
                            db.execute(_PATH_INDEX)
                            db.execute(f"PRAGMA user_version = {LAYOUT}")
            self._db = db
        return self._db

    def close(self) -> None:
        if self._db is not None:
            self._db.close()
            self._db = None

    def layout(self) -> int:
        """The branch's layout: 2, or 1 for a branch written with `job_id=<J>/` directories."""
        return LAYOUT if self._connect().execute("PRAGMA user_version").fetchone()[0] >= LAYOUT else 1

    def generation(self) -> int:
        """The id of the last commit (changes whenever any table of the branch changes)."""
        return self._connect().execute("SELECT max(commit_id) FROM commits").fetchone()[0]

    def snapshot(self, batch_id: str | None = None, job_id: str | None = None, *, files: bool = True) -> Snapshot:
        """The branch's files, read in one transaction (none for a branch without a directory):
        every file, or with `batch_id` and/or `job_id` only the files a query of that scope reads
        (the job's files and its batch's batch-level files; found by index, the branch is not read);
        `files=False`: only the generation and the tables, no file."""
        if not LOCAL.is_dir(self.root):
            return Snapshot(0, ())
        where, args = _scope_condition(batch_id, job_id)
        db = self._connect()
        with _transaction(db):
            generation = db.execute("SELECT max(commit_id) FROM commits").fetchone()[0]
            rows = (
                db.execute(
                    "SELECT table_name, batch_id, job_id, path, rows, min_ts, max_ts, columns FROM files "
                    f"{where} ORDER BY table_name, batch_id, job_id",
                    args,
                ).fetchall()
                if files
                else []
            )
            tables = frozenset(row[0] for row in db.execute(_TABLES) if row[0] is not None)
        entries = tuple(_entry(row) for row in rows)
        shared = frozenset(e.path for e in entries if e.job_id) if job_id is not None else frozenset()
        return Snapshot(generation, entries, tables, shared)

    def job_versions(self, batch_id: str) -> dict[str, int]:
        """Each job of the batch and its version: the last commit that wrote any of its tables
        (`metric_results` aside), which a re-ingest (or a compaction) changes."""
        if not LOCAL.is_dir(self.root):
            return {}
        db = self._connect()
        with _transaction(db):
            return dict(db.execute(_VERSIONS, (batch_id, paths.METRIC_RESULTS_TABLE)).fetchall())

    def batches(self) -> list[str]:
        """The batches with at least one job (a `metadata` row), sorted (read from the index alone)."""
        if not LOCAL.is_dir(self.root):
            return []
        return [
            row[0]
            for row in self._connect().execute(
                "SELECT DISTINCT batch_id FROM files WHERE table_name = ? ORDER BY batch_id", (paths.METADATA_TABLE,)
            )
        ]

    def find(self, table: str, batch_id: str, job_id: str = "") -> FileEntry | None:
        """The file of one table's job (or batch), if any."""
        if not LOCAL.is_dir(self.root):
            return None
        row = (
            self._connect()
            .execute(
                "SELECT table_name, batch_id, job_id, path, rows, min_ts, max_ts, columns FROM files "
                "WHERE table_name = ? AND batch_id = ? AND job_id = ?",
                (table, batch_id, job_id),
            )
            .fetchone()
        )
        return None if row is None else _entry(row)

    def logs(self, batch_id: str, job_id: str) -> str | None:
        """The folder of the job's logs (relative to the branch directory), if a commit recorded one."""
        if not LOCAL.is_dir(self.root):
            return None
        try:
            row = (
                self._connect()
                .execute("SELECT path FROM logs WHERE batch_id = ? AND job_id = ?", (batch_id, job_id))
                .fetchone()
            )
        except sqlite3.OperationalError:  # a record no commit has written logs to
            return None
        return None if row is None else row[0]

    def commit(
        self,
        what: str,
        entries: Sequence[FileEntry],
        drop_jobs: Iterable[tuple[str, str]] = (),
        *,
        layout: int | None = None,
        logs: Sequence[tuple[str, str, str]] = (),
        expect: JobVersions | None = None,
    ) -> list[str]:
        """One transaction: drop every table's rows of `drop_jobs` (batch, job), replace the rows of
        `entries`' keys by them, record each job's logs folder of `logs` (batch, job, path), add a
        commit (and set the branch's `layout`); returns the paths no row references any more.
        `expect`: the commit is made only if the batch's jobs still have those versions (else
        StaleJobsError, nothing changed), and the versions this commit gives its jobs go into it."""
        db = self._connect()
        with _transaction(db, immediate=True):
            if expect is not None:
                now = dict(db.execute(_VERSIONS, (expect.batch_id, paths.METRIC_RESULTS_TABLE)).fetchall())
                changed = sorted(set(now) ^ set(expect.versions) | {j for j in now if now[j] != expect.versions.get(j)})
                if changed:
                    raise StaleJobsError(expect.batch_id, changed)
            if logs:
                db.execute(_LOGS_TABLE)
            for batch_id, job_id, path in logs:
                db.execute("INSERT OR REPLACE INTO logs VALUES (?, ?, ?)", (batch_id, job_id, path))
            if layout is not None:
                db.execute(_PATH_INDEX)
                db.execute(f"PRAGMA user_version = {layout}")
            old: set[str] = set()
            for batch_id, job_id in drop_jobs:
                old.update(
                    r[0]
                    for r in db.execute("SELECT path FROM files WHERE batch_id = ? AND job_id = ?", (batch_id, job_id))
                )
                db.execute("DELETE FROM files WHERE batch_id = ? AND job_id = ?", (batch_id, job_id))
            commit_id = db.execute("INSERT INTO commits (what) VALUES (?)", (what,)).lastrowid
            for entry in entries:
                old.update(
                    r[0]
                    for r in db.execute(
                        "SELECT path FROM files WHERE table_name = ? AND batch_id = ? AND job_id = ?", entry.key
                    )
                )
                db.execute(
                    "INSERT OR REPLACE INTO files VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (
                        *entry.key,
                        entry.path,
                        entry.rows,
                        entry.min_ts,
                        entry.max_ts,
                        json.dumps(entry.columns),
                        commit_id,
                    ),
                )
            superseded = sorted(
                path
                for path in old - {entry.path for entry in entries}
                if db.execute("SELECT 1 FROM files WHERE path = ? LIMIT 1", (path,)).fetchone() is None
            )
            db.executemany(
                "INSERT OR REPLACE INTO trash VALUES (?, ?)", [(_hidden(path), time.time()) for path in superseded]
            )
            if expect is not None:
                for entry in entries:
                    if entry.batch_id == expect.batch_id and entry.job_id in expect.versions:
                        expect.versions[entry.job_id] = commit_id
        return superseded

    def expired(self, grace: float) -> list[str]:
        """Take the hidden links superseded more than `grace` seconds ago off the trash list."""
        db = self._connect()
        with _transaction(db, immediate=True):
            limit = time.time() - grace
            found = [r[0] for r in db.execute("SELECT path FROM trash WHERE superseded_at < ?", (limit,))]
            db.execute("DELETE FROM trash WHERE superseded_at < ?", (limit,))
        return found

    def trashed(self) -> set[str]:
        """The hidden links still in their grace period."""
        return {r[0] for r in self._connect().execute("SELECT path FROM trash")}

    def referenced(self, batch_id: str) -> set[str]:
        """The paths the record holds for one batch (its jobs' and its own)."""
        return {r[0] for r in self._connect().execute("SELECT path FROM files WHERE batch_id = ?", (batch_id,))}


def current_file(lake: Path, branch: str, table: str, batch_id: str, job_id: str = "") -> Path | None:
    """The file that holds `table`'s rows of one job (job_id '': of one batch) now, if any."""
    record = Record(lake, branch)
    try:
        entry = record.find(table, batch_id, job_id)
    finally:
        record.close()
    return None if entry is None else record.root / entry.path


def job_logs_dir(lake: Path, branch: str, batch_id: str, job_id: str) -> Path:
    """Where the job's log files are: the folder its last ingest recorded, else `<branch>/_logs/<B>/<J>/`
    (logs copied there by hand, or by a lakegate that did not record them); it may not exist."""
    record = Record(lake, branch)
    try:
        folder = record.logs(batch_id, job_id)
    finally:
        record.close()
    return record.root / folder if folder is not None else paths.logs_dir(lake, branch, batch_id, job_id)


class Change:
    """Files staged for one atomic switch of a branch's record (see the module docstring).

    `add` moves a finished file into its partition under a fresh name (`add_merged`: one file for
    many jobs); `commit` switches the record to them in one transaction and removes what they
    supersede. It takes the `paths.batch_files_lock` of every batch whose job tables it changes
    (unless `hold` holds them), migrates a layout v1 branch first, and rewrites each file shared with
    jobs it does not replace without the jobs it replaces. Writers of the same job must hold its
    `paths.job_lock` around `commit` (batch tables: the batch's lock).
    """

    def __init__(self, lake: Path, branch: str, *, progress: bool = False):
        self.lake, self.branch = Path(lake), branch
        self.record = Record(lake, branch)
        self.entries: list[FileEntry] = []
        self.dropped: list[tuple[str, str]] = []
        self.progress = progress
        self._moved: list[FileEntry] = []  # other jobs' rows, moved out of files this change splits
        self._holding = False
        self.logs: list[tuple[str, str, str]] = []  # (batch, job, folder relative to the branch directory)

    def add(self, table: str, batch_id: str, job_id: str | None, staged: Path) -> FileEntry:
        """Publish `staged` as the file of `table` for one job (job_id None: for one batch)."""
        target = paths.new_data_file(self.lake, self.branch, table, batch_id, job_id)
        paths.publish_linked(staged, target)
        entry = describe_file(self.record.root, table, batch_id, job_id or "", target)
        self.entries.append(entry)
        _pause("added")
        return entry

    def add_jobs(self, table: str, batch_id: str, staged: Path, job_ids: Sequence[str]) -> list[FileEntry]:
        """Publish `staged`, which holds one row of each job of `job_ids` (a `metadata` file of many
        jobs, sorted by job), as their file."""
        target = paths.new_data_file(self.lake, self.branch, table, batch_id, None)
        paths.publish_linked(staged, target)
        described = describe_file(self.record.root, table, batch_id, "", target)
        found = [dataclasses.replace(described, job_id=job_id, rows=1) for job_id in job_ids]
        self.entries.extend(found)
        _pause("added")
        return found

    def add_merged(self, entries: Sequence[FileEntry]) -> list[FileEntry]:
        """Publish the rows of `entries` (current files of jobs of one table and batch) as one file per
        distinct schema, sorted by job, and stage their rows naming it; returns them. A job whose file
        cannot be read is left out (it keeps its file)."""
        found = self._merge(entries)
        self.entries.extend(found)
        return found

    def _merge(self, entries: Sequence[FileEntry]) -> list[FileEntry]:
        root = self.record.root
        groups: list[tuple[pa.Schema, list[tuple[FileEntry, pa.Table]]]] = []
        by_path: dict[str, list[FileEntry]] = {}
        for entry in entries:
            by_path.setdefault(entry.path, []).append(entry)
        for path, shared in by_path.items():  # each file read once, however many of its jobs are kept
            try:
                jobs = batch_files.jobs_rows(
                    root / path,
                    [entry.job_id for entry in shared],
                    v1=paths.is_v1_path(path),
                    position=batch_files.job_id_position(shared[0].table, shared[0].columns),
                )
            except (OSError, pa.ArrowException):
                continue
            for entry in shared:
                rows = jobs[entry.job_id]
                schema = rows.schema.remove_metadata()
                group = next((g for s, g in groups if s.equals(schema)), None)
                if group is None:
                    groups.append((schema, group := []))
                group.append((entry, rows))
        merged = []
        for schema, group in groups:
            first = group[0][0]
            target = paths.new_data_file(self.lake, self.branch, first.table, first.batch_id, None)
            with paths.staging(self.lake, self.branch) as scratch:
                staged = scratch / "merged.parquet"
                batch_files.write_jobs(staged, [(entry.job_id, rows) for entry, rows in group])
                paths.publish_linked(staged, target)
            relative = target.relative_to(root).as_posix()
            merged += [dataclasses.replace(e, path=relative, columns=tuple(schema.names)) for e, _ in group]
        _pause("added")
        return merged

    def set_logs(self, batch_id: str, job_id: str, staged: Path) -> Path:
        """Move the staged folder `staged` (a copy of the job's logs) to a fresh folder of the lake, to be
        the job's logs from this change's commit on; the folder it replaces is removed after the commit.
        Writers of the job must hold its `paths.job_lock`."""
        target = paths.new_logs_dir(self.lake, self.branch, batch_id, job_id)
        current = self.record.logs(batch_id, job_id)
        for folder in paths.abandoned_logs(self.lake, self.branch, batch_id, job_id):  # of killed writers
            if current is None or folder != self.record.root / current:
                LOCAL.delete_tree(folder)
        LOCAL.make_dirs(target.parent)
        LOCAL.move(staged, target)
        self.logs.append((batch_id, job_id, target.relative_to(self.record.root).as_posix()))
        return target

    def replace_job(self, batch_id: str, job_id: str) -> None:
        """Drop every table's file of this job that `add` does not replace."""
        self.dropped.append((batch_id, job_id))

    def _batches(self) -> list[str]:
        """The batches whose job tables this change replaces rows of."""
        found = {e.batch_id for e in self.entries if e.table not in paths.BATCH_TABLES}
        return sorted(found | {batch_id for batch_id, _ in self.dropped})

    @contextlib.contextmanager
    def hold(self, batch_ids: Iterable[str]) -> Iterator[None]:
        """Hold the files locks of `batch_ids` (in order) and migrate a layout v1 branch: a caller that
        reads the batches' current files before adding (compaction) sees them unchanged until `commit`."""
        with paths.batch_files_lock(self.lake, self.branch, *batch_ids):
            self._upgrade()
            self._holding = True
            try:
                yield
            finally:
                self._holding = False

    def commit(self, what: str, expect: JobVersions | None = None) -> list[Path]:
        """Switch the record; returns the published files (`expect`: as `Record.commit`)."""
        _pause("commit")
        try:
            if self._holding:
                return self._switch(what, expect=expect)
            with self.hold(self._batches()):
                return self._switch(what, expect=expect)
        finally:
            self.record.close()

    def _switch(self, what: str, layout: int | None = None, expect: JobVersions | None = None) -> list[Path]:
        replaced_logs = [self.record.logs(batch_id, job_id) for batch_id, job_id, _ in self.logs]
        try:
            self._split()
            superseded = self.record.commit(
                what, self.entries + self._moved, self.dropped, layout=layout, logs=self.logs, expect=expect
            )
        except BaseException:
            for entry in {e.path: e for e in self._moved}.values():  # files split for this commit
                paths.remove_published(self.record.root / entry.path)
                paths.remove_published(paths.reader_path(self.record.root, entry.path))
            for _, _, folder in self.logs:  # logs moved in for this commit
                LOCAL.delete_tree(self.record.root / folder)
            self._moved, self.logs = [], []
            raise
        committed, self.entries, self._moved = self.entries, [], []
        for (batch_id, job_id, _), old in zip(self.logs, replaced_logs):  # the job's earlier logs
            if old is not None:
                LOCAL.delete_tree(self.record.root / old)
            LOCAL.delete_tree(paths.logs_dir(self.lake, self.branch, batch_id, job_id))  # copied by hand
        self.logs = []
        for relative in superseded:  # gone for Trino now; lakegate's queries keep the reader link a while
            paths.remove_published(self.record.root / relative)
        for relative in self.record.expired(GRACE_SECONDS):
            paths.remove_published(self.record.root / relative)
        for batch_id in {e.batch_id for e in committed} | {batch_id for batch_id, _ in self.dropped}:
            self._sweep(batch_id)
        return list(dict.fromkeys(self.record.root / entry.path for entry in committed))

    def _split(self) -> None:
        """Rewrite each shared file that loses some of its jobs to this change for the jobs it keeps."""
        replaced = {entry.key for entry in self.entries}
        dropped = set(self.dropped)
        for batch_id in self._batches():
            by_path: dict[str, list[FileEntry]] = {}
            for entry in self.record.snapshot(batch_id).files:
                if entry.table not in paths.BATCH_TABLES:
                    by_path.setdefault(entry.path, []).append(entry)
            for group in by_path.values():
                kept = [e for e in group if e.key not in replaced and (e.batch_id, e.job_id) not in dropped]
                if kept and len(kept) < len(group):
                    self._moved += self._merge(kept)

    def _upgrade(self) -> None:
        """Migrate a layout v1 branch (`job_id=<J>/` directories) to layout v2 in one commit: each
        batch's files of each table become one file holding its jobs (unreadable files stay)."""
        if self.record.layout() == LAYOUT:
            return
        with paths.layout_lock(self.lake, self.branch):
            if self.record.layout() == LAYOUT:
                return
            migration = Change(self.lake, self.branch)
            groups: dict[tuple[str, str], list[FileEntry]] = {}
            for entry in self.record.snapshot().files:
                if paths.is_v1_path(entry.path):
                    groups.setdefault((entry.table, entry.batch_id), []).append(entry)
            bar = tqdm(groups.values(), desc="migrating to layout v2", unit="file", disable=not self.progress)
            for group in bar:
                migration.add_merged(group)
            try:
                migration._switch("layout v2", layout=LAYOUT)
            finally:
                migration.record.close()
            keep = {entry.path for entry in self.record.snapshot().files}
            for table in paths.table_names(self.lake, self.branch):  # what killed v1 writers left
                for directory in {file.parent for file in paths.v1_data_files(self.lake, self.branch, table)}:
                    for file in paths.abandoned_files(directory):
                        if file.relative_to(self.record.root).as_posix() not in keep:
                            paths.remove_published(file)

    def discard(self) -> None:
        """Remove the files added and not committed (a no-op after `commit`)."""
        for entry in {e.path: e for e in self.entries + self._moved}.values():
            paths.remove_published(self.record.root / entry.path)
            paths.remove_published(paths.reader_path(self.record.root, entry.path))
        for _, _, folder in self.logs:
            LOCAL.delete_tree(self.record.root / folder)
        self.entries, self._moved, self.logs = [], [], []
        self.record.close()

    def _sweep(self, batch_id: str) -> None:
        """Remove files of one batch that no row references and no living writer is about to commit."""
        referenced = self.record.referenced(batch_id)
        keep = referenced | {_hidden(path) for path in referenced} | self.record.trashed()
        root = self.record.root
        for table in paths.table_names(self.lake, self.branch):
            directory = paths.partition_dir(self.lake, self.branch, table, batch_id)
            links = root / paths.READERS / directory.relative_to(root)
            for file in paths.abandoned_files(directory) + paths.abandoned_files(links):
                if file.relative_to(root).as_posix() not in keep:
                    paths.remove_published(file)


def _pause(point: str) -> None:
    where, _, marker = os.environ.get(PAUSE_ENV, "").partition(":")
    if where == point:
        Path(marker).touch()
        end = time.monotonic() + 60
        while Path(marker).exists() and time.monotonic() < end:  # removing the marker lets it go on
            time.sleep(0.02)


@contextlib.contextmanager
def _transaction(db: sqlite3.Connection, *, immediate: bool = False) -> Iterator[None]:
    """A transaction of the record; a full disk (SQLite's "database or disk is full", after which
    SQLite has rolled back already) is OSError ENOSPC, as for any other file of the lake."""
    try:
        db.execute("BEGIN IMMEDIATE" if immediate else "BEGIN")
        try:
            yield
        except BaseException:
            if db.in_transaction:
                db.execute("ROLLBACK")
            raise
        db.execute("COMMIT")
    except sqlite3.OperationalError as error:
        if db.in_transaction:
            db.execute("ROLLBACK")
        if "full" in str(error):
            raise OSError(errno.ENOSPC, f"No space left on device (the lake's file record, {RECORD})") from None
        raise


#: The distinct tables of `files`, one index seek per table (not a scan of every file).
_TABLES = """WITH RECURSIVE t(name) AS (SELECT min(table_name) FROM files
    UNION ALL SELECT (SELECT min(table_name) FROM files WHERE table_name > name) FROM t WHERE name IS NOT NULL)
    SELECT name FROM t"""


def _scope_condition(batch_id: str | None, job_id: str | None) -> tuple[str, tuple[str, ...]]:
    """The WHERE clause (and its arguments) of the files a query of one scope reads: batch-level
    files (job_id '') belong to every job of their batch."""
    if batch_id is not None and job_id is not None:
        return "WHERE batch_id = ? AND job_id IN (?, '')", (batch_id, job_id)
    if batch_id is not None:
        return "WHERE batch_id = ?", (batch_id,)
    if job_id is not None:
        return "WHERE job_id IN (?, '')", (job_id,)
    return "", ()


def _hidden(relative: str) -> str:
    return f"{paths.READERS}/{relative}"


def _entry(row: tuple) -> FileEntry:
    table, batch_id, job_id, path, rows, low, high, columns = row
    return FileEntry(table, batch_id, job_id, path, rows, low, high, _columns(columns))


@functools.lru_cache(maxsize=1024)
def _columns(text: str) -> tuple[str, ...]:
    """The columns of a `files` row (a table's files mostly share one list: decoded once)."""
    return tuple(json.loads(text))


def _created(db: sqlite3.Connection) -> bool:
    """Whether the record has its tables and first commit (read only: nothing to write then)."""
    if db.execute("SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = 'commits'").fetchone()[0] == 0:
        return False
    return db.execute("SELECT count(*) FROM commits").fetchone()[0] > 0


def _migrate(db: sqlite3.Connection, root: Path) -> bool:
    """Record the files of a lake written before the record existed (one listing of the branch, in
    layout v1); returns whether there were any (the branch is then in layout v1)."""
    lake, branch = root.parent, paths.decode_branch(root.name)
    db.execute("INSERT INTO commits (what) VALUES ('create')")
    found = False
    for table in paths.table_names(lake, branch):
        batch_table = table in paths.BATCH_TABLES
        files = paths.data_files(lake, branch, table) if batch_table else paths.v1_data_files(lake, branch, table)
        for file in files:
            found = True
            batch_id = paths.partition_value(file.parent if batch_table else file.parent.parent, "batch_id")
            job_id = "" if batch_table else paths.partition_value(file.parent, "job_id")
            paths.link_reader(file)
            try:
                entry = describe_file(root, table, batch_id, job_id, file)
            except (OSError, ValueError):  # unreadable: recorded, so a query of it says which file
                entry = FileEntry(table, batch_id, job_id, file.relative_to(root).as_posix(), 0)
            db.execute(
                "INSERT OR REPLACE INTO files VALUES (?, ?, ?, ?, ?, ?, ?, ?, 1)",
                (*entry.key, entry.path, entry.rows, entry.min_ts, entry.max_ts, json.dumps(entry.columns)),
            )
    return found
