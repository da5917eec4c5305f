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
from pathlib import Path
from typing import Any, Callable

#: Modules that each contribute one command (or a command group).
COMMAND_MODULES = (
    "config_command",
    "ingest_command",
    "query_command",
    "serve_command",
    "metrics_command",
    "demo_command",
    "trino_ddl_command",
)


class UserError(Exception):
    """An error caused by the user's input; printed as `lakegate: <message>`, exit code 1."""


def port_number(text: str) -> int:
    """An argparse type: a TCP port number, 0 to 65535 (0: any free port)."""
    try:
        number = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a port number (0 to 65535), got {text!r}") from None
    if not 0 <= number <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port number (0 to 65535; 0 picks a free one), got {text!r}")
    return number


def positive(kind: type) -> Callable[[str], Any]:
    """An argparse `type` that reads a `kind` (int or float) greater than 0."""
    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
        return value
    return parse


def os_error_text(error: OSError) -> str:
    """An OSError in one line: why, and the file (`No space left on device: 'lake/x'`)."""
    reason = error.strerror or str(error)
    return f"{reason}: {str(error.filename)!r}" if error.filename is not None else reason


def writable_lake(path: Path) -> Path:
    """`path` as a lake to write to (it need not exist yet); UserError if it is not a folder."""
    if path.exists() and not path.is_dir():
        raise UserError(f"--lake {str(path)!r} is not a directory (a lake is a folder; it is created if missing)")
    return path


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="lakegate",
        description="A Trino-compatible SQL gateway over a Parquet data lake of robot test data.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(f"lakegate.gateway.{name}").add_parser(subparsers)
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


if __name__ == "__main__":
    # Run the imported module's main, so `UserError` is the class the command modules raise.
    from lakegate.gateway.cli import main as _main

    sys.exit(_main())
