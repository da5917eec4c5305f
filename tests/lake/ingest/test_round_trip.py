"""Ingestion round trip: real emissions files -> real Parquet -> real DuckDB queries, every field type
and the file contract, and metric objects of files written before `extra`."""

from __future__ import annotations

import pyarrow as pa
import pyarrow.parquet as pq

from lakegate.lake.catalog import Catalog
from lakegate.lake.emitter import Emitter
from lakegate.lake.ingest import ingest_job
from lakegate.lake.record import current_file
from tests.lake.ingest.lines import GOAL, NO_METRIC_KEYS, bits, line, odom, query, write_lines

# -- round trip --------------------------------------------------------------------------


def test_round_trip_of_every_field_type_through_emitter_ingest_and_duckdb(tmp_path, config_path, config):
    emissions = tmp_path / "emissions.resim.jsonl"
    record = {
        "i": -(2**63),
        "f": 3,
        "b": True,
        "s": 'ünï "q" \\ 🚀\n',
        "st": "PASSED",
        "im": "a.png",
        "vi": "v.mp4",
        "tags": ["a", "b"],
        "metrics": [
            {"name": "m", "type": "scalar", "value": 2.5, "unit": "m/s", "limits": [0, 3.5]},
            {"name": "t", "type": "text", "value": "hi", "description": "d", "status": "PASSED"},
            {"name": "img", "type": "image", "value": ["1.png", "2.png"]},
            {"name": "p", "type": "plotly", "value": {"data": [], "layout": {}}},
        ],
    }
    second = {**record, "i": 2**63 - 1, "f": -0.0, "b": False, "s": "", "tags": [], "metrics": []}
    with Emitter(config_path=config_path, output_path=emissions) as emitter:
        emitter.emit("sample", record, timestamp=5)
        emitter.emit("sample", second, timestamp=6)
        plain = {k: record[k] for k in ("i", "f", "b", "s", "tags")}
        emitter.emit("plain", plain, timestamp=5)
        emitter.emit("plain", {k: second[k] for k in ("i", "f", "b", "s", "tags")}, timestamp=6)
        emitter.emit_event(
            "goal_reached",
            {
                "name": "Goal 1",
                "description": "reached",
                "status": "PASSED",
                "tags": ["nav"],
                "metrics": record["metrics"][:1],
            },
            timestamp=7,
        )
        emitter.emit_series(
            "odom",
            {"x": [0.1, 1e-300, 1.7976931348623157e308], "y": [1, 2, 3], "z": [0.5, 0.25, -4.0]},
            timestamps=[1, 2, 3],
        )
    report = ingest_job(
        tmp_path / "lake",
        "main",
        "b1",
        "j1",
        [emissions],
        config=config,
        metadata={"experience_name": "sunny", "build_version": "1.2.3"},
    )
    assert report.rows == {"odom": 3, "sample": 2, "plain": 2, "goal_reached": 1, "stop": 0, "never": 0}
    assert report.bad_lines == 0 and report.events == 1
    lake = tmp_path / "lake"
    expected_metrics = [
        # keys beyond the documented ones are kept, as a JSON object text in `extra`
        {
            **NO_METRIC_KEYS,
            "name": "m",
            "type": "scalar",
            "value": "2.5",
            "extra": '{"unit": "m/s", "limits": [0, 3.5]}',
        },
        {**NO_METRIC_KEYS, "name": "t", "description": "d", "status": "PASSED", "type": "text", "value": "hi"},
        {**NO_METRIC_KEYS, "name": "img", "type": "image", "value": '["1.png", "2.png"]'},
        {**NO_METRIC_KEYS, "name": "p", "type": "plotly", "value": '{"data": [], "layout": {}}'},
    ]
    rows = query(
        lake,
        "SELECT timestamp, i, f, b, s, st, im, vi, tags, metrics, experience_name, build_version, batch_id, "
        "job_id FROM sample ORDER BY timestamp",
    )
    assert rows == [
        (
            5,
            -(2**63),
            3.0,
            True,
            'ünï "q" \\ 🚀\n',
            "PASSED",
            "a.png",
            "v.mp4",
            ["a", "b"],
            expected_metrics,
            "sunny",
            "1.2.3",
            "b1",
            "j1",
        ),
        (6, 2**63 - 1, -0.0, False, "", "PASSED", "a.png", "v.mp4", [], [], "sunny", "1.2.3", "b1", "j1"),
    ]
    assert bits(rows[1][2]) == bits(-0.0)
    types = query(
        lake,
        "SELECT typeof(timestamp), typeof(i), typeof(f), typeof(b), typeof(s), typeof(st), typeof(tags), "
        "typeof(metrics), typeof(experience_name), typeof(batch_id) FROM sample LIMIT 1",
    )[0]
    assert types[:7] == ("BIGINT", "BIGINT", "DOUBLE", "BOOLEAN", "VARCHAR", "VARCHAR", "VARCHAR[]")
    assert (
        types[7].replace('"', "")
        == "STRUCT(name VARCHAR, description VARCHAR, status VARCHAR, type VARCHAR, value VARCHAR, extra VARCHAR)[]"
    )
    assert types[8:] == ("VARCHAR", "VARCHAR")
    # the fast path (no metric[] field) gives exactly the same values and types
    assert query(lake, "SELECT timestamp, i, f, b, s, tags FROM plain ORDER BY timestamp") == [
        r[:5] + (r[8],) for r in rows
    ]
    assert query(lake, "SELECT typeof(i), typeof(f), typeof(b), typeof(s), typeof(tags) FROM plain LIMIT 1")[0] == (
        "BIGINT",
        "DOUBLE",
        "BOOLEAN",
        "VARCHAR",
        "VARCHAR[]",
    )
    floats = query(lake, "SELECT x, y FROM odom ORDER BY timestamp")
    assert floats == [(0.1, 1.0), (1e-300, 2.0), (1.7976931348623157e308, 3.0)]
    events = query(
        lake, "SELECT timestamp, topic, name, description, status, tags, metrics, experience_name FROM events"
    )
    assert events == [(7, "goal_reached", "Goal 1", "reached", "PASSED", ["nav"], expected_metrics[:1], "sunny")]
    metadata = query(lake, "SELECT batch_id, job_id, experience_name, build_version, job_status FROM metadata")
    assert metadata == [("b1", "j1", "sunny", "1.2.3", "SUCCEEDED")]


def test_parquet_files_have_the_contract_columns_and_zstd(tmp_path, config):
    emissions = write_lines(
        tmp_path / "e.jsonl", [odom(1), line("stop", 9, {"name": "halt", "speed": 0.5}, event=True)]
    )
    ingest_job(tmp_path / "lake", "main", "b1", "j1", [emissions], config=config)
    topic_file = current_file(tmp_path / "lake", "main", "odom", "b1", "j1")
    schema = pq.read_schema(topic_file)
    assert schema.names == [
        "timestamp",
        *("x", "y", "z"),
        *("experience_name", "build_version", "project_id", "run_counter", "job_id"),
    ]
    assert str(schema.field("timestamp").type) == "int64"
    assert pq.ParquetFile(topic_file).metadata.row_group(0).column(1).compression == "ZSTD"
    events_file = current_file(tmp_path / "lake", "main", "events", "b1", "j1")
    assert pq.read_schema(events_file).names == [
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
        "job_id",
    ]
    # an event topic without description/status/tags/metrics fields leaves them NULL in events
    assert query(tmp_path / "lake", "SELECT topic, name, description, tags, metrics FROM events") == [
        ("stop", "halt", None, None, None)
    ]
    assert query(tmp_path / "lake", "SELECT name, speed FROM stop") == [("halt", 0.5)]


def test_metric_objects_of_old_files_without_extra_read_with_new_ones_in_either_order(tmp_path, config):
    """Files written before metric objects had `extra` hold a 5-field struct; a query over them and
    newer files together gives each row its own `extra` (NULL for the old ones), also when an old one is read first."""
    lake = tmp_path / "lake"
    unit = {"name": "speed", "type": "scalar", "value": 1.5, "unit": "m/s"}
    plain = {"name": "speed", "type": "scalar", "value": 2.5}
    for job_id in ("a", "b", "c"):
        metric = plain if job_id == "a" else unit
        path = write_lines(tmp_path / f"{job_id}.jsonl", [line("goal_reached", 1, {**GOAL, "metrics": [metric]}, True)])
        ingest_job(lake, "main", "b1", job_id, [path], config=config)
    # job a (read first) as an earlier version wrote it: the struct without `extra`, in place (same file, same links)
    old = pa.struct([(name, pa.string()) for name in ("name", "description", "status", "type", "value")])
    for table in ("goal_reached", "events"):
        path = current_file(lake, "main", table, "b1", "a")
        stored = pq.read_table(path)
        metrics = stored.column("metrics").to_pylist()
        assert metrics == [[{**NO_METRIC_KEYS, "name": "speed", "type": "scalar", "value": "2.5"}]]
        narrowed = [[{k: v for k, v in m.items() if k != "extra"} for m in ms] for ms in metrics]
        index = stored.schema.get_field_index("metrics")
        stored = stored.set_column(index, "metrics", pa.array(narrowed, pa.list_(old)))
        pq.write_table(stored, path)
    expected = [
        ("a", "2.5", None),
        ("b", "1.5", '{"unit": "m/s"}'),
        ("c", "1.5", '{"unit": "m/s"}'),
    ]
    for table in ("goal_reached", "events"):
        rows = query(lake, f"SELECT job_id, metrics[1].value, metrics[1].extra FROM {table} ORDER BY job_id")
        assert rows == expected, table
    # the old job alone reads too
    con = Catalog(lake).connect("main")
    assert con.execute("SELECT metrics[1].extra FROM events WHERE job_id = 'a'").fetchall() == [(None,)]
