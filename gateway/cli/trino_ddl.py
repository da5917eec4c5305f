"""`lakegate trino-ddl`: print the Trino Hive-connector DDL that registers the lake's tables in a
cluster, or (`--apply`) register them in a running Trino and record where (`trino_registration`)."""

from __future__ import annotations

import argparse
import sys

from lakegate.gateway.cli.backends import trino_connection
from lakegate.gateway.cli.command_errors import UserError
from lakegate.gateway.engine.trino_ddl import DDLError, ddl
from lakegate.gateway.engine.trino_registration import RegistrationError, register, unregister
from lakegate.lake.paths import LakePathError


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
