"""The metrics config file (`.resim/metrics/config.resim.yaml`) as typed objects.

`load_config(paths)` reads one or several files, checks them and merges them; every
problem found is collected into one `ConfigError` whose `problems` each name the
file, the YAML line and column, and what was expected. Where lakegate is stricter than
ReSim on purpose, the finding is a warning in `Config.warnings` instead (the file loads as
ReSim reads it), or a problem with `strict=True` (`--strict`). The keys each section allows
are described once in `config_schema` (which also yields the JSON Schema); the YAML
walking lives in `config_yaml`.
"""

from __future__ import annotations

import glob
import os
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ruamel.yaml.nodes import MappingNode

from lakegate.lake import paths
from lakegate.lake.config_schema import FILE, TOPIC_NAME_RULES
from lakegate.lake.config_yaml import CheckedValue, FileReader, Named, RawProblem, RawWarning, did_you_mean

#: Ends a warning that `strict` makes a problem.
STRICT_NOTE = " (ReSim accepts this; refused because of --strict)"
#: SignalFlag's `global:` setting (and the metric key it sets): skip a metric whose query has no rows.
GLOBAL_SKIP = "skip-if-no-data"
DEFAULT_CONFIG_PATH = Path(".resim/metrics/config.resim.yaml")
#: Where `find_default_config` looks, relative to a folder, in this order.
DEFAULT_CONFIG_PATHS = (DEFAULT_CONFIG_PATH, DEFAULT_CONFIG_PATH.with_suffix(".yml"))


@dataclass(frozen=True)
class Location:
    """Where something was written: file and 1-based YAML line and column (0: the whole file)."""

    path: str
    line: int
    column: int

    def __str__(self) -> str:
        return f"{self.path}:{self.line}:{self.column}" if self.line else self.path


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
    #: Where each field's name is written (fields merged in from a YAML alias may have none).
    field_locations: dict[str, Location] = field(default_factory=dict)


@dataclass
class StatusCheck:
    query_string: str
    block: Any = None  # a check may have only `warn`, or only `block`
    warn: Any = None
    location: Location | None = None
    query_location: Location | None = None  # where the query_string value starts


@dataclass
class Metric:
    name: str
    type: str  # test | batch | dashboard | report
    query_string: str
    description: str = ""
    template_type: str = "system"  # system | custom
    template: str | None = None  # a system template kind: lake/template_kinds.py TEMPLATES
    template_file: str | None = None
    template_settings: dict[str, Any] = field(default_factory=dict)
    units: str | None = None
    status: StatusCheck | None = None
    skip_if_no_data: bool = False
    location: Location | None = None
    query_location: Location | None = None  # where the query_string value starts
    #: The templates folder given with the config (`templates_path`), searched last.
    templates_dir: Path | None = None

    def template_path(self) -> Path | None:
        """The custom template file: next to the config file declaring the metric, else in its
        `templates/` folder, else in `templates_dir`; None when none holds it (a file must stay inside
        the folder it is looked up in)."""
        if not self.template_file or self.location is None or "\0" in self.template_file:
            return None
        folder = Path(self.location.path).parent.resolve()
        places = [(folder, folder / self.template_file), (folder, folder / "templates" / self.template_file)]
        if self.templates_dir is not None:
            root = self.templates_dir.resolve()
            places.append((root, root / self.template_file))
        for root, candidate in places:
            path = candidate.resolve()
            if path.is_relative_to(root) and path.is_file():
                return path
        return None


@dataclass
class Dashboard:
    """A `dashboards:` entry: a page of the metrics of one set over the batches of the last `day_range` days."""

    name: str
    metrics_set: str | None = None
    day_range: int | None = None  # None: every batch of the branch
    refresh: Any = None
    description: str = ""
    #: The entry as written (keys lakegate does not use are kept here too).
    settings: dict[str, Any] = field(default_factory=dict)
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
    dashboards: dict[str, Dashboard] = field(default_factory=dict)
    #: The `global:` sections, merged (last file wins); each applies to its own file's metrics only.
    global_settings: dict[str, Any] = field(default_factory=dict)
    paths: list[str] = field(default_factory=list)
    templates_path: str | None = None
    #: Findings where lakegate is stricter than ReSim on purpose (refused with strict=True).
    warnings: list[Problem] = field(default_factory=list)

    def metrics_in_set(self, name: str) -> list[Metric]:
        """The metrics of set `name`, in the set's order; KeyError naming the known sets if none."""
        metrics_set = self.metrics_sets.get(name)
        if metrics_set is None:
            known = ", ".join(repr(n) for n in self.metrics_sets) or "none"
            raise KeyError(f"no metrics set {name!r}{did_you_mean(name, self.metrics_sets)}; known sets: {known}")
        return [self.metrics[m] for m in metrics_set.metrics]

    def dashboard(self, name: str) -> Dashboard:
        """The dashboard `name`; KeyError naming the known dashboards, or saying it has no metrics_set."""
        dashboard = self.dashboards.get(name)
        if dashboard is None:
            known = ", ".join(repr(n) for n in self.dashboards) or "none"
            raise KeyError(f"no dashboard {name!r}{did_you_mean(name, self.dashboards)}; known dashboards: {known}")
        if dashboard.metrics_set is None:
            raise KeyError(f"dashboard {name!r} ({dashboard.location}) has no metrics_set")
        return dashboard

    def summary(self) -> str:
        """`10 topics, 14 metrics, 1 metrics set` (and dashboards, when there are any)."""
        parts = [
            _count(len(self.topics), "topic"),
            _count(len(self.metrics), "metric"),
            _count(len(self.metrics_sets), "metrics set", "metrics sets"),
        ]
        if self.dashboards:
            parts.append(_count(len(self.dashboards), "dashboard"))
        return ", ".join(parts)


def _count(n: int, one: str, many: str | None = None) -> str:
    return f"{n} {one if n == 1 else many or one + 's'}"


def find_default_config(start: Path | None = None) -> Path | None:
    """The first `.resim/metrics/config.resim.yaml` (or `.yml`) in `start` (default: the
    current directory) or one of its parents, or None."""
    folder = Path(start if start is not None else Path.cwd()).resolve()
    for candidate_folder in (folder, *folder.parents):
        for relative in DEFAULT_CONFIG_PATHS:
            if (candidate_folder / relative).is_file():
                return candidate_folder / relative
    return None


# Strings, quoted identifiers and comments of Trino SQL: a `?` inside them is no parameter.
_SQL_NOT_CODE = re.compile(r"""'(?:[^']|'')*'|"(?:[^"]|"")*"|--[^\n]*|/\*.*?\*/""", re.S)


def count_placeholders(sql: str) -> int:
    """The number of `?` parameters in Trino SQL (outside literals, quoted names and comments).

    Raises ValueError for an unterminated string literal, quoted identifier or comment.
    """
    code = _SQL_NOT_CODE.sub(" ", sql)
    for opener, what in (("'", "string literal"), ('"', "quoted identifier"), ("/*", "comment")):
        if opener in code:
            raise ValueError(f"unterminated {what}")
    return code.count("?")


def duplicate_message(noun: str, name: str, first: Location | None) -> str:
    """SignalFlag's error for a name two config files define, with the first definition's place."""
    return f"duplicate {noun} name '{name}' found across config files (first defined at {first})"


def config_path_list(paths: str | os.PathLike[str] | Iterable[str | os.PathLike[str]] | None) -> list[Path]:
    """One config path or several as a list (SignalFlag's `metrics_config_path`: a path or a sequence)."""
    if paths is None:
        return []
    if isinstance(paths, (str, os.PathLike)):
        return [Path(paths)]
    return [Path(p) for p in paths]


def expand_config_paths(patterns: Iterable[str | os.PathLike[str]]) -> list[Path]:
    """The files of `--metrics-config-path` values, as SignalFlag's CLI resolves them: a value may hold
    several paths separated by commas; a path with `*`, `?` or `[` is a glob whose matches are taken in
    sorted order (none: an error); a literal path must exist, or its `.yml`/`.yaml` twin. Raises
    FileNotFoundError naming the value."""
    found: list[Path] = []
    for value in patterns:
        for text in (part.strip() for part in os.fspath(value).split(",")):
            if not text:
                continue
            if any(c in text for c in "*?["):
                matches = sorted(glob.glob(text, recursive=True))
                files = [Path(m) for m in matches if Path(m).is_file()]
                if not files:
                    raise FileNotFoundError(f"glob pattern {text!r} matched no config files")
                found += files
                continue
            path = Path(text)
            twin = {".yml": ".yaml", ".yaml": ".yml"}.get(path.suffix)
            if path.is_file():
                found.append(path)
            elif twin is not None and path.with_suffix(twin).is_file():
                found.append(path.with_suffix(twin))
            else:
                raise FileNotFoundError(
                    f"config file {text!r} does not exist" + (f" (nor its {twin} twin)" if twin else "")
                )
    return found


def load_config(
    paths: str | Path | Sequence[str | Path],
    *,
    strict: bool = False,
    templates_path: str | Path | None = None,
) -> Config:
    """Load, check and merge config files; raise ConfigError listing every problem found.

    Files are merged as SignalFlag merges them: topics, metrics, metrics sets and dashboards by name
    (a name in two files is an error naming both places); every file has `version: 1`; a file's
    `global: {skip-if-no-data: B}` applies to the metrics of that file that do not set it themselves.
    Custom templates are found beside the file declaring the metric, in its `templates/` folder, or in
    `templates_path`. Findings where lakegate is stricter than ReSim are `Config.warnings`, or
    problems when `strict`.
    """
    path_list = [paths] if isinstance(paths, (str, Path)) else list(paths)
    if not path_list:
        raise ValueError("load_config needs at least one config file")
    raw: list[RawProblem] = []
    warnings: list[RawWarning] = []
    config = Config(
        paths=[str(p) for p in path_list], templates_path=None if templates_path is None else str(templates_path)
    )
    builder = _Builder(config, raw, warnings)
    for path in path_list:
        reader = FileReader(str(path), raw, warnings)
        root = reader.compose()
        if root is not None:
            builder.add_file(reader, reader.section(root, FILE, "the config file", root))
    builder.check_sets()
    if strict:
        raw += [(p, line, column, message + STRICT_NOTE) for p, line, column, message, _ in warnings]
    if raw:
        raise ConfigError(_in_order(raw, path_list))
    found = [(p, line, column, f"{message}: {instead}") for p, line, column, message, instead in warnings]
    builder.config.warnings = _in_order(found, path_list)
    return builder.config


def _in_order(raw: list[RawProblem], path_list: list) -> list[Problem]:
    """Problems by file (in the order given), line and column; each once (an aliased node is
    checked everywhere it is used)."""
    order = {str(p): i for i, p in enumerate(path_list)}
    unique = sorted(dict.fromkeys(raw), key=lambda p: (order.get(p[0], 0), p[1], p[2]))
    return [Problem(Location(p, line, column), message) for p, line, column, message in unique]


class _Builder:
    """Turns the checked entries of each file into one Config, checking names across files."""

    def __init__(self, config: Config, problems: list[RawProblem], warnings: list[RawWarning]):
        self.config = config
        self.problems = problems
        self.warnings = warnings
        self._topic_names: dict[str, Topic] = {}  # lower-case name -> topic
        self._set_items: list[tuple[MetricsSet, list[tuple[str, Location]]]] = []
        self._data_locations: dict[tuple[str, Any], Location] = {}  # (section, key) -> where defined

    def _error(self, location: Location, message: str) -> None:
        self.problems.append((location.path, location.line, location.column, message))

    def _warn(self, location: Location, message: str, instead: str) -> None:
        self.warnings.append((location.path, location.line, location.column, message, instead))

    def add_file(self, reader: FileReader, entries: dict[str, CheckedValue]) -> None:
        def at(node: Any) -> Location:
            return Location(reader.path, *reader.position(node))

        for named in _value(entries, "topics", []):
            schema = named.entries.get("schema")
            keys = reader.plain_keys(schema.node) if schema is not None and isinstance(schema.node, MappingNode) else {}
            self._add_topic(
                Topic(
                    named.name,
                    _value(named.entries, "schema", {}),
                    _value(named.entries, "event", False),
                    at(named.key),
                    {str(name): at(node) for name, node in keys.items()},
                )
            )
        skip_default = self._global(entries.get("global"))
        for named in _value(entries, "metrics", []):
            self._add("metric", self.config.metrics, self._metric(named, at, skip_default))
        for named in _value(entries, "metrics sets", []):
            items = _value(named.entries, "metrics", [])
            metrics_set = MetricsSet(named.name, [name for name, _ in items], at(named.key))
            if self._add("metrics set", self.config.metrics_sets, metrics_set):
                self._set_items.append((metrics_set, [(name, at(node)) for name, node in items]))
        if "dashboards" in entries:
            self._dashboards(entries["dashboards"], reader, at)

    def _global(self, entry: CheckedValue | None) -> bool | None:
        """The file's `global: {skip-if-no-data: B}` (SignalFlag's only global setting), or None."""
        if entry is None or not entry.value:
            return None
        settings = {key: item.value for key, item in entry.value.items()}
        self.config.global_settings.update(settings)
        return settings.get(GLOBAL_SKIP)

    def _dashboards(self, entry: CheckedValue, reader: FileReader, at: Callable[[Any], Location]) -> None:
        if not entry.value:
            return
        if not isinstance(entry.value, dict):
            self._error(at(entry.node), f"dashboards must be a mapping, got {type(entry.value).__name__}")
            return
        nodes = reader.plain_keys(entry.node)
        for name, settings in entry.value.items():
            location = at(nodes.get(name, entry.node))
            settings = settings if isinstance(settings, dict) else {}
            day_range = settings.get("day_range")
            if day_range is not None and (type(day_range) is not int or day_range <= 0):
                self._error(
                    location, f"dashboard '{name}': day_range must be a positive number of days, got {day_range!r}"
                )
                day_range = None
            metrics_set = settings.get("metrics_set")
            dashboard = Dashboard(
                str(name),
                None if metrics_set is None else str(metrics_set),
                day_range,
                settings.get("refresh"),
                str(settings.get("description") or ""),
                settings,
                location,
            )
            self._add("dashboard", self.config.dashboards, dashboard)

    def _add_topic(self, topic: Topic) -> None:
        assert topic.location is not None
        if not any(re.search(rule.pattern, topic.name) for rule in TOPIC_NAME_RULES):  # else reported already
            try:
                paths.check_table_name(topic.name)  # what the schema's rules cannot say (its length in bytes)
            except paths.LakePathError as exc:
                self._error(topic.location, str(exc))
        other = self._topic_names.get(topic.name.lower())
        if other is not None and other.name != topic.name:
            self._error(
                topic.location,
                f"topic '{topic.name}' differs only in letter case from topic "
                f"'{other.name}' ({other.location}); SQL table names ignore case",
            )
        elif self._add("topic", self.config.topics, topic):
            self._topic_names[topic.name.lower()] = topic

    def _add(self, noun: str, into: dict[str, Any], thing: Any) -> bool:
        """Add a named thing unless another file defined it already (then report both places)."""
        if thing.name in into:
            self._error(thing.location, duplicate_message(noun, thing.name, into[thing.name].location))
            return False
        into[thing.name] = thing
        return True

    def _metric(self, named: Named, at: Callable[[Any], Location], skip_default: bool | None = None) -> Metric:
        e = named.entries
        metric = Metric(
            name=named.name,
            type=_value(e, "type", "test"),
            query_string=_value(e, "query_string", ""),
            description=_value(e, "description", ""),
            template_type=_value(e, "template_type", "system"),
            template=_value(e, "template", None),
            template_file=_value(e, "template_file", None),
            template_settings=_value(e, "template_settings", {}),
            units=self._units(named.name, e, at),
            skip_if_no_data=_value(e, "skip_if_no_data", _value(e, GLOBAL_SKIP, skip_default or False)),
            templates_dir=None if self.config.templates_path is None else Path(self.config.templates_path),
            location=at(named.key),
            query_location=at(e["query_string"].node) if "query_string" in e else None,
        )
        if metric.template_type == "custom" and metric.template_settings and "template_settings" in e:
            self._warn(
                at(e["template_settings"].node),
                f"template_settings of metric '{metric.name}' ({', '.join(setting_names(metric.template_settings))}) "
                f"are not applied to its custom template {metric.template_file!r}",
                "ignored, as SignalFlag ignores them (a custom template's figure is what the template writes: "
                "set titles, ranges and colours there)",
            )
        if "status" in e:
            s = e["status"].value
            query = s.get("query_string")
            metric.status = StatusCheck(
                query_string=_value(s, "query_string", ""),
                block=_value(s, "block", None),
                warn=_value(s, "warn", None),
                location=at(e["status"].node),
                query_location=at(query.node) if query else None,
            )
            if query is not None:
                self._check_status_query(metric.name, query.value, at(query.node))
        return metric

    def _units(self, metric: str, e: dict[str, CheckedValue], at: Callable[[Any], Location]) -> str | None:
        """`units`, or `unit` as some ReSim configs write it; both differing: a warning, `units` wins."""
        units, unit = _value(e, "units", None), _value(e, "unit", None)
        if units is not None and unit is not None and units != unit:
            self._warn(
                at(e["unit"].node), f"metric '{metric}' has both units '{units}' and unit '{unit}'", "units is used"
            )
        return units if units is not None else unit

    def _check_status_query(self, metric: str, sql: str, location: Location) -> None:
        try:
            count = count_placeholders(sql)
        except ValueError as exc:
            self._error(location, f"status query_string of metric '{metric}' has an {exc}")
            return
        if count != 1:
            self._error(
                location,
                f"status query_string of metric '{metric}' must have exactly one ? "
                f"placeholder (replaced by the block and warn thresholds), found {count}",
            )

    def check_sets(self) -> None:
        """Every name in a metrics set must be a metric of the merged config (of any type, as in ReSim)."""
        metrics = self.config.metrics
        for dashboard in self.config.dashboards.values():
            if dashboard.metrics_set is not None and dashboard.metrics_set not in self.config.metrics_sets:
                assert dashboard.location is not None
                self._error(
                    dashboard.location,
                    f"dashboard '{dashboard.name}' names unknown metrics set '{dashboard.metrics_set}'"
                    f"{did_you_mean(dashboard.metrics_set, self.config.metrics_sets)}",
                )
        for metrics_set, items in self._set_items:
            for name, location in items:
                if name not in metrics:
                    self._error(
                        location,
                        f"metrics set '{metrics_set.name}' names unknown metric '{name}'{did_you_mean(name, metrics)}",
                    )


def setting_names(settings: Any) -> list[str]:
    """The settings of a `template_settings` mapping as `section.key` (or `section` when it is no mapping)."""
    if not isinstance(settings, dict):
        return []
    names = []
    for section, value in settings.items():
        keys = list(value) if isinstance(value, dict) else []
        names += [f"{section}.{key}" for key in keys] or [str(section)]
    return names


def _value(entries: dict[str, CheckedValue], key: str, default: Any) -> Any:
    entry = entries.get(key)
    return default if entry is None else entry.value
