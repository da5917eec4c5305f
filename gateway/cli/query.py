"""`lakegate query`: run one Trino-dialect query on the embedded DuckDB backend (or forwarded to a
Trino cluster, `--backend trino`) and print the result."""

from __future__ import annotations

import argparse
import csv
import json
import sys
from typing import Any, TextIO

import tzlocal

from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope
from lakegate.gateway.cli.backends import engine_from_args
from lakegate.gateway.cli.command_errors import UserError
from lakegate.gateway.engine.arrow_output import write_arrow, write_parquet
from lakegate.gateway.engine.backend import QueryResult
from lakegate.gateway.engine.trino_backend import TrinoBackend
from lakegate.gateway.engine.trino_values import encode_rows, protocol_type


def _where(error: DialectError) -> str:
    if error.line is not None and error.column is not None:
        return f"line {error.line}, column {error.column}: {error.message}"
    return error.message


def query_command(args: argparse.Namespace) -> int:
    sql = sys.stdin.read() if args.sql == "-" else args.sql
    if args.lake is not None and not args.lake.is_dir():
        raise UserError(f"no lake at {args.lake} (not a directory)")
    scope = Scope(batch_id=args.batch, job_id=args.job) if args.batch or args.job else None
    engine = engine_from_args(args, args.lake)
    try:
        if args.explain and isinstance(engine.backend, TrinoBackend):
            print(engine.backend.forward(sql, branch=args.branch, scope=scope).sql)
            return 0
        if args.explain:
            zone = engine.session(time_zone=args.time_zone or tzlocal.get_localzone_name()).zone()
            print(engine.backend.translate(sql, branch=args.branch, scope=scope, time_zone=zone).duckdb_sql)
            return 0
        session = engine.session(
            branch=args.branch if args.lake is not None or args.backend == "trino" else None,
            scope=scope,
            time_zone=args.time_zone or tzlocal.get_localzone_name(),
        )
        result = engine.execute(sql, session)
        if args.format in ("arrow", "parquet"):
            _write_binary(args, result)
        elif args.output is not None:
            with args.output.open("w", encoding="utf-8", newline="") as out:
                {"table": write_table, "json": write_json, "csv": write_csv}[args.format](result, out)
        else:
            {"table": write_table, "json": write_json, "csv": write_csv}[args.format](result, sys.stdout)
    except DialectError as error:
        raise UserError(_where(error)) from None
    finally:
        engine.close()
    return 0


def _write_binary(args: argparse.Namespace, result: QueryResult) -> None:
    """--format arrow or parquet, to --output or standard output (never to a terminal)."""
    write = write_arrow if args.format == "arrow" else write_parquet
    if args.output is not None:
        partial = args.output.with_name(args.output.name + ".partial")
        try:
            with partial.open("wb") as out:
                write(result, out)
            partial.replace(args.output)  # an error mid-way leaves no half file under the name
        finally:
            partial.unlink(missing_ok=True)
        return
    if sys.stdout.isatty():
        raise UserError(f"--format {args.format} writes binary data: redirect standard output or give --output FILE")
    sys.stdout.flush()
    write(result, sys.stdout.buffer)
    sys.stdout.buffer.flush()


def _encoded_rows(result: QueryResult):
    for batch in result.batches:
        yield from encode_rows(result.columns, batch)


def _text(value: Any, null: str) -> str:
    if value is None:
        return null
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, dict)):
        return json.dumps(value, ensure_ascii=False)
    return str(value)


def write_json(result: QueryResult, out: TextIO) -> None:
    """`{"columns": [{"name", "type"}], "rows": [[...]]}`, types and values written as the Trino protocol does."""
    rows = list(_encoded_rows(result))  # all rows first: an error mid-way must not leave half a document
    columns = json.dumps(
        [{"name": name, "type": protocol_type(trino_type)} for name, trino_type in result.columns], ensure_ascii=False
    )
    out.write(f'{{"columns": {columns}, "rows": [')
    for i, row in enumerate(rows):
        out.write(("," if i else "") + "\n  " + json.dumps(row, ensure_ascii=False, allow_nan=False))
    out.write("\n]}\n")


def write_csv(result: QueryResult, out: TextIO) -> None:
    """RFC 4180 CSV (CRLF line ends) with a header row; NULL is an empty field."""
    rows = list(_encoded_rows(result))  # all rows first: an error mid-way must not leave half a file
    writer = csv.writer(out, lineterminator="\r\n")
    writer.writerow([name for name, _ in result.columns])
    for row in rows:
        writer.writerow([_text(value, "") for value in row])


def write_table(result: QueryResult, out: TextIO) -> None:
    """Aligned columns under a header, numbers right-aligned, NULL as `NULL`, then the row count."""
    names = [name for name, _ in result.columns]
    numeric = [
        t.split("(")[0] in ("tinyint", "smallint", "integer", "bigint", "real", "double", "decimal")
        for _, t in result.columns
    ]
    rows = [[_text(value, "NULL").split("\n") for value in row] for row in _encoded_rows(result)]
    widths = [max([len(name), *(len(line) for row in rows for line in row[i])]) for i, name in enumerate(names)]
    out.write(" " + " | ".join(name.center(w) for name, w in zip(names, widths)).rstrip() + "\n")
    out.write("-" + "-+-".join("-" * w for w in widths) + "-\n")
    for row in rows:
        for k in range(max(len(lines) for lines in row)):
            cells = [lines[k] if k < len(lines) else "" for lines in row]
            cells = [v.rjust(w) if right else v.ljust(w) for v, w, right in zip(cells, widths, numeric)]
            out.write(" " + " | ".join(cells).rstrip() + "\n")
    out.write(f"({len(rows)} row{'' if len(rows) == 1 else 's'})\n")
