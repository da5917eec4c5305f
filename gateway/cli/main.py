"""The `lakegate` command line.

Each command lives in its own module under `lakegate.gateway` that defines
`add_parser(subparsers)`; the parser it adds sets `func(args) -> int`. Errors meant
for the user are raised as `UserError` and printed as one line, without a traceback; so
are the `OSError`s of files the user named (a missing folder, a full or read-only disk).
Exit code 1 for both.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from lakegate.gateway.cli.errors import UserError, os_error_text

#: Modules that each contribute one command (or a command group).
COMMAND_MODULES = (
    "config",
    "ingest",
    "query",
    "serve",
    "metrics",
    "demo",
    "trino_ddl",
    "import_mcap",
    "compare",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="lakegate",
        description="A Trino-compatible SQL gateway over a Parquet data lake of robot test data.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(f"lakegate.gateway.cli.{name}").add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"lakegate: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"lakegate: {os_error_text(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("lakegate: interrupted", file=sys.stderr)
        return 130
