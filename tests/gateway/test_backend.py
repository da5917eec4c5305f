"""The embedded DuckDB backend over a real lake (ingested Parquet): translated queries streamed as
Arrow batches with Trino column types, scopes, parameters, SHOW / DESCRIBE / EXPLAIN, cancelation,
refreshed views, and the locked-down connection: hostile input is refused and the lake unchanged."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import duckdb
import pyarrow as pa
import pytest
import trino

from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope
from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.limits import Limits
from lakegate.lake import paths
from lakegate.lake.config import load_config
from lakegate.lake.config_schema import PLATFORM_TABLES
from lakegate.lake.ingest import ingest_job

CONFIG = """\
version: 1
topics:
  odom:
    schema: {x: float, y: float}
  time_to_goal:
    schema: {goal_name: string, time_s: float}
  never_emitted:
    schema: {n: int}
"""
#: (batch, job, rows per topic): j1 and j2 in batch b1, j3 in b2; odom x = 0, 1, 2, ...
JOBS = [("b1", "j1", 3), ("b1", "j2", 2), ("b2", "j3", 4)]


def line(topic: str, timestamp: int, data: dict) -> str:
    return json.dumps({"$metadata": {"topic": topic, "timestamp": timestamp}, "$data": data}) + "\n"


def build_lake(root: Path, jobs=JOBS, config_text: str = CONFIG) -> Path:
    lake = root / "lake"
    config_file = root / "config.resim.yaml"
    config_file.write_text(config_text)
    config = load_config([config_file])
    for batch, job, n in jobs:
        emissions = root / f"{job}.jsonl"
        emissions.write_text(
            "".join(line("odom", i * 10**9, {"x": float(i), "y": 1.0}) for i in range(n))
            + "".join(line("time_to_goal", i, {"goal_name": f"g{i}", "time_s": 1.5 * i}) for i in range(n))
        )
        ingest_job(lake, "main", batch, job, [emissions], config=config, metadata={"experience_name": f"exp {job}"})
    return lake


def snapshot(root: Path) -> dict[str, tuple[int, int, str]]:
    """Every file under `root`: size, modification time and content digest (not the record's
    SQLite WAL and shared-memory files, which come and go with its readers' connections)."""
    return {
        str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns, hashlib.sha256(p.read_bytes()).hexdigest())
        for p in sorted(root.rglob("*"))
        if p.is_file() and not p.name.endswith(("-wal", "-shm"))
    }


@pytest.fixture(scope="module")
def lake(tmp_path_factory) -> Path:
    return build_lake(tmp_path_factory.mktemp("backend"))


@pytest.fixture(scope="module")
def backend(lake):
    backend = DuckDBBackend(lake, memory_limit="512MB", threads=2)
    yield backend
    backend.close()


def refused(backend, sql, **kwargs) -> DialectError:
    with pytest.raises(DialectError) as caught:
        backend.execute(sql, **kwargs).rows()
    return caught.value


def test_a_query_streams_arrow_batches_with_trino_column_types(backend):
    result = backend.execute(
        "SELECT job_id, count(*) AS n, avg(x), sum(timestamp) / 1E9 AS s FROM odom GROUP BY 1 ORDER BY 1"
    )
    assert result.columns == [("job_id", "varchar"), ("n", "bigint"), ("_col2", "double"), ("s", "double")]
    batches = list(result.batches)
    assert batches and all(isinstance(b, pa.RecordBatch) for b in batches)
    assert pa.Table.from_batches(batches).to_pylist() == [
        {"job_id": "j1", "n": 3, "_col2": 1.0, "s": 3.0},
        {"job_id": "j2", "n": 2, "_col2": 0.5, "s": 1.0},
        {"job_id": "j3", "n": 4, "_col2": 1.5, "s": 6.0},
    ]


def test_the_schema_is_the_catalogs(backend):
    schema = backend.schema("main")
    assert set(schema) == {"odom", "time_to_goal", "never_emitted", "events", "metadata", *PLATFORM_TABLES}
    assert schema["odom"]["x"] == "double" and schema["odom"]["timestamp"] == "bigint"
    assert backend.execute("SELECT count(*) FROM never_emitted").rows() == [(0,)]


def test_scopes_restrict_every_table(backend):
    sql = "SELECT m.experience_name, count(*) FROM odom o JOIN metadata m ON o.job_id = m.job_id GROUP BY 1 ORDER BY 1"
    assert backend.execute(sql, scope=Scope(batch_id="b1", job_id="j2")).rows() == [("exp j2", 2)]
    assert backend.execute(sql, scope=Scope(batch_id="b1")).rows() == [("exp j1", 3), ("exp j2", 2)]
    assert backend.execute(sql).rows() == [("exp j1", 3), ("exp j2", 2), ("exp j3", 4)]


@pytest.mark.parametrize("threshold, blocks", [(3, False), (3.5, True), (4, True)])
def test_status_check_parameters(backend, threshold, blocks):
    result = backend.execute(
        "SELECT '1' FROM time_to_goal HAVING COUNT(*) < ?", scope=Scope(job_id="j1"), params=[threshold]
    )
    assert result.rows() == ([("1",)] if blocks else [])


def test_constant_queries_need_no_lake():
    backend = DuckDBBackend(None)
    try:
        assert backend.schema("main") == {}
        assert backend.execute("SELECT 5 / 2, typeof(5 / 2)").rows() == [(2, "integer")]
        assert refused(backend, "SELECT * FROM odom").error_name == "TABLE_NOT_FOUND"
    finally:
        backend.close()


def test_an_unknown_branch_is_a_clear_error(backend):
    error = refused(backend, "SELECT 1", branch="nope")
    assert error.error_name == "SCHEMA_NOT_FOUND" and "branches: main" in error.message


def test_show_and_describe_are_the_engines(backend):
    """SHOW and DESCRIBE are answered by the Engine's system tables, once, over the backend's lake;
    the backend itself translates queries only."""
    engine = Engine(backend)
    session = engine.session(branch="main")
    assert engine.execute("SHOW TABLES", session).rows() == [
        ("container_performance",),
        ("events",),
        ("metadata",),
        ("never_emitted",),
        ("odom",),
        ("test_length_seconds",),
        ("time_to_goal",),
    ]
    result = engine.execute("SHOW TABLES FROM lake.main LIKE 'o%'", session)
    assert result.columns == [("Table", "varchar")] and result.rows() == [("odom",)]
    result = engine.execute("DESCRIBE odom", session)
    assert result.columns == [("Column", "varchar"), ("Type", "varchar"), ("Extra", "varchar"), ("Comment", "varchar")]
    assert result.rows()[:3] == [("timestamp", "bigint", "", ""), ("x", "double", "", ""), ("y", "double", "", "")]
    assert engine.execute("SHOW COLUMNS FROM main.odom LIKE '%\\_id' ESCAPE '\\'", session).rows() == [
        ("project_id", "varchar", "", ""),
        ("batch_id", "varchar", "", ""),
        ("job_id", "varchar", "", ""),
    ]
    assert engine.execute("SHOW SCHEMAS", session).rows() == [("information_schema",), ("main",)]
    assert engine.execute("SHOW CATALOGS", session).rows() == [("lake",), ("system",)]
    with pytest.raises(DialectError) as error:
        engine.execute("DESCRIBE nothing", session)
    assert error.value.error_name == "TABLE_NOT_FOUND"
    for escape in ("''", "'$$'"):  # as the real Trino 476 answers
        with pytest.raises(DialectError) as error:
            engine.execute(f"SHOW SESSION LIKE 't$_%' ESCAPE {escape}", session)
        assert error.value.error_name == "INVALID_FUNCTION_ARGUMENT"
        assert str(error.value).startswith("Escape string must be a single character")
    assert refused(backend, "SHOW TABLES").error_name == "NOT_SUPPORTED"


def test_explain_shows_duckdbs_plan_of_the_translation(backend):
    result = backend.execute("EXPLAIN SELECT count(*) FROM odom")
    assert result.columns == [("Query Plan", "varchar")]
    assert "READ_PARQUET" in result.rows()[0][0]
    assert "Total Time" in backend.execute("EXPLAIN ANALYZE SELECT count(*) FROM odom").rows()[0][0]
    error = refused(backend, "EXPLAIN SELECT nope FROM odom")
    assert error.error_name == "COLUMN_NOT_FOUND" and (error.line, error.column) == (1, 16)


def test_runtime_errors_carry_trinos_error_names(backend):
    assert refused(backend, "SELECT timestamp / 0 FROM odom").error_name == "DIVISION_BY_ZERO"
    assert refused(backend, "SELECT ARRAY[1, 2][5]").error_name == "INVALID_FUNCTION_ARGUMENT"


def test_cancel_interrupts_a_running_query(backend):
    result = backend.execute(
        "SELECT count(*) FROM UNNEST(sequence(1, 10000)) AS a(x) "
        "CROSS JOIN UNNEST(sequence(1, 10000)) AS b(y) CROSS JOIN UNNEST(sequence(1, 10000)) AS c(z)"
    )
    threading.Timer(0.2, result.cancel).start()
    started = time.monotonic()
    with pytest.raises(DialectError) as caught:
        result.rows()
    assert caught.value.error_name == "USER_CANCELED" and caught.value.error_code == 3
    assert time.monotonic() - started < 30
    assert backend.execute("SELECT count(*) FROM odom").rows() == [(9,)]  # the backend goes on


def test_queries_run_concurrently(backend):
    results: dict[int, list] = {}

    def query(i: int) -> None:
        results[i] = backend.execute("SELECT count(*) FROM odom WHERE x >= ?", params=[i]).rows()

    def same_query(i: int) -> None:  # one text: one cached DuckDB statement shared by the threads
        results[10 + i] = [backend.execute("SELECT count(*), sum(x) FROM odom").rows() for _ in range(20)]

    threads = [threading.Thread(target=query, args=(i,)) for i in range(4)]
    threads += [threading.Thread(target=same_query, args=(i,)) for i in range(3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert {k: v for k, v in results.items() if k < 10} == {0: [(9,)], 1: [(6,)], 2: [(3,)], 3: [(1,)]}
    assert all(results[10 + i] == [[(9, 10.0)]] * 20 for i in range(3))


def test_a_cursor_is_reused_only_after_a_query_read_all_its_rows(backend):
    assert backend.execute("SELECT count(*) FROM odom").rows() == [(9,)]
    idle = backend._branches["main"].idle
    kept = list(idle)
    assert kept and backend.execute("SELECT sum(x) FROM odom").rows() == [(10.0,)]
    assert idle == kept  # the same cursor served the second query and came back
    run = backend.execute("SELECT x FROM odom ORDER BY x").batches
    next(run)  # one batch read, then abandoned: its open result must not reach another query
    run.close()
    assert backend.execute("SELECT count(*) FROM odom").rows() == [(9,)]
    refused(backend, "SELECT CAST('a' AS integer) FROM odom")  # a failed query's cursor closes
    scope = Scope(batch_id="b1")
    assert backend.execute("SELECT count(*) FROM odom", scope=scope).rows() == [(5,)]
    scoped = [entry for entry in idle if entry[1] is not None]
    assert len(scoped) == 1  # a scoped query's cursor comes back with the views it reads
    assert backend.execute("SELECT sum(x) FROM odom", scope=scope).rows() == [(4.0,)]
    assert [entry for entry in idle if entry[1] is not None] == scoped  # and serves the scope's next query
    assert backend.execute("SELECT count(*) FROM odom").rows() == [(9,)]  # not the scoped views
    assert backend.execute("SELECT count(*) FROM odom", scope=Scope(batch_id="b2")).rows() == [(4,)]
    assert backend.execute("SELECT count(*) FROM odom", scope=scope).rows() == [(5,)]
    assert backend.execute("SELECT count(*) FROM odom").rows() == [(9,)]
    assert 1 <= len(idle) <= 4


def test_views_follow_new_topics_and_jobs(tmp_path):
    lake = build_lake(tmp_path, jobs=[("b1", "j1", 2)])
    backend = DuckDBBackend(lake)
    try:
        assert backend.execute("SELECT count(*) FROM odom").rows() == [(2,)]
        build_lake(tmp_path, jobs=[("b1", "j2", 3)], config_text=CONFIG + "  speed:\n    schema: {v: float}\n")
        assert backend.execute("SELECT count(*) FROM odom").rows() == [(5,)]
        assert backend.execute("SELECT count(*) FROM speed").rows() == [(0,)]
    finally:
        backend.close()


def test_branches_follow_the_lake(tmp_path):
    lake = build_lake(tmp_path, jobs=[("b1", "j1", 2)])
    backend = DuckDBBackend(lake)
    try:
        assert backend.branches() == ["main"]
        config = load_config([tmp_path / "config.resim.yaml"])
        ingest_job(lake, "feature/x", "b1", "j9", [tmp_path / "j1.jsonl"], config=config, metadata={})
        assert backend.branches() == ["feature/x", "main"]  # listed again: the lake directory changed
        assert backend.execute("SELECT count(*) FROM odom", branch="feature/x").rows() == [(2,)]
        shutil.rmtree(lake / "feature%2Fx")
        assert backend.branches() == ["main"]
        assert refused(backend, "SELECT 1", branch="feature/x").error_name == "SCHEMA_NOT_FOUND"
    finally:
        backend.close()


def test_the_duckdb_connection_is_locked_down(backend, lake, tmp_path):
    con = backend.connection("main")
    try:
        settings = dict(
            con.execute(
                "SELECT name, value FROM duckdb_settings() WHERE name IN "
                "('enable_external_access', 'lock_configuration', 'autoload_known_extensions', "
                "'autoinstall_known_extensions')"
            ).fetchall()
        )
        assert settings == {
            "enable_external_access": "false",
            "lock_configuration": "true",
            "autoload_known_extensions": "false",
            "autoinstall_known_extensions": "false",
        }
        outside = tmp_path / "out.csv"
        for sql, error in [
            ("SELECT * FROM read_csv('/etc/passwd')", duckdb.PermissionException),
            ("SELECT * FROM read_text('/etc/hostname')", duckdb.PermissionException),
            (f"COPY (SELECT 1) TO '{outside}'", duckdb.PermissionException),
            (f"ATTACH '{tmp_path / 'other.duckdb'}' AS other", duckdb.PermissionException),
            ("SET threads = 8", duckdb.InvalidInputException),
            ("SET enable_external_access = true", duckdb.InvalidInputException),
            ("RESET lock_configuration", duckdb.InvalidInputException),
            ("INSTALL httpfs", duckdb.PermissionException),
            ("LOAD httpfs", duckdb.PermissionException),
        ]:
            with pytest.raises(error):
                con.execute(sql)
        assert not outside.exists() and not (tmp_path / "other.duckdb").exists()
        # the lake itself stays readable
        assert con.execute("SELECT count(*) FROM odom").fetchone() == (9,)
    finally:
        con.close()


@pytest.mark.parametrize(
    "sql",
    [
        "SELECT * FROM read_csv('/etc/passwd')",
        "SELECT * FROM read_text('{lake}/main/odom/batch_id=b1/job_id=j1/data.parquet')",
        "SELECT * FROM read_parquet('{lake}/main/odom/*/*/*.parquet')",
        "SELECT * FROM '{lake}/main/odom/batch_id=b1/job_id=j1/data.parquet'",
        "SELECT * FROM glob('{lake}/*')",
        "COPY odom TO '{lake}/main/odom/batch_id=b1/job_id=j1/data.parquet' (FORMAT parquet)",
        "COPY (SELECT 1) TO '{lake}/evil.csv'",
        "INSERT INTO odom SELECT * FROM odom",
        "DELETE FROM odom",
        "DROP VIEW odom",
        "CREATE OR REPLACE VIEW odom AS SELECT 1 AS x",
        "ATTACH '{lake}/evil.duckdb' AS evil",
        "EXPORT DATABASE '{lake}/dump'",
        "SET allowed_directories = ['/']",
        "SET enable_external_access = true",
        "PRAGMA threads = 1",
        "INSTALL httpfs",
        "SELECT 1; COPY (SELECT 1) TO '{lake}/evil.csv'",
        "SELECT count(*) FROM odom; DROP VIEW odom",
        "SELECT " + "(" * 499_990 + "1" + ")" * 499_990,
        b"SELECT '\xc3\x28' FROM odom",
        "SELECT 'a\x00' FROM odom",
    ],
)
def test_hostile_input_is_refused_and_the_lake_unchanged(backend, lake, sql):
    before = snapshot(lake)
    text = sql.replace(b"{lake}", str(lake).encode()) if isinstance(sql, bytes) else sql.replace("{lake}", str(lake))
    error = refused(backend, text)
    assert error.error_name in ("PERMISSION_DENIED", "SYNTAX_ERROR", "NOT_SUPPORTED", "TABLE_NOT_FOUND")
    assert error.message
    assert snapshot(lake) == before
    assert backend.execute("SELECT count(*) FROM odom").rows() == [(9,)]


def test_only_one_select_reaches_duckdb(backend):
    con = backend.connection("main")
    try:
        for text in ("COPY (SELECT 1) TO 'x.csv'", "SELECT 1; SELECT 2", "CREATE VIEW v AS SELECT 1"):
            with pytest.raises(DialectError) as caught:
                backend._single_select(con, text)
            assert caught.value.error_name == "GENERIC_INTERNAL_ERROR"
        assert backend._single_select(con, "SELECT 1").type == duckdb.StatementType.SELECT
    finally:
        con.close()


# -- lake integrity: fresh catalogs, whole-job visibility, unreadable files -------------------

REINGEST_SCRIPT = """
import sys
from pathlib import Path
from lakegate.lake.config import load_config
from lakegate.lake import paths
from lakegate.lake.ingest import ingest_job
lake, config, emissions, runs = Path(sys.argv[1]), load_config([sys.argv[2]]), Path(sys.argv[3]), int(sys.argv[4])
for run in range(runs):
    ingest_job(lake, "main", "b1", "j1", [emissions], config=config, metadata={"experience_name": f"token {run}"})
"""


def ingest_one(root: Path, lake: Path, job: str, lines: str, name: str = "exp") -> None:
    (root / "config.resim.yaml").write_text(CONFIG)
    emissions = root / f"{job}-{len(lines)}.jsonl"
    emissions.write_text(lines)
    ingest_job(
        lake,
        "main",
        "b1",
        job,
        [emissions],
        config=load_config([root / "config.resim.yaml"]),
        metadata={"experience_name": name},
    )


def test_a_query_never_sees_a_job_half_re_ingested(tmp_path):
    """Another process re-ingests job j1 200 times (its experience name, a token present in every
    table's rows, changes each time) while queries read all its tables in one statement: every
    answer is one version of the job."""
    lake = build_lake(tmp_path, jobs=[("b1", "j1", 3)])
    emissions = tmp_path / "j1.jsonl"
    process = subprocess.Popen(
        [sys.executable, "-c", REINGEST_SCRIPT, str(lake), str(tmp_path / "config.resim.yaml"), str(emissions), "200"],
        stderr=subprocess.PIPE,
        text=True,
    )
    sql = (
        "SELECT (SELECT array_agg(DISTINCT experience_name) FROM odom), "
        "(SELECT array_agg(DISTINCT experience_name) FROM time_to_goal), "
        "(SELECT array_agg(experience_name) FROM metadata)"
    )
    answers, mixed = 0, []
    backend = DuckDBBackend(lake, memory_limit="256MB", threads=1)
    try:
        deadline = time.monotonic() + 300
        while process.poll() is None and time.monotonic() < deadline:
            odom, goals, metadata = backend.execute(sql, branch="main").rows()[0]
            answers += 1
            if not (len(metadata) == 1 and odom == goals == metadata):
                mixed.append((odom, goals, metadata))
    finally:
        backend.close()
        process.kill() if process.poll() is None else None
        process.wait()
    assert process.returncode == 0, process.stderr.read()
    assert answers > 20 and not mixed, (answers, mixed[:5])


def test_a_backend_sees_files_that_appear_in_an_emptied_topic(tmp_path):
    """A topic whose only job was re-ingested without it, then written again: the same backend
    answers its new rows (no stale catalog)."""
    lake = tmp_path / "lake"
    ingest_one(
        tmp_path,
        lake,
        "j1",
        line("odom", 1, {"x": 1.0, "y": 1.0}) + line("time_to_goal", 1, {"goal_name": "g", "time_s": 1.0}),
    )
    ingest_one(tmp_path, lake, "j1", line("odom", 1, {"x": 1.0, "y": 1.0}))  # the topic's directory stays
    backend = DuckDBBackend(lake, memory_limit="256MB", threads=1)
    try:
        assert backend.execute("SELECT count(*) FROM time_to_goal", branch="main").rows() == [(0,)]
        ingest_one(tmp_path, lake, "j2", line("time_to_goal", 2, {"goal_name": "h", "time_s": 2.0}) * 1)
        assert backend.execute("SELECT goal_name FROM time_to_goal", branch="main").rows() == [("h",)]
    finally:
        backend.close()


def test_a_topic_dropped_by_a_re_ingest_reads_as_empty(tmp_path):
    """The same backend, after the re-ingest that removed a topic's files: 0 rows, not an error
    naming a server path."""
    lake = tmp_path / "lake"
    ingest_one(
        tmp_path,
        lake,
        "j1",
        line("odom", 1, {"x": 1.0, "y": 1.0}) + line("time_to_goal", 1, {"goal_name": "g", "time_s": 1.0}),
    )
    backend = DuckDBBackend(lake, memory_limit="256MB", threads=1)
    try:
        assert backend.execute("SELECT count(*) FROM time_to_goal", branch="main").rows() == [(1,)]
        ingest_one(tmp_path, lake, "j1", line("odom", 1, {"x": 1.0, "y": 1.0}))
        assert backend.execute("SELECT count(*) FROM time_to_goal", branch="main").rows() == [(0,)]
        assert backend.execute("SELECT count(*) FROM odom", branch="main").rows() == [(1,)]
    finally:
        backend.close()


@pytest.mark.parametrize("job", ["j1", "j2"])
def test_an_unreadable_file_fails_only_the_queries_that_read_it(tmp_path, job):
    """One corrupt Parquet file (the first or a later one of its table): SELECT 1, other tables and
    the table's other jobs still answer; a query that reads it fails with HIVE_BAD_DATA naming the
    table, batch and job, never a path (Trino's Hive connector raises HIVE_BAD_DATA for a file it
    cannot read: io.trino.plugin.hive.HiveErrorCode)."""
    lake = build_lake(tmp_path, jobs=[("b1", "j1", 3), ("b1", "j2", 2)])
    bad = next(lake.glob(f"main/odom/batch_id=b1/*-{job}.parquet"))
    bad.write_bytes(b"not parquet at all" * 10)
    other = "j2" if job == "j1" else "j1"
    backend = DuckDBBackend(lake, memory_limit="256MB", threads=1)
    try:
        assert backend.execute("SELECT 1", branch="main").rows() == [(1,)]
        assert backend.execute("SELECT count(*) FROM time_to_goal", branch="main").rows() == [(5,)]
        scoped = backend.execute("SELECT count(*) FROM odom", branch="main", scope=Scope(batch_id="b1", job_id=other))
        assert scoped.rows() == [(3 if other == "j1" else 2,)]
        for scope in (None, Scope(batch_id="b1", job_id=job)):
            error = refused(backend, "SELECT count(*) FROM odom", branch="main", scope=scope)
            assert error.error_name == "HIVE_BAD_DATA", error
            assert f"table odom, batch b1, job {job}" in error.message and str(tmp_path) not in error.message
    finally:
        backend.close()


def test_query_serve_and_lake_ls_with_a_corrupt_file(tmp_path):
    """Real `lakegate query`, `lakegate serve` (with the trino client) and `lakegate lake ls` on a lake
    with one corrupt file: only the queries that read it fail, with a clear message and no
    traceback or path; `lake ls` lists the branch and reports the file as unreadable."""
    lake = build_lake(tmp_path, jobs=[("b1", "j1", 3), ("b1", "j2", 2)])
    next(lake.glob("main/odom/batch_id=b1/*-j1.parquet")).write_bytes(b"PAR1 truncated")
    cli = [sys.executable, "-m", "lakegate.gateway.cli"]

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([*cli, *args], capture_output=True, text=True, timeout=120)

    assert run("query", "--lake", str(lake), "SELECT 1").returncode == 0
    assert "5" in run("query", "--lake", str(lake), "SELECT count(*) FROM time_to_goal").stdout
    failed = run("query", "--lake", str(lake), "SELECT count(*) FROM odom")
    assert failed.returncode == 1 and "table odom, batch b1, job j1" in failed.stderr, failed.stderr
    assert "Traceback" not in failed.stderr and str(tmp_path) not in failed.stderr
    listed = run("lake", "ls", "--lake", str(lake), "--branch", "main")
    assert listed.returncode == 0 and "Traceback" not in listed.stderr, listed.stderr
    assert "unreadable files (1)" in listed.stdout and "table odom, batch b1, job j1: " in listed.stdout
    assert "time_to_goal" in listed.stdout

    server = subprocess.Popen(
        [*cli, "serve", "--lake", str(lake), "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        line = server.stdout.readline()
        host, port = line.split(" at ", 1)[1].split()[0].split("//", 1)[1].rstrip("/").split(":")
        connection = trino.dbapi.connect(host=host, port=int(port), user="t", catalog="lake", schema="main")
        cursor = connection.cursor()
        cursor.execute("SELECT 1")
        assert cursor.fetchall() == [[1]]
        cursor.execute("SELECT count(*) FROM odom WHERE job_id = 'j2'")
        assert cursor.fetchall() == [[2]]
        with pytest.raises(trino.exceptions.TrinoQueryError) as caught:
            cursor.execute("SELECT count(*) FROM odom")
            cursor.fetchall()
        assert caught.value.error_name == "HIVE_BAD_DATA" and str(tmp_path) not in caught.value.message
    finally:
        server.terminate()
        server.wait(30)


def _overwrite(path: Path, offset: int, size: int) -> None:
    """Random bytes over `size` bytes of a file at `offset` (in place: its reader link sees them too)."""
    import random

    with path.open("r+b") as file:
        file.seek(offset)
        file.write(random.Random(offset).randbytes(size))


def test_damage_inside_a_compacted_file_is_found(tmp_path):
    """Random bytes inside a compacted file (one file for both jobs): in a page's values, `lake ls`
    finds them by the page's checksum and names table, batch and job; over a page header (which
    DuckDB reports without naming the file), a query fails with HIVE_BAD_DATA naming them."""
    import pyarrow.parquet as pq

    from lakegate.lake.compaction import compact_batch

    lake = build_lake(tmp_path, jobs=[("b1", "j1", 300), ("b1", "j2", 200)])
    compact_batch(lake, "main", "b1")
    [compacted] = [f for f in lake.glob("main/odom/batch_id=b1/*.parquet")]
    group = pq.ParquetFile(compacted).metadata.row_group(0)
    chunk = next(group.column(i) for i in range(group.num_columns) if group.column(i).path_in_schema == "x")
    cli = [sys.executable, "-m", "lakegate.gateway.cli"]

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([*cli, *args], capture_output=True, text=True, timeout=120)

    assert "unreadable" not in run("lake", "ls", "--lake", str(lake), "--branch", "main").stdout
    _overwrite(compacted, chunk.data_page_offset + chunk.total_compressed_size - 24, 16)  # inside the values
    listed = run("lake", "ls", "--lake", str(lake), "--branch", "main")
    assert listed.returncode == 0 and "Traceback" not in listed.stderr, listed.stderr
    assert "unreadable files (2)" in listed.stdout, listed.stdout
    for job in ("j1", "j2"):
        assert f"table odom, batch b1, job {job}: the file is corrupt: a page fails its checksum" in listed.stdout

    _overwrite(compacted, chunk.data_page_offset, 16)  # over the first page's header
    failed = run("query", "--lake", str(lake), "SELECT sum(x) FROM odom")
    assert failed.returncode == 1 and "Traceback" not in failed.stderr, failed.stderr
    assert "Cannot read the Parquet file of table odom, batch b1, job j" in failed.stderr, failed.stderr
    assert str(tmp_path) not in failed.stderr


def test_a_file_deleted_by_hand_fails_only_its_job(tmp_path):
    lake = build_lake(tmp_path, jobs=[("b1", "j1", 3), ("b1", "j2", 2)])
    for file in lake.glob("**/odom/batch_id=b1/*-j1.parquet"):  # the visible file and the reader link
        file.unlink()
    backend = DuckDBBackend(lake, memory_limit="256MB", threads=1)
    try:
        assert backend.execute("SELECT count(*) FROM odom WHERE job_id = 'j2'", branch="main").rows() == [(2,)]
        error = refused(backend, "SELECT count(*) FROM odom", branch="main")
        assert error.error_name == "HIVE_BAD_DATA" and "table odom, batch b1, job j1" in error.message
    finally:
        backend.close()


ENDLESS = (
    "SELECT count(*) FROM UNNEST(sequence(1, 10000)) AS a(x) CROSS JOIN UNNEST(sequence(1, 10000)) AS b(y) "
    "CROSS JOIN UNNEST(sequence(1, 10000)) AS c(z)"
)


def test_the_time_limit_and_the_concurrency_bound_hold_for_every_caller(lake):
    """Trino: query.max-execution-time fails a query (EXPLAIN ANALYZE executes it too) with
    EXCEEDED_TIME_LIMIT (trinodb/trino docs/src/main/sphinx/admin/properties-query-management.rst)."""
    backend = DuckDBBackend(lake, limits=Limits(query_timeout=1.0, max_concurrent_queries=1))
    try:
        for sql in (ENDLESS, f"EXPLAIN ANALYZE {ENDLESS}"):
            started = time.monotonic()
            with pytest.raises(DialectError) as caught:
                backend.execute(sql).rows()
            assert (caught.value.error_name, caught.value.message) == (
                "EXCEEDED_TIME_LIMIT",
                "Query exceeded the maximum execution time limit of 1.00s",
            )
            assert time.monotonic() - started < 10
    finally:
        backend.close()
    backend = DuckDBBackend(lake, limits=Limits(max_concurrent_queries=1))
    try:
        held = backend.execute("SELECT count(*) FROM odom")  # started, not read: it holds the only slot
        answers: list = []
        waiting = threading.Thread(target=lambda: answers.append(backend.execute("SELECT 1").rows()))
        waiting.start()
        waiting.join(0.5)
        assert waiting.is_alive() and not answers  # waits for the slot
        held.batches.close()
        waiting.join(10)
        assert answers == [[(1,)]]
    finally:
        backend.close()


def test_errors_and_plans_name_lake_files_relative_to_the_lake(tmp_path):
    lake = build_lake(tmp_path)
    backend = DuckDBBackend(lake)
    try:
        plan = backend.execute("EXPLAIN ANALYZE SELECT count(*) FROM odom").rows()[0][0]
        broken = next((lake / "main" / "odom").rglob("*.parquet"))
        broken.write_bytes(b"not a parquet file")
        error = refused(backend, "SELECT count(*) FROM odom")
        unknown = refused(backend, "SELECT 1", branch="nope")
    finally:
        backend.close()
    assert error.error_name == "HIVE_BAD_DATA" and "table odom" in error.message
    for text in (plan, error.message, unknown.message):
        assert str(tmp_path) not in text


def test_a_scoped_query_reads_only_the_files_of_its_scope(tmp_path):
    """A test metric's (job) and a batch metric's (batch) queries read views over only their
    files, found in the record: after the views are loaded, the first odom file of the branch (job
    j1, the one DuckDB would open to bind a view over every file) is overwritten with garbage.
    Queries scoped to other jobs or batches still answer; those that read j1 fail naming it."""
    lake = build_lake(tmp_path)
    backend = DuckDBBackend(lake, memory_limit="256MB", threads=1)
    try:
        assert backend.execute("SELECT count(*) FROM odom").rows() == [(9,)]
        first = next(lake.glob("main/odom/batch_id=b1/*-j1.parquet"))
        first.write_bytes(b"not parquet at all" * 10)  # the reader link is the same file
        sql = "SELECT m.experience_name, count(*) FROM odom o JOIN metadata m ON o.job_id = m.job_id GROUP BY 1"
        assert backend.execute(sql, scope=Scope(batch_id="b1", job_id="j2")).rows() == [("exp j2", 2)]
        assert backend.execute(sql, scope=Scope(batch_id="b2")).rows() == [("exp j3", 4)]
        assert backend.execute(sql, scope=Scope(job_id="j3")).rows() == [("exp j3", 4)]
        for scope in (Scope(batch_id="b1"), Scope(batch_id="b1", job_id="j1")):
            error = refused(backend, sql, scope=scope)
            assert "table odom, batch b1, job j1" in error.message and str(tmp_path) not in error.message
    finally:
        backend.close()


def test_scoped_views_follow_a_re_ingest(tmp_path):
    """A scope's views belong to one generation of the record: after the job is ingested again, the
    same scoped query reads the new files (with the new rows)."""
    lake = build_lake(tmp_path)
    backend = DuckDBBackend(lake, memory_limit="256MB", threads=1)
    try:
        scope = Scope(batch_id="b1", job_id="j1")
        assert backend.execute("SELECT count(*), min(experience_name) FROM odom", scope=scope).rows() == [(3, "exp j1")]
        ingest_one(tmp_path, lake, "j1", "".join(line("odom", i, {"x": 1.0, "y": 2.0}) for i in range(5)), name="new")
        assert backend.execute("SELECT count(*), min(experience_name) FROM odom", scope=scope).rows() == [(5, "new")]
        assert backend.execute("SELECT count(*) FROM odom", scope=Scope(batch_id="b1")).rows() == [(7,)]
    finally:
        backend.close()


def test_branches_share_one_database_and_idle_ones_are_released(tmp_path):
    """20 branches are attached databases of the backend's one DuckDB database, so one
    memory limit and one thread pool bound them together; a branch not queried for `idle_seconds`
    is detached and answers again (its views made anew) at its next query."""
    lake = build_lake(tmp_path, jobs=[("b1", "j1", 3)])
    branches = [f"team/{i}" for i in range(20)]
    for branch in branches:
        shutil.copytree(lake / "main", paths.branch_dir(lake, branch))
    backend = DuckDBBackend(lake, memory_limit="300MB", threads=2, limits=Limits(query_timeout=1.0), idle_seconds=3600)
    expected = duckdb.connect(config={"memory_limit": "300MB", "threads": 2})
    attached = "SELECT count(*) FROM duckdb_databases() WHERE database_name LIKE 'branch_%'"
    try:
        for branch in branches:
            assert backend.execute("SELECT count(*), min(job_id) FROM odom", branch=branch).rows() == [(3, "j1")]
        con = backend.connection(branches[0])
        assert con.execute(attached).fetchone() == (20,)
        settings = "SELECT current_setting('memory_limit'), current_setting('threads')"
        assert con.execute(settings).fetchone() == expected.execute(settings).fetchone()
        con.close()
        backend.idle_seconds = 0.0  # every branch is idle now (no waiting: the test holds under any load)
        assert backend.execute("SELECT count(*) FROM odom", branch=branches[5]).rows() == [(3,)]
        con = backend.connection(branches[5])
        assert con.execute(attached).fetchone() == (1,)  # the others were idle: released
        con.close()
        scoped = backend.execute("SELECT count(*) FROM odom", branch=branches[7], scope=Scope("b1", "j1"))
        assert scoped.rows() == [(3,)]
    finally:
        backend.close()
        expected.close()


def test_a_scope_has_views_only_of_the_tables_its_queries_name(tmp_path):
    """A scoped query's views are made when a query first names their tables (binding one reads its
    files' footers): a job scope that read odom holds only odom's view until a query joins metadata;
    the next job scope makes those two with the table its first query names, in one transaction (as
    a metrics run's jobs run the same queries); scopes on threads at once answer as the branch does."""
    lake = build_lake(tmp_path)
    backend = DuckDBBackend(lake, memory_limit="256MB", threads=2)
    views = "SELECT view_name FROM duckdb_views() WHERE schema_name LIKE 'scope_%' ORDER BY 1"
    try:
        scope = Scope(batch_id="b1", job_id="j1")
        assert backend.execute("SELECT count(*) FROM odom", scope=scope).rows() == [(3,)]
        con = backend.connection()
        assert con.execute(views).fetchall() == [("odom",)]
        sql = "SELECT m.experience_name, count(*) FROM odom o JOIN metadata m ON o.job_id = m.job_id GROUP BY 1"
        assert backend.execute(sql, scope=scope).rows() == [("exp j1", 3)]
        assert con.execute(views).fetchall() == [("metadata",), ("odom",)]
        assert backend.execute("SELECT count(*) FROM time_to_goal", scope=Scope("b1", "j2")).rows() == [(2,)]
        assert con.execute(views).fetchall() == [("metadata",)] * 2 + [("odom",)] * 2 + [("time_to_goal",)]
        assert backend.execute("SELECT count(*) FROM odom", scope=Scope("b1")).rows() == [(5,)]  # a batch's: its own
        assert con.execute(views.replace("ORDER BY 1", "AND view_name = 'time_to_goal'")).fetchall() == [
            ("time_to_goal",)
        ]
        con.close()
        total = "SELECT sum(time_s) FROM time_to_goal"  # time_s = 1.5 * i of each job's i-th goal
        queries = [(sql, Scope("b1", "j1")), (sql, Scope("b1", "j2")), (total, None)]
        queries += [(total, Scope(batch, job)) for batch, job, _ in JOBS]
        with ThreadPoolExecutor(4) as pool:
            answers = list(pool.map(lambda query: backend.execute(query[0], scope=query[1]).rows(), queries * 4))
        assert answers[: len(queries)] == [[("exp j1", 3)], [("exp j2", 2)], [(15.0,)], [(4.5,)], [(1.5,)], [(9.0,)]]
        assert answers == answers[: len(queries)] * 4
    finally:
        backend.close()
