"""The parser of `lakegate trino-ddl`."""

from __future__ import annotations

import argparse
from pathlib import Path

from lakegate.gateway.cli.parsers import Command
from lakegate.gateway.cli.parsers.shared_options import add_trino_connection_arguments


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "trino-ddl",
        help="register the lake's tables in a Trino cluster (--apply), or print the DDL that does",
        description="Print the Trino Hive-connector DDL (one schema per branch, one external Parquet table per "
        "lake table partitioned by batch_id, job_id a column, then partition sync calls) that registers "
        "the lake's tables in a Trino cluster, once the lake's files are copied to --location; run it in "
        "Trino (e.g. trino --file ddl.sql), again after new ingests. With --apply, register them in the "
        "running Trino at --trino-url yourself: by default reading the lake where it is "
        "(local:///abs/path, for a Trino on this machine), checking what the catalog already holds, "
        "adding columns topics gained, syncing every table's partitions; and record the registration "
        "in the lake (<lake>/_trino.json), where '--backend trino --trino-url URL' finds it. Run it "
        "again after ingesting new batches. A branch written by an earlier lakegate is refused until "
        "'lakegate lake compact' migrates it.",
    )
    parser.add_argument("--lake", required=True, type=Path, metavar="DIR", help="the lake's directory")
    parser.add_argument(
        "--location",
        metavar="URI",
        help="where the lake's directory is copied, as Trino reads it (s3://bucket/lake, gs://..., hdfs://...); "
        "required without --apply; with --apply the default is the lake itself, local:///abs/path",
    )
    parser.add_argument(
        "--catalog", default="hive", metavar="C", help="the Trino catalog of the Hive connector (default: hive)"
    )
    parser.add_argument(
        "--schema-prefix", default="", metavar="P", help="prepended to every schema name (a-z, 0-9, '_'; default: none)"
    )
    parser.add_argument(
        "--branch",
        action="append",
        metavar="B",
        dest="branches",
        help="register this branch only (repeat for several; default: every branch)",
    )
    parser.add_argument(
        "--skip-empty",
        action="store_true",
        help="leave out tables without data files yet (Trino requires an external location "
        "to exist on HDFS and local storage; --apply always leaves them out until they have files)",
    )
    parser.add_argument("--output", type=Path, metavar="FILE", help="write the DDL to FILE instead of standard output")
    apply = parser.add_argument_group("registering in a running Trino (--apply)")
    apply.add_argument(
        "--apply",
        action="store_true",
        help="register the lake in the Trino at --trino-url instead of printing the DDL, and record it in the lake",
    )
    apply.add_argument(
        "--drop",
        action="store_true",
        help="instead, drop the tables and schemas the lake's registration at --trino-url made (their files "
        "stay) and forget it",
    )
    add_trino_connection_arguments(apply)
    parser.set_defaults(func=Command("trino_ddl", "trino_ddl_command"))
