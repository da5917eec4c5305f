"""The forwarding backend, tested for real: `TrinoBackend` sends queries with the official `trino` client
to a second `lakegate serve` on loopback (it speaks Trino's protocol; the shared test lake and server
of conftest.py), and every answer is compared with the embedded DuckDB backend's on the same lake:
columns, Trino types, values, scopes, parameters, errors with their positions in the user's SQL,
cancelation, schemas and branches. `lakegate metrics run --backend trino` gives the results of the
DuckDB backend, and password authentication over TLS reaches the server."""

from __future__ import annotations

import argparse
import gc
import json
import math
import re
import socket
import subprocess
import sys
from pathlib import Path

import bcrypt
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import requests

from lakegate.dialect.errors import ERROR_CODES, DialectError
from lakegate.dialect.scope import Scope
from lakegate.dialect.translate import parse
from lakegate.fixtures.generate import CONFIG_PATH, generate_batch
from lakegate.gateway.cli.backends import backend_from_args
from lakegate.gateway.cli.command_errors import UserError
from lakegate.gateway.cli.parsers.shared_options import add_backend_arguments
from lakegate.gateway.engine import trino_backend
from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.trino_backend import RemoteQueryError, TrinoBackend, forwarded_sql
from lakegate.gateway.engine.trino_ddl import schema_name
from lakegate.gateway.metrics.results_table import read_results
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file
from lakegate.lake.record import current_file

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
TOPIC = "odom_linear_velocity"


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def start_server(lake: Path, log: Path, *args: str) -> tuple[subprocess.Popen, str]:
    """`lakegate serve` of `lake` on 127.0.0.1 and its URL, once it says it is serving."""
    process = subprocess.Popen(
        [*CLI, "serve", "--lake", str(lake), "--port", "0", *args],
        stdout=subprocess.PIPE,
        stderr=log.open("w"),
        text=True,
    )
    line = process.stdout.readline()  # `lakegate: serving <lake> at <url> ...`, or nothing when it failed
    if " at " not in line:
        process.kill()
        process.wait()
        raise RuntimeError(f"lakegate serve did not start: {line}{log.read_text()}")
    return process, line.split(" at ", 1)[1].split()[0]


def stop_server(process: subprocess.Popen) -> None:
    process.terminate()
    try:
        process.wait(20)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    process.stdout.close()


@pytest.fixture(scope="module")
def remote(lake_server):
    backend = TrinoBackend(lake_server.url, user="tester", catalog="lake", schema_map={"*": "{branch}"})
    yield backend
    backend.close()


@pytest.fixture(scope="module")
def local(server_lake):
    backend = DuckDBBackend(server_lake)
    yield backend
    backend.close()


@pytest.fixture(scope="module")
def jobs(local) -> list[tuple[str, str]]:
    """(batch, job) of every job of branch main, in order."""
    return local.execute("SELECT batch_id, job_id FROM metadata ORDER BY batch_id, time, job_id").rows()


def same(a: object, b: object) -> bool:
    """Equal values at any depth; doubles equal to the last bits a parallel sum may change (DuckDB's
    threads add in any order, so even two runs of one backend differ there), NaN equal to NaN, and
    of the same Python types (1.25 is not Decimal('1.25'))."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return math.isclose(a, b, rel_tol=1e-12) or (math.isnan(a) and math.isnan(b))
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return a == b


def answer(backend, sql: str, **kwargs) -> tuple[list, list]:
    """Columns and rows of `sql`; the DuckDB side's SHOW and DESCRIBE are its Engine's (they are
    answered by the system tables, a backend runs queries only)."""
    if isinstance(backend, DuckDBBackend) and sql.startswith(("SHOW", "DESCRIBE")):
        engine = Engine(backend)
        result = engine.execute(sql, engine.session(branch="main", scope=kwargs.get("scope")))
    else:
        result = backend.execute(sql, **kwargs)
    return result.columns, result.rows()


def job_rows(lake: Path, batch: str, job_id: str) -> int:
    """Rows of the topic's Parquet file of one job of main, read directly."""
    return pq.read_metadata(current_file(lake, "main", TOPIC, batch, job_id)).num_rows


QUERIES = [
    (
        "integers and doubles",
        f"SELECT job_id, count(*) AS n, avg(x), sum(timestamp), max(y) - min(y) FROM {TOPIC} GROUP BY 1 ORDER BY 1",
    ),
    (
        "decimals",
        f"SELECT job_id, CAST(avg(x) AS decimal(12,4)) AS d, sum(CAST(x AS decimal(10,3))) FROM {TOPIC} "
        "GROUP BY 1 ORDER BY 1",
    ),
    (
        "varchar, arrays, timestamps",
        "SELECT job_id, experience_name, experience_tag_names, custom_field_keys, time, "
        "build_creation_timestamp, date_trunc('hour', time) AS hour FROM metadata "
        "ORDER BY job_id",
    ),
    ("every metadata column", "SELECT * FROM metadata ORDER BY job_id"),
    (
        "event rows",
        "SELECT job_id, timestamp, name, status, tags, metrics FROM events ORDER BY job_id, timestamp, name",
    ),
    (
        "metadata join",
        f"SELECT m.experience_name, count(*) AS n, max(o.x) FROM {TOPIC} o JOIN metadata m "
        "ON o.job_id = m.job_id AND o.batch_id = m.batch_id GROUP BY 1 ORDER BY 1",
    ),
    (
        "literals of every type",
        "SELECT 1.25 d, nan() n, infinity() i, DATE '2024-01-02' dt, "
        "TIMESTAMP '2024-01-02 03:04:05.123456' ts, ARRAY[1, 2, NULL] a, "
        "MAP(ARRAY['a'], ARRAY[1.5]) m, CAST(ROW(1, 'x') AS ROW(a bigint, b varchar)) r, "
        "CAST(NULL AS bigint) nl, 5 / 2 q, typeof(1) t, CAST(1.5 AS real) re, "
        "CAST(3 AS smallint) sm, CAST(3 AS tinyint) ti, "
        "TIMESTAMP '2024-01-02 03:04:05.123 UTC' tz, INTERVAL '3' DAY iv, "
        "INTERVAL '14' MONTH ym, true b",
    ),
    ("a CTE that shadows a topic", f"WITH {TOPIC} AS (SELECT 7 AS x) SELECT x FROM {TOPIC}"),
    ("no rows", f"SELECT timestamp, x FROM {TOPIC} WHERE x > 1e9"),
    ("SHOW TABLES", "SHOW TABLES"),
    ("DESCRIBE", "DESCRIBE metadata"),
]


@pytest.mark.parametrize("sql", [sql for _, sql in QUERIES], ids=[name for name, _ in QUERIES])
@pytest.mark.parametrize("scope", [None, Scope("b1"), Scope("b1", "JOB")], ids=["branch", "batch", "job"])
def test_queries_answer_as_the_duckdb_backend(jobs, remote, local, sql, scope):
    if scope is not None and scope.job_id == "JOB":
        scope = Scope(*jobs[1])
    theirs = answer(local, sql, scope=scope)
    ours = answer(remote, sql, scope=scope)
    assert ours[0] == theirs[0]
    assert bool(ours[1]) == ("WHERE x > 1e9" not in sql)
    assert same(ours[1], theirs[1]), (ours[1][:3], theirs[1][:3])


def test_scopes_restrict_every_lake_table_to_the_batch_or_job(server_lake, jobs, remote):
    counts = {job: job_rows(server_lake, batch, job) for batch, job in jobs}
    sql = f"SELECT o.job_id, count(*) FROM {TOPIC} o JOIN metadata m ON o.job_id = m.job_id GROUP BY 1 ORDER BY 1"
    assert answer(remote, sql)[1] == sorted(counts.items())
    b1 = [job for batch, job in jobs if batch == "b1"]
    assert len(b1) == 2 and len(jobs) == 3
    assert answer(remote, sql, scope=Scope("b1"))[1] == sorted((j, counts[j]) for j in b1)
    assert answer(remote, sql, scope=Scope("b1", b1[1]))[1] == [(b1[1], counts[b1[1]])]
    assert answer(remote, sql, scope=Scope("b2", b1[1]))[1] == []


@pytest.mark.parametrize("params", [(0.5, "no such job"), (-1e300, ""), (1.0, "it's")])
def test_parameters_bind_as_literals(remote, local, params):
    sql = f"SELECT count(*), ? AS threshold FROM {TOPIC} WHERE x > ? AND job_id <> ?"
    values = (params[0], *params)
    assert answer(remote, sql, params=values) == answer(local, sql, params=values)
    assert answer(remote, sql, params=values, scope=Scope("b2"))[1][0][1] == params[0]


def test_batches_carry_the_arrow_types_of_the_trino_types(remote):
    result = remote.execute(
        "SELECT 1.25 d, CAST(2 AS bigint) b, 2 i, 1.5e0 x, 'v' s, DATE '2024-01-02' dt, "
        "TIMESTAMP '2024-01-02 03:04:05.123' t3, TIMESTAMP '2024-01-02 03:04:05.123456' t6, "
        "ARRAY['a'] a, MAP(ARRAY['k'], ARRAY[1]) m, "
        "CAST(ROW(1, 'x') AS ROW(a bigint, b varchar)) r, NULL n"
    )
    batch = next(result.batches)
    assert batch.schema.types == [
        pa.decimal128(3, 2),
        pa.int64(),
        pa.int32(),
        pa.float64(),
        pa.string(),
        pa.date32(),
        pa.timestamp("ms"),
        pa.timestamp("us"),
        pa.list_(pa.string()),
        pa.map_(pa.string(), pa.int32()),
        pa.struct([("a", pa.int64()), ("b", pa.string())]),
        pa.null(),
    ]
    assert batch.to_pylist()[0]["t3"].microsecond == 123000


def error_of(backend, sql: str, **kwargs) -> DialectError:
    with pytest.raises(DialectError) as caught:
        backend.execute(sql, **kwargs).rows()
    return caught.value


@pytest.mark.parametrize(
    "sql, params, name, where",
    [
        ("SELECT nope FROM odom_linear_velocity", (), "COLUMN_NOT_FOUND", (1, 8)),
        (
            "SELECT x\nFROM odom_linear_velocity o JOIN metadata m ON o.job_id = m.job_id\n"
            "  WHERE o.x > ? AND m.nope = ?",
            (1.5, "it's"),
            "COLUMN_NOT_FOUND",
            (3, 21),
        ),
        ("SELECT count(*) FROM odom_linear_velocity o, nope_table", (), "TABLE_NOT_FOUND", (1, 46)),
    ],
)
@pytest.mark.parametrize("scope", [None, Scope("b1", "j")], ids=["unscoped", "scoped"])
def test_remote_errors_keep_their_name_and_the_position_in_the_users_sql(
    remote, local, sql, params, name, where, scope
):
    ours, theirs = error_of(remote, sql, params=params, scope=scope), error_of(local, sql, params=params, scope=scope)
    assert isinstance(ours, RemoteQueryError)
    assert (ours.error_name, ours.line, ours.column) == (name, *where)
    assert (theirs.error_name, theirs.line, theirs.column) == (name, *where)
    assert ours.error_code == ERROR_CODES[name] and ours.error_type == "USER_ERROR" and ours.query_id
    assert not ours.message.startswith("line ")


def test_runtime_errors_arrive_while_reading(remote):
    error = error_of(remote, f"SELECT 1 / (count(*) - count(*)) FROM {TOPIC}")
    assert error.error_name == "DIVISION_BY_ZERO"


def test_the_guard_refuses_before_anything_is_sent():
    unreachable = TrinoBackend(f"http://127.0.0.1:{free_port()}", catalog="lake")  # nothing listens there
    error = error_of(unreachable, "DELETE FROM metadata")
    assert error.error_name == "PERMISSION_DENIED" and "read-only" in error.message
    assert error_of(unreachable, "SELECT read_parquet('/etc/passwd')").error_name == "PERMISSION_DENIED"
    gone = error_of(unreachable, "SELECT 1")
    assert gone.error_name == "GENERIC_INTERNAL_ERROR" and "the Trino cluster at http://127.0.0.1:" in gone.message


def test_cancel_stops_a_streaming_query(remote):
    result = remote.execute(
        "SELECT a.x * b.x FROM UNNEST(sequence(1, 10000)) a(x) CROSS JOIN UNNEST(sequence(1, 10000)) b(x)"
    )
    first = next(result.batches)
    assert first.num_rows > 0
    result.cancel()
    with pytest.raises(DialectError) as caught:
        for _ in result.batches:
            pass
    assert caught.value.error_name == "USER_CANCELED"
    assert answer(remote, "SELECT 1")[1] == [(1,)]  # the server goes on serving


def test_schema_and_branches_come_from_the_cluster(remote, local, all_types):
    branch, _ = all_types
    assert remote.schema("main") == local.schema("main")
    assert remote.schema(branch) == local.schema(branch)
    assert {"main", branch} <= set(remote.branches())


def test_a_branch_maps_to_its_schema(lake_server, remote, local, all_types):
    branch, emitted = all_types
    sql = "SELECT s, tags, metrics FROM sample ORDER BY timestamp"
    explicit = TrinoBackend(lake_server.url, catalog="lake", schema_map={"work": branch})
    default = TrinoBackend(lake_server.url, catalog="lake")
    try:
        assert (
            answer(explicit, sql, branch="work")
            == answer(remote, sql, branch=branch)
            == answer(local, sql, branch=branch)
        )
        assert [row[0] for row in answer(explicit, sql, branch="work")[1]] == [row["s"] for row in emitted]
        assert default.schema_for(branch) == schema_name(branch) != branch
        assert error_of(default, sql, branch=branch).error_name in ("SCHEMA_NOT_FOUND", "TABLE_NOT_FOUND")
    finally:
        explicit.close()
        default.close()


def test_the_forwarded_text_is_the_users_with_only_the_edits():
    forwarded = forwarded_sql(
        "SELECT o.x, ?  -- the threshold\nFROM odom o CROSS JOIN lake.main.metadata\n WHERE x > ?;",
        scope=Scope("b'1", "j1"),
        params=[1.5, "it's"],
        tables={"odom", "metadata"},
    )
    assert forwarded.sql == (
        "SELECT o.x, 1.5E0  -- the threshold\n"
        "FROM (SELECT * FROM odom WHERE batch_id = 'b''1' AND job_id = 'j1') o CROSS JOIN "
        "(SELECT * FROM lake.main.metadata WHERE batch_id = 'b''1' AND job_id = 'j1') metadata\n WHERE x > 'it''s'"
    )
    # positions in the sent text map back to the user's: unchanged text exactly, edits to their start
    sent = forwarded.sql
    line3 = sent.split("\n")[2]
    assert forwarded.user_position(3, line3.index("x >") + 1) == (3, 8)
    assert forwarded.user_position(2, sent.split("\n")[1].index("JOIN") + 1) == (2, 19)
    assert forwarded.user_position(2, sent.split("\n")[1].index("job_id") + 1) == (2, 6)
    assert forwarded.user_position(1, 13) == (1, 13)
    explain = forwarded_sql("EXPLAIN (TYPE IO)\nSELECT * FROM odom", scope=Scope("b"), tables={"odom"})
    assert explain.sql == "EXPLAIN (TYPE IO)\nSELECT * FROM (SELECT * FROM odom WHERE batch_id = 'b') odom"
    several = forwarded_sql("SELECT x FROM odom", scope=Scope(batches=("a", "b'2")), tables={"odom"})
    assert several.sql == "SELECT x FROM (SELECT * FROM odom WHERE batch_id IN ('a', 'b''2')) odom"  # dashboards
    with pytest.raises(DialectError) as caught:
        forwarded_sql("SELECT ?, ?", params=[1])
    assert caught.value.error_name == "INVALID_PARAMETER_USAGE"


def lakegate(*args) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=300)


def test_metrics_run_forwarded_to_trino_gives_the_duckdb_results(tmp_path_factory):
    """Every metric of the fixture config on the same batch in two identical lakes: one evaluated
    with embedded DuckDB, one through a `lakegate serve` of it (so the batch metrics also read the
    job statuses the engine wrote). The JSON and the stored results (figures included) match."""
    root = tmp_path_factory.mktemp("metrics-forwarding")
    jobs = generate_batch(root / "inputs", jobs=3, samples_per_goal=8)
    config = load_config(CONFIG_PATH)
    for name in ("duckdb", "trino"):
        BranchConfigs(root / name, "main").store([CONFIG_PATH])
        for job in jobs:
            ingest_job(
                root / name,
                "main",
                "nav",
                job.job_id,
                [job.emissions_path],
                config=config,
                metadata=load_metadata_file(job.metadata_path),
                logs=job.logs_dir,
            )
    run = ["metrics", "run", "--branch", "main", "--batch", "nav", "--all-metrics", "--format", "json"]
    process, url = start_server(root / "trino", root / "serve.log")
    try:
        forwarded = lakegate(
            *run,
            "--lake",
            root / "trino",
            "--backend",
            "trino",
            "--trino-url",
            url,
            "--trino-catalog",
            "lake",
            "--trino-schema-map",
            "*={branch}",
        )
    finally:
        stop_server(process)
    embedded = lakegate(*run, "--lake", root / "duckdb")
    assert embedded.returncode == 2, embedded.stderr  # the generated batch has a BLOCKER job
    assert forwarded.returncode == embedded.returncode, forwarded.stderr
    # Image metrics name their files in each lake's own logs: the two lakes differ only by folder.
    same_lake = (str(root / "trino"), str(root / "duckdb"))
    ours, theirs = json.loads(forwarded.stdout.replace(*same_lake)), json.loads(embedded.stdout)
    assert ours.pop("evaluated_at") and theirs.pop("evaluated_at")
    assert same(ours, theirs), [(a, b) for a, b in zip(ours["metrics"], theirs["metrics"]) if a != b]
    statuses = {m["status"] for m in ours["metrics"]}
    assert {"PASSED", "WARNING", "BLOCKER"} <= statuses and "ERROR" not in statuses
    unordered = {
        name for name, metric in config.metrics.items() if parse(metric.query_string).args.get("order") is None
    }

    def comparable(row: dict) -> dict:
        """A stored result without its time; a table of a query without ORDER BY as a set of rows."""
        row = {k: json.loads(v) if k.endswith("_json") and v else v for k, v in row.items() if k != "evaluated_at"}
        if row["metric_name"] in unordered and (row["details_json"] or {}).get("table"):
            row["details_json"]["table"]["rows"].sort(key=repr)
            del row["figure_json"]  # drawn from those rows, in their order
        return row

    stored = [[comparable(row) for row in read_results(root / name, "main", "nav")] for name in ("trino", "duckdb")]
    # ... and each ingest commits a job's logs into a folder of its own (`<pid>-<id>`).
    stored = [
        json.loads(re.sub(r"(_job_logs/[^/]+/[^/]+/)[^/]+/", r"\1*/", json.dumps(rows).replace(*same_lake)))
        for rows in stored
    ]
    differing = [(a["metric_name"], k, a[k], b[k]) for a, b in zip(*stored) for k in a if not same(a[k], b.get(k))]
    assert not differing and len(stored[0]) == len(stored[1]) == len(ours["metrics"]), differing[:3]
    assert sum(1 for row in stored[0] if row.get("figure_json")) > 10


def test_backend_options_are_checked(server_lake):
    run = lakegate(
        "metrics",
        "run",
        "--lake",
        server_lake,
        "--branch",
        "main",
        "--batch",
        "b1",
        "--all-metrics",
        "--backend",
        "trino",
    )
    assert run.returncode == 1 and run.stderr == "lakegate: --backend trino needs --trino-url\n"
    parser = argparse.ArgumentParser()
    add_backend_arguments(parser)
    for args, message in [
        (["--trino-url", "ftp://x"], "--trino-url 'ftp://x' is not an http:// or https:// URL"),
        (
            ["--trino-url", "http://h:1", "--trino-password-env", "LAKEGATE_NO_SUCH_VAR"],
            "environment variable LAKEGATE_NO_SUCH_VAR is not set",
        ),
        (["--trino-url", "http://h:1", "--trino-jwt-env", "HOME"], "credentials need an https:// URL"),
        (
            ["--trino-url", "http://h:1", "--trino-schema-map", "main"],
            "--trino-schema-map 'main': expected BRANCH=SCHEMA",
        ),
        (["--trino-url", "http://h:1", "--trino-schema-prefix", "A-"], "schema prefix 'A-' may only contain"),
    ]:
        with pytest.raises(UserError, match=re.escape(message)):
            backend_from_args(parser.parse_args(["--backend", "trino", *args]), server_lake)
    chosen = backend_from_args(
        parser.parse_args(
            [
                "--backend",
                "trino",
                "--trino-url",
                "https://h",
                "--trino-user",
                "me",
                "--trino-schema-map",
                "main=robots",
                "--trino-insecure",
            ]
        ),
        server_lake,
    )
    assert isinstance(chosen, TrinoBackend) and chosen.schema_for("main") == "robots" and chosen.user == "me"
    embedded = backend_from_args(parser.parse_args([]), server_lake)
    assert isinstance(embedded, DuckDBBackend)
    embedded.close()


def test_without_exact_positions_the_query_is_regenerated_and_errors_carry_none(monkeypatch):
    monkeypatch.setattr(trino_backend, "_span", lambda table: None)  # as if sqlglot kept no position
    forwarded = forwarded_sql("SELECT x FROM odom WHERE x > ?", scope=Scope("b"), params=[2], tables={"odom"})
    assert forwarded.sql == "SELECT x FROM (SELECT * FROM odom WHERE batch_id = 'b') AS odom WHERE x > 2"
    assert forwarded.user_position(1, 10) == (None, None)


def test_a_password_goes_over_tls_to_the_cluster(server_lake, tmp_path, monkeypatch, make_certificate):
    """`lakegate serve --users --tls-cert` as the cluster: HTTP Basic over https, with the server's
    self-signed certificate as the CA bundle (which wins over REQUESTS_CA_BUNDLE, unlike in a plain
    requests session); a wrong password is a clear error."""
    monkeypatch.setenv("REQUESTS_CA_BUNDLE", requests_ca_bundle())
    cert_file, key_file = make_certificate(tmp_path, "lakegate forwarding test")
    users = tmp_path / "users.txt"
    users.write_text(f"alice:{bcrypt.hashpw(b'wonderland', bcrypt.gensalt(4)).decode()}\n")
    process, url = start_server(
        server_lake,
        tmp_path / "serve.log",
        "--users",
        str(users),
        "--tls-cert",
        str(cert_file),
        "--tls-key",
        str(key_file),
    )
    backends = [
        TrinoBackend(
            url, user="alice", catalog="lake", schema_map={"*": "{branch}"}, password=password, verify=str(cert_file)
        )
        for password in ("wonderland", "nope")
    ]
    try:
        assert url.startswith("https://")
        assert answer(backends[0], "SELECT count(*) FROM metadata", scope=Scope("b1"))[1] == [(2,)]
        assert "401" in error_of(backends[1], "SELECT 1").message
    finally:
        for backend in backends:
            backend.close()  # kept-alive connections would hold up the server's graceful stop,
        gc.collect()  # and so would the one the caught 401's traceback still holds
        stop_server(process)


def requests_ca_bundle() -> str:
    """The CA bundle requests uses by default (certifi's)."""
    return requests.utils.DEFAULT_CA_BUNDLE_PATH
