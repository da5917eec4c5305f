"""Where things live in the lake, and how files appear there atomically.

Layout (see docs/lake-format.md)::

    <lake>/<branch-dir>/<table>/batch_id=<B>/<pid>-<id>.parquet       topics, metadata, events, metric_results
    <lake>/<branch-dir>/<table>/batch_id=<B>/job_id=<J>/<name>.parquet   the same, in lakes of layout v1
    <lake>/<branch-dir>/_lake.sqlite                                   which file is current (`lake.record`)
    <lake>/<branch-dir>/_readers/<table>/...                           hard links lakegate's queries read
    <lake>/<branch-dir>/_job_logs/<B>/<J>/<pid>-<id>/...               job log files (images the metrics show),
                                                                       one folder per ingest; the record says which
    <lake>/<branch-dir>/_logs/<B>/<J>/...                              the same, as copied by hand (read when the
                                                                       record names no folder for the job)
    <lake>/<branch-dir>/_configs/v000001/...                           the branch's config versions
    <lake>/<branch-dir>/_quarantine/<B>/<J>.jsonl                      bad lines kept by --skip-bad-lines
    <lake>/<branch-dir>/_staging/...                                   scratch space of running writers

A branch name is encoded into exactly one safe path segment (`encode_branch`), reversibly.
Every table is partitioned by `batch_id` only (layout v2); `job_id` is a column in the files (a
job's own file holds one job, a compacted file every job of its batch). Layout v1 (still read,
migrated by the first writer: `lake.compaction`) had a `job_id=<J>` directory per job.
Batch ids, job ids and table names are used as they are, so they are checked
(`check_segment`): readers glob `<table>/batch_id=*/*.parquet` and parse Hive
partitions, which rules out `/`, glob characters, `=`, `%` (Hive values are URL-decoded)
and `\\`. Writers prepare files under `_staging/`, `publish` each by a rename (`LOCAL.move`) under a
fresh name (`new_data_file`, never overwriting a file a reader may use), and make them current
in the branch's record (`lake.record`); a killed writer leaves only files no record row holds.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import uuid
from collections.abc import Iterator
from pathlib import Path

from lakegate.lake.storage import LOCAL

#: The column of topic and event rows whose min/max the record keeps.
TIMESTAMP_COLUMN = "timestamp"
METADATA_TABLE = "metadata"
EVENTS_TABLE = "events"
#: Evaluated metrics: one file per batch (job_id is a column, NULL for batch metrics).
METRIC_RESULTS_TABLE = "metric_results"
STAGING = "_staging"
CONFIGS = "_configs"
QUARANTINE = "_quarantine"
LOGS = "_logs"
JOB_LOGS = "_job_logs"
READERS = "_readers"
#: Names a topic may not have, because the branch directory uses them.
RESERVED_TABLES = frozenset({METADATA_TABLE, EVENTS_TABLE, METRIC_RESULTS_TABLE})
#: Tables with one file per batch, whose record rows have job_id '' (the others: a row per job).
BATCH_TABLES = frozenset({METRIC_RESULTS_TABLE})
#: The Hive partition keys of every table (layout v2); layout v1 had `V1_KEYS` for job tables.
PARTITION_KEYS = ("batch_id",)
V1_KEYS = ("batch_id", "job_id")

_SAFE = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_.")
_MAX_SEGMENT = 240  # bytes; file systems allow 255
_FORBIDDEN = {
    "/": "'/'",
    "\\": "'\\'",
    "=": "'='",
    "%": "'%'",
    "*": "a glob character '*'",
    "?": "a glob character '?'",
    "[": "a glob character '['",
    "]": "a glob character ']'",
    "{": "a glob character '{'",
    "}": "a glob character '}'",
}


class LakePathError(ValueError):
    """A name that cannot be stored in the lake; the message says which and why."""


def encode_branch(name: str) -> str:
    """The directory name of branch `name`: one path segment, reversible with `decode_branch`.

    Letters, digits, `-`, `_` and `.` are kept (except a leading `.` or `_`); every other
    byte of the UTF-8 text becomes `%XX`. So `feature/x` -> `feature%2Fx`, `..` -> `%2E.`.
    """
    if not isinstance(name, str) or not name:
        raise LakePathError("a branch name must be a non-empty string")
    try:
        data = name.encode("utf-8")
    except UnicodeEncodeError:
        raise LakePathError(f"branch name {name!r} is not valid Unicode text") from None
    parts = []
    for i, byte in enumerate(data):
        char = chr(byte)
        if char in _SAFE and not (i == 0 and char in "._"):
            parts.append(char)
        else:
            parts.append(f"%{byte:02X}")
    segment = "".join(parts)
    if len(segment) > _MAX_SEGMENT:
        raise LakePathError(
            f"branch name {name[:40]!r}... is too long for the lake "
            f"({len(segment)} bytes encoded, at most {_MAX_SEGMENT})"
        )
    return segment


def decode_branch(segment: str) -> str:
    """The branch name of a directory made by `encode_branch`; LakePathError for anything else."""
    data = bytearray()
    i = 0
    while i < len(segment):
        char = segment[i]
        if char == "%" and _is_hex(segment[i + 1 : i + 3]):
            data.append(int(segment[i + 1 : i + 3], 16))
            i += 3
        elif char in _SAFE:
            data.append(ord(char))
            i += 1
        else:
            raise LakePathError(f"{segment!r} is not an encoded branch name")
    try:
        name = data.decode("utf-8")
    except UnicodeDecodeError:
        raise LakePathError(f"{segment!r} is not an encoded branch name") from None
    if not name or encode_branch(name) != segment:
        raise LakePathError(f"{segment!r} is not an encoded branch name")
    return name


def _is_hex(text: str) -> bool:
    return len(text) == 2 and all(c in "0123456789ABCDEF" for c in text)


def check_segment(value: str, what: str) -> str:
    """Return `value` if it can name a directory of the lake as it is, else LakePathError.

    `what` names the value in the message (`batch id`, `job id`, `topic name`).
    """
    if not isinstance(value, str) or not value:
        raise LakePathError(f"{what} must be a non-empty string, got {value!r}")
    if value in (".", ".."):
        raise LakePathError(f"{what} {value!r} is not allowed")
    for char in value:
        if char in _FORBIDDEN:
            raise LakePathError(f"{what} {value!r} contains {_FORBIDDEN[char]}, which the lake's paths cannot hold")
        if ord(char) < 0x20 or ord(char) == 0x7F:
            raise LakePathError(f"{what} {value!r} contains a control character")
    if value == "__HIVE_DEFAULT_PARTITION__":
        raise LakePathError(f"{what} {value!r} is reserved by Hive for NULL")
    if len(value.encode("utf-8", "surrogatepass")) > _MAX_SEGMENT:
        raise LakePathError(f"{what} {value[:40]!r}... is too long (at most {_MAX_SEGMENT} bytes)")
    return value


def check_table_name(name: str) -> str:
    """A topic name that can be a table directory: a safe segment, not reserved, no leading `_`/`.`."""
    check_segment(name, "topic name")
    if name in RESERVED_TABLES:
        raise LakePathError(f"topic name {name!r} is reserved for the lake's own {name!r} table")
    if name[0] in "_.":
        raise LakePathError(f"topic name {name!r} cannot start with {name[0]!r} in the lake")
    return name


def branch_dir(lake: Path, branch: str) -> Path:
    return Path(lake) / encode_branch(branch)


def table_dir(lake: Path, branch: str, table: str) -> Path:
    return branch_dir(lake, branch) / table


def partition_dir(lake: Path, branch: str, table: str, batch_id: str) -> Path:
    """`<lake>/<branch-dir>/<table>/batch_id=<B>` (the batch id checked)."""
    check_segment(batch_id, "batch id")
    return table_dir(lake, branch, table) / f"batch_id={batch_id}"


def new_data_file(lake: Path, branch: str, table: str, batch_id: str, job_id: str | None) -> Path:
    """A fresh file name in `table`'s partition of one batch, for the rows of one job (its id ends
    the name, for humans) or of many (job_id None: a batch table's file, or a compacted file).

    The name starts with the writer's process id, so files of writers that died are recognised.
    """
    suffix = "" if job_id is None else f"-{check_segment(job_id, 'job id')}"
    name = f"{os.getpid()}-{uuid.uuid4().hex}{suffix}"
    if len(name.encode("utf-8", "surrogatepass")) > _MAX_SEGMENT - len(".parquet"):
        name = f"{os.getpid()}-{uuid.uuid4().hex}"
    return partition_dir(lake, branch, table, batch_id) / f"{name}.parquet"


def is_v1_path(relative: str) -> bool:
    """Whether a data file's path (relative to its branch) is in a layout v1 `job_id=` directory."""
    return "/job_id=" in relative


def abandoned_files(directory: Path) -> list[Path]:
    """Parquet files in a partition directory that no living writer is about to publish."""
    files = LOCAL.glob(directory, "*.parquet")
    return [Path(file.path) for file in files if not file.is_dir and not _writer_alive(file.name.split("-", 1)[0])]


def reader_path(branch_root: Path, relative: str) -> Path:
    """The hard link lakegate's readers open for the published file `<branch_root>/<relative>`:
    the same path under `<branch_root>/_readers/`.

    Other readers of the lake (Trino's Hive connector, a DuckDB glob of `<table>/...`) never see
    it; it outlives the visible name for a grace period after a writer supersedes the file, so a
    query that listed it can still read it.
    """
    return Path(reader_file(str(branch_root), relative))


def reader_file(branch_root: str, relative: str) -> str:
    """`reader_path` as text, made without pathlib (views list one per file of the branch)."""
    return f"{branch_root}/{READERS}/{relative}"


def table_names(lake: Path, branch: str) -> list[str]:
    """The table directories of a branch (not `_`/`.` ones), sorted."""
    return [entry.name for entry in LOCAL.list(branch_dir(lake, branch)) if entry.is_dir and entry.name[0] not in "_."]


def partition_keys(table: str) -> tuple[str, ...]:
    """The Hive partition keys of `table`'s directories (every table: `batch_id`)."""
    return PARTITION_KEYS


def _file_pattern(table: str) -> str:
    return "/".join([*(f"{key}=*" for key in partition_keys(table)), "*.parquet"])


def v1_data_files(lake: Path, branch: str, table: str) -> list[Path]:
    """The data files of `table` in layout v1 `batch_id=<B>/job_id=<J>/` directories."""
    return _files(table_dir(lake, branch, table), "batch_id=*/job_id=*/*.parquet")


def table_glob(lake: Path, branch: str, table: str) -> str:
    """The glob that matches every data file of `table` on `branch` (and nothing in `_staging`)."""
    return str(table_dir(lake, branch, table) / _file_pattern(table))


def data_files(lake: Path, branch: str, table: str) -> list[Path]:
    """The data files of `table` on `branch` (those `table_glob` matches), sorted."""
    return _files(table_dir(lake, branch, table), _file_pattern(table))


def _files(directory: Path, pattern: str) -> list[Path]:
    return [Path(entry.path) for entry in LOCAL.glob(directory, pattern) if not entry.is_dir]


def configs_dir(lake: Path, branch: str) -> Path:
    return branch_dir(lake, branch) / CONFIGS


def quarantine_file(lake: Path, branch: str, batch_id: str, job_id: str) -> Path:
    """Where the bad lines of a job ingested with --skip-bad-lines are kept."""
    check_segment(batch_id, "batch id")
    check_segment(job_id, "job id")
    return branch_dir(lake, branch) / QUARANTINE / batch_id / f"{job_id}.jsonl"


def logs_dir(lake: Path, branch: str, batch_id: str, job_id: str) -> Path:
    """Where a job's log files (e.g. the images its metrics show) are kept."""
    check_segment(batch_id, "batch id")
    check_segment(job_id, "job id")
    return branch_dir(lake, branch) / LOGS / batch_id / job_id


def new_logs_dir(lake: Path, branch: str, batch_id: str, job_id: str) -> Path:
    """A fresh folder for one ingest's copy of a job's logs (`<branch-dir>/_job_logs/<B>/<J>/<pid>-<id>`);
    the branch's record makes it the job's logs in the ingest's commit."""
    check_segment(batch_id, "batch id")
    check_segment(job_id, "job id")
    return branch_dir(lake, branch) / JOB_LOGS / batch_id / job_id / f"{os.getpid()}-{uuid.uuid4().hex}"


def abandoned_logs(lake: Path, branch: str, batch_id: str, job_id: str) -> list[Path]:
    """The job's log folders whose writer is gone (current or not: the caller keeps the current one)."""
    parent = branch_dir(lake, branch) / JOB_LOGS / batch_id / job_id
    if not LOCAL.is_dir(parent):
        return []
    return [Path(e.path) for e in LOCAL.list(parent) if e.is_dir and not _writer_alive(e.name.split("-", 1)[0])]


def partition_value(directory: Path, key: str) -> str | None:
    """`B` for a directory named `<key>=B`, else None."""
    prefix = f"{key}="
    return directory.name[len(prefix) :] if directory.name.startswith(prefix) else None


def publish(source: Path, target: Path) -> None:
    """Move a finished file into place atomically (replacing any older version)."""
    LOCAL.make_dirs(target.parent)
    LOCAL.move(source, target)


def publish_linked(source: Path, target: Path) -> None:
    """`publish`, then add the file's reader link (`reader_path`)."""
    publish(source, target)
    link_reader(target)


def link_reader(target: Path) -> None:
    """Add the reader link of a published file (`reader_path`; the branch is its table's parent)."""
    root = target.parents[3] if target.parent.name.startswith("job_id=") else target.parents[2]  # v1, v2
    link = reader_path(root, target.relative_to(root).as_posix())
    LOCAL.hard_link(target, link)


def remove_published(target: Path) -> None:
    """Remove a published data file and the partition directories it leaves empty."""
    LOCAL.delete(target, missing_ok=True)
    for directory in (target.parent, target.parent.parent):
        if "=" not in directory.name:  # a table's own directory stays (Trino's table location)
            break
        if not LOCAL.remove_empty_dir(directory):
            break


@contextlib.contextmanager
def staging(lake: Path, branch: str) -> Iterator[Path]:
    """A fresh scratch directory under `<branch-dir>/_staging/`, removed afterwards.

    Scratch left behind by writers that died (their process is gone) is removed first.
    """
    root = branch_dir(lake, branch) / STAGING
    LOCAL.make_dirs(root)
    _remove_abandoned(root)
    directory = root / f"{os.getpid()}-{uuid.uuid4().hex}"
    LOCAL.make_dirs(directory)
    try:
        yield directory
    finally:
        LOCAL.delete_tree(directory)


def _remove_abandoned(root: Path) -> None:
    for entry in LOCAL.list(root):
        pid_text = entry.name.split("-", 1)[0]
        if entry.is_dir and pid_text.isdigit() and not _writer_alive(pid_text):
            LOCAL.delete_tree(entry.path)


def _writer_alive(pid_text: str) -> bool:
    """Whether the process a file or directory name starts with (`<pid>-...`) still runs."""
    if not pid_text.isdigit():
        return False
    try:
        os.kill(int(pid_text), 0)
    except ProcessLookupError:
        return False
    except OSError:
        pass
    return True


@contextlib.contextmanager
def job_lock(lake: Path, branch: str, batch_id: str, job_id: str) -> Iterator[None]:
    """Hold an exclusive lock on one job, so two writers of the same job take turns.

    Jobs share 64 lock files by hash, so the lock files never pile up (two writers of
    different jobs rarely wait for each other, and never for long).
    """
    check_segment(batch_id, "batch id")
    check_segment(job_id, "job id")
    stripe = hashlib.sha1(f"{batch_id}\0{job_id}".encode()).digest()[0] % 64
    with _locked(lake, branch, f"{stripe:02d}.lock"):
        yield


@contextlib.contextmanager
def batch_lock(lake: Path, branch: str, batch_id: str) -> Iterator[None]:
    """Hold an exclusive lock on one batch's evaluation (`metrics run`), shared by 64 stripes like `job_lock`."""
    check_segment(batch_id, "batch id")
    stripe = hashlib.sha1(batch_id.encode()).digest()[0] % 64
    with _locked(lake, branch, f"batch-{stripe:02d}.lock"):
        yield


@contextlib.contextmanager
def batch_files_lock(lake: Path, branch: str, *batch_ids: str) -> Iterator[None]:
    """Hold the lock every record commit that changes a batch's job-table files takes (ingest, metadata
    updates, metrics run, compaction): files shared by the batch's jobs change under it alone.

    Batches share 64 lock files by hash; several batches' are taken in one order, each file once.
    Lock order: `batch_lock`, then `job_lock`, then this, then `layout_lock`.
    """
    stripes = sorted({hashlib.sha1(check_segment(b, "batch id").encode()).digest()[0] % 64 for b in batch_ids})
    with contextlib.ExitStack() as stack:
        for stripe in stripes:
            stack.enter_context(_locked(lake, branch, f"files-{stripe:02d}.lock"))
        yield


@contextlib.contextmanager
def layout_lock(lake: Path, branch: str) -> Iterator[None]:
    """Hold the branch's layout lock (the migration of a layout v1 branch takes it)."""
    with _locked(lake, branch, "layout.lock"):
        yield


@contextlib.contextmanager
def _locked(lake: Path, branch: str, name: str) -> Iterator[None]:
    with LOCAL.lock(branch_dir(lake, branch) / STAGING / "locks" / name):
        yield
