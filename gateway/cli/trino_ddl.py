"""`lakegate trino-ddl`: print the Trino Hive-connector DDL that registers the lake's tables in a
cluster, or (`--apply`) register them in a running Trino and record where (`trino_registration`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lakegate.gateway.cli.backends import add_trino_connection_arguments, trino_connection
from lakegate.gateway.cli.errors import UserError
from lakegate.gateway.engine.trino_ddl import DDLError, ddl
from lakegate.gateway.engine.trino_registration import RegistrationError, register, unregister
from lakegate.lake.paths import LakePathError


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
    parser.set_defaults(func=trino_ddl_command)


def trino_ddl_command(args: argparse.Namespace) -> int:
    if not args.lake.is_dir():
        raise UserError(f"no lake at {args.lake} (not a directory)")
    if args.apply and args.drop:
        raise UserError("--apply registers, --drop unregisters: give one of them")
    if args.apply or args.drop:
        return _apply(args)
    if args.location is None:
        raise UserError("--location is required without --apply (where Trino reads the copied lake)")
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


def _apply(args: argparse.Namespace) -> int:
    if not args.trino_url:
        raise UserError(
            f"--{'drop' if args.drop else 'apply'} needs --trino-url (the Trino coordinator, http(s)://host:port)"
        )
    if args.output is not None:
        raise UserError("--output writes the DDL; --apply runs it instead (give one of them)")
    connection = trino_connection(args, catalog=args.catalog)
    try:
        if args.drop:
            dropped = unregister(args.lake, connection)
            print(f"dropped {len(dropped)} schema(s) in Trino at {args.trino_url}: {', '.join(dropped) or 'none'}")
            return 0
        reports = register(
            args.lake,
            connection,
            location=args.location,
            catalog=args.catalog,
            schema_prefix=args.schema_prefix,
            branches=args.branches,
        )
    except (DDLError, RegistrationError, LakePathError) as error:
        raise UserError(str(error)) from None
    finally:
        connection.close()
    for report in reports:
        made = f"{len(report.created)} table(s) created, {len(report.kept)} kept"
        if report.added_columns:
            made += f", columns added: {', '.join(report.added_columns)}"
        if report.left_out:
            made += f", left out until they have files: {', '.join(report.left_out)}"
        print(
            f"branch {report.branch!r} -> {args.catalog}.{report.schema}: {made}; partitions synced; "
            f"Trino sees {report.jobs_in_trino} job(s), the lake has {report.jobs_in_lake}"
        )
        if report.jobs_in_trino != report.jobs_in_lake:
            print(
                f"lakegate: warning: Trino sees {report.jobs_in_trino} job(s) of branch {report.branch!r}, "
                f"the lake has {report.jobs_in_lake} (an ingest running? run this again when it is done)",
                file=sys.stderr,
            )
    print(f"recorded in {args.lake / '_trino.json'}: --backend trino --trino-url {args.trino_url} finds it there")
    return 0
