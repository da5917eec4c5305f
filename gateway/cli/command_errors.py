"""Errors the command line prints as one line (no traceback), and argument checks shared by commands."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from lakegate.lake.config import Config, expand_config_paths, find_default_config


class UserError(Exception):
    """An error caused by the user's input; printed as `lakegate: <message>`, exit code 1."""


def os_error_text(error: OSError) -> str:
    """An OSError in one line: why, and the file (`No space left on device: 'lake/x'`)."""
    reason = error.strerror or str(error)
    return f"{reason}: {str(error.filename)!r}" if error.filename is not None else reason


def writable_lake(path: Path) -> Path:
    """`path` as a lake to write to (it need not exist yet); UserError if it is not a folder."""
    if path.exists() and not path.is_dir():
        raise UserError(f"--lake {str(path)!r} is not a directory (a lake is a folder; it is created if missing)")
    return path


def existing_configs(given: Sequence[Path] | None) -> list[Path]:
    """The config files a command reads: those given (globs and commas expanded as SignalFlag's CLI does,
    `lake.config.expand_config_paths`), else the repository's default config; UserError when there is
    none or one does not exist."""
    if not given:
        default = find_default_config()
        if default is None:
            raise UserError("no config: pass --metrics-config-path (no .resim/metrics/config.resim.yaml here)")
        return [default]
    try:
        return expand_config_paths(given)
    except FileNotFoundError as error:
        raise UserError(str(error)) from None


def print_config_warnings(config: Config) -> None:
    """Each warning of a loaded config as one line on standard error: `file:line:col: warning: ...`."""
    for warning in config.warnings:
        print(f"{warning.location}: warning: {warning.message}", file=sys.stderr)
