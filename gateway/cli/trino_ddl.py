"""`lakegate trino-ddl`: print the Trino Hive-connector DDL that registers the lake's tables in a cluster."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lakegate.gateway.cli.errors import UserError
from lakegate.gateway.engine.trino_ddl import DDLError, ddl
from lakegate.lake.paths import LakePathError


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "trino-ddl",
        help="print the Trino DDL that registers the lake's tables in a Trino cluster",
        description="Print the Trino Hive-connector DDL (one schema per branch, one external Parquet table per "
        "lake table partitioned by batch_id, job_id a column, then partition sync calls) that registers "
        "the lake's tables in a Trino cluster, once the lake's files are copied to --location. A branch "
        "written by an earlier lakegate is refused until 'lakegate lake compact' migrates it. "
        "Run the output in Trino (e.g. trino --file ddl.sql); run it again after new ingests.",
    )
    parser.add_argument("--lake", required=True, type=Path, metavar="DIR", help="the lake's directory")
    parser.add_argument(
        "--location",
        required=True,
        metavar="URI",
        help="where the lake's directory is copied, as Trino reads it (s3://bucket/lake, gs://..., hdfs://...)",
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
        "to exist on HDFS and local storage)",
    )
    parser.add_argument("--output", type=Path, metavar="FILE", help="write the DDL to FILE instead of standard output")
    parser.set_defaults(func=trino_ddl_command)


def trino_ddl_command(args: argparse.Namespace) -> int:
    if not args.lake.is_dir():
        raise UserError(f"no lake at {args.lake} (not a directory)")
    try:
        text = ddl(
            args.lake,
            args.location,
            catalog=args.catalog,
            schema_prefix=args.schema_prefix,
            branches=args.branches,
            skip_empty=args.skip_empty,
        )
    except (DDLError, LakePathError) as error:
        raise UserError(str(error)) from None
    if args.output is None:
        sys.stdout.write(text)
    else:
        args.output.write_text(text, encoding="utf-8")
    return 0
