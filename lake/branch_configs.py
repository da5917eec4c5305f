"""Config versions of a branch: every config used to ingest into it, numbered, never dropped.

`<lake>/<branch-dir>/_configs/v000001/` holds the source files of one version (in merge
order, as `00-<name>`, `01-<name>` ...), the custom template files they name (at the same
path relative to the config as in the source folder, so the stored config finds them) and
`manifest.json` (original paths, template files, content hash, time). A version appears by
renaming a finished directory into place, so readers never see half of one and two writers never
share a number. The newest version is `current()`; the catalog uses it (and older versions, for
topics no longer declared) to know every table's columns.

Versions are listed, stored and renamed through the lake's storage (`lake.storage`), so they work
on any file system; loading one needs a local one, because the config loader and the custom
templates it finds beside a config read local files.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
import tempfile
import uuid
from collections.abc import Sequence
from pathlib import Path

from lakegate.lake import paths
from lakegate.lake.config import Config, ConfigError, load_config
from lakegate.lake.storage import LakeStorage

_PREFIX = "v"
MANIFEST = "manifest.json"


class BranchConfigs:
    """The config versions of one branch of a lake."""

    def __init__(self, lake: Path | str, branch: str):
        """`lake`: the lake's location, a local path or a URI (`lake.storage`)."""
        self.storage = LakeStorage(lake)
        self.branch = branch
        self.root = paths.configs_dir(Path(self.storage.root), branch)

    def versions(self) -> list[int]:
        """Every stored version number, oldest first."""
        found = []
        for entry in self.storage.list(self.root):
            number = entry.name[len(_PREFIX) :]
            if entry.name.startswith(_PREFIX) and number.isdigit() and self.storage.is_file(f"{entry.path}/{MANIFEST}"):
                found.append(int(number))
        return sorted(found)

    def current_version(self) -> int | None:
        versions = self.versions()
        return versions[-1] if versions else None

    def current(self) -> Config | None:
        """The newest stored config, or None when the branch has none."""
        version = self.current_version()
        return None if version is None else self.load(version)

    def files(self, version: int) -> list[Path]:
        """The stored source files of `version`, in merge order, as local files (LocalOnlyError on
        a lake that is not local: the config loader reads local files)."""
        directory = self._dir(version)
        manifest = json.loads(self.storage.read_text(directory / MANIFEST))
        return [self.storage.local_path(directory / name, "loading a stored config") for name in manifest["files"]]

    def load(self, version: int) -> Config:
        """The config of `version` (KeyError if there is no such version)."""
        if not self.storage.is_file(self._dir(version) / MANIFEST):
            raise KeyError(f"branch {self.branch!r} has no config version {version}")
        return load_config(self.files(version))

    def store(self, sources: Sequence[str | Path], *, templates_path: str | Path | None = None) -> int:
        """Store config source files as a new version and return its number, with the custom template
        files they name (found beside them, in their `templates/` folder, or in `templates_path`).

        If the newest version has the same files (same contents, same order), its number is
        returned and nothing is stored.
        """
        contents = [(Path(p).name, Path(p).read_bytes()) for p in sources]
        if not contents:
            raise ValueError("a config version needs at least one file")
        templates = _template_files(sources, templates_path)
        digest = _digest(contents + templates)
        latest = self.current_version()
        if latest is not None and self._manifest(latest).get("sha256") == digest:
            return latest
        scratch = self.root / f"_new-{os.getpid()}-{uuid.uuid4().hex}"
        try:
            names = [f"{i:02d}-{name}" for i, (name, _) in enumerate(contents)]
            for name, (_, data) in zip(names, contents):
                self.storage.write_bytes(scratch / name, data)
            for name, data in templates:  # where the stored config finds them: beside it, as beside the source
                self.storage.write_bytes(scratch / name, data)
            manifest = {
                "files": names,
                "templates": [name for name, _ in templates],
                "sources": [str(Path(p).resolve()) for p in sources],
                "sha256": digest,
                "stored_at": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            }
            self.storage.write_text(scratch / MANIFEST, json.dumps(manifest, indent=2) + "\n")
            number = (latest or 0) + 1
            while True:
                try:
                    self.storage.move(scratch, self._dir(number))
                    return number
                except OSError:
                    if not self.storage.exists(self._dir(number)):
                        raise
                    if self._manifest(number).get("sha256") == digest and number == self.current_version():
                        return number  # another writer stored the same config just now
                    number += 1
        finally:
            self.storage.delete_tree(scratch)

    def store_config(self, config: Config) -> int:
        """Store `config` by its source files, or (when built in memory) as YAML of its topics."""
        if config.paths and all(Path(p).is_file() for p in config.paths):
            return self.store(config.paths, templates_path=config.templates_path)
        with tempfile.TemporaryDirectory(prefix="lakegate-config-") as scratch:
            generated = Path(scratch) / "config.resim.yaml"
            generated.write_text(topics_yaml(config))
            return self.store([generated])

    def _dir(self, version: int) -> Path:
        return self.root / f"{_PREFIX}{version:06d}"

    def _manifest(self, version: int) -> dict:
        try:
            return json.loads(self.storage.read_text(self._dir(version) / MANIFEST))
        except (OSError, ValueError):
            return {}


def _template_files(sources: Sequence[str | Path], templates_path: str | Path | None) -> list[tuple[str, bytes]]:
    """(path relative to its config's folder, contents) of every custom template file the config
    names that exists there (one found in `templates_path`: under `templates/`, where the stored
    config finds it); none for a config that does not load (loading it says why)."""
    try:
        config = load_config(sources, templates_path=templates_path)
    except (ConfigError, OSError):
        return []
    found: dict[str, bytes] = {}
    for metric in config.metrics.values():
        path = metric.template_path()
        if path is not None and metric.location is not None:
            folder = Path(metric.location.path).parent.resolve()
            if path.is_relative_to(folder):
                name = path.relative_to(folder).as_posix()
            else:
                assert metric.templates_dir is not None
                name = "templates/" + path.relative_to(metric.templates_dir.resolve()).as_posix()
            found.setdefault(name, path.read_bytes())
    return sorted(found.items())


def _digest(contents: list[tuple[str, bytes]]) -> str:
    digest = hashlib.sha256()
    for _, data in contents:
        digest.update(len(data).to_bytes(8, "big"))
        digest.update(data)
    return digest.hexdigest()


def topics_yaml(config: Config) -> str:
    """A config file declaring just the topics of `config` (for configs built in code)."""
    lines = ["# generated by lakegate from a config built in code: topics only", "version: 1", "topics:"]
    if not config.topics:
        lines[-1] = "topics: {}"
    for topic in config.topics.values():
        lines.append(f"  {json.dumps(topic.name)}:")
        if topic.event:
            lines.append("    event: true")
        schema = ", ".join(f"{json.dumps(name)}: {json.dumps(kind)}" for name, kind in topic.fields.items())
        lines.append(f"    schema: {{{schema}}}")
    return "\n".join(lines) + "\n"
