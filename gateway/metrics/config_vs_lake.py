"""A metrics config checked against what a lake's branch stores (`lakegate metrics validate --lake L --branch B`).

Two kinds of findings, each a `Problem` at the place in the config file:

- Topics. A branch's topics only grow, as in SignalFlag, which refuses a sync that removes or
  retypes a topic's column ("schemas are additive per branch"): a topic the config declares must
  keep every field the lake's stored configs give it (the newest stored declaration), with the same
  type, and stay an event topic or a plain one. New topics and new fields are fine.
- Queries. Every metric's query and status query is analysed as `lakegate metrics run` would run
  it (`dialect.translate`, nothing executed) over the tables the branch has, the config's topics
  replacing the stored ones: a table or column the lake does not have, a type mismatch or a
  construct lakegate refuses is reported with Trino's message and its position in the config file.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from lakegate.dialect.errors import DialectError
from lakegate.dialect.session_functions import SessionNames
from lakegate.dialect.translate import translate
from lakegate.gateway.metrics.evaluation import config_position
from lakegate.lake import platform_tables
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.catalog import Catalog
from lakegate.lake.config import Config, Location, Metric, Problem, Topic
from lakegate.lake.paths import METRIC_RESULTS_TABLE
from lakegate.lake.schema import METRIC_RESULTS_COLUMNS, topic_columns


@dataclass(frozen=True)
class StoredTopic:
    """A topic as the lake's branch stores it: its newest declaration and the config version holding it."""

    topic: Topic
    version: int


def stored_topics(lake: Path, branch: str) -> dict[str, StoredTopic]:
    """Every topic any stored config version of the branch declares, as its newest version declares it."""
    registry = BranchConfigs(lake, branch)
    found: dict[str, StoredTopic] = {}
    for version in reversed(registry.versions()):
        for topic in registry.load(version).topics.values():
            found.setdefault(topic.name, StoredTopic(topic, version))
    return found


def check_against_lake(config: Config, lake: Path, branch: str) -> list[Problem]:
    """The config's conflicts with the branch's stored topics, then its queries the branch cannot answer."""
    stored = stored_topics(lake, branch)
    problems = [p for topic in config.topics.values() if topic.name in stored for p in _topic(topic, stored)]
    schema = Catalog(lake).schema(branch) if lake.is_dir() else {}
    schema.setdefault(METRIC_RESULTS_TABLE, dict(METRIC_RESULTS_COLUMNS))  # there once a batch is evaluated
    for topic in platform_tables.TOPICS.values():  # every branch has them once a job is ingested
        schema.setdefault(topic.name, dict(topic_columns(topic)))
    schema.update({topic.name: dict(topic_columns(topic)) for topic in config.topics.values()})
    session = SessionNames("lakegate", "lake", branch)  # what current_user and the like answer in a metrics run
    for metric in config.metrics.values():
        problems += _queries(metric, schema, session)
    return problems


def _topic(topic: Topic, stored: dict[str, StoredTopic]) -> list[Problem]:
    held = stored[topic.name]
    version = f"config version {held.version}"
    at = topic.location or Location("", 0, 0)
    problems = []
    if topic.event != held.topic.event:
        kinds = ["a plain topic", "an event topic"]
        problems.append(
            Problem(
                at,
                f"topic '{topic.name}' is declared {kinds[topic.event]}, but the lake holds it as "
                f"{kinds[held.topic.event]} ({version}); a topic cannot change kind",
            )
        )
    for name, kind in held.topic.fields.items():
        if name not in topic.fields:
            problems.append(
                Problem(
                    at,
                    f"topic '{topic.name}' leaves out field '{name}', which the lake holds as {kind} ({version}); "
                    "a branch's topics only grow (SignalFlag refuses removing a column)",
                )
            )
        elif topic.fields[name] != kind:
            problems.append(
                Problem(
                    topic.field_locations.get(name, at),
                    f"topic '{topic.name}' field '{name}' is declared {topic.fields[name]}, but the lake holds it as "
                    f"{kind} ({version}); SignalFlag refuses retyping a column",
                )
            )
    return problems


def _queries(metric: Metric, schema: dict[str, dict[str, str]], session: SessionNames) -> list[Problem]:
    checks = [("query", metric.query_string, metric.query_location, ())]
    if metric.status is not None:
        threshold = metric.status.block if metric.status.block is not None else metric.status.warn
        checks.append(("status query", metric.status.query_string, metric.status.query_location, (threshold,)))
    problems = []
    for which, sql, start, params in checks:
        try:
            translate(sql, schema, params=params, session=session)
        except DialectError as error:
            at = config_position(start, sql, error.line, error.column) or start or metric.location
            message = error.message
            where = "" if at is not start or error.line is None else f" (line {error.line}, column {error.column})"
            problems.append(Problem(at or Location("", 0, 0), f"{which} of metric '{metric.name}': {message}{where}"))
    return problems
