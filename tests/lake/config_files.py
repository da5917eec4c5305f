"""Config files written for the config tests, and the problems loading them reports."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from lakegate.lake.config import (
    ConfigError,
    load_config,
)

FIXTURE = Path(__file__).resolve().parents[2] / "fixtures" / "config.resim.yaml"

HEADER = "version: 1\n"


def write(folder: Path, text: str, name: str = "config.resim.yaml") -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
    return path


def errors(path: Path | list[Path]) -> list[tuple[int, int, str]]:
    """(line, column, message) of every problem with --strict; fails when the config loads."""
    with pytest.raises(ConfigError) as caught:
        load_config(path, strict=True)
    return [(p.location.line, p.location.column, p.message) for p in caught.value.problems]


def warnings_of(path: Path | list[Path]) -> list[tuple[int, int, str]]:
    """(line, column, message) of every warning of a config that loads without --strict."""
    return [(p.location.line, p.location.column, p.message) for p in load_config(path).warnings]


#: How a warning (lakegate stricter than ReSim on purpose) ends when --strict refuses it.
STRICT = " (ReSim accepts this; refused because of --strict)"
RESERVED = "metadata, events, metric_results, container_performance, test_length_seconds"


def one_error(folder: Path, text: str) -> tuple[int, int, str]:
    found = errors(write(folder, text))
    assert len(found) == 1, found
    return found[0]


def line_of(path: Path, text: str) -> int:
    """1-based number of the first line of `path` that is exactly `text`."""
    return path.read_text().splitlines().index(text) + 1
