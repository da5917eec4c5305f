"""The catalog: branches, batches, jobs, tables, Trino schema and DuckDB views over real Parquet."""

from __future__ import annotations

import json

import pytest

from lakegate.lake import paths
from lakegate.lake.catalog import Catalog, JobRef
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.schema import METADATA_COLUMNS

V1 = """\
version: 1
topics:
  odom:
    schema: {x: float, y: float}
  speed:
    schema: {v: float}
  goal_reached:
    event: true
    schema: {name: string, status: status, tags: "string[]", metrics: "metric[]"}
  never:
    schema: {n: int, f: float, b: boolean, s: string, tags: "string[]", metrics: "metric[]"}
"""
# odom gains z and its y becomes an int; speed is dropped
V2 = """\
version: 1
topics:
  odom:
    schema: {x: float, y: int, z: float}
  never:
    schema: {n: int, f: float, b: boolean, s: string, tags: "string[]", metrics: "metric[]"}
"""


def line(topic, timestamp, data, event=False):
    meta = {"topic": topic, "timestamp": timestamp, **({"event": True} if event else {})}
    return json.dumps({"$metadata": meta, "$data": data}) + "\n"


def ingest(tmp_path, lake, text, branch, batch, job, lines, **metadata):
    config_path = tmp_path / f"config-{abs(hash(text))}.yaml"
    config_path.write_text(text)
    emissions = tmp_path / f"{batch}-{job}.jsonl"
    emissions.write_text("".join(lines))
    return ingest_job(lake, branch, batch, job, [emissions], config=load_config(config_path), metadata=metadata)


def test_empty_lake(tmp_path):
    catalog = Catalog(tmp_path / "nothing")
    assert catalog.branches() == []
    assert catalog.jobs("main") == [] and catalog.batches("main") == []


def test_lists_branches_batches_jobs_and_tables_with_row_counts(tmp_path):
    lake = tmp_path / "lake"
    odom = [line("odom", i, {"x": 1.0 * i, "y": 2.0}) for i in range(3)]
    ingest(tmp_path, lake, V1, "main", "b1", "j1", odom, experience_name="sunny")
    ingest(tmp_path, lake, V1, "main", "b1", "j2", odom[:1])
    ingest(
        tmp_path,
        lake,
        V1,
        "main",
        "b2",
        "j3",
        [line("goal_reached", 5, {"name": "g", "status": "PASSED", "tags": [], "metrics": []}, True)],
    )
    ingest(tmp_path, lake, V1, "feature/ünï x", "007", "1e5", odom)
    (lake / "not-a-branch%").mkdir()
    catalog = Catalog(lake)
    assert catalog.branches() == ["feature/ünï x", "main"]
    assert catalog.batches("main") == ["b1", "b2"]
    assert catalog.jobs("main") == [JobRef("b1", "j1"), JobRef("b1", "j2"), JobRef("b2", "j3")]
    assert catalog.jobs("main", "b1") == [JobRef("b1", "j1"), JobRef("b1", "j2")]
    assert catalog.jobs("feature/ünï x") == [("007", "1e5")]
    tables = {t.name: t for t in catalog.tables("main")}
    assert list(tables) == [
        "odom",
        "speed",
        "goal_reached",
        "never",
        "container_performance",
        "test_length_seconds",
        "events",
        "metadata",
    ]
    assert {n: (t.kind, t.row_count) for n, t in tables.items()} == {
        "odom": ("topic", 4),
        "speed": ("topic", 0),
        "goal_reached": ("topic", 1),
        "never": ("topic", 0),
        "container_performance": ("topic", 0),
        "test_length_seconds": ("topic", 0),
        "events": ("events", 1),
        "metadata": ("metadata", 3),
    }
    assert tables["odom"].columns == [
        ("timestamp", "bigint"),
        ("x", "double"),
        ("y", "double"),
        ("experience_name", "varchar"),
        ("build_version", "varchar"),
        ("project_id", "varchar"),
        ("run_counter", "bigint"),
        ("batch_id", "varchar"),
        ("job_id", "varchar"),
    ]
    # ids stay text: never auto-cast to numbers
    con = catalog.connect("feature/ünï x")
    assert con.execute("SELECT DISTINCT batch_id, job_id, typeof(batch_id) FROM odom").fetchall() == [
        ("007", "1e5", "VARCHAR")
    ]


def test_schema_speaks_trino_and_views_match_it(tmp_path):
    lake = tmp_path / "lake"
    ingest(tmp_path, lake, V1, "main", "b1", "j1", [line("odom", 1, {"x": 1.0, "y": 2.0})])
    catalog = Catalog(lake)
    schema = catalog.schema("main")
    assert schema["never"] == {
        "timestamp": "bigint",
        "n": "bigint",
        "f": "double",
        "b": "boolean",
        "s": "varchar",
        "tags": "array(varchar)",
        "metrics": (
            "array(row(name varchar, description varchar, status varchar, type varchar, value varchar, extra varchar))"
        ),
        "experience_name": "varchar",
        "build_version": "varchar",
        "project_id": "varchar",
        "run_counter": "bigint",
        "batch_id": "varchar",
        "job_id": "varchar",
    }
    assert list(schema["metadata"].items()) == list(METADATA_COLUMNS)
    assert (
        schema["metadata"]["time"] == "timestamp(3)" and schema["metadata"]["experience_tag_names"] == "array(varchar)"
    )
    assert list(schema["events"]) == [
        "timestamp",
        "topic",
        "name",
        "description",
        "status",
        "tags",
        "metrics",
        "experience_name",
        "build_version",
        "project_id",
        "run_counter",
        "batch_id",
        "job_id",
    ]
    con = catalog.connect("main")
    duck = {
        "bigint": "BIGINT",
        "double": "DOUBLE",
        "boolean": "BOOLEAN",
        "varchar": "VARCHAR",
        "array(varchar)": "VARCHAR[]",
        "timestamp(3)": "TIMESTAMP_MS",
    }
    for table, columns in schema.items():
        described = con.execute(f'DESCRIBE "{table}"').fetchall()
        assert [row[0] for row in described] == list(columns), table  # every column once, in order
        for (name, trino), row in zip(columns.items(), described):
            if trino.startswith("array(row"):
                assert (
                    row[1].replace('"', "")
                    == "STRUCT(name VARCHAR, description VARCHAR, status VARCHAR, type VARCHAR, "
                    "value VARCHAR, extra VARCHAR)[]"
                )
            else:
                assert row[1] == duck[trino], (table, name)
    # declared but never emitted: an empty table, not an error
    assert con.execute("SELECT COUNT(*), MAX(n) FROM never").fetchall() == [(0, None)]
    assert con.execute("SELECT COUNT(*) FROM events").fetchall() == [(0,)]
    assert con.execute("SELECT COUNT(*) FROM metadata").fetchall() == [(1,)]


def test_views_only_read_inside_the_lake_and_quote_every_name(tmp_path):
    lake = tmp_path / "it's a lake"
    odd = 'odd "name" it\'s'
    config = V1 + f"  {json.dumps(odd)}:\n    schema: {{x: float}}\n"
    ingest(
        tmp_path, lake, config, "main", "b1", "j1", [line("odom", 1, {"x": 1.0, "y": 2.0}), line(odd, 2, {"x": 0.5})]
    )
    views = Catalog(lake).view_sql("main")
    assert Catalog(lake).connect("main").execute('SELECT x, job_id FROM "odd ""name"" it\'s"').fetchall() == [
        (0.5, "j1")
    ]
    for sql in views.values():
        for piece in sql.split("read_parquet('")[1:]:
            path = piece.split("', hive_partitioning")[0].replace("''", "'")
            assert path.startswith(str(paths.branch_dir(lake, "main")) + "/")
    assert "hive_types = {'batch_id': VARCHAR})" in views["odom"]  # job_id is a column of the files
    assert Catalog(lake).connect("main").execute("SELECT COUNT(*) FROM odom").fetchall() == [(1,)]


def test_two_branches_with_different_schemas_for_one_topic(tmp_path):
    lake = tmp_path / "lake"
    ingest(tmp_path, lake, V1, "main", "b1", "j1", [line("odom", 1, {"x": 1.5, "y": 2.5})])
    ingest(tmp_path, lake, V2, "feature/z", "b1", "j1", [line("odom", 1, {"x": 1.5, "y": 7, "z": 3.5})])
    catalog = Catalog(lake)
    assert catalog.schema("main")["odom"]["y"] == "double" and "z" not in catalog.schema("main")["odom"]
    assert catalog.schema("feature/z")["odom"]["y"] == "bigint"
    assert catalog.connect("main").execute("SELECT x, y FROM odom").fetchall() == [(1.5, 2.5)]
    assert catalog.connect("feature/z").execute("SELECT x, y, z, typeof(y) FROM odom").fetchall() == [
        (1.5, 7, 3.5, "BIGINT")
    ]
    assert "speed" in catalog.schema("main") and "speed" not in catalog.schema("feature/z")


def test_files_of_older_config_versions_still_read(tmp_path):
    lake = tmp_path / "lake"
    ingest(
        tmp_path, lake, V1, "main", "b1", "old", [line("odom", 1, {"x": 1.0, "y": 2.0}), line("speed", 1, {"v": 4.0})]
    )
    ingest(tmp_path, lake, V2, "main", "b1", "new", [line("odom", 2, {"x": 3.0, "y": 4, "z": 5.0})])
    catalog = Catalog(lake)
    schema = catalog.schema("main")
    assert list(schema["odom"])[:4] == ["timestamp", "x", "y", "z"] and schema["odom"]["y"] == "bigint"
    con = catalog.connect("main")
    rows = con.execute("SELECT job_id, x, y, z, typeof(y), typeof(z) FROM odom ORDER BY timestamp").fetchall()
    assert rows == [("old", 1.0, 2, None, "BIGINT", "DOUBLE"), ("new", 3.0, 4, 5.0, "BIGINT", "DOUBLE")]
    # a topic the current config dropped stays readable while it has files
    assert con.execute("SELECT v FROM speed").fetchall() == [(4.0,)]
    assert [t.name for t in catalog.tables("main")][:3] == ["odom", "never", "speed"]


def test_a_dropped_topic_without_files_is_not_a_table(tmp_path):
    lake = tmp_path / "lake"
    ingest(tmp_path, lake, V1, "main", "b1", "j1", [line("odom", 1, {"x": 1.0, "y": 2.0})])
    ingest(tmp_path, lake, V2, "main", "b1", "j2", [line("odom", 2, {"x": 3.0, "y": 4, "z": 5.0})])
    assert "speed" not in Catalog(lake).schema("main")


def test_views_read_the_files_of_one_snapshot_of_the_record(tmp_path):
    lake = tmp_path / "lake"
    ingest(tmp_path, lake, V1, "main", "b1", "j1", [line("odom", 1, {"x": 1.0, "y": 2.0})])
    con = Catalog(lake).connect("main")
    ingest(tmp_path, lake, V1, "main", "b1", "j2", [line("odom", 1, {"x": 1.0, "y": 2.0})])
    assert con.execute("SELECT COUNT(*) FROM odom").fetchall() == [(1,)]  # no glob: the snapshot's files
    assert Catalog(lake).connect("main").execute("SELECT COUNT(*) FROM odom").fetchall() == [(2,)]


@pytest.mark.parametrize("branch", ["main", "feature/x", ".."])
def test_metadata_view_has_each_column_once(tmp_path, branch):
    lake = tmp_path / "lake"
    ingest(tmp_path, lake, V1, branch, "b1", "j1", [], experience_name="e", experience_tag_names=["t1", "t2"])
    rows = Catalog(lake).connect(branch).execute("SELECT * FROM metadata").fetchall()
    assert len(rows) == 1 and len(rows[0]) == len(METADATA_COLUMNS)
    row = dict(zip([c for c, _ in METADATA_COLUMNS], rows[0]))
    assert (row["batch_id"], row["job_id"], row["branch_name"], row["experience_tag_names"]) == (
        "b1",
        "j1",
        branch,
        ["t1", "t2"],
    )
