"""The parser of `lakegate config check` and `config schema`."""

from __future__ import annotations

import argparse
from pathlib import Path

from lakegate.gateway.cli.parsers import Command
from lakegate.gateway.cli.parsers.shared_options import add_strict_option


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "config",
        help="check metrics config files, or write their JSON Schema",
        description="Check metrics config files, or write their JSON Schema.",
    )
    commands = parser.add_subparsers(dest="config_command", metavar="SUBCOMMAND")
    commands.required = True

    check = commands.add_parser(
        "check",
        help="check config files and print every problem (file:line:column: message)",
        description="Load and merge the given config files; print every problem, one per line, and exit 1, "
        "or print a one-line summary and exit 0.",
    )
    check.add_argument(
        "paths",
        nargs="*",
        metavar="PATH",
        help="config files to check together (default: .resim/metrics/config.resim.yaml "
        "or .yml, in this folder or a parent)",
    )
    add_strict_option(check)
    check.set_defaults(func=Command("config", "check_command"))

    schema = commands.add_parser(
        "schema",
        help="write the JSON Schema (draft 2020-12) of the config file, for editors",
        description="Write the JSON Schema (draft 2020-12) of the metrics config file, for editors.",
    )
    schema.add_argument(
        "-o", "--output", metavar="FILE", type=Path, help="file to write the schema to (default: standard output)"
    )
    schema.set_defaults(func=Command("config", "schema_command"))
