"""The lake's filesystem layer: the same operations on a local path, a `file://` URI and file
systems that are not local (pyarrow's `mock://` and a SubTreeFileSystem), which refuse what
needs a local one."""

from __future__ import annotations

import fcntl
import os

import pyarrow as pa
import pyarrow.fs as pafs
import pytest

from lakegate.gateway.cli.command_errors import os_error_text
from lakegate.lake.storage import LakeStorage, LocalOnlyError

KINDS = ["path", "file-uri", "mock", "subtree"]


def storage_of(kind: str, tmp_path) -> LakeStorage:
    lake = tmp_path / "lake"
    if kind == "path":
        return LakeStorage(lake)
    if kind == "file-uri":
        return LakeStorage(lake.as_uri())
    if kind == "mock":
        return LakeStorage("mock:///bucket/lake")
    lake.mkdir()
    return LakeStorage("", pafs.SubTreeFileSystem(str(lake), pafs.LocalFileSystem()))


@pytest.mark.parametrize("kind", KINDS)
def test_files_are_written_read_listed_and_globbed(kind, tmp_path):
    storage = storage_of(kind, tmp_path)
    storage.write_text(storage.path("main", "_configs", "v000001", "manifest.json"), "{}\n")
    table = pa.table({"timestamp": [1, 2, 3]})
    for batch, job in [("b1", "j1"), ("b1", "j2"), ("b2", "j1")]:
        storage.write_parquet(table, storage.path("main", "odom", f"batch_id={batch}", f"job_id={job}", "1-a.parquet"))
    storage.write_bytes(storage.path("main", "odom", "batch_id=b1", "job_id=j1", "notes.txt"), b"not data")

    assert storage.read_text(storage.path("main", "_configs", "v000001", "manifest.json")) == "{}\n"
    assert [e.name for e in storage.list(storage.path("main"))] == ["_configs", "odom"]
    assert all(e.is_dir for e in storage.list(storage.path("main")))
    found = storage.glob(storage.path("main", "odom"), "batch_id=*/job_id=*/*.parquet")
    assert [e.path.split("/odom/")[1] for e in found] == [
        "batch_id=b1/job_id=j1/1-a.parquet",
        "batch_id=b1/job_id=j2/1-a.parquet",
        "batch_id=b2/job_id=j1/1-a.parquet",
    ]
    first = found[0].path
    assert storage.read_parquet(first).equals(table)
    assert storage.parquet_file(first).metadata.num_rows == 3
    assert storage.stat(first).size == found[0].size > 0
    assert storage.read_head(storage.path("main", "odom", "batch_id=b1", "job_id=j1", "notes.txt"), 3) == b"not"
    assert storage.is_file(first) and not storage.is_dir(first) and storage.exists(first)
    assert storage.is_dir(storage.path("main", "odom")) and not storage.is_file(storage.path("main", "odom"))


@pytest.mark.parametrize("kind", KINDS)
def test_parquet_and_text_files_are_written_in_parts(kind, tmp_path):
    storage = storage_of(kind, tmp_path)
    parquet = storage.path("main", "_staging", "1-a", "odom.parquet")
    with storage.parquet_writer(parquet, pa.schema([("timestamp", pa.int64())]), compression="zstd") as writer:
        writer.write_table(pa.table({"timestamp": [1, 2]}))
        writer.write_table(pa.table({"timestamp": [3]}))
    text = storage.path("main", "_staging", "1-a", "quarantine.jsonl")
    with storage.text_writer(text) as lines:
        lines.writelines(["{}\n", "caf\u00e9\n"])

    assert storage.read_parquet(parquet).column("timestamp").to_pylist() == [1, 2, 3]
    assert storage.parquet_file(parquet).metadata.num_row_groups == 2
    assert storage.read_bytes(text) == "{}\ncaf\u00e9\n".encode()


@pytest.mark.parametrize("kind", KINDS)
def test_local_folders_are_put_into_the_lake(kind, tmp_path):
    storage = storage_of(kind, tmp_path)
    logs = tmp_path / "logs"
    (logs / "camera").mkdir(parents=True)
    (logs / "camera" / "a.png").write_bytes(b"\x89PNG")
    (logs / "notes.txt").write_text("hi")
    (tmp_path / "empty").mkdir()
    storage.put(logs, storage.path("main", "_logs", "b1", "j1"))
    storage.put(tmp_path / "empty", storage.path("main", "_logs", "b1", "j2"))
    storage.put(logs / "notes.txt", storage.path("main", "_logs", "b2", "j1", "notes.txt"))
    assert [e.path.split("/_logs/")[1] for e in storage.glob(storage.path("main", "_logs"), "*/*/*")] == [
        "b1/j1/camera",
        "b1/j1/notes.txt",
        "b2/j1/notes.txt",
    ]
    assert storage.read_bytes(storage.path("main", "_logs", "b1", "j1", "camera", "a.png")) == b"\x89PNG"
    assert storage.is_dir(storage.path("main", "_logs", "b1", "j2"))


@pytest.mark.parametrize("kind", KINDS)
def test_missing_files_are_errors_naming_them_and_missing_directories_are_empty(kind, tmp_path):
    storage = storage_of(kind, tmp_path)
    missing = storage.path("main", "odom", "gone.parquet")
    with pytest.raises(FileNotFoundError, match="gone.parquet"):
        storage.read_bytes(missing)
    with pytest.raises(FileNotFoundError) as raised:
        storage.stat(missing)
    assert raised.value.filename == missing
    with pytest.raises(FileNotFoundError, match="gone.parquet"):
        storage.delete(missing)
    storage.delete(missing, missing_ok=True)
    storage.delete_tree(storage.path("main", "nothing"))
    assert storage.list(storage.path("nothing")) == [] and storage.glob(storage.path("nothing"), "*/*") == []
    assert not storage.exists(missing) and not storage.is_file(missing) and not storage.is_dir(missing)


@pytest.mark.parametrize("kind", KINDS)
def test_move_replaces_a_file_and_refuses_a_directory_that_is_not_empty(kind, tmp_path):
    storage = storage_of(kind, tmp_path)
    old, new = storage.path("t", "data.parquet"), storage.path("_staging", "x", "data.parquet")
    storage.write_bytes(old, b"old")
    storage.write_bytes(new, b"new")
    storage.move(new, old)
    assert storage.read_bytes(old) == b"new" and not storage.exists(new)
    storage.write_bytes(storage.path("v1", "manifest.json"), b"{}")
    storage.write_bytes(storage.path("scratch", "manifest.json"), b"{}")
    with pytest.raises(OSError):
        storage.move(storage.path("scratch"), storage.path("v1"))
    storage.delete_tree(storage.path("scratch"))
    assert not storage.exists(storage.path("scratch")) and storage.exists(storage.path("v1", "manifest.json"))


def test_local_file_errors_read_as_python_s_own_naming_the_path(tmp_path):
    storage = LakeStorage(tmp_path)
    storage.write_bytes(tmp_path / "file", b"")
    attempts = {
        "No such file or directory": lambda: storage.read_bytes(tmp_path / "gone.parquet"),
        "Not a directory": lambda: storage.write_bytes(tmp_path / "file" / "x" / "a.parquet", b""),
    }
    for reason, attempt in attempts.items():
        with pytest.raises(OSError) as raised:
            attempt()
        assert os_error_text(raised.value).startswith(f"{reason}: '{tmp_path}/")


def test_a_local_move_is_a_rename_and_empty_directories_are_removed_alone(tmp_path):
    storage = LakeStorage(tmp_path)
    source, target = tmp_path / "_staging" / "a.parquet", tmp_path / "t" / "b=1" / "a.parquet"
    storage.write_bytes(source, b"rows")
    inode = source.stat().st_ino
    storage.make_dirs(target.parent)
    storage.move(source, target)
    assert target.stat().st_ino == inode  # the same file under its new name: readers see all of it or none
    assert not storage.remove_empty_dir(target.parent) and target.exists()
    storage.delete(target)
    assert storage.remove_empty_dir(target.parent) and not target.parent.exists()


def test_a_file_uri_lake_is_the_same_lake_as_its_path(tmp_path):
    by_path, by_uri = LakeStorage(tmp_path / "lake"), LakeStorage((tmp_path / "lake").as_uri())
    assert by_uri.is_local and by_uri.root == by_path.root == str(tmp_path / "lake")
    by_uri.write_text(by_uri.path("main", "x.txt"), "written by URI")
    assert by_path.read_text(by_path.path("main", "x.txt")) == "written by URI"
    assert (tmp_path / "lake" / "main" / "x.txt").read_text() == "written by URI"


def test_hard_links_and_locks_on_a_local_lake(tmp_path):
    storage = LakeStorage(tmp_path)
    storage.write_bytes(tmp_path / "t" / "a.parquet", b"rows")
    link = tmp_path / "_readers" / "t" / "a.parquet"
    storage.hard_link(tmp_path / "t" / "a.parquet", link)
    storage.hard_link(tmp_path / "t" / "a.parquet", link)  # already there: nothing to do
    assert link.stat().st_ino == (tmp_path / "t" / "a.parquet").stat().st_ino
    lock_file = tmp_path / "_staging" / "locks" / "01.lock"
    with storage.lock(lock_file), open(lock_file) as other:
        with pytest.raises(BlockingIOError):
            fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
    with open(lock_file) as other:
        fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)  # released when the block ends


@pytest.mark.parametrize("kind", ["mock", "subtree"])
def test_a_lake_that_is_not_local_refuses_local_only_capabilities_in_one_line(kind, tmp_path):
    storage = storage_of(kind, tmp_path)
    storage.write_bytes(storage.path("t", "a.parquet"), b"rows")
    assert not storage.is_local
    attempts = {
        "a reader link (a hard link)": lambda: storage.hard_link(storage.path("t", "a.parquet"), storage.path("r")),
        "a lock (flock)": lambda: storage.lock(storage.path("01.lock")).__enter__(),
        "a link to a local folder": lambda: storage.symlink(storage.path("logs"), tmp_path),
        "the record": lambda: storage.local_path(storage.path("_lake.sqlite"), "the record"),
    }
    for capability, attempt in attempts.items():
        with pytest.raises(LocalOnlyError) as raised:
            attempt()
        expected = (
            f"object-store lakes are not supported yet: {capability} needs a local file system "
            f"(the lake is at {storage.location})"
        )
        assert os_error_text(raised.value) == expected  # what the CLI prints, without a traceback
    storage.write_bytes(storage.path("t", "b", "c.parquet"), b"rows")
    storage.delete(storage.path("t", "b", "c.parquet"))
    assert not storage.remove_empty_dir(storage.path("t", "b"))  # kept: no atomic "remove if empty" there
    assert os.listdir(tmp_path) in ([], ["lake"])  # nothing escaped to the local disk beside the subtree
