"""lake.schema: the one description of every lake table, checked against what ingest writes and
what DuckDB reads back from real Parquet."""

from __future__ import annotations

import json

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from lakegate.lake import paths
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.record import Record
from lakegate.lake.schema import ARROW_TYPES, EVENTS_COLUMNS, METADATA_COLUMNS, duckdb_type, file_schema, topic_columns
from lakegate.lake.types import FIELD_TYPES, trino_type

CONFIG = """\
version: 1
topics:
  every:
    schema: {n: int, f: float, b: boolean, s: string, st: status, i: image, v: video, tags: "string[]", m: "metric[]"}
  goal:
    event: true
    schema: {name: string, status: status, tags: "string[]", metrics: "metric[]"}
"""
METRICS = [{"name": "speed", "type": "scalar", "value": 1.5}]


def _line(topic, timestamp, data, event=False):
    meta = {"topic": topic, "timestamp": timestamp, **({"event": True} if event else {})}
    return json.dumps({"$metadata": meta, "$data": data}) + "\n"


@pytest.fixture(scope="module")
def lake(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("schema")
    (tmp / "config.yaml").write_text(CONFIG)
    every = {
        "n": 1,
        "f": 2.5,
        "b": True,
        "s": "a",
        "st": "PASSED",
        "i": "x.png",
        "v": "x.mp4",
        "tags": ["t"],
        "m": METRICS,
    }
    goal = {"name": "g", "status": "PASSED", "tags": ["t"], "metrics": METRICS}
    (tmp / "e.jsonl").write_text(_line("every", 1, every) + _line("goal", 2, goal, event=True))
    config = load_config(tmp / "config.yaml")
    ingest_job(tmp / "lake", "main", "b1", "j1", [tmp / "e.jsonl"], config=config, metadata={})
    return tmp / "lake", config


def _written(lake, table):
    root = paths.branch_dir(lake, "main")
    (entry,) = Record(lake, "main").snapshot().of(table)
    return pq.read_schema(root / entry.path)


def test_every_field_type_has_an_arrow_type():
    assert {trino_type(t) for t in FIELD_TYPES} <= set(ARROW_TYPES)


def test_ingest_writes_the_schema_of_each_table(lake):
    lake, config = lake
    expected = {
        "every": topic_columns(config.topics["every"]),
        "goal": topic_columns(config.topics["goal"]),
        paths.EVENTS_TABLE: EVENTS_COLUMNS,
        paths.METADATA_TABLE: METADATA_COLUMNS,
    }
    for table, columns in expected.items():
        written = _written(lake, table)
        assert written.remove_metadata() == file_schema(table, columns), table


def test_duckdb_reads_each_lake_type_as_its_duckdb_type(lake):
    """The view casts (`duckdb_type`) are what DuckDB itself reads the written Arrow types as."""
    lake, config = lake
    root = paths.branch_dir(lake, "main")
    (entry,) = Record(lake, "main").snapshot().of("every")
    columns = dict(topic_columns(config.topics["every"]))
    with duckdb.connect() as con:
        read = con.sql(f"SELECT * FROM read_parquet('{root / entry.path}')")
        for name, duck in zip(read.columns, read.types):
            if columns[name] != "timestamp(3)":
                assert con.type(duckdb_type(columns[name])) == duck, name
    assert duckdb_type("timestamp(3)") == "TIMESTAMP_MS"


@pytest.mark.parametrize("trino", list(ARROW_TYPES))
def test_each_duckdb_type_is_duckdbs_reading_of_the_arrow_type(trino):
    empty = pa.schema([("c", ARROW_TYPES[trino])]).empty_table()
    with duckdb.connect() as con:
        assert con.from_arrow(empty).types == [con.type(duckdb_type(trino))]
