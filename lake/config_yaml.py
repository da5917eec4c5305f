"""Walking one composed YAML file against the config description (`config_schema`).

`FileReader` composes a file with ruamel.yaml (safe, YAML 1.2: `on`, `yes` and `1:30` are
strings) so every node keeps its line and column, and checks mappings against a `Section`:
unknown keys (with a did-you-mean), missing keys, value types, duplicate keys and names.
Every problem is appended to a shared list; nothing here raises for bad input. Where lakegate
is stricter than ReSim on purpose (an unknown key, a name YAML reads as a number or boolean, a
key its template type does not use) the finding is a warning, with what lakegate does instead
(the key is ignored, the name read as its text), and the file still loads; a reader without a
warnings list (lakegate's own formats) reports it as a problem. The dashboard edits configs with
the same library (round-trip mode), so what it writes reads back the same.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.composer import MaxDepthExceededError
from ruamel.yaml.constructor import SafeConstructor
from ruamel.yaml.error import MarkedYAMLError
from ruamel.yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from lakegate.lake.config_schema import FIELD_TYPE_NAMES, Key, NameRule, Section
from lakegate.lake.types import canonical_type

_TAG = "tag:yaml.org,2002:"
_MERGE_TAG = _TAG + "merge"
_TAG_NAMES = {"str": "string", "int": "integer", "float": "number", "bool": "boolean"}
_A_TYPE = {"int": "an integer", "float": "a number", "bool": "a boolean", "null": "null", "timestamp": "a date"}
_NOTHING = object()
#: A problem as (path, line, column, message); line and column are 0 for the whole file.
RawProblem = tuple[str, int, int, str]
#: A warning as (path, line, column, message, what lakegate does instead of refusing).
RawWarning = tuple[str, int, int, str, str]
#: The largest config file read (bytes): far above any real config, and composed in seconds.
MAX_FILE_BYTES = 2 * 1024 * 1024
#: The deepest nesting of mappings and lists in a config file (a real one nests about 6 levels).
MAX_DEPTH = 64
#: What an empty (null) value of a nullable key stands for.
_EMPTY = {"names": list, "named": list, "data": dict, "fields": dict, "section": dict}


def did_you_mean(word: str, choices: Any) -> str:
    """` (did you mean 'x'?)` for the closest of `choices`, or ''."""
    close = difflib.get_close_matches(word, [str(c) for c in choices], n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def describe(node: Node) -> str:
    """A node's YAML type and value for messages: `string 'abc'`, `a list`."""
    if isinstance(node, MappingNode):
        return "a mapping"
    if isinstance(node, SequenceNode):
        return "a list"
    tag = node.tag.removeprefix(_TAG)
    if tag == "null":
        return "nothing (null)"
    if tag == "str":
        return f"string {node.value!r}"
    return f"{_TAG_NAMES.get(tag, tag)} {node.value}"


def _yaml_kind(node: ScalarNode) -> str:
    """`an integer`, `a boolean`: what YAML reads a plain scalar as."""
    return _A_TYPE.get(node.tag.removeprefix(_TAG), node.tag)


def _is(node: Node, tag: str) -> bool:
    return isinstance(node, ScalarNode) and node.tag == _TAG + tag


def _is_null(node: Node) -> bool:
    return _is(node, "null")


@dataclass
class Named:
    """One entry of a mapping of names (a topic, a metric, a set) and its checked keys."""

    name: str
    key: ScalarNode
    entries: dict[str, CheckedValue]


@dataclass
class CheckedValue:
    """A key's checked value (converted as its `Key.kind` says) and the value's node."""

    value: Any
    node: Node


class FileReader:
    """Reads one config file; problems are appended to `problems`, and warnings to `warnings`
    (to `problems`, when it is None)."""

    def __init__(self, path: str, problems: list[RawProblem], warnings: list[RawWarning] | None = None):
        self.path = path
        self.problems = problems
        self.warnings = warnings
        self._yaml = YAML(typ="safe", pure=True)
        self._yaml.max_depth = MAX_DEPTH
        self._yaml.allow_duplicate_keys = True  # reported by `items` with both places
        self._constructor: SafeConstructor = self._yaml.constructor

    # -- places and problems -------------------------------------------------------

    def position(self, node: Node) -> tuple[int, int]:
        """1-based line and column where `node` starts."""
        return node.start_mark.line + 1, node.start_mark.column + 1

    def error(self, node: Node, message: str) -> None:
        self.problems.append((self.path, *self.position(node), message))

    def warn(self, node: Node, message: str, instead: str) -> None:
        """A rule where lakegate is stricter than ReSim: a warning saying what is done `instead`."""
        if self.warnings is None:
            self.error(node, message)
        else:
            self.warnings.append((self.path, *self.position(node), message, instead))

    def _first_at(self, node: Node) -> str:
        line, column = self.position(node)
        return f"first at line {line}, column {column}"

    # -- composing -----------------------------------------------------------------

    def compose(self) -> Node | None:
        """The file's root node, or None (with a problem) when it cannot be read or parsed."""
        try:
            with open(self.path, encoding="utf-8") as stream:
                text = stream.read(MAX_FILE_BYTES + 1)
        except (OSError, UnicodeDecodeError) as exc:
            self.problems.append((self.path, 0, 0, f"cannot read the file: {exc}"))
            return None
        if len(text.encode("utf-8", "surrogatepass")) > MAX_FILE_BYTES:
            message = f"the file is larger than {MAX_FILE_BYTES:,} bytes, the limit of a config file"
            self.problems.append((self.path, 0, 0, message))
            return None
        try:
            root = self._yaml.compose(text)
        except MaxDepthExceededError as exc:
            mark = exc.problem_mark
            message = f"mappings and lists nest deeper than {MAX_DEPTH} levels, the limit of a config file"
            self.problems.append((self.path, mark.line + 1, mark.column + 1, message))
            return None
        except MarkedYAMLError as exc:
            self._yaml_error(exc)
            return None
        if root is None:
            self.problems.append((self.path, 1, 1, "the file is empty; expected a mapping starting with 'version: 1'"))
        return root

    def _yaml_error(self, exc: MarkedYAMLError) -> None:
        mark = exc.problem_mark or exc.context_mark
        message = f"invalid YAML: {exc.problem or exc.context}"
        if exc.context and exc.problem and exc.context_mark is not None:
            message += f" ({exc.context}, line {exc.context_mark.line + 1}, column {exc.context_mark.column + 1})"
        line, column = (mark.line + 1, mark.column + 1) if mark is not None else (0, 0)
        self.problems.append((self.path, line, column, message))

    # -- mappings ------------------------------------------------------------------

    def items(
        self, node: MappingNode, noun: str, where: str, *, string_keys: bool = True
    ) -> list[tuple[ScalarNode, Node]]:
        """The (key, value) nodes of a mapping, `<<` merges applied; duplicates are reported.

        A duplicate reads `duplicate {noun} 'k'{where} (first at ...)`; explicit keys
        win over merged ones, as in YAML.
        """
        explicit: list[tuple[ScalarNode, Node]] = []
        merged: list[tuple[ScalarNode, Node]] = []
        for key, value in node.value:
            if key.tag == _MERGE_TAG:
                for source in value.value if isinstance(value, SequenceNode) else [value]:
                    if isinstance(source, MappingNode):
                        merged.extend(self.items(source, noun, where, string_keys=string_keys))
                    else:
                        self.error(source, f"'<<' can only merge mappings, got {describe(source)}")
            elif not isinstance(key, ScalarNode):
                self.error(key, f"{noun}{where} must be a string, got {describe(key)}")
            else:
                if string_keys and key.tag != _TAG + "str":
                    read_as = f"{noun} '{key.value}'{where} is read by YAML as {_yaml_kind(key)}, not a string"
                    self.warn(key, read_as, f"taken as the text '{key.value}' (quote it)")
                explicit.append((key, value))
        seen: dict[str, ScalarNode] = {}
        result = []
        for key, value in explicit:
            if key.value in seen:
                self.error(key, f"duplicate {noun} '{key.value}'{where} ({self._first_at(seen[key.value])})")
                continue
            seen[key.value] = key
            result.append((key, value))
        for key, value in merged:
            if key.value not in seen:
                seen[key.value] = key
                result.append((key, value))
        return result

    def section(self, node: Node, section: Section, label: str, anchor: Node) -> dict[str, CheckedValue]:
        """Check a mapping against `section`; returns its valid entries by key.

        `label` names the mapping in messages ("metric 'Robot Speed'"); missing keys are
        reported at `anchor` (usually the node of the mapping's name).
        """
        if not isinstance(node, MappingNode):
            self.error(node, f"{label} must be a mapping, got {describe(node)}")
            return {}
        entries: dict[str, CheckedValue] = {}
        present: set[str] = set()
        for key, value in self.items(node, "key", f" in {label}"):
            name = key.value
            spec = section.keys.get(name)
            if spec is None:
                self.warn(key, f"unknown key '{name}' in {label}{did_you_mean(name, section.keys)}", "ignored")
                continue
            present.add(name)
            checked = self._value(spec, name, value, key, label)
            if checked is not _NOTHING:
                entries[name] = CheckedValue(checked, value)
        for name, spec in section.keys.items():
            if spec.required and name not in present:
                self.error(anchor, f"missing required key '{name}' in {label}")
        if section.one_of and not present.intersection(section.one_of):
            keys = " or ".join(f"'{name}'" for name in section.one_of)
            self.error(anchor, f"{label} needs {keys}")
        for rule in section.when:
            value = entries[rule.key].value if rule.key in entries else section.keys[rule.key].default
            if (rule.key in present and rule.key not in entries) or value != rule.value:
                continue  # the rule does not apply, or its key's value was invalid
            for name in rule.requires:
                if name not in present:
                    self.error(anchor, f"missing key '{name}' in {label}, needed with {rule.key}: {rule.value}")
            for name in rule.refuses:
                if name in entries:
                    self.warn(
                        entries[name].node, f"'{name}' in {label} is not used with {rule.key}: {rule.value}", "ignored"
                    )
                    del entries[name]
        return entries

    # -- values --------------------------------------------------------------------

    def _value(self, spec: Key, name: str, node: Node, key: ScalarNode, label: str) -> Any:
        """The value of key `name` converted per `spec.kind`, or _NOTHING after reporting."""
        kind = spec.kind
        if spec.nullable and _is_null(node):
            return _EMPTY[kind]()
        where = f"'{name}' in {label}"
        if kind == "version":
            if (_is(node, "int") or _is(node, "float")) and self._constructor.construct_object(node) == 1:
                return 1
            return self._wrong(node, f"version must be 1, got {describe(node)}")
        if kind in ("string", "query"):
            if not _is(node, "str"):
                hint = " (quote it)" if isinstance(node, ScalarNode) and not _is_null(node) else ""
                return self._wrong(node, f"{where} must be a string, got {describe(node)}{hint}")
            if kind == "query" and not node.value.strip():
                return self._wrong(node, f"{where} must not be empty")
            if spec.choices and node.value not in spec.choices:
                return self._wrong(
                    node,
                    f"unknown {name} '{node.value}' in {label}"
                    f"{did_you_mean(node.value, spec.choices)}; expected one of "
                    f"{', '.join(spec.choices)}",
                )
            return node.value
        if kind == "boolean":
            if _is(node, "bool"):
                return self._constructor.construct_object(node)
            return self._wrong(node, f"{where} must be a boolean (true or false), got {describe(node)}")
        if kind == "threshold":
            if _is(node, "int") or _is(node, "float"):
                return self._constructor.construct_object(node)
            if _is(node, "str"):  # SignalFlag refuses it at sync: "Expected Number but got String"
                return self._wrong(node, f"{where} must be a number, not a quoted string, got {describe(node)}")
            return self._wrong(node, f"{where} must be a number, got {describe(node)}")
        if kind == "data":
            if not isinstance(node, MappingNode):
                return self._wrong(node, f"{where} must be a mapping, got {describe(node)}")
            return self.plain(node, f" in {name} of {label}")
        if kind == "names":
            return self._names(spec, node, where, f" in {label}")
        if kind == "fields":
            return self._fields(spec, node, where, label)
        if kind == "section":
            assert spec.section is not None
            return self.section(node, spec.section, f"{name} of {label}", key)
        if kind == "named":
            return self._named(spec, node, where)
        raise ValueError(f"unknown key kind {kind!r}")

    def _wrong(self, node: Node, message: str) -> Any:
        self.error(node, message)
        return _NOTHING

    def _names(self, spec: Key, node: Node, where: str, inside: str) -> Any:
        if not isinstance(node, SequenceNode):
            return self._wrong(node, f"{where} must be a list of {spec.what} names, got {describe(node)}")
        names: list[tuple[str, ScalarNode]] = []
        seen: dict[str, ScalarNode] = {}
        for item in node.value:
            if not isinstance(item, ScalarNode) or _is_null(item):
                self.error(item, f"{spec.what} names{inside} must be strings, got {describe(item)}")
                continue
            if not _is(item, "str"):
                read_as = f"{spec.what} name '{item.value}'{inside} is read by YAML as {_yaml_kind(item)}, not a string"
                self.warn(item, read_as, f"taken as the text '{item.value}' (quote it)")
            if item.value in seen:
                self.error(item, f"duplicate {spec.what} '{item.value}'{inside} ({self._first_at(seen[item.value])})")
            else:
                seen[item.value] = item
                names.append((item.value, item))
        return names

    def _check_name(self, rules: tuple[NameRule, ...], subject: str, key: ScalarNode) -> bool:
        """Report the first rule `key`'s name breaks, as `{subject} {rule.message}`."""
        for rule in rules:
            if re.search(rule.pattern, key.value):
                self.error(key, f"{subject} {rule.message}")
                return False
        return True

    def _fields(self, spec: Key, node: Node, where: str, label: str) -> Any:
        if not isinstance(node, MappingNode):
            return self._wrong(node, f"{where} must be a mapping of field names to types, got {describe(node)}")
        fields: dict[str, str] = {}
        folded: dict[str, ScalarNode] = {}
        for key, value in self.items(node, "field", f" in {label}"):
            name = key.value
            if not self._check_name(spec.name_rules, f"field '{name}' of {label}", key):
                continue
            if name.lower() in folded:
                other = folded[name.lower()]
                self.error(
                    key,
                    f"field '{name}' of {label} differs only in letter case from field "
                    f"'{other.value}' ({self._first_at(other).removeprefix('first ')}); "
                    "SQL column names ignore case",
                )
                continue
            folded[name.lower()] = key
            if not _is(value, "str"):
                self.error(
                    value,
                    f"field '{name}' of {label} needs a type, got {describe(value)}; "
                    f"expected one of {', '.join(FIELD_TYPE_NAMES)}",
                )
                continue
            field_type = canonical_type(value.value)
            if field_type is None:
                self.error(
                    value,
                    f"unknown field type '{value.value}' for field '{name}' of {label}"
                    f"{did_you_mean(value.value, FIELD_TYPE_NAMES)}; expected one of "
                    f"{', '.join(FIELD_TYPE_NAMES)}",
                )
                continue
            fields[name] = field_type
        return fields

    def _named(self, spec: Key, node: Node, where: str) -> Any:
        if not isinstance(node, MappingNode):
            return self._wrong(
                node, f"{where} must be a mapping of {spec.what} names to {spec.what} definitions, got {describe(node)}"
            )
        assert spec.section is not None
        named = []
        for key, value in self.items(node, spec.what, ""):
            label = f"{spec.what} '{key.value}'"
            self._check_name(spec.name_rules, label, key)
            named.append(Named(key.value, key, self.section(value, spec.section, label, key)))
        return named

    # -- plain data ----------------------------------------------------------------

    def plain(self, node: Node, where: str) -> Any:
        """A node as plain Python data (for sections kept as data), duplicate keys reported."""
        if not self._check_plain(node, where, set()):
            return {}
        try:
            return self._constructor.construct_object(node, deep=True)
        except MarkedYAMLError as exc:
            self._yaml_error(exc)
            return {}

    def plain_keys(self, node: MappingNode) -> dict[Any, ScalarNode]:
        """The keys of a plain-data mapping as Python values, with their nodes (merges left out)."""
        return {
            self._constructor.construct_object(key): key
            for key, _ in node.value
            if isinstance(key, ScalarNode) and key.tag != _MERGE_TAG
        }

    def _check_plain(self, node: Node, where: str, active: set[int]) -> bool:
        if id(node) in active:
            self.error(node, f"recursive alias{where}")
            return False
        active.add(id(node))
        try:
            if isinstance(node, MappingNode):
                children = [v for _, v in self.items(node, "key", where, string_keys=False)]
            elif isinstance(node, SequenceNode):
                children = node.value
            else:
                children = []
            return all([self._check_plain(child, where, active) for child in children])
        finally:
            active.discard(id(node))
