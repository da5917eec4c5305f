"""The parser of `lakegate query`."""

from __future__ import annotations

import argparse
from pathlib import Path

from lakegate.gateway.cli.parsers import Command
from lakegate.gateway.cli.parsers.shared_options import add_backend_arguments


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "query",
        help="run one Trino-dialect SQL statement on the lake and print the result",
        description="Run one Trino-dialect SQL statement on the embedded DuckDB backend and print the result, "
        "answered exactly as `lakegate serve` answers it (catalog lake, schema = the branch). "
        "Without --lake only constant queries work (SELECT 1 + 1), unless --backend trino forwards it.",
    )
    parser.add_argument(
        "sql", metavar="SQL", help="the query, in Trino's SQL dialect ('-' reads it from standard input)"
    )
    parser.add_argument(
        "--lake", type=Path, metavar="DIR", help="the lake's directory (omit it for queries that read no table)"
    )
    parser.add_argument("--branch", default="main", metavar="B", help="the branch to query (default: main)")
    parser.add_argument(
        "--format",
        choices=("table", "json", "csv", "arrow", "parquet"),
        default="table",
        help="output: aligned columns (table, the default), JSON with the Trino protocol's "
        "value encoding (json), RFC 4180 CSV with a header (csv), or binary for pandas and other "
        "dataframes, millions of rows a second: an Arrow IPC stream (arrow) or a Parquet file (parquet), "
        "each column's Trino type in its field metadata (docs/bulk-results.md)",
    )
    parser.add_argument(
        "--output",
        "-o",
        type=Path,
        metavar="FILE",
        help="write the result to FILE instead of standard output (with --format parquet it is required "
        "unless standard output is redirected)",
    )
    parser.add_argument(
        "--explain",
        action="store_true",
        help="print the DuckDB SQL the query translates to (with --backend trino: the text sent to the "
        "cluster) instead of running it",
    )
    parser.add_argument("--batch", metavar="ID", help="restrict every table to the rows of this batch")
    parser.add_argument("--job", metavar="ID", help="restrict every table to the rows of this job")
    parser.add_argument(
        "--time-zone",
        "--timezone",
        metavar="ZONE",
        default=None,
        help="the session time zone (America/New_York, +05:45, UTC; a negative offset as --time-zone=-08:30); "
        "default: this machine's zone, as the trino CLI and Python client use",
    )
    add_backend_arguments(parser)
    parser.set_defaults(func=Command("query", "query_command"))
