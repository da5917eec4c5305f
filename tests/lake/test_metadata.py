"""The metadata table: the metadata file, defaults and generated ids, atomic row updates."""

from __future__ import annotations

import datetime as dt
import uuid

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from lakegate.lake import paths
from lakegate.lake.metadata import (
    COLUMN_NAMES,
    FILE_SCHEMA,
    MetadataError,
    build_metadata_row,
    load_metadata_file,
    read_metadata_row,
    read_metadata_rows,
    stage_metadata_rows,
    update_metadata_row,
    write_metadata_row,
)
from lakegate.lake.record import Change, current_file


def row_for(tmp_path, values, **kw):
    return build_metadata_row(values, lake=tmp_path, branch=kw.get("branch", "main"), batch_id="b1", job_id="j1")


def test_defaults_and_generated_ids(tmp_path):
    row = row_for(
        tmp_path,
        {
            "experience_name": "sunny",
            "build_name": "nav",
            "build_version": "1.2",
            "experience_tag_names": ["rain", "night"],
            "test_suite_name": "nightly",
        },
    )
    assert list(row) == list(COLUMN_NAMES)
    assert row["batch_id"] == "b1" and row["job_id"] == "j1"
    assert row["branch_name"] == "main"
    assert row["job_status"] == "SUCCEEDED"
    assert row["job_metrics_status"] is None and row["job_conflated_status"] is None
    assert row["custom_field_keys"] == [] and row["custom_field_values"] == []
    assert row["build_creation_timestamp"] is None and isinstance(row["time"], dt.datetime)
    for column in ("org_id", "project_id", "branch_id", "build_id", "experience_id", "test_suite_id"):
        assert uuid.UUID(row[column])
    assert len(row["experience_tag_ids"]) == 2 and all(uuid.UUID(i) for i in row["experience_tag_ids"])
    # ids derived from names are deterministic: re-ingesting a job keeps them
    again = row_for(
        tmp_path,
        {
            "experience_name": "sunny",
            "build_name": "nav",
            "build_version": "1.2",
            "experience_tag_names": ["night", "rain"],
            "test_suite_name": "nightly",
        },
    )
    for column in ("org_id", "project_id", "branch_id", "build_id", "experience_id", "test_suite_id"):
        assert again[column] == row[column]
    assert again["experience_tag_ids"] == row["experience_tag_ids"][::-1]
    # other names give other ids
    other = row_for(tmp_path, {"experience_name": "rainy", "build_name": "nav", "build_version": "1.3"})
    assert other["experience_id"] != row["experience_id"] and other["build_id"] != row["build_id"]


def test_ids_without_names_are_random(tmp_path):
    first, second = row_for(tmp_path, {}), row_for(tmp_path, {})
    assert first["experience_id"] != second["experience_id"]
    assert first["project_id"] == second["project_id"]  # a lake is one project


def test_failed_job_is_conflated_error_unless_given(tmp_path):
    assert row_for(tmp_path, {"job_status": "FAILED"})["job_conflated_status"] == "ERROR"
    assert (
        row_for(tmp_path, {"job_status": "FAILED", "job_conflated_status": "BLOCKER"})["job_conflated_status"]
        == "BLOCKER"
    )


def test_given_values_win_and_are_checked(tmp_path):
    row = row_for(
        tmp_path,
        {
            "org_id": "resim.ai",
            "experience_id": "e-1",
            "branch_name": "release",
            "time": "2025-01-31T12:00:00.123456+01:00",
            "test_suite_revision": 7,
        },
    )
    assert row["org_id"] == "resim.ai" and row["experience_id"] == "e-1" and row["branch_name"] == "release"
    assert row["time"] == dt.datetime(2025, 1, 31, 11, 0, 0, 123000)  # UTC, milliseconds
    assert row["test_suite_revision"] == 7
    with pytest.raises(
        MetadataError, match="unknown metadata column 'experiance_name'.*did you mean 'experience_name'"
    ):
        row_for(tmp_path, {"experiance_name": "x"})
    with pytest.raises(MetadataError, match="test_suite_revision.*expected an integer"):
        row_for(tmp_path, {"test_suite_revision": "7"})
    with pytest.raises(MetadataError, match="parallel"):
        row_for(tmp_path, {"custom_field_keys": ["a", "b"], "custom_field_values": ["1"]})
    with pytest.raises(MetadataError, match="batch_id 'other'"):
        row_for(tmp_path, {"batch_id": "other"})


def test_metadata_file(tmp_path):
    path = tmp_path / "job.yaml"
    path.write_text(
        "experience_name: Sunny day\n"
        "build_version: 1.10\n"  # a YAML float: kept as written
        "experience_tag_names: [my_tag, my_prefix_a]\n"
        "build_creation_timestamp: 2025-01-02 03:04:05\n"
        "time: '2025-01-02T03:04:05.678Z'\n"
        "test_suite_revision: 3\n"
        "custom_field_keys: [robot]\n"
        "custom_field_values: [r2]\n"
        "job_metrics_status: ~\n"
    )
    values = load_metadata_file(path)
    assert values == {
        "experience_name": "Sunny day",
        "build_version": "1.10",
        "experience_tag_names": ["my_tag", "my_prefix_a"],
        "build_creation_timestamp": dt.datetime(2025, 1, 2, 3, 4, 5),
        "time": dt.datetime(2025, 1, 2, 3, 4, 5, 678000),
        "test_suite_revision": 3,
        "custom_field_keys": ["robot"],
        "custom_field_values": ["r2"],
        "job_metrics_status": None,
    }
    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing\n")
    assert load_metadata_file(empty) == {}


@pytest.mark.parametrize(
    "text, expected",
    [
        (
            "experiance_name: x\n",
            "job.yaml:1:1: unknown metadata column 'experiance_name' (did you mean 'experience_name'?)",
        ),
        ("experience_name: x\nbuild_name: [a]\n", "job.yaml:2:13: build_name: expected a single value, got a list"),
        ("test_suite_revision: three\n", "job.yaml:1:22: test_suite_revision: expected an integer, got string 'three'"),
        (
            "time: yesterday\n",
            "job.yaml:1:7: time: expected an ISO 8601 timestamp like 2025-01-31T12:00:00Z, got 'yesterday'",
        ),
        (
            "experience_tag_names: rain\n",
            "job.yaml:1:23: experience_tag_names: expected a list of strings, got string 'rain'",
        ),
        ("- a\n- b\n", "job.yaml:1:1: expected a mapping of metadata columns to values, got a list"),
        ("experience_name: a\nexperience_name: b\n", "job.yaml:2:1: duplicate metadata column 'experience_name'"),
        ("experience_name: [\n", "job.yaml:2:1: invalid YAML"),
    ],
)
def test_metadata_file_errors_say_where(tmp_path, text, expected):
    path = tmp_path / "job.yaml"
    path.write_text(text)
    with pytest.raises(MetadataError) as caught:
        load_metadata_file(path)
    assert caught.value.problems[0].startswith(str(tmp_path / expected.split(":")[0]) + ":" + expected.split(":", 1)[1])


def test_every_problem_is_reported(tmp_path):
    path = tmp_path / "job.yaml"
    path.write_text("experiance_name: x\ntest_suite_revision: x\ntime: never\n")
    with pytest.raises(MetadataError) as caught:
        load_metadata_file(path)
    assert [p.split(":")[1] for p in caught.value.problems] == ["1", "2", "3"]


def test_write_read_and_update_a_row_atomically(tmp_path):
    row = row_for(tmp_path, {"experience_name": "sunny", "experience_tag_names": ["a"]})
    target = write_metadata_row(tmp_path, "main", "b1", "j1", row)
    assert target == current_file(tmp_path, "main", "metadata", "b1", "j1")
    assert read_metadata_row(tmp_path, "main", "b1", "j1") == row
    updated = update_metadata_row(
        tmp_path, "main", "b1", "j1", job_metrics_status="PASSED", job_conflated_status="PASSED"
    )
    assert updated["job_metrics_status"] == "PASSED" and updated["experience_name"] == "sunny"
    con = duckdb.connect()
    glob = paths.table_glob(tmp_path, "main", "metadata")
    got = con.execute(
        f"SELECT job_id, job_conflated_status, typeof(experience_tag_names) "
        f"FROM read_parquet('{glob}', hive_partitioning = true)"
    ).fetchall()
    assert got == [("j1", "PASSED", "VARCHAR[]")]
    assert not target.exists()  # superseded by the update
    stored = pq.read_schema(current_file(tmp_path, "main", "metadata", "b1", "j1"))
    assert stored.field("time").type == pa.timestamp("ms")  # Trino's Hive connector reads timestamp(3)
    assert "batch_id" not in FILE_SCHEMA.names and FILE_SCHEMA.names[1] == "job_id"  # a file may hold many jobs
    assert [p.name for p in (paths.branch_dir(tmp_path, "main") / paths.STAGING).iterdir()] == ["locks"]
    with pytest.raises(MetadataError, match="lacks column"):
        write_metadata_row(tmp_path, "main", "b1", "j1", {"experience_name": "x"})
    with pytest.raises(MetadataError, match="job_id 'j2'"):
        write_metadata_row(tmp_path, "main", "b1", "j1", {**row, "job_id": "j2"})
    with pytest.raises(FileNotFoundError):
        update_metadata_row(tmp_path, "main", "b1", "nope", job_metrics_status="PASSED")


def test_a_row_written_before_a_column_existed_reads_it_as_null_and_updates(tmp_path):
    """A lake from an earlier lakegate (metadata files without run_counter and project_id): reading and
    updating a row work, and the missing columns read NULL, as they do through SQL."""
    row = row_for(tmp_path, {"experience_name": "sunny"})
    target = write_metadata_row(tmp_path, "main", "b1", "j1", row)
    old = pq.read_table(target).drop_columns(["run_counter", "project_id"])
    pq.write_table(old, target)
    read = read_metadata_row(tmp_path, "main", "b1", "j1")
    assert read["run_counter"] is None and read["project_id"] is None
    assert read["experience_name"] == "sunny"
    updated = update_metadata_row(tmp_path, "main", "b1", "j1", job_metrics_status="PASSED")
    assert updated["job_metrics_status"] == "PASSED" and updated["run_counter"] is None


def test_rows_of_many_jobs_are_read_at_once_from_one_file_or_their_own(tmp_path):
    """`read_metadata_rows` reads each file once: three jobs written as one file of the batch (as a
    metrics run stages their statuses) and one job in its own file read as `read_metadata_row` reads
    each; a job without a row is left out."""
    rows = {
        job: build_metadata_row(
            {"experience_name": f"exp {job}"}, lake=tmp_path, branch="main", batch_id="b1", job_id=job
        )
        for job in ("j1", "j2", "j3", "j4")
    }
    change = Change(tmp_path, "main")
    with paths.staging(tmp_path, "main") as scratch:
        stage_metadata_rows(change, scratch, "b1", {job: rows[job] for job in ("j3", "j1", "j2")})
    change.commit("three jobs")
    write_metadata_row(tmp_path, "main", "b1", "j4", rows["j4"])
    read = read_metadata_rows(tmp_path, "main", "b1", ["j4", "j2", "nope", "j1", "j3"])
    assert list(read) == ["j4", "j2", "j1", "j3"] and read == {job: rows[job] for job in read}
    assert read == {job: read_metadata_row(tmp_path, "main", "b1", job) for job in read}
    assert current_file(tmp_path, "main", "metadata", "b1", "j1") == current_file(
        tmp_path, "main", "metadata", "b1", "j3"
    )
