"""The parsers of every `lakegate` command, built without importing what the commands do.

Each module here adds one command's parser (`add_parser(subparsers)`) and imports only argparse, the
standard library and plain constants, so `lakegate COMMAND --help` answers as fast as `lakegate --help`.
The parser's `func` is a `Command`: it imports the command's module under `lakegate.gateway.cli` only
when the command runs.
"""

from __future__ import annotations

import argparse
import importlib


class Command:
    """`function` of module `lakegate.gateway.cli.<module>`, imported when called with the parsed arguments."""

    def __init__(self, module: str, function: str) -> None:
        self.module, self.function = module, function

    def __call__(self, args: argparse.Namespace) -> int:
        run = getattr(importlib.import_module(f"lakegate.gateway.cli.{self.module}"), self.function)
        return run(args)

    def __repr__(self) -> str:
        return f"Command({self.module!r}, {self.function!r})"
