"""The lake's one filesystem layer: the lake's files are read, written, listed, moved and deleted
through a `LakeStorage`, over `pyarrow.fs` (local disk, or any file system pyarrow knows by URI:
`s3://`, `gs://`, `hdfs://`, `mock://`). What does not go through it, and why, is in
docs/lake-format.md, "Filesystem layer"; tests/test_architecture.py keeps the list.

A storage is made from the lake's location, a local path or a URI. Its methods take paths of
that file system, as `pyarrow.fs` does: local paths (str or Path) on a local lake, `bucket/key`
paths on an object store; `root` is the lake's own. Hard links (the reader links), `flock` locks
and symbolic links exist only on a local file system: the other file systems refuse them with
`LocalOnlyError`. So does `local_path`, for what needs a path of this machine: the file record
(`_lake.sqlite`) is a SQLite database, which needs a local POSIX file system.
"""

from __future__ import annotations

import contextlib
import errno
import fnmatch
import functools
import io
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, TypeVar

import pyarrow as pa
import pyarrow.fs as pafs
import pyarrow.parquet as pq

try:
    import fcntl
except ImportError:  # pragma: no cover - not on POSIX
    fcntl = None  # type: ignore[assignment]

StoragePath = str | os.PathLike
T = TypeVar("T")


class _ParquetWriter(pq.ParquetWriter):
    """pyarrow's ParquetWriter, closed once even when closing fails (a full disk): the caller gets
    the error, and the garbage collector never tries again (no "Exception ignored" traceback)."""

    def close(self) -> None:
        try:
            super().close()
        finally:
            self.is_open = False

    def __del__(self) -> None:
        with contextlib.suppress(OSError):
            super().__del__()


class LocalOnlyError(OSError):
    """A capability the lake's file system lacks because it is not local (one line, no traceback:
    the CLI prints OSErrors as their message)."""

    def __init__(self, capability: str, location: str):
        super().__init__(
            errno.ENOTSUP,
            f"object-store lakes are not supported yet: {capability} needs a local file system "
            f"(the lake is at {location})",
        )


@dataclass(frozen=True)
class ListingEntry:
    """One file or directory of a listing."""

    path: str  # the path in the storage's file system
    name: str
    is_dir: bool
    size: int | None  # bytes, None for a directory
    mtime_ns: int | None


def _plain_errors(method: Callable[..., T]) -> Callable[..., T]:
    """Raise pyarrow's OSErrors as Python's own, `<reason>: '<path>'` (the path is the method's
    first), which the CLI prints in one line like every other file error."""

    @functools.wraps(method)
    def wrapper(self: LakeStorage, *args: Any, **options: Any) -> T:
        try:
            return method(self, *args, **options)
        except OSError as error:
            if error.errno is None or error.filename is not None or isinstance(error, LocalOnlyError):
                raise
            path = next(_text(arg) for arg in args if isinstance(arg, str | os.PathLike))
            raise type(error)(error.errno, os.strerror(error.errno), path) from None

    return wrapper


class LakeStorage:
    """The file system a lake lives on, and the lake's root in it."""

    def __init__(self, location: StoragePath, filesystem: pafs.FileSystem | None = None):
        """`location`: a local path or a URI (`file:///srv/lake`, `s3://bucket/lake`). With
        `filesystem`, `location` is the root's path in that file system instead."""
        text = os.fspath(location)
        if filesystem is not None:
            self.filesystem, self.root = filesystem, text.rstrip("/")
        elif "://" in text:
            self.filesystem, self.root = pafs.FileSystem.from_uri(text)
        else:
            self.filesystem, self.root = pafs.LocalFileSystem(), str(Path(text).absolute())
        self.location = text

    def __repr__(self) -> str:
        return f"LakeStorage({self.location!r})"

    @property
    def is_local(self) -> bool:
        """Whether the lake's paths are paths of this machine's file system."""
        return isinstance(self.filesystem, pafs.LocalFileSystem)

    def path(self, *parts: str) -> str:
        """The path of `root/part/...` in the storage's file system."""
        return str(PurePosixPath(self.root, *parts)) if self.root else "/".join(parts)

    # -- reading and writing ----------------------------------------------------------------

    @_plain_errors
    def read_bytes(self, path: StoragePath) -> bytes:
        with self.filesystem.open_input_stream(_text(path)) as stream:
            return stream.read()

    def read_text(self, path: StoragePath) -> str:
        return self.read_bytes(path).decode("utf-8")

    @_plain_errors
    def read_head(self, path: StoragePath, size: int) -> bytes:
        """The first `size` bytes of a file (fewer if it is shorter)."""
        with self.filesystem.open_input_stream(_text(path)) as stream:
            return stream.read(size)

    @_plain_errors
    def write_bytes(self, path: StoragePath, data: bytes) -> None:
        """Write a whole file (its directory is made if missing). Not atomic: write under a
        fresh name and `move` it into place when readers may be looking."""
        self.make_dirs(_parent(path))
        with self.filesystem.open_output_stream(_text(path)) as stream:
            stream.write(data)

    def write_text(self, path: StoragePath, text: str) -> None:
        self.write_bytes(path, text.encode("utf-8"))

    @_plain_errors
    def read_parquet(self, path: StoragePath, **options: Any) -> pa.Table:
        return pq.read_table(_text(path), filesystem=self.filesystem, **options)

    @_plain_errors
    def parquet_file(self, path: StoragePath, **options: Any) -> pq.ParquetFile:
        """A Parquet file open for reading (its schema, metadata, row groups); `options` as
        pyarrow's ParquetFile takes them."""
        return pq.ParquetFile(self.filesystem.open_input_file(_text(path)), **options)

    def damage(self, path: StoragePath) -> str | None:
        """Why a Parquet file cannot be read whole, or None: its footer, and every page of every
        column (against the page's CRC checksum, which lakegate's writers store; an older file's
        pages are checked by decoding them). Reads the whole file, a row group at a time."""
        try:
            parquet = self.parquet_file(path, page_checksum_verification=True)
        except FileNotFoundError:
            return "the file is missing"
        except (OSError, pa.ArrowException):
            return "the file is corrupt or not Parquet"
        try:
            for group in range(parquet.num_row_groups):
                parquet.read_row_group(group)
        except (OSError, pa.ArrowException) as error:
            if "checksum" in str(error).lower():
                return "the file is corrupt: a page fails its checksum"
            return "the file is corrupt: a page cannot be decoded"
        return None

    @_plain_errors
    def write_parquet(self, table: pa.Table, path: StoragePath, **options: Any) -> None:
        self.make_dirs(_parent(path))
        options.setdefault("write_page_checksum", True)  # so that `damage` finds a corrupt page
        pq.write_table(table, _text(path), filesystem=self.filesystem, **options)

    @_plain_errors
    def parquet_writer(self, path: StoragePath, schema: pa.Schema, **options: Any) -> pq.ParquetWriter:
        """A Parquet file open for writing in parts (`write_table`, then `close`); its directory is
        made if missing. Not atomic, as `write_bytes`."""
        self.make_dirs(_parent(path))
        options.setdefault("write_page_checksum", True)  # so that `damage` finds a corrupt page
        return _ParquetWriter(_text(path), schema, filesystem=self.filesystem, **options)

    @_plain_errors
    def text_writer(self, path: StoragePath) -> io.TextIOWrapper:
        """A UTF-8 text file open for writing in parts (its directory is made if missing); close
        it, or use it as a context manager. Not atomic, as `write_bytes`."""
        self.make_dirs(_parent(path))
        return io.TextIOWrapper(self.filesystem.open_output_stream(_text(path)), encoding="utf-8")

    # -- what is there ------------------------------------------------------------------------

    @_plain_errors
    def stat(self, path: StoragePath) -> ListingEntry:
        """The file or directory at `path`; FileNotFoundError naming it if there is none."""
        info = self.filesystem.get_file_info(_text(path))
        if info.type == pafs.FileType.NotFound:
            raise FileNotFoundError(errno.ENOENT, "No such file or directory", _text(path))
        return _entry(info)

    def exists(self, path: StoragePath) -> bool:
        return self.filesystem.get_file_info(_text(path)).type != pafs.FileType.NotFound

    def is_file(self, path: StoragePath) -> bool:
        return self.filesystem.get_file_info(_text(path)).type == pafs.FileType.File

    def is_dir(self, path: StoragePath) -> bool:
        return self.filesystem.get_file_info(_text(path)).type == pafs.FileType.Directory

    @_plain_errors
    def list(self, directory: StoragePath) -> list[ListingEntry]:
        """The entries of a directory, sorted by name; none for a missing directory."""
        selector = pafs.FileSelector(_text(directory), allow_not_found=True)
        return sorted((_entry(info) for info in self.filesystem.get_file_info(selector)), key=lambda e: e.name)

    def glob(self, directory: StoragePath, pattern: str) -> list[ListingEntry]:
        """The entries matching `pattern` (`fnmatch` per `/`-separated segment, as `Path.glob`
        without `**`) under `directory`, sorted; only directories on the way are listed."""
        found = [ListingEntry(_text(directory), "", True, None, None)]
        segments = pattern.split("/")
        for depth, segment in enumerate(segments):
            last = depth == len(segments) - 1
            found = [
                entry
                for parent in found
                if parent.is_dir
                for entry in self.list(parent.path)
                if fnmatch.fnmatchcase(entry.name, segment) and (last or entry.is_dir)
            ]
        return found

    # -- changing -----------------------------------------------------------------------------

    @_plain_errors
    def make_dirs(self, path: StoragePath) -> None:
        """Make a directory and its parents (nothing if it exists)."""
        self.filesystem.create_dir(_text(path), recursive=True)

    @_plain_errors
    def move(self, source: StoragePath, target: StoragePath) -> None:
        """Move a file or directory to `target`, replacing a file there (a directory there that
        is not empty is an OSError). Atomic on a local file system (a rename), where
        publishing relies on it; object stores copy and delete."""
        self.filesystem.move(_text(source), _text(target))

    @_plain_errors
    def delete(self, path: StoragePath, *, missing_ok: bool = False) -> None:
        """Delete a file (FileNotFoundError if there is none, unless `missing_ok`)."""
        try:
            self.filesystem.delete_file(_text(path))
        except FileNotFoundError:
            if not missing_ok:
                raise

    def delete_tree(self, path: StoragePath) -> None:
        """Delete a directory and everything in it, as far as it goes: scratch clean-up, so errors
        (it is missing, another process removes it at the same time) are ignored."""
        with contextlib.suppress(OSError):
            self.filesystem.delete_dir(_text(path))

    def remove_empty_dir(self, path: StoragePath) -> bool:
        """Remove a directory if it is empty, in one step (a writer may be adding to it); whether
        it was removed. Other file systems have no atomic "remove if empty": they keep it."""
        if not self.is_local:
            return False
        try:
            os.rmdir(_text(path))
        except OSError:
            return False
        return True

    def put(self, source: Path, target: StoragePath) -> None:
        """Copy a local file or directory (a user's files, e.g. a job's logs) into the lake at `target`."""
        files = [source]
        if source.is_dir():
            self.make_dirs(target)
            files = sorted(f for f in source.rglob("*") if f.is_file())
        for file in files:
            destination = f"{_text(target)}/{file.relative_to(source).as_posix()}" if file != source else _text(target)
            self.make_dirs(_parent(destination))
            pafs.copy_files(
                str(file), destination, source_filesystem=pafs.LocalFileSystem(), destination_filesystem=self.filesystem
            )

    # -- only on a local file system ----------------------------------------------------------

    def local_path(self, path: StoragePath, capability: str) -> Path:
        """`path` as a path of this machine, for what only a local file system can do
        (`capability` names it in the LocalOnlyError of any other)."""
        if not self.is_local:
            raise LocalOnlyError(capability, self.location)
        return Path(_text(path))

    def hard_link(self, target: StoragePath, link: StoragePath) -> None:
        """Make `link` a second name of the file `target` (nothing if `link` exists)."""
        link_path = self.local_path(link, "a reader link (a hard link)")
        link_path.parent.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(FileExistsError):
            os.link(_text(target), link_path)

    def symlink(self, link: StoragePath, target: Path) -> None:
        """Make `link` a symbolic link to the local directory `target`."""
        self.local_path(link, "a link to a local folder").symlink_to(target, target_is_directory=True)

    @contextlib.contextmanager
    def lock(self, path: StoragePath) -> Iterator[None]:
        """Hold an exclusive `flock` on the lock file `path` (made if missing) while in the block."""
        lock_path = self.local_path(path, "a lock (flock)")
        lock_path.parent.mkdir(parents=True, exist_ok=True)
        with open(lock_path, "a") as handle:
            if fcntl is not None:
                fcntl.flock(handle, fcntl.LOCK_EX)
            try:
                yield
            finally:
                if fcntl is not None:
                    fcntl.flock(handle, fcntl.LOCK_UN)


#: The storage of local paths given as they are (for code that has a path but no lake yet).
LOCAL = LakeStorage("/")


def _text(path: StoragePath) -> str:
    return os.fspath(path)


def _parent(path: StoragePath) -> str:
    return str(PurePosixPath(_text(path)).parent)


def _entry(info: pafs.FileInfo) -> ListingEntry:
    is_dir = info.type == pafs.FileType.Directory
    return ListingEntry(info.path, info.base_name, is_dir, None if is_dir else info.size, info.mtime_ns)
