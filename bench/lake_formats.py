"""Lake format comparison: the present layout and record against Delta Lake and Iceberg.

    python3 dev.py bench lake_formats [--jobs 1000] [--batch-jobs 100] [--runs 5]

One topic table (`robot_speed` of the scale benchmark's 40 simulated jobs, cycled) is written job
by job, `--jobs` times, into each format:

(a) **hive + record**: lakegate's own writer (`lake.record.Change`: a file per job under its Hive
    partition, a hard link for readers, one SQLite commit);
(b) **delta**: `deltalake.write_deltalake(mode="append")` (a commit in `_delta_log/` per job);
(c) **iceberg**: `pyiceberg` with its SQL catalog on SQLite, `Table.append` (a snapshot per job).

Delta and Iceberg tables are partitioned by `batch_id` only, `job_id` being a column whose min/max
their metadata keeps (a job's files are found by those statistics), so that compaction can merge a
batch's jobs into one file: neither merges files across partitions.

Then, on each (median of `--runs`): append one more job; replace one job (re-ingest: lakegate's
commit of the job's keys, Delta's `overwrite` with a predicate, Iceberg's `overwrite` with a
filter); find the files of one batch (the format's own metadata) and read them with DuckDB
(`read_parquet` of the list: the same reader for all); `count(*)` of the table from metadata
alone (the record's row counts, Delta's add actions, Iceberg's snapshot summary); the number of
files (data and metadata) on disk; and for Delta its `optimize.compact()`, then a batch read and a
job's replace again (pyiceberg has no compaction). A format whose package is missing is skipped with a
message (they are in the optional `bench` extra: `pip install -e .[bench]`). Writes section "Lake formats"
of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shutil
import statistics
import sys
import time
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import parse_args, timed, write_section  # noqa: E402
from scale import BRANCH, source  # noqa: E402

from lakegate.lake import paths  # noqa: E402
from lakegate.lake.record import Change, Record  # noqa: E402

WORK = Path(__file__).resolve().parent / ".work" / "lake_formats"
TABLE = "robot_speed"


class Format:
    """One way of keeping the table: what each measured operation does in it."""

    name = ""
    package: str | None = None

    def __init__(self, root: Path):
        self.root = root

    def append(self, batch_id: str, job_id: str, rows: pa.Table) -> None:
        raise NotImplementedError

    def replace(self, batch_id: str, job_id: str, rows: pa.Table) -> None:
        raise NotImplementedError

    def batch_files(self, batch_id: str) -> list[str]:
        """The data files of one batch, found through the format's metadata."""
        raise NotImplementedError

    def count(self) -> int:
        """The table's rows, from metadata alone."""
        raise NotImplementedError

    def file_count(self) -> tuple[int, int]:
        """(data files, other files) under the table's directory."""
        files = [f for f in self.root.rglob("*") if f.is_file()]
        data = [f for f in files if f.suffix == ".parquet" and paths.READERS not in f.parts]
        return len(data), len(files) - len(data)


class HiveRecord(Format):
    name = "hive + record"

    def append(self, batch_id: str, job_id: str, rows: pa.Table) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        staged = self.root / "staged.parquet"
        pq.write_table(rows.drop_columns(["batch_id"]), staged)  # job_id is a column of the files (layout v2)
        change = Change(self.root, BRANCH)
        change.add(TABLE, batch_id, job_id, staged)
        change.replace_job(batch_id, job_id)
        change.commit(f"append {batch_id}/{job_id}")

    replace = append  # a job's commit replaces its files

    def batch_files(self, batch_id: str) -> list[str]:
        record = Record(self.root, BRANCH)
        try:
            snapshot = record.snapshot(batch_id)
        finally:
            record.close()
        root = str(record.root)
        return [paths.reader_file(root, entry.path) for entry in snapshot.of(TABLE)]

    def count(self) -> int:
        record = Record(self.root, BRANCH)
        try:
            return sum(entry.rows for entry in record.snapshot().of(TABLE))
        finally:
            record.close()


class Delta(Format):
    name = "delta"
    package = "deltalake"

    def append(self, batch_id: str, job_id: str, rows: pa.Table) -> None:
        import deltalake

        deltalake.write_deltalake(self.root, rows, mode="append", partition_by=["batch_id"])

    def replace(self, batch_id: str, job_id: str, rows: pa.Table) -> None:
        import deltalake

        predicate = f"batch_id = '{batch_id}' AND job_id = '{job_id}'"
        deltalake.write_deltalake(self.root, rows, mode="overwrite", predicate=predicate, partition_by=["batch_id"])

    def batch_files(self, batch_id: str) -> list[str]:
        import deltalake

        table = deltalake.DeltaTable(self.root)
        return [uri.removeprefix("file://") for uri in table.file_uris([("batch_id", "=", batch_id)])]

    def count(self) -> int:
        import deltalake

        actions = pa.table(deltalake.DeltaTable(self.root).get_add_actions(flatten=True))
        return sum(actions.column("num_records").to_pylist())

    def compact(self) -> dict:
        import deltalake

        return deltalake.DeltaTable(self.root).optimize.compact()


class Iceberg(Format):
    name = "iceberg"
    package = "pyiceberg"

    def __init__(self, root: Path):
        super().__init__(root)
        from pyiceberg.catalog.sql import SqlCatalog

        root.mkdir(parents=True, exist_ok=True)
        self.catalog = SqlCatalog("bench", uri=f"sqlite:///{root}/catalog.sqlite", warehouse=root.as_uri())
        self._table = None

    def table(self, rows: pa.Table | None = None):
        from pyiceberg.exceptions import NoSuchTableError

        if self._table is None:
            try:
                self._table = self.catalog.load_table(("lake", TABLE))
            except NoSuchTableError:
                self.catalog.create_namespace_if_not_exists("lake")
                self._table = self.catalog.create_table(("lake", TABLE), schema=rows.schema)
                with self._table.update_spec() as spec:
                    spec.add_identity("batch_id")
        return self._table

    def append(self, batch_id: str, job_id: str, rows: pa.Table) -> None:
        self.table(rows).append(rows)

    def replace(self, batch_id: str, job_id: str, rows: pa.Table) -> None:
        from pyiceberg.expressions import And, EqualTo

        self.table(rows).overwrite(rows, overwrite_filter=And(EqualTo("batch_id", batch_id), EqualTo("job_id", job_id)))

    def batch_files(self, batch_id: str) -> list[str]:
        from pyiceberg.expressions import EqualTo

        table = self.catalog.load_table(("lake", TABLE))
        return [
            task.file.file_path.removeprefix("file://")
            for task in table.scan(EqualTo("batch_id", batch_id)).plan_files()
        ]

    def count(self) -> int:
        return int(self.catalog.load_table(("lake", TABLE)).current_snapshot().summary["total-records"])


FORMATS = (HiveRecord, Delta, Iceberg)


def job_rows(source_lake: Path) -> list[pa.Table]:
    """The topic's rows of each of the 40 source jobs (without partition columns)."""
    record = Record(source_lake, BRANCH)
    root = record.root
    try:
        return [pq.read_table(root / entry.path) for entry in record.snapshot().of(TABLE)]
    finally:
        record.close()


def with_keys(rows: pa.Table, batch_id: str, job_id: str) -> pa.Table:
    """`rows` with the job's partition columns."""
    n = rows.num_rows
    return rows.append_column("batch_id", pa.array([batch_id] * n)).append_column("job_id", pa.array([job_id] * n))


def measure(kind: type[Format], jobs: int, batch_jobs: int, runs: int, sources: list[pa.Table]) -> dict[str, float]:
    """Build the table of `jobs` jobs in format `kind`, then time each operation (median of `runs`)."""
    root = WORK / kind.name.replace(" + ", "-")
    shutil.rmtree(root, ignore_errors=True)
    store = kind(root)

    def job(index: int) -> tuple[str, str, pa.Table]:
        batch_id, job_id = f"b{index // batch_jobs:04d}", f"j{index:06d}"
        return batch_id, job_id, with_keys(sources[index % len(sources)], batch_id, job_id)

    started = time.perf_counter()
    for index in range(jobs):
        store.append(*job(index))
    figures = {"build (s)": time.perf_counter() - started}
    figures["append one job (s)"] = statistics.median(
        timed(lambda i=i: store.append(*job(jobs + i))) for i in range(runs)
    )
    figures["replace one job (s)"] = statistics.median(
        timed(lambda i=i: store.replace(*job(i * 7))) for i in range(runs)
    )
    connection = duckdb.connect(config={"threads": 2})

    def read_batch() -> None:
        files = store.batch_files("b0001")
        listed = ", ".join("'" + file.replace("'", "''") + "'" for file in files)
        connection.execute(f"SELECT count(*), avg(speed) FROM read_parquet([{listed}])").fetchall()

    figures["find one batch's files (s)"] = statistics.median(
        timed(lambda: store.batch_files("b0001")) for _ in range(runs)
    )
    figures["scoped read of one batch (s)"] = statistics.median(timed(read_batch) for _ in range(runs))
    figures["count(*) from metadata (s)"] = statistics.median(timed(store.count) for _ in range(runs))
    expected = sum(job(i)[2].num_rows for i in range(jobs + runs))

    def check() -> None:
        if store.count() != expected:
            raise SystemExit(f"{kind.name}: count {store.count()} != {expected} rows written")

    check()
    figures["data files"], figures["metadata files"] = store.file_count()
    if isinstance(store, Delta):
        started = time.perf_counter()
        store.compact()
        figures["compact (s)"] = time.perf_counter() - started
        figures["data files after compact"] = len(store.batch_files("b0001"))
        figures["scoped read of one batch after compact (s)"] = statistics.median(
            timed(read_batch) for _ in range(runs)
        )
        figures["replace one job after compact (s)"] = statistics.median(
            timed(lambda i=i: store.replace(*job(batch_jobs + i))) for i in range(runs)
        )
        check()
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--jobs", type=int, default=1000, help="jobs written into each format")
    parser.add_argument("--batch-jobs", type=int, default=100, help="jobs per batch")
    parser.add_argument("--runs", type=int, default=5)
    args = parse_args(parser, argv, jobs=4, batch_jobs=2, runs=1)
    load_before = os.getloadavg()
    sources = job_rows(source(min(args.jobs, 40))[0])
    results: dict[str, dict[str, float]] = {}
    for kind in FORMATS:
        if kind.package and importlib.util.find_spec(kind.package) is None:
            print(f"{kind.name}: skipped, package {kind.package} is not installed (pip install -e .[bench])")
            continue
        results[kind.name] = measure(kind, args.jobs, args.batch_jobs, args.runs, sources)
        print(json.dumps({kind.name: results[kind.name]}), flush=True)
    write_section(
        "Lake formats",
        f"python3 dev.py bench lake_formats --jobs {args.jobs} --batch-jobs {args.batch_jobs} --runs {args.runs}",
        _lines(results, args, load_before),
    )
    return 0


def _lines(results: dict[str, dict[str, float]], args: argparse.Namespace, load_before: tuple) -> list[str]:
    names = list(results)
    measures = list(dict.fromkeys(m for figures in results.values() for m in figures))
    lines = [
        f"One topic table written job by job: {args.jobs:,} jobs in batches of {args.batch_jobs} "
        f"(one file per job), then each operation {args.runs} times (median). Load average at the start: "
        f"{', '.join(f'{x:.2f}' for x in load_before)}; at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())} "
        "(2 cores, shared).",
        "",
        "| measure | " + " | ".join(names) + " |",
        "|---|" + "---:|" * len(names),
    ]
    for measure in measures:
        cells = []
        for name in names:
            value = results[name].get(measure)
            cells.append("-" if value is None else _cell(measure, value))
        lines.append(f"| {measure.replace(' (s)', '')} | " + " | ".join(cells) + " |")
    return lines


def _cell(measure: str, value: float) -> str:
    if not measure.endswith("(s)"):
        return f"{value:,.0f}"
    return f"{value * 1000:.1f} ms" if value < 1 else f"{value:.2f} s"


if __name__ == "__main__":
    sys.exit(main())
