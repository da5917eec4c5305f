"""Forwarding to the real Trino 476 (the session fixture `trino_url`): `lakegate trino-ddl --apply`
registers a lake in its hive catalog and records where, `--backend trino --trino-url URL` finds
that registration with no other flag, and

- `metrics run` / `metrics dashboard` forwarded to Trino, directly and through a `lakegate serve`
  that forwards to it, give the embedded engine's metric values, statuses and `metric_results` rows
  for every metric of fixtures/ and tests/compat/configs/ on the demo lake;
- Trino sees each job exactly once after an ingest, a re-ingest of a job with fewer topics, a
  compaction and the status updates of `metrics run`;
- registering reports what stands in the way (Trino unreachable, no such catalog, not a Hive
  catalog, a branch in layout v1, a schema or table of that name elsewhere, an old registration).

Every schema lives under a prefix of this module's own and is dropped at the end (`trino-ddl --drop`:
the lake's files stay).
"""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import uuid
from pathlib import Path
from urllib.parse import urlsplit

import pytest
import trino
from sqlglot import exp

from lakegate.dialect.translate import parse
from lakegate.fixtures.generate import CONFIG_PATH, generate_batch
from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.gateway.engine.trino_registration import RECORD, read_registration
from lakegate.gateway.metrics.plotly_arrays import is_typed, plain
from lakegate.gateway.metrics.results_table import read_results
from lakegate.lake import paths
from lakegate.lake.catalog import Catalog
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file
from tests.compat import test_platform_tables as platform
from tests.compat import test_resim_configs as robot
from tests.compat import test_resim_media as field
from tests.gateway.test_trino_backend import CLI, same, start_server, stop_server
from tests.lake.v1_lake import to_v1

PREFIX = f"forwarding_{uuid.uuid4().hex[:8]}_"


def lakegate(*args, timeout: float = 1800) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=timeout)


def cursor(url: str) -> trino.dbapi.Cursor:
    parts = urlsplit(url)
    return trino.dbapi.connect(host=parts.hostname, port=parts.port, user="lakegate-tests").cursor()


def trino_rows(url: str, sql: str) -> list[list]:
    cur = cursor(url)
    cur.execute(sql)
    return cur.fetchall()


@pytest.fixture(scope="module")
def registered(trino_url):
    """`register(lake, name)`: `lakegate trino-ddl --apply` of `lake` under this module's prefix +
    `name`; every registration is dropped at the end."""
    lakes = []

    def register(lake: Path, name: str, *more: str) -> subprocess.CompletedProcess:
        done = lakegate(
            "trino-ddl", "--lake", lake, "--apply", "--trino-url", trino_url, "--schema-prefix", PREFIX + name, *more
        )
        assert done.returncode == 0, done.stderr
        lakes.append(lake)
        return done

    yield register
    failed = []
    for lake in lakes:
        if lake.is_dir() and read_registration(lake, trino_url) is not None:
            dropped = lakegate("trino-ddl", "--lake", lake, "--drop", "--trino-url", trino_url)
            failed += [dropped.stderr] if dropped.returncode else []
    for (schema,) in trino_rows(trino_url, f"SHOW SCHEMAS FROM hive LIKE '{PREFIX}%'"):  # what a failure left
        for (table,) in trino_rows(trino_url, f"SHOW TABLES FROM hive.{schema}"):
            trino_rows(trino_url, f"DROP TABLE hive.{schema}.{table}")
        trino_rows(trino_url, f"DROP SCHEMA hive.{schema}")
        failed.append(f"schema {schema} was left")
    assert failed == []


# --- every metric, embedded and forwarded ----------------------------------------------------------


def demo_lake(root: Path) -> Path:
    """`lakegate demo` (3 jobs, the dashboard's earlier builds) plus branch `robot` (the split config of
    tests/compat, its 2 jobs), branch `field` (the field robot config, its job and log files) and branch
    `platform` (the config over the platform tables, its 3 job folders, one without platform files)."""
    lake = root / "lake"
    demo = lakegate("demo", "--lake", lake, "--jobs", "3", "--no-progress")
    assert demo.returncode == 0, demo.stderr
    split = [arg for path in robot.SPLIT for arg in ("--metrics-config-path", path)]
    for job_id, job in robot.JOBS.items():
        done = lakegate(
            "ingest", "--lake", lake, "--branch", "robot", "--batch", "b1", "--job", job_id, *split,
            "--build-version", "1.0", "--no-progress", robot.emissions(root / f"{job_id}.jsonl", job),
        )  # fmt: skip
        assert done.returncode == 0, done.stderr
    done = lakegate(
        "ingest", "--lake", lake, "--branch", "field", "--batch", "b1", "--job", "j1",
        "--metrics-config-path", field.CONFIG, "--no-progress", field.emissions(root / "field.jsonl"),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    logs = paths.logs_dir(lake, "field", "b1", "j1")
    for name, data in field.LOGS.items():
        (logs / name).parent.mkdir(parents=True, exist_ok=True)
        (logs / name).write_bytes(data)
    platform.ingest(lake, root / "platform", branch="platform")
    return lake


#: (branch, batch, config files: None for the branch's stored one) of every metrics run compared.
RUNS = [
    ("main", "nav-regression-1", None),
    ("robot", "b1", robot.SPLIT),
    ("field", "b1", [field.CONFIG]),
    ("platform", "b1", [platform.CONFIG]),
]


def without_times(value):
    """A JSON value without its `evaluated_at` times and the run's duration, at any depth, with a
    figure's typed arrays as lists (their bytes hold a double's last bits, which may differ)."""
    if is_typed(value):
        return plain(value)
    if isinstance(value, dict):
        return {k: without_times(v) for k, v in value.items() if k not in ("evaluated_at", "seconds", "duration")}
    if isinstance(value, list):
        return [without_times(v) for v in value]
    return value


def metric_kinds(configs: list[Path] | None) -> tuple[set[str], set[str]]:
    """The metrics whose query has no ORDER BY (their tables compare as sets of rows) and those that
    select `*` (their tables compare by column name: in Trino `batch_id`, the Hive partition
    column, comes last, a difference README's Trino section states)."""
    config = load_config(configs or [CONFIG_PATH, CONFIG_PATH.parent / "dashboard.resim.yaml"])
    unordered, starred = set(), set()
    for name, metric in config.metrics.items():
        query = parse(metric.query_string)
        if query.args.get("order") is None:
            unordered.add(name)
        if any(isinstance(e, exp.Star) for e in query.expressions):
            starred.add(name)
    return unordered, starred


def by_name(table: dict) -> dict:
    """A result table with its columns in name order."""
    order = sorted(range(len(table["columns"])), key=lambda i: table["columns"][i])
    return {
        **table,
        "columns": [table["columns"][i] for i in order],
        "rows": [[r[i] for i in order] for r in table["rows"]],
    }


def comparable(row: dict, kinds: tuple[set[str], set[str]], lake: Path) -> dict:
    """A stored result without its time and its lake's folder (image paths); a table of a query
    without ORDER BY as a set of rows, of a `SELECT *` by column name."""
    unordered, starred = kinds
    row = {k: v for k, v in row.items() if k != "evaluated_at"}
    row = {
        k: without_times(json.loads(v.replace(str(lake), "<lake>"))) if k.endswith("_json") and v else v
        for k, v in row.items()
    }
    table = (row["details_json"] or {}).get("table")
    if table and row["metric_name"] in starred:
        row["details_json"]["table"] = table = by_name(table)
        del row["figure_json"]  # drawn in the columns' order
    if row["metric_name"] in unordered:
        row["value_text"] = unordered_summary(row["value_text"])
        if table:
            table["rows"].sort(key=repr)
            row.pop("figure_json", None)  # drawn from those rows, in their order
    return row


def comparable_output(output: dict, kinds: tuple[set[str], set[str]]) -> dict:
    unordered, starred = kinds
    output = without_times(output)
    for metric in output.get("metrics", []):
        if isinstance(metric.get("table"), dict) and metric.get("metric") in starred:
            metric["table"] = by_name(metric["table"])
            metric.pop("figure", None)
        if metric.get("metric") in unordered:
            metric["value"] = unordered_summary(metric.get("value"))
            if isinstance(metric.get("table"), dict):
                metric["table"]["rows"].sort(key=repr)
                metric.pop("figure", None)
    return output


def unordered_summary(text: str | None) -> str | None:
    """A small table's one-line summary (`a: 1; b: 2`, its rows in their order) with its parts sorted:
    the rows of a query without ORDER BY come in any order, from Trino as from DuckDB."""
    return "; ".join(sorted(text.split("; "))) if text else text


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_every_metric_forwarded_to_trino_gives_the_embedded_results(tmp_path_factory, trino_url, registered):
    root = tmp_path_factory.mktemp("forwarding")
    lakes = {"embedded": demo_lake(root)}
    for name in ("trino", "served"):
        lakes[name] = root / name
        shutil.copytree(lakes["embedded"], lakes[name], symlinks=True)
        applied = registered(lakes[name], f"{name}_")
        assert applied.stdout.startswith("branch 'field' -> hive.")  # every branch, sorted
        assert f"recorded in {lakes[name] / RECORD}" in applied.stdout
    process, served_url = start_server(
        lakes["served"], root / "serve.log", "--backend", "trino", "--trino-url", trino_url
    )
    flags = {
        "embedded": [],
        "trino": ["--backend", "trino", "--trino-url", trino_url],  # nothing else: the registration says where
        "served": ["--backend", "trino", "--trino-url", served_url, "--trino-catalog", "lake"]
        + ["--trino-schema-map", "*={branch}"],
    }
    compared = {"test and batch metrics": 0, "dashboard metrics": 0}
    try:
        for branch, batch, configs in RUNS:
            config_args = [a for path in configs or [] for a in ("--metrics-config-path", path)]
            kinds = metric_kinds(configs)
            outputs, stored = {}, {}
            for name, lake in lakes.items():
                done = lakegate(
                    "metrics", "run", "--lake", lake, "--branch", branch, "--batch", batch, "--all-metrics",
                    *config_args, "--format", "json", "--no-progress", "--no-compact", *flags[name],
                )  # fmt: skip
                assert done.returncode in (0, 2), (name, branch, done.stderr)
                outputs[name] = (
                    done.returncode,
                    comparable_output(json.loads(done.stdout.replace(str(lake), "<lake>")), kinds),
                )
                stored[name] = [comparable(row, kinds, lake) for row in read_results(lake, branch, batch)]
            for name in ("trino", "served"):
                assert outputs[name][0] == outputs["embedded"][0], (name, branch)
                ours, theirs = outputs[name][1]["metrics"], outputs["embedded"][1]["metrics"]
                assert same(ours, theirs), (name, branch, [(a, b) for a, b in zip(ours, theirs) if not same(a, b)])
                assert same(outputs[name][1], outputs["embedded"][1]), (name, branch)
                assert same(stored[name], stored["embedded"]), (name, branch)
                assert len(stored[name]) == len(ours)
            compared["test and batch metrics"] += len(outputs["embedded"][1]["metrics"])
            statuses = {metric["status"] for metric in outputs["embedded"][1]["metrics"]}
            assert "ERROR" not in statuses or branch == "field", (branch, statuses)
        dashboards = {}
        for name, lake in lakes.items():
            done = lakegate(
                "metrics", "dashboard", "--lake", lake, "--branch", "main", "--format", "json", *flags[name]
            )
            assert done.returncode in (0, 2), (name, done.stderr)
            dashboards[name] = comparable_output(
                json.loads(done.stdout.replace(str(lake), "<lake>")), metric_kinds(None)
            )
        for name in ("trino", "served"):
            ours, theirs = dashboards[name]["metrics"], dashboards["embedded"]["metrics"]
            assert same(ours, theirs), (name, [(a, b) for a, b in zip(ours, theirs) if not same(a, b)])
            assert same(dashboards[name], dashboards["embedded"]), name
        compared["dashboard metrics"] += len(dashboards["embedded"]["metrics"])
    finally:
        stop_server(process)
    print(f"forwarding compared: {compared}")
    assert compared["test and batch metrics"] >= 60 and compared["dashboard metrics"] >= 2
    # the job statuses metrics run wrote are the same rows in the three lakes, and in Trino
    sql = "SELECT batch_id, job_id, job_metrics_status, job_conflated_status FROM metadata ORDER BY 1, 2"
    expected = DuckDBBackend(lakes["embedded"]).execute(sql, branch="main").rows()
    schema = read_registration(lakes["trino"], trino_url).schemas["main"]
    assert [tuple(r) for r in trino_rows(trino_url, sql.replace("metadata", f"hive.{schema}.metadata"))] == expected


# --- each job exactly once ---------------------------------------------------------------------------


def census(url: str, lake: Path, schema: str) -> dict[str, list]:
    """Per table of branch main: the (batch, job, rows) Trino sees, checked equal to what the embedded
    backend sees in the lake (a table Trino lacks must be empty in the lake)."""
    local = DuckDBBackend(lake)
    registered = {row[0] for row in trino_rows(url, f"SHOW TABLES FROM hive.{schema}")}
    seen = {}
    try:
        for table in Catalog(lake).schema("main"):
            sql = f"SELECT batch_id, job_id, count(*) FROM {table} GROUP BY 1, 2"
            expected = sorted(local.execute(sql, branch="main").rows(), key=repr)
            got = []
            if table in registered:
                got = sorted(
                    (tuple(r) for r in trino_rows(url, sql.replace(table, f"hive.{schema}.{table}"))), key=repr
                )
            assert got == expected, (table, got, expected)
            seen[table] = got
    finally:
        local.close()
    return seen


def jobs_of(seen: dict[str, list]) -> list[tuple[str, str]]:
    """(batch, job) of each metadata row Trino sees: each job once."""
    return sorted((batch, job) for batch, job, rows in seen["metadata"] for _ in range(rows))


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_trino_sees_each_job_once_through_ingests_compaction_and_metrics_runs(tmp_path, trino_url, registered):
    generated = generate_batch(tmp_path / "inputs", jobs=3, samples_per_goal=3)
    config = load_config(CONFIG_PATH)
    lake = tmp_path / "lake"

    def ingest(batch: str, job, emissions: Path | None = None) -> None:
        metadata = load_metadata_file(job.metadata_path)
        ingest_job(lake, "main", batch, job.job_id, [emissions or job.emissions_path], config=config, metadata=metadata)

    one, two, three = generated
    ingest("b1", one)
    ingest("b1", two)
    registered(lake, "once_")
    schema = read_registration(lake, trino_url).schemas["main"]
    assert jobs_of(census(trino_url, lake, schema)) == sorted([("b1", one.job_id), ("b1", two.job_id)])

    ingest("b1", three)  # a new job of a registered batch: seen at once, no new partition
    assert len(jobs_of(census(trino_url, lake, schema))) == 3

    ingest("b2", three)  # a new batch: a new partition, which metrics run --backend trino syncs itself
    run = ["metrics", "run", "--lake", lake, "--branch", "main", "--all-metrics", "--no-progress"]
    run += ["--format", "json", "--backend", "trino", "--trino-url", trino_url]
    done = lakegate(*run, "--batch", "b2", "--no-compact")
    assert done.returncode in (0, 2), done.stderr
    seen = census(trino_url, lake, schema)  # the statuses written, the metric_results partition synced
    assert ("b2", three.job_id) in jobs_of(seen) and {r[0] for r in seen["metric_results"]} == {"b2"}

    topics = {"odom_linear_velocity", "goal_status"}
    fewer = tmp_path / "fewer.jsonl"
    lines = one.emissions_path.read_text().splitlines()
    fewer.write_text("".join(line + "\n" for line in lines if json.loads(line)["$metadata"]["topic"] in topics))
    ingest("b1", one, fewer)  # the job's other topics are gone, for Trino too
    seen = census(trino_url, lake, schema)
    assert {t for t, rows in seen.items() if any(r[1] == one.job_id for r in rows)} == {*topics, "metadata"}
    assert len(jobs_of(seen)) == 4

    compacted = lakegate("lake", "compact", "--lake", lake, "--branch", "main")
    assert compacted.returncode == 0 and "compacted batch 'b1'" in compacted.stdout, compacted.stderr
    assert len(jobs_of(census(trino_url, lake, schema))) == 4

    ingest("b1", two)  # a re-ingest into the compacted batch rewrites its shared files without the job
    assert len(jobs_of(census(trino_url, lake, schema))) == 4

    done = lakegate(*run, "--batch", "b1")  # statuses of b1, then compaction
    assert done.returncode in (0, 2), done.stderr
    census(trino_url, lake, schema)
    sql = "SELECT batch_id, job_id, job_metrics_status, job_conflated_status FROM metadata"
    statuses = sorted(tuple(r) for r in trino_rows(trino_url, sql.replace("metadata", f"hive.{schema}.metadata")))
    assert [s[2] for s in statuses] != [None] * 4 and len(statuses) == 4
    assert statuses == sorted(DuckDBBackend(lake).execute(sql, branch="main").rows())

    queried = lakegate(
        "query", "--lake", lake, "--backend", "trino", "--trino-url", trino_url, "--format", "csv",
        "SELECT batch_id, count(*) AS jobs FROM metadata GROUP BY 1 ORDER BY 1",
    )  # fmt: skip
    assert queried.stdout == "batch_id,jobs\nb1,3\nb2,1\n", queried.stderr


# --- what stands in the way ----------------------------------------------------------------------------


def tiny_lake(root: Path, fields: str = "{x: float, y: float}") -> Path:
    root.mkdir(parents=True, exist_ok=True)
    config_file = root / "config.resim.yaml"
    config_file.write_text(f"version: 1\ntopics:\n  odom:\n    schema: {fields}\n")
    emissions = root / "e.jsonl"
    emissions.write_text('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0}}\n')
    lake = root / "lake"
    for job in ("j1", "j2"):
        ingest_job(lake, "main", "b1", job, [emissions], config=load_config([config_file]))
    return lake


@pytest.mark.slow
def test_registering_says_what_stands_in_the_way(tmp_path, trino_url, registered):
    lake = tiny_lake(tmp_path)
    apply = ["trino-ddl", "--lake", lake, "--apply"]
    refused = lakegate(*apply)
    assert refused.returncode == 1 and refused.stderr == (
        "lakegate: --apply needs --trino-url (the Trino coordinator, http(s)://host:port)\n"
    )
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        nobody = f"http://127.0.0.1:{sock.getsockname()[1]}"
    refused = lakegate(*apply, "--trino-url", nobody)
    assert refused.stderr == (
        f"lakegate: cannot reach the Trino cluster at {nobody}: [Errno 111] Connection refused "
        "(is Trino running there?)\n"
    )
    refused = lakegate(*apply, "--trino-url", trino_url, "--catalog", "nowhere")
    assert refused.returncode == 1 and refused.stderr.startswith(
        f"lakegate: Trino at {trino_url} has no catalog 'nowhere' (its catalogs: hive, memory, system)"
    )
    refused = lakegate(*apply, "--trino-url", trino_url, "--catalog", "memory")
    assert refused.stderr == (
        f"lakegate: catalog 'memory' of Trino at {trino_url} is a memory catalog, not a Hive one "
        "(connector.name=hive)\n"
    )
    assert not (lake / RECORD).exists()

    registered(lake, "way_")
    schema = read_registration(lake, trino_url).schemas["main"]
    other = tiny_lake(tmp_path / "other")  # another lake, the same schema names
    refused = lakegate(*apply[:2], other, "--apply", "--trino-url", trino_url, "--schema-prefix", PREFIX + "way_")
    assert refused.returncode == 1 and refused.stderr == (
        f"lakegate: schema hive.{schema} already exists at 'local://{lake.resolve()}/main', not at "
        f"'local://{other.resolve()}/main': register this lake under another --schema-prefix, or drop that schema\n"
    )

    # a column dropped in Trino (as if the topic gained it later) is added again
    trino_rows(trino_url, f"ALTER TABLE hive.{schema}.odom DROP COLUMN y")
    again = registered(lake, "way_")
    assert "0 table(s) created, 5 kept, columns added: odom.y" in again.stdout  # odom, metadata, events, 2 platform
    assert trino_rows(trino_url, f"SELECT job_id, x, y FROM hive.{schema}.odom ORDER BY 1") == [
        ["j1", 1.0, 2.0],
        ["j2", 1.0, 2.0],
    ]

    # a table registered by an earlier lakegate, partitioned by batch_id and job_id
    trino_rows(trino_url, f"DROP TABLE hive.{schema}.odom")
    trino_rows(
        trino_url,
        f"CREATE TABLE hive.{schema}.odom (x double, batch_id varchar, job_id varchar) WITH ("
        f"external_location = 'local://{lake.resolve()}/main/odom', format = 'PARQUET', "
        "partitioned_by = ARRAY['batch_id', 'job_id'])",
    )
    refused = lakegate(*apply, "--trino-url", trino_url, "--schema-prefix", PREFIX + "way_")
    assert refused.returncode == 1 and refused.stderr == (
        f"lakegate: table hive.{schema}.odom is partitioned by ARRAY['batch_id','job_id'], as an earlier "
        "lakegate registered it; this lake's layout is partitioned by ARRAY['batch_id']: drop it "
        f'(DROP TABLE "hive"."{schema}"."odom" leaves its files) and run this again\n'
    )
    trino_rows(trino_url, f"DROP TABLE hive.{schema}.odom")
    assert "1 table(s) created" in registered(lake, "way_").stdout

    # a branch in layout v1
    old = tiny_lake(tmp_path / "old")
    to_v1(old)
    refused = lakegate("trino-ddl", "--lake", old, "--apply", "--trino-url", trino_url)
    assert refused.returncode == 1 and "lakegate lake compact --lake" in refused.stderr
    assert not (old / RECORD).exists()
