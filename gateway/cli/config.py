"""`lakegate config check|schema`: check config files, or write the config's JSON Schema."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from lakegate.gateway.cli.errors import UserError, add_strict_option, print_config_warnings
from lakegate.lake.config import ConfigError, find_default_config, load_config
from lakegate.lake.config_schema import json_schema


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
    check.set_defaults(func=check_command)

    schema = commands.add_parser(
        "schema",
        help="write the JSON Schema (draft 2020-12) of the config file, for editors",
        description="Write the JSON Schema (draft 2020-12) of the metrics config file, for editors.",
    )
    schema.add_argument(
        "-o", "--output", metavar="FILE", type=Path, help="file to write the schema to (default: standard output)"
    )
    schema.set_defaults(func=schema_command)


def check_command(args: argparse.Namespace) -> int:
    paths = list(args.paths)
    if not paths:
        found = find_default_config()
        if found is None:
            raise UserError(
                "no config file given and no .resim/metrics/config.resim.yaml (or .yml) found "
                "in this folder or its parents"
            )
        paths = [str(found)]
    try:
        config = load_config(paths, strict=args.strict)
    except ConfigError as exc:
        for problem in exc.problems:
            print(problem)
        return 1
    print_config_warnings(config)
    warned = f", {len(config.warnings)} warning(s)" if config.warnings else ""
    print(f"ok: {config.summary()}{warned} ({', '.join(paths)})")
    return 0


def schema_command(args: argparse.Namespace) -> int:
    text = json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"
    if args.output is None:
        print(text, end="")
        return 0
    try:
        args.output.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise UserError(f"cannot write {args.output}: {exc.strerror}") from None
    return 0
