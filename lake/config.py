"""The metrics config file (`.resim/metrics/config.resim.yaml`) as typed objects.

`load_config(paths)` reads one or several files, checks them and merges them; every
problem found is collected into one `ConfigError` whose `problems` each name the
file, the YAML line and column, and what was expected.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

DEFAULT_CONFIG_PATH = Path(".resim/metrics/config.resim.yaml")


@dataclass(frozen=True)
class Location:
    """Where something was written: file and 1-based YAML line and column."""

    path: str
    line: int
    column: int

    def __str__(self) -> str:
        return f"{self.path}:{self.line}:{self.column}"


@dataclass(frozen=True)
class Problem:
    """One config error at one place."""

    location: Location
    message: str

    def __str__(self) -> str:
        return f"{self.location}: {self.message}"


class ConfigError(ValueError):
    """The config is invalid; `problems` lists every error found, each with its place."""

    def __init__(self, problems: list[Problem]):
        self.problems = problems
        super().__init__("\n".join(str(p) for p in problems))


@dataclass
class Topic:
    name: str
    fields: dict[str, str]  # field name -> canonical field type (lake.types), in file order
    event: bool = False
    location: Location | None = None


@dataclass
class StatusCheck:
    query_string: str
    block: Any
    warn: Any = None
    location: Location | None = None


@dataclass
class Metric:
    name: str
    type: str  # test | batch | dashboard | report
    query_string: str
    description: str = ""
    template_type: str = "system"  # system | custom
    template: str | None = None  # line | bar | table | scalar | image | state_timeline | histogram | pie | video | artifact
    template_file: str | None = None
    template_settings: dict[str, Any] = field(default_factory=dict)
    units: str | None = None
    status: StatusCheck | None = None
    skip_if_no_data: bool = False
    location: Location | None = None


@dataclass
class MetricsSet:
    name: str
    metrics: list[str]
    location: Location | None = None


@dataclass
class Config:
    version: int = 1
    topics: dict[str, Topic] = field(default_factory=dict)
    metrics: dict[str, Metric] = field(default_factory=dict)
    metrics_sets: dict[str, MetricsSet] = field(default_factory=dict)
    dashboards: dict[str, Any] = field(default_factory=dict)
    global_settings: dict[str, Any] = field(default_factory=dict)
    paths: list[str] = field(default_factory=list)
