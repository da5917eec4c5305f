"""The dashboard's edits of a config: the config files a session starts from (FileConfig on disk,
BranchConfig stored in the lake), and the edits of its metrics written into them with ruamel.yaml in
round-trip mode (order, comments and quoting of everything else kept), checked field by field.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.scalarstring import LiteralScalarString

from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import Config

#: Keys of a metric that a session may set, in the order they are written to the config.
METRIC_KEYS = ("type", "description", "query_string", "template_type", "template", "units", "status")

STATUS_KEYS = ("query_string", "block", "warn")


class SessionError(ValueError):
    """A session edit or request was refused; `problems` lists the config problems it would cause."""

    def __init__(self, message: str, problems: list[str] | None = None):
        self.problems = problems or []
        super().__init__(message)


# -- where the config comes from ----------------------------------------------------------------


@dataclass
class ConfigFiles:
    """The config's source files at one moment: paths, names in the export, texts, stored version."""

    paths: list[Path]
    names: list[str]
    texts: list[str]
    version: int | None = None


class FileConfig:
    """Config files on disk (the debug command's `--metrics-config-path`), re-read when they change."""

    def __init__(self, paths: list[Path]):
        self.paths = [Path(p) for p in paths]

    def stamp(self) -> object:
        try:
            return tuple((p.stat().st_mtime_ns, p.stat().st_size) for p in self.paths)
        except OSError:
            return None

    def read(self) -> ConfigFiles:
        return ConfigFiles(
            list(self.paths), [p.name for p in self.paths], [p.read_text(encoding="utf-8") for p in self.paths]
        )


class BranchConfig:
    """A branch's stored config (its current version), re-read when a new version is stored."""

    def __init__(self, lake: Path, branch: str):
        self.registry = BranchConfigs(lake, branch)

    def stamp(self) -> object:
        return self.registry.current_version()

    def read(self) -> ConfigFiles:
        version = self.registry.current_version()
        if version is None:
            raise SessionError(
                f"branch {self.registry.branch!r} has no stored config (store one with 'lakegate metrics sync')"
            )
        files = self.registry.files(version)
        names = [re.sub(r"^\d+-", "", f.name) for f in files]  # stored as 00-<name>, 01-<name> ...
        return ConfigFiles(files, names, [self.registry.storage.read_text(f) for f in files], version)


# -- editing YAML, keeping the rest of the document -----------------------------------------------


def _indentation(text: str) -> tuple[int, int]:
    """(mapping indent, offset of a block sequence's dash under its key) as the document writes them."""
    mapping = offset = None
    parent: tuple[int, bool] | None = None  # (indent, ends with ':') of the previous content line
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        indent = len(line) - len(line.lstrip(" "))
        if parent is not None and parent[1] and indent >= parent[0]:
            if stripped.startswith("- ") and offset is None:
                offset = indent - parent[0]
            elif not stripped.startswith("-") and indent > parent[0] and mapping is None:
                mapping = indent - parent[0]
        if mapping is not None and offset is not None:
            break
        parent = (indent, stripped.split(" #")[0].endswith(":"))
    return mapping or 2, 2 if offset is None else offset


def _yaml(text: str) -> YAML:
    yaml = YAML()  # round-trip mode
    yaml.preserve_quotes = True
    yaml.width = 4096  # never fold long lines of the original
    mapping, offset = _indentation(text)
    yaml.indent(mapping=mapping, sequence=offset + 2, offset=offset)
    return yaml


def _scalar(text: str) -> Any:
    """A query as YAML: a literal block (`|`) when it has several lines, else a plain string."""
    text = text.strip("\n").rstrip()
    return LiteralScalarString(text + "\n") if "\n" in text else text


def _node_value(key: str, value: Any) -> Any:
    if key == "query_string":
        return _scalar(value)
    if key == "status":
        status = CommentedMap()
        for name in STATUS_KEYS:
            if value.get(name) is not None:
                status[name] = _scalar(value[name]) if name == "query_string" else value[name]
        return status
    return value


def _set_keys(node: CommentedMap, fields: dict[str, Any]) -> None:
    """Set (or, for None, remove) metric keys on a metric's mapping; new keys go in METRIC_KEYS order."""
    for key in METRIC_KEYS:
        if key not in fields:
            continue
        value = fields[key]
        if value is None or (value == "" and key not in ("description", "query_string")):
            if key in node:
                del node[key]
            continue
        if key in node:
            node[key] = _node_value(key, value)
        else:
            earlier = METRIC_KEYS[: METRIC_KEYS.index(key)]
            position = max((i + 1 for i, k in enumerate(node) if k in earlier), default=0)
            node.insert(position, key, _node_value(key, value))


def _last_entry(node: Any) -> tuple[Any, Any] | None:
    """The innermost last (container, key) of a mapping or list, where a trailing comment hangs."""
    found = None
    while isinstance(node, (CommentedMap, CommentedSeq)) and len(node):
        key = list(node)[-1] if isinstance(node, CommentedMap) else len(node) - 1
        found = (node, key)
        node = node[key]
    return found


def _append_entry(mapping: CommentedMap, key: str, value: CommentedMap) -> None:
    """Add `key` at the end of a block mapping, moving the comment lines that followed the last entry
    (say a blank line and the next section's comment) after the new one."""
    before = _last_entry(mapping)
    if not len(mapping):
        mapping.fa.set_block_style()
    mapping[key] = value
    if before is None:
        return
    container, last = before
    token = container.ca.items.get(last, [None, None, None, None])[2]
    if token is None or "\n" not in token.value:
        return
    own, rest = token.value.split("\n", 1)  # the end-of-line comment stays; later lines move
    if not rest:
        return
    token.value = own + "\n" + ("\n" if rest.startswith("\n") else "")
    after = _last_entry(value)
    if after is not None:
        moved = type(token)("\n" + rest, token.start_mark, None)
        after[0].ca.items[after[1]] = [None, None, moved, None]


def edited_documents(
    files: ConfigFiles, base: Config, edits: dict[str, dict], added: dict[str, dict], metrics_set: str | None
) -> list[str]:
    """The texts of the config files with the session's edits and added metrics applied.

    Edits go to the file that defines the metric; added metrics to the file that defines the
    metrics set (and are appended to the set), else the first file.
    """
    yamls = [_yaml(text) for text in files.texts]
    docs = [yaml.load(text) if text.strip() else CommentedMap() for yaml, text in zip(yamls, files.texts)]
    where = {str(path): i for i, path in enumerate(files.paths)}
    for name, fields in edits.items():
        location = base.metrics[name].location
        doc = docs[where.get(location.path if location else "", 0)]
        _set_keys(doc["metrics"][name], fields)
    if added:
        target_set = base.metrics_sets.get(metrics_set) if metrics_set else None
        index = where.get(target_set.location.path, 0) if target_set and target_set.location else 0
        doc = docs[index]
        if not isinstance(doc.get("metrics"), CommentedMap):
            position = list(doc).index("metrics sets") if "metrics sets" in doc else len(doc)
            doc.insert(position, "metrics", CommentedMap())
        for name, spec in added.items():
            node = CommentedMap()
            _set_keys(node, spec)
            _append_entry(doc["metrics"], name, node)
            if target_set is not None:
                items = doc["metrics sets"][metrics_set]["metrics"]
                if items is None:
                    items = doc["metrics sets"][metrics_set]["metrics"] = CommentedSeq()
                items.append(name)
    texts = []
    for yaml, doc in zip(yamls, docs):
        out = io.StringIO()
        yaml.dump(doc, out)
        texts.append(out.getvalue())
    return texts


def clean(fields: dict[str, Any]) -> dict[str, Any]:
    """Metric keys from the page: only known keys; thresholds as numbers; an empty status removed."""
    unknown = set(fields) - set(METRIC_KEYS)
    if unknown:
        raise SessionError(f"unknown metric key(s): {', '.join(sorted(unknown))}")
    out = dict(fields)
    status = out.get("status")
    if isinstance(status, dict):
        if not (status.get("query_string") or "").strip():
            out["status"] = None
        else:
            out["status"] = {
                "query_string": status["query_string"],
                "block": _threshold(status.get("block")),
                "warn": _threshold(status.get("warn")),
            }
    for key in ("units", "template"):
        if key in out and isinstance(out[key], str) and not out[key].strip():
            out[key] = None
    return out


def _threshold(value: Any) -> Any:
    """A status threshold from a form: a number when it reads as one, else the text (None when empty)."""
    if not isinstance(value, str):
        return value
    text = value.strip()
    if not text:
        return None
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text
