"""Maps and anonymous rows built by queries (map_agg, multimap_agg, zip, map_entries) through
a real `lakegate serve` on 127.0.0.1 and the official `trino` client: the client decodes them by the
type the server declares. Expected values come from DuckDB reading the lake's Parquet files."""

from __future__ import annotations

from collections import defaultdict

from tests.gateway.test_server_clients import connect, parquet


def test_maps_and_rows_reach_the_trino_client_typed(lake_server, server_lake):
    sql = (
        "SELECT map_agg(job_id, cardinality(experience_tag_names)), multimap_agg(batch_id, job_id), "
        "zip(ARRAY[1, 2], ARRAY['a']), map_entries(MAP(ARRAY['k'], ARRAY[1.5E0])) FROM metadata"
    )
    with connect(lake_server) as connection:
        cursor = connection.cursor()
        cursor.execute(sql)
        (row,) = cursor.fetchall()
        types = [column[1] for column in cursor.description]
    assert types == [
        "map(varchar, bigint)",
        "map(varchar, array(varchar))",
        "array(row(integer, varchar(1)))",
        "array(row(varchar(1), double))",
    ]
    jobs = parquet(server_lake, "SELECT job_id, len(experience_tag_names), batch_id FROM {metadata}")
    by_batch = defaultdict(list)
    for job, _, batch in jobs:
        by_batch[batch].append(job)
    assert row[0] == {job: tags for job, tags, _ in jobs} and len(row[0]) == 3
    assert {batch: sorted(found) for batch, found in row[1].items()} == {b: sorted(j) for b, j in by_batch.items()}
    assert [tuple(r) for r in row[2]] == [(1, "a"), (2, None)]
    assert [tuple(r) for r in row[3]] == [("k", 1.5)]
