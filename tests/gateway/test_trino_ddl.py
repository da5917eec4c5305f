"""`lakegate trino-ddl`: the Hive-connector DDL for a real lake, parsed back with sqlglot's Trino dialect
and checked against the catalog (columns, types, partitions, locations) and against the Parquet files
the external tables will read."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import sqlglot
from sqlglot import exp

from lakegate.fixtures.generate import CONFIG_PATH, generate_batch
from lakegate.gateway.engine.trino_ddl import DDLError, hive_type, schema_name
from lakegate.gateway.metrics.evaluation import MetricsEngine, select_metrics
from lakegate.lake import paths
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.catalog import Catalog
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file
from tests.lake.v1_lake import to_v1

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]
LOCATION = "s3://robot-lake/it's/lake"
#: Trino types the Hive connector stores in Parquet, by sqlglot's name, and the Arrow type of the
#: Parquet column it reads.
SCALARS = {
    exp.DataType.Type.BIGINT: pa.types.is_int64,
    exp.DataType.Type.DOUBLE: pa.types.is_float64,
    exp.DataType.Type.BOOLEAN: pa.types.is_boolean,
    exp.DataType.Type.VARCHAR: lambda t: pa.types.is_string(t) or pa.types.is_large_string(t),
}


def lakegate(*args):
    return subprocess.run(
        [*CLI, *map(str, args)], capture_output=True, text=True, timeout=120, env={**os.environ, "COLUMNS": "200"}
    )


@pytest.fixture(scope="module")
def lake(tmp_path_factory) -> Path:
    """The fixture config's topics (every lake field type, events with metric[] rows), 2 jobs of a
    batch on `main` (evaluated: `metric_results` is partitioned by batch only) and 1 on `feature/Nav-2`."""
    root = tmp_path_factory.mktemp("ddl")
    jobs = generate_batch(root / "inputs", jobs=3, samples_per_goal=3)
    lake = root / "lake"
    config = load_config(CONFIG_PATH)
    for branch, batch, job in [("main", "b1", jobs[0]), ("main", "b1", jobs[1]), ("feature/Nav-2", "b2", jobs[2])]:
        ingest_job(
            lake,
            branch,
            batch,
            job.job_id,
            [job.emissions_path],
            config=config,
            metadata=load_metadata_file(job.metadata_path),
        )
    with MetricsEngine(lake) as engine:
        engine.evaluate_batch("main", "b1", select_metrics(config, None, all_metrics=True))
    assert paths.METRIC_RESULTS_TABLE in Catalog(lake).schema("main")
    return lake


def statements(text: str) -> list[exp.Expression]:
    """Every statement of a script, parsed by sqlglot's Trino dialect (CALL as a Command)."""
    logging.getLogger("sqlglot").setLevel(logging.ERROR)  # the warning that CALL is parsed as a Command
    return [s for s in sqlglot.parse(text, read="trino") if s is not None]


def unquoted(kind: exp.DataType) -> str:
    """A type's Trino text with row field names unquoted, to compare types."""
    return kind.transform(lambda n: exp.to_identifier(n.name) if isinstance(n, exp.Identifier) else n).sql("trino")


def check_hive_type(kind: exp.DataType, where: str) -> None:
    """Every type in the tree is one the Hive connector accepts for Parquet columns."""
    if kind.this in SCALARS:
        return
    if kind.this == exp.DataType.Type.TIMESTAMP:
        assert [p.this.this for p in kind.expressions] == ["3"] or [p.sql() for p in kind.expressions] == ["3"], (
            f"{where}: timestamp must be timestamp(3)"
        )
        return
    assert kind.this in (exp.DataType.Type.ARRAY, exp.DataType.Type.STRUCT), f"{where}: {kind.sql('trino')}"
    for child in kind.expressions:
        check_hive_type(child.args["kind"] if isinstance(child, exp.ColumnDef) else child, where)


def matches_parquet(kind: exp.DataType, arrow: pa.DataType) -> bool:
    """The Parquet column (as Arrow reads it) holds values of the declared Trino type."""
    if kind.this in SCALARS:
        return SCALARS[kind.this](arrow)
    if kind.this == exp.DataType.Type.TIMESTAMP:
        return pa.types.is_timestamp(arrow) and arrow.unit == "ms" and arrow.tz is None
    if kind.this == exp.DataType.Type.ARRAY:
        return pa.types.is_list(arrow) and matches_parquet(kind.expressions[0], arrow.value_type)
    if kind.this == exp.DataType.Type.STRUCT:
        fields = [(c.name, c.args["kind"]) for c in kind.expressions]
        return (
            pa.types.is_struct(arrow)
            and [f.name for f in arrow] == [name for name, _ in fields]
            and all(matches_parquet(k, arrow.field(name).type) for name, k in fields)
        )
    return False


def property_value(create: exp.Create, name: str) -> exp.Expression:
    """The value of one WITH (...) property of a CREATE statement, as sqlglot parsed it."""
    special = {
        "location": exp.LocationProperty,
        "format": exp.FileFormatProperty,
        "partitioned_by": exp.PartitionedByProperty,
    }
    for prop in create.args["properties"].expressions:
        if name in special and isinstance(prop, special[name]):
            return prop.this
        if type(prop) is exp.Property and prop.name.lower() == name:
            return prop.args["value"]
    raise AssertionError(f"no property {name} in {create.sql('trino')}")


def test_the_ddl_registers_every_table_of_every_branch_as_the_catalog_describes_it(lake):
    result = lakegate("trino-ddl", "--lake", lake, "--location", LOCATION + "/", "--catalog", "hive")
    assert result.returncode == 0, result.stderr
    parsed = statements(result.stdout)
    catalog = Catalog(lake)
    expected_tables = {(branch, table) for branch in catalog.branches() for table in catalog.schema(branch)}
    schemas = [s for s in parsed if isinstance(s, exp.Create) and s.kind == "SCHEMA"]
    tables = [s for s in parsed if isinstance(s, exp.Create) and s.kind == "TABLE"]
    calls = [s for s in parsed if isinstance(s, exp.Command) and s.this.upper() == "CALL"]
    assert len(parsed) == len(schemas) + len(tables) + len(calls)
    assert len(schemas) == 2 and len(tables) == len(calls) == len(expected_tables)

    schema_of = {branch: schema_name(branch) for branch in catalog.branches()}
    assert schema_of["main"] == "main"
    assert schema_of["feature/Nav-2"].startswith("feature_nav_2_")
    for create in schemas:
        target = create.this
        assert target.catalog == "hive" and target.db in schema_of.values()
        branch = next(b for b, s in schema_of.items() if s == target.db)
        assert property_value(create, "location").name == f"{LOCATION}/{paths.encode_branch(branch)}"

    seen = set()
    for create in tables:
        table = create.this.this
        assert table.catalog == "hive"
        branch = next(b for b, s in schema_of.items() if s == table.db)
        seen.add((branch, table.name))
        columns = [(c.name, c.args["kind"]) for c in create.this.expressions]
        keys = paths.partition_keys(table.name)
        assert keys == ("batch_id",)  # job_id is a data column: a compacted file holds many jobs
        declared = catalog.schema(branch)[table.name]
        # the catalog's columns, partition columns moved last, each with the catalog's type
        assert [name for name, _ in columns] == [c for c in declared if c not in keys] + list(keys)
        for name, kind in columns:
            assert unquoted(kind) == unquoted(exp.DataType.build(declared[name], dialect="trino")), name
            check_hive_type(kind, f"{table.name}.{name}")
        assert [k.name for k in property_value(create, "partitioned_by").expressions] == list(keys)
        assert property_value(create, "format").name == "PARQUET"
        assert (
            property_value(create, "external_location").name == f"{LOCATION}/{paths.encode_branch(branch)}/{table.name}"
        )
        # the external table reads the lake's files: every data column is in them, with a matching type
        for data_file in paths.data_files(lake, branch, table.name):
            file_schema = pq.read_schema(data_file)
            assert not set(keys) & set(file_schema.names) and "job_id" in file_schema.names
            for name, kind in columns[: -len(keys)]:
                assert matches_parquet(kind, file_schema.field(name).type), (data_file, name, file_schema.field(name))
    assert seen == expected_tables

    registered = set()
    for call in calls:
        procedure = sqlglot.parse_one("SELECT " + call.expression.name, read="trino").expressions[0]
        assert procedure.sql("trino").startswith('"hive".system.sync_partition_metadata(')
        schema, table, mode = (arg.name for arg in procedure.find(exp.Anonymous).expressions)
        assert mode == "ADD"
        registered.add((next(b for b, s in schema_of.items() if s == schema), table))
    assert registered == expected_tables


def test_types_the_hive_connector_cannot_store_in_parquet_are_refused():
    assert hive_type("array(row(name varchar, type varchar))", "t.c") == 'array(row("name" varchar, "type" varchar))'
    assert hive_type("map(varchar, array(bigint))", "t.c") == "map(varchar, array(bigint))"
    assert hive_type("decimal(10,2)", "t.c") == "decimal(10,2)"
    for bad in (
        "timestamp(6)",
        "timestamp(3) with time zone",
        "time(3)",
        "json",
        "uuid",
        "interval day to second",
        "row(bigint, varchar)",
    ):
        with pytest.raises(DDLError, match=r"t\.c: type .* cannot be a Hive-connector Parquet column"):
            hive_type(bad, "t.c")


def test_schema_names_are_hive_names_and_never_collide():
    assert schema_name("main") == "main" and schema_name("main", "lg_") == "lg_main"
    names = {schema_name(b) for b in ("Main", "main", "feature/x", "feature_x", "feature-x", "é", "a" * 240)}
    assert len(names) == 7
    assert all(len(n) <= 100 and n.replace("_", "").isalnum() and n.isascii() and n == n.lower() for n in names)
    assert schema_name("feature/x") == schema_name("feature/x")
    with pytest.raises(DDLError, match="schema prefix 'Bad-' may only contain"):
        schema_name("main", "Bad-")


def test_options_choose_branches_catalog_prefix_and_output_file(lake, tmp_path):
    output = tmp_path / "ddl.sql"
    result = lakegate(
        "trino-ddl",
        "--lake",
        lake,
        "--location",
        "hdfs://nn/lake",
        "--catalog",
        "my hive",
        "--schema-prefix",
        "robots_",
        "--branch",
        "feature/Nav-2",
        "--output",
        output,
    )
    assert result.returncode == 0 and result.stdout == "", result.stderr
    parsed = statements(output.read_text())
    targets = {(s.this.this if s.kind == "TABLE" else s.this).sql("trino") for s in parsed if isinstance(s, exp.Create)}
    suffix = schema_name("feature/Nav-2")
    assert f'"my hive"."robots_{suffix}"' in targets
    assert f'"my hive"."robots_{suffix}"."metadata"' in targets
    assert not any('"main"' in t for t in targets)


def test_tables_without_files_are_noted_or_skipped(tmp_path):
    config_file = tmp_path / "config.resim.yaml"
    config_file.write_text("version: 1\ntopics:\n  odom:\n    schema: {x: float}\n  never:\n    schema: {n: int}\n")
    emissions = tmp_path / "e.jsonl"
    emissions.write_text('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0}}\n')
    ingest_job(tmp_path / "lake", "main", "b", "j", [emissions], config=load_config([config_file]))

    def tables(*args) -> tuple[str, set[str]]:
        result = lakegate("trino-ddl", "--lake", tmp_path / "lake", "--location", "s3://b/l", *args)
        assert result.returncode == 0, result.stderr
        return result.stdout, {
            s.this.this.name for s in statements(result.stdout) if isinstance(s, exp.Create) and s.kind == "TABLE"
        }

    text, every = tables()
    assert every == {"odom", "never", "events", "metadata", "container_performance", "test_length_seconds"}
    assert "-- table 'never' has no data files yet: its location must exist" in text
    text, some = tables("--skip-empty")
    assert some == {"odom", "metadata"}
    assert "-- table 'never' has no data files yet: left out (--skip-empty)" in text


@pytest.mark.parametrize(
    "args, message",
    [
        (["--location", "/local/path"], "--location '/local/path' is not a URI"),
        (["--location", "s3://b/l", "--branch", "nope"], "no branch 'nope' in the lake"),
        (["--location", "s3://b/l", "--schema-prefix", "X"], "schema prefix 'X' may only contain"),
        ([], "--location is required without --apply (where Trino reads the copied lake)"),
        (["--apply"], "--apply needs --trino-url (the Trino coordinator, http(s)://host:port)"),
        (["--drop"], "--drop needs --trino-url"),
        (["--apply", "--drop"], "--apply registers, --drop unregisters: give one of them"),
        (["--apply", "--trino-url", "http://h:1", "--output", "x.sql"], "--output writes the DDL; --apply runs it"),
        (["--apply", "--trino-url", "ftp://h"], "--trino-url 'ftp://h' is not an http:// or https:// URL"),
    ],
)
def test_bad_options_are_one_line_errors(lake, args, message):
    result = lakegate("trino-ddl", "--lake", lake, *args)
    assert result.returncode == 1 and result.stdout == ""
    assert result.stderr.startswith("lakegate: ") and message in result.stderr and "Traceback" not in result.stderr


def test_tables_whose_names_differ_only_in_case_are_refused(tmp_path):
    """A config refuses such topics, but a branch's config versions can still bring both names."""
    lake = tmp_path / "lake"
    emissions = tmp_path / "e.jsonl"
    for version, topic in enumerate(("Odom", "odom")):
        config_file = tmp_path / f"v{version}.resim.yaml"
        config_file.write_text(f"version: 1\ntopics:\n  {topic}:\n    schema: {{x: float}}\n")
        emissions.write_text(f'{{"$metadata": {{"topic": "{topic}", "timestamp": 1}}, "$data": {{"x": 1.0}}}}\n')
        BranchConfigs(lake, "main").store([config_file])
        ingest_job(lake, "main", "b", f"j{version}", [emissions], config=load_config([config_file]))
    assert {"Odom", "odom"} <= set(Catalog(lake).schema("main"))
    result = lakegate("trino-ddl", "--lake", lake, "--location", "s3://b/l")
    assert result.returncode == 1
    assert "tables 'odom' and 'Odom' would be the same name in Trino" in result.stderr


def test_a_layout_v1_branch_is_refused_until_lake_compact_migrates_it(tmp_path):
    config_file = tmp_path / "config.resim.yaml"
    config_file.write_text("version: 1\ntopics:\n  odom:\n    schema: {x: float}\n")
    emissions = tmp_path / "e.jsonl"
    emissions.write_text('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0}}\n')
    lake = tmp_path / "lake"
    for job in ("j1", "j2"):
        ingest_job(lake, "main", "b1", job, [emissions], config=load_config([config_file]))
    to_v1(lake)
    refused = lakegate("trino-ddl", "--lake", lake, "--location", "s3://b/l")
    assert refused.returncode == 1 and not refused.stdout
    assert refused.stderr == (
        "lakegate: branch 'main' is in the layout of earlier lakegate versions (a job_id=<J>/ directory per job, "
        f"which Trino would read without job_id): run 'lakegate lake compact --lake {lake} --branch main' first; "
        "it moves job_id into the files\n"
    )
    compacted = lakegate("lake", "compact", "--lake", lake, "--branch", "main")
    assert compacted.returncode == 0, compacted.stderr
    assert compacted.stdout == (
        "migrated branch 'main' to layout v2 (job_id in the files, each batch's files of a table merged): "
        "4 files -> 2\nbatch 'b1' (2 job(s)) is compacted already: 2 files\n"
    )
    assert lakegate("trino-ddl", "--lake", lake, "--location", "s3://b/l").returncode == 0
    (odom,) = paths.data_files(lake, "main", "odom")
    assert pq.read_table(odom).column("job_id").to_pylist() == ["j1", "j2"]


def test_ids_hive_would_escape_are_warned_about(tmp_path):
    config_file = tmp_path / "config.resim.yaml"
    config_file.write_text("version: 1\ntopics:\n  odom:\n    schema: {x: float}\n")
    emissions = tmp_path / "e.jsonl"
    emissions.write_text('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0}}\n')
    for batch in ("2024-05-01T10:00", "plain"):
        ingest_job(tmp_path / "lake", "main", batch, "j1", [emissions], config=load_config([config_file]))
    result = lakegate("trino-ddl", "--lake", tmp_path / "lake", "--location", "s3://b/l")
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stdout.splitlines() if line.startswith("-- warning:")]
    assert warnings == [
        "-- warning: id '2024-05-01T10:00' has a character Hive escapes in directory names; "
        "sync_partition_metadata may fail on its partitions or register them wrongly"
    ]
