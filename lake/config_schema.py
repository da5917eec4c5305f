"""The shape of the metrics config file, described once.

`FILE` is a table of the keys each section of `config.resim.yaml` allows and what
their values must be. The loader (`lakegate.lake.config`) checks files against it and
`json_schema()` turns it into a JSON Schema (draft 2020-12) for editors, so the two
cannot drift apart. Checks a JSON Schema cannot express (one `?` in a status query,
sets naming defined metrics, duplicates across files) live in the loader only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from lakegate.lake.template_kinds import TEMPLATES
from lakegate.lake.types import FIELD_TYPES, TYPE_ALIASES

METRIC_TYPES = ("test", "batch", "dashboard", "report")
#: Metric types a metrics set evaluates; ReSim's sets may also list dashboard and report metrics.
SET_METRIC_TYPES = ("test", "batch")
TEMPLATE_TYPES = ("system", "custom")
#: Tables ReSim's platform generates for every job (from resource_metrics.resim.jsonl and
#: test_length_metric.resim.jsonl): SignalFlag's validator (open-core signalflag/demo/config_test.py,
#: BUILTIN_TABLES) lets no topic shadow them.
PLATFORM_TABLES = ("container_performance", "test_length_seconds")
#: Table names of the lake, and of ReSim's platform, that a topic may not take.
RESERVED_TOPIC_NAMES = ("metadata", "events", "metric_results", *PLATFORM_TABLES)
#: Columns every topic row has besides its declared fields.
TOPIC_COLUMNS = ("timestamp", "batch_id", "job_id", "experience_name", "build_version", "project_id", "run_counter")


def _any_case(word: str) -> str:
    """A regex matching `word` in any letter case (JSON Schema regexes have no flags)."""
    return "".join(f"[{c.lower()}{c.upper()}]" if c.isalpha() else c for c in word)


def _one_of_words(words: tuple[str, ...]) -> str:
    return "^(?:" + "|".join(_any_case(w) for w in words) + ")$"


@dataclass(frozen=True)
class NameRule:
    """A name is refused when `pattern` (a regex valid in Python and ECMA-262) is found in it."""

    pattern: str
    message: str  # completes "topic 'x' ..."


TOPIC_NAME_RULES = (
    NameRule("^$", "has an empty name"),
    NameRule("/", "contains '/', which topic names may not"),
    NameRule("^[_.]", "starts with '_' or '.', which topic names may not"),
    NameRule("[\\u0000-\\u001f\\u007f]", "contains a control character"),
    NameRule(_one_of_words(RESERVED_TOPIC_NAMES), f"is a reserved table name ({', '.join(RESERVED_TOPIC_NAMES)})"),
    # the lake's paths (lake.paths.check_table_name): Hive partitions URL-decode '%', readers glob the rest
    NameRule("[\\\\=%*?\\[\\]{}]", "contains one of \\ = % * ? [ ] { }, which the lake's table paths cannot hold"),
)
FIELD_NAME_RULES = (
    NameRule("^$", "has an empty name"),
    NameRule("[\\u0000-\\u001f\\u007f]", "contains a control character"),
    NameRule(_one_of_words(TOPIC_COLUMNS), f"is a column every topic row already has ({', '.join(TOPIC_COLUMNS)})"),
)
NAME_RULES = (NameRule("^$", "has an empty name"),)


@dataclass(frozen=True)
class Key:
    """What one key's value must be.

    kind: `version` (the integer 1), `string`, `query` (non-blank string), `boolean`,
    `threshold` (a number; SignalFlag refuses '0.5'), `data` (any mapping, kept as plain data), `names`
    (list of unique strings), `fields` (mapping of field names to field types),
    `section` (a mapping checked against `section`), `named` (a mapping of names to
    mappings checked against `section`).
    """

    kind: str
    doc: str
    required: bool = False
    choices: tuple[str, ...] = ()
    default: str | None = None
    nullable: bool = False  # an empty value (null) means the same as an empty mapping/list
    section: Section | None = None
    what: str = ""  # for `named` and `names`: what one entry is ("topic", "metric")
    name_rules: tuple[NameRule, ...] = NAME_RULES


@dataclass(frozen=True)
class When:
    """Keys required or refused in a section when `key` has `value` (its default counts)."""

    key: str
    value: str
    requires: tuple[str, ...] = ()
    refuses: tuple[str, ...] = ()


@dataclass(frozen=True)
class Section:
    """The keys a mapping allows, and conditional rules between them."""

    title: str
    keys: dict[str, Key]
    when: tuple[When, ...] = ()
    one_of: tuple[str, ...] = ()  # at least one of these keys is required


STATUS = Section(
    "status",
    {
        "query_string": Key(
            "query",
            "SQL query with exactly one ? placeholder, replaced by the threshold. "
            "The check fails when the query returns rows.",
            required=True,
        ),
        "block": Key("threshold", "Threshold for a blocking failure."),
        "warn": Key("threshold", "Threshold for a warning (a check may have only warn, as in ReSim)."),
    },
    one_of=("block", "warn"),
)

METRIC = Section(
    "metric",
    {
        "type": Key(
            "string",
            "test: one job's data; batch: every job of a batch; dashboard and report: shown on dashboards and reports.",
            required=True,
            choices=METRIC_TYPES,
        ),
        "description": Key("string", "What the metric shows (optional, as in ReSim)."),
        "query_string": Key("query", "SQL query in the Trino dialect.", required=True),
        "template_type": Key(
            "string", "system: a built-in template; custom: a template file.", choices=TEMPLATE_TYPES, default="system"
        ),
        "template": Key("string", "How the query result is rendered.", choices=tuple(TEMPLATES)),
        "template_file": Key("string", "The custom template file (with template_type: custom)."),
        "template_settings": Key(
            "data",
            "Settings of a system template (not applied to custom ones): xaxis.label, yaxis.label, yaxis.min, "
            "yaxis.max, display.bins, series (group_name and color).",
            nullable=True,
        ),
        "units": Key("string", "Units of the values, shown with the metric (after a scalar value)."),
        "unit": Key("string", "Same as units (some ReSim configs write unit)."),
        "status": Key("section", "A pass/fail check run with the block and warn thresholds.", section=STATUS),
        "skip_if_no_data": Key("boolean", "Skip the metric when its topics have no rows."),
        "skip-if-no-data": Key("boolean", "Same as skip_if_no_data (the spelling of SignalFlag's global section)."),
    },
    when=(
        When("template_type", "system", requires=("template",), refuses=("template_file",)),
        When("template_type", "custom", requires=("template_file",)),
    ),
)

TOPIC = Section(
    "topic",
    {
        "schema": Key("fields", "Field names and their types.", required=True, name_rules=FIELD_NAME_RULES),
        "event": Key("boolean", "Emissions of this topic are events (emit_event)."),
    },
)

METRICS_SET = Section(
    "metrics set",
    {
        "metrics": Key(
            "names",
            "Names of the metrics of this set (dashboard and report metrics are not evaluated yet).",
            required=True,
            nullable=True,
            what="metric",
        )
    },
)

GLOBAL = Section(
    "global",
    {
        "skip-if-no-data": Key(
            "boolean",
            "Every metric of this file that does not set skip_if_no_data itself is skipped when its query "
            "has no rows (SignalFlag: the setting is scoped per file).",
        )
    },
)

FILE = Section(
    "the config file",
    {
        "version": Key("version", "Version of the config format; must be 1.", required=True),
        "topics": Key(
            "named",
            "Topics that can be emitted, by name.",
            nullable=True,
            section=TOPIC,
            what="topic",
            name_rules=TOPIC_NAME_RULES,
        ),
        "metrics": Key("named", "Metrics, by name.", nullable=True, section=METRIC, what="metric"),
        "metrics sets": Key("named", "Metrics sets, by name.", nullable=True, section=METRICS_SET, what="metrics set"),
        "dashboards": Key(
            "data",
            "Dashboards by name: metrics_set (the set shown), day_range (days of batches), refresh, description.",
            nullable=True,
        ),
        "global": Key("section", "Settings for the metrics of this file.", nullable=True, section=GLOBAL),
    },
)

#: Every type name a topic field may have, aliases included.
FIELD_TYPE_NAMES = (*FIELD_TYPES, *TYPE_ALIASES)

_DRAFT = "https://json-schema.org/draft/2020-12/schema"


def _names_schema(rules: tuple[NameRule, ...]) -> dict[str, Any]:
    return {"allOf": [{"not": {"pattern": rule.pattern}} for rule in rules]}


def _nullable(schema: dict[str, Any]) -> dict[str, Any]:
    """Also allow null (an empty YAML value); the other keywords apply to their own type only."""
    return {**schema, "type": [schema["type"], "null"]}


def _key_schema(key: Key, defs: dict[str, Any]) -> dict[str, Any]:
    kind = key.kind
    if kind == "version":
        schema: dict[str, Any] = {"type": "integer", "const": 1}
    elif kind == "string":
        schema = {"type": "string"}
        if key.choices:
            schema["enum"] = list(key.choices)
        if key.default is not None:
            schema["default"] = key.default
    elif kind == "query":
        schema = {"type": "string", "pattern": "\\S"}
    elif kind == "boolean":
        schema = {"type": "boolean"}
    elif kind == "threshold":
        schema = {"type": "number"}
    elif kind == "data":
        schema = {"type": "object"}
    elif kind == "names":
        schema = {"type": "array", "items": {"type": "string"}, "uniqueItems": True}
    elif kind == "fields":
        schema = {
            "type": "object",
            "propertyNames": _names_schema(key.name_rules),
            "additionalProperties": {"enum": list(FIELD_TYPE_NAMES)},
        }
    elif kind == "section":
        schema = {"$ref": f"#/$defs/{_section_def(key.section, defs)}"}
    elif kind == "named":
        schema = {
            "type": "object",
            "propertyNames": _names_schema(key.name_rules),
            "additionalProperties": {"$ref": f"#/$defs/{_section_def(key.section, defs)}"},
        }
    else:
        raise ValueError(f"unknown key kind {kind!r}")
    if key.nullable:
        schema = {"anyOf": [schema, {"type": "null"}]} if "$ref" in schema else _nullable(schema)
    return {"description": key.doc, **schema}


def _when_schema(rule: When, section: Section) -> dict[str, Any]:
    condition: dict[str, Any] = {"properties": {rule.key: {"const": rule.value}}}
    if section.keys[rule.key].default != rule.value:
        condition["required"] = [rule.key]
    then: dict[str, Any] = {}
    if rule.requires:
        then["required"] = list(rule.requires)
    if rule.refuses:
        then["not"] = {"anyOf": [{"required": [name]} for name in rule.refuses]}
    return {"if": condition, "then": then}


def _section_schema(section: Section, defs: dict[str, Any]) -> dict[str, Any]:
    schema: dict[str, Any] = {
        "type": "object",
        "properties": {name: _key_schema(key, defs) for name, key in section.keys.items()},
        "additionalProperties": False,
    }
    required = [name for name, key in section.keys.items() if key.required]
    if required:
        schema["required"] = required
    if section.when:
        schema["allOf"] = [_when_schema(rule, section) for rule in section.when]
    if section.one_of:
        schema["anyOf"] = [{"required": [name]} for name in section.one_of]
    return schema


def _section_def(section: Section | None, defs: dict[str, Any]) -> str:
    assert section is not None
    name = section.title.replace(" ", "_")
    if name not in defs:
        defs[name] = {}  # reserve the name before recursing
        defs[name] = {"title": section.title, **_section_schema(section, defs)}
    return name


def json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a metrics config file."""
    defs: dict[str, Any] = {}
    body = _section_schema(FILE, defs)
    return {
        "$schema": _DRAFT,
        "title": "ReSim metrics config (.resim/metrics/config.resim.yaml)",
        **body,
        "$defs": defs,
    }
