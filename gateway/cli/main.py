"""The `lakegate` command line.

Each command lives in its own module under `lakegate.gateway.cli`; its parser is in the module of the
same name under `lakegate.gateway.cli.parsers` (`add_parser(subparsers)`), which imports none of the
command's work: the parser's `func(args) -> int` imports the command's module when it runs. Errors meant
for the user are raised as `UserError` and printed as one line, without a traceback; so
are the `OSError`s of files the user named (a missing folder, a full or read-only disk).
Exit code 1 for both.

Only the parser of the command given is built (`lakegate --help` builds none of them, so it answers
at once; `lakegate COMMAND --help` imports no command module either): `COMMANDS` lists every command
with its one-line help, which tests/gateway/test_cli_help.py checks against the parsers the modules add.
"""

from __future__ import annotations

import argparse
import importlib
import sys

#: Every command: its name -> (the module under lakegate.gateway.cli.parsers that adds it, its one-line help).
COMMANDS: dict[str, tuple[str, str]] = {
    "config": ("config", "check metrics config files, or write their JSON Schema"),
    "ingest": ("ingest", "ingest the emissions files of one job into the lake"),
    "lake": ("ingest", "look at what is in a lake"),
    "query": ("query", "run one Trino-dialect SQL statement on the lake and print the result"),
    "serve": ("serve", "serve the lake over the Trino client protocol (trino, SQLAlchemy, pandas, BI tools)"),
    "metrics": ("metrics", "store a branch's metrics config, evaluate metrics on a batch or over many batches"),
    "demo": (
        "demo",
        "simulate a batch of navigation runs, ingest it, evaluate its metrics, write a report and a trends page",
    ),
    "trino-ddl": ("trino_ddl", "register the lake's tables in a Trino cluster (--apply), or print the DDL that does"),
    "import": ("import_mcap", "import robot logs (MCAP) as emissions or into a job of the lake"),
    "compare": (
        "compare",
        "compare two batches (or builds) of a branch: new failures, fixes, flaky experiences, metric changes",
    ),
    "flakes": ("compare", "list the experiences whose status or metric values vary across runs of one build"),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of `lakegate`, with the full parser of `command` (every command when "*") and the others
    as one-line entries of the help."""
    parser = argparse.ArgumentParser(
        prog="lakegate",
        description="A Trino-compatible SQL gateway over a Parquet data lake of robot test data.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers.required = True
    chosen = {module for name, (module, _) in COMMANDS.items() if command in (name, "*")}
    added: set[str] = set()
    for name, (module, help_text) in COMMANDS.items():
        if module in chosen and module not in added:
            importlib.import_module(f"lakegate.gateway.cli.parsers.{module}").add_parser(subparsers)
            added.add(module)
        elif module not in chosen:
            subparsers.add_parser(name, help=help_text)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv[0] if argv and argv[0] in COMMANDS else None)
    args = parser.parse_args(argv)
    from lakegate.gateway.cli.command_errors import UserError, os_error_text

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
