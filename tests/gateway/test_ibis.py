"""ibis (its Trino backend, over the `trino` client) against a real `lakegate serve`: a table named
without a database resolves through `SELECT current_catalog` and `SELECT current_schema`, as ibis
does against Trino, and its expressions run on lakegate and give the rows DuckDB reads from the
lake's Parquet files. The real Trino 476 answers the same connection-time queries alike."""

from __future__ import annotations

import duckdb
import ibis
import pytest

from lakegate.lake import paths
from lakegate.lake.catalog import Catalog


def parquet(lake, sql: str) -> list[tuple]:
    """`sql` over the metadata table of branch main, read by DuckDB from its Parquet files."""
    table = (
        f"read_parquet('{paths.table_glob(lake, 'main', 'metadata')}', hive_partitioning = true, "
        "hive_types = {'batch_id': VARCHAR})"
    )
    return duckdb.sql(sql.format(metadata=table)).fetchall()


def connect(server, **kwargs):
    return ibis.trino.connect(host=server.host, port=server.port, user="tester", **kwargs)


def test_table_without_a_database(lake_server, server_lake):
    con = connect(lake_server, database="lake", schema="main")
    assert (con.current_catalog, con.current_database) == ("lake", "main")
    metadata = con.table("metadata")
    assert list(metadata.schema().names) == list(Catalog(server_lake).schema("main")["metadata"])
    assert metadata.count().execute() == parquet(server_lake, "SELECT count(*) FROM {metadata}")[0][0]
    per_batch = metadata.group_by("batch_id").aggregate(jobs=metadata.job_id.nunique()).order_by("batch_id").to_pandas()
    expected = parquet(server_lake, "SELECT batch_id, count(DISTINCT job_id) FROM {metadata} GROUP BY 1 ORDER BY 1")
    assert list(per_batch.itertuples(index=False, name=None)) == expected
    assert set(con.list_tables()) == set(Catalog(server_lake).schema("main"))


def test_no_session_catalog(lake_server, server_lake):
    con = connect(lake_server)
    assert (con.current_catalog, con.current_database) == (None, None)
    metadata = con.table("metadata", database=("lake", "main"))
    assert metadata.count().execute() == parquet(server_lake, "SELECT count(*) FROM {metadata}")[0][0]


@pytest.mark.parametrize("session", [{}, {"database": "memory"}, {"database": "memory", "schema": "default"}])
def test_connection_queries_as_on_trino(session, lake_server, trino_url):
    """What ibis reads at connect time has the same shape on the real Trino: None where unset."""
    host, port = trino_url.split("://")[1].split(":")
    judge = ibis.trino.connect(host=host, port=int(port), user="tester", **session)
    ours = connect(lake_server, **{k: {"memory": "lake", "default": "main"}[v] for k, v in session.items()})
    for attribute in ("current_catalog", "current_database"):
        assert (getattr(ours, attribute) is None) == (getattr(judge, attribute) is None), attribute
    assert ours.version == judge.version == "476"
