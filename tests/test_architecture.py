"""The import arrows between lakegate's packages (README, Layout), read from the source with `ast`.

cli -> {server, dashboard, metrics, engine}; sdk -> {metrics, engine}; server -> engine; dashboard ->
metrics -> engine; engine -> dialect, lake. An arrow may be followed further (the dashboard may use the engine the
metrics use), never backwards: nothing imports cli or sdk, and nothing in lake or dialect imports gateway.
No module imports another module's private (`_name`) names, and every import is absolute.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Each package and the packages it may import directly.
ARROWS = {
    "gateway.cli": {"gateway.server", "gateway.dashboard", "gateway.metrics", "gateway.engine"},
    "sdk": {"gateway.metrics", "gateway.engine"},  # Batch and Test: ingest and evaluate, a top layer as cli
    "gateway.server": {"gateway.engine"},
    "gateway.dashboard": {"gateway.metrics"},
    "gateway.metrics": {"gateway.engine"},
    "gateway.engine": {"dialect", "lake"},
    "dialect": set(),
    "lake": set(),
    "gateway": set(),  # gateway/__init__.py only: every module lives in one of its five packages
}


def _reachable(package: str) -> set[str]:
    """The packages `package` may import: itself and everything its arrows lead to."""
    seen, todo = {package}, [package]
    while todo:
        for target in ARROWS.get(todo.pop(), ()):
            if target not in seen:
                seen.add(target)
                todo.append(target)
    return seen


def _package(module: str) -> str | None:
    """The package of ARROWS a dotted `lakegate.` module name belongs to (None: fixtures etc.)."""
    name = module.removeprefix("lakegate.")
    return max((p for p in ARROWS if name == p or name.startswith(p + ".")), key=len, default=None)


def _imports(source: str) -> list[tuple[int, str, list[str]]]:
    """(line, module, names imported from it) of every `lakegate.` import in `source`."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name, []) for alias in node.names if alias.name.startswith("lakegate.")]
        elif isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("lakegate.")):
            found.append((node.lineno, "." * node.level + (node.module or ""), [alias.name for alias in node.names]))
    return found


def _violations(path: str, source: str) -> list[str]:
    """What in `source` (the file at `path`, relative to the repository) breaks the arrows."""
    own = _package(_module(path))
    allowed = _reachable(own)
    wrong = []
    for line, module, names in _imports(source):
        if module.startswith("."):
            wrong.append(f"{path}:{line}: relative import {module}; write lakegate.…")
        elif _package(module) not in allowed | {None}:
            wrong.append(f"{path}:{line}: {own} must not import {module}")
        wrong += [
            f"{path}:{line}: imports the private name {module}.{name}"
            for name in names
            if name.startswith("_") and not name.startswith("__")
        ]
    return wrong


def _module(path: str) -> str:
    """The dotted name of the module at `path` (relative to the repository)."""
    return "lakegate." + path.removesuffix(".py").removesuffix("/__init__").replace("/", ".")


def _sources() -> list[str]:
    return sorted(
        str(p.relative_to(ROOT))
        for folder in ("lake", "dialect", "gateway", "sdk")
        for p in (ROOT / folder).rglob("*.py")
    )


@pytest.mark.parametrize("path", _sources())
def test_imports_follow_the_arrows(path: str) -> None:
    assert _violations(path, (ROOT / path).read_text(encoding="utf-8")) == []


def test_every_module_belongs_to_a_package() -> None:
    modules = [_module(p) for p in _sources()]
    assert [m for m in modules if _package(m) is None] == []


def test_a_wrong_arrow_is_reported() -> None:
    """The check itself: upward arrows, a relative import and a private name are each reported."""
    source = (
        "from lakegate.gateway.server.app import create_app\n"
        "import lakegate.gateway.cli.main\n"
        "from .backend import Backend\n"
        "from lakegate.gateway.engine.backend import _Run\n"
    )
    assert _violations("gateway/engine/probe.py", source) == [
        "gateway/engine/probe.py:1: gateway.engine must not import lakegate.gateway.server.app",
        "gateway/engine/probe.py:2: gateway.engine must not import lakegate.gateway.cli.main",
        "gateway/engine/probe.py:3: relative import .backend; write lakegate.…",
        "gateway/engine/probe.py:4: imports the private name lakegate.gateway.engine.backend._Run",
    ]
    assert _violations("dialect/probe.py", "from lakegate.gateway.engine.engine import Engine\n") == [
        "dialect/probe.py:1: dialect must not import lakegate.gateway.engine.engine"
    ]


@pytest.mark.parametrize("package", sorted(p for p in ARROWS if p.startswith("gateway.")))
def test_each_package_imports_on_its_own(package: str) -> None:
    """Every module of a package imports in a fresh interpreter, that package first (no import cycle)."""
    modules = [
        _module(p)
        for p in _sources()
        if p.startswith(package.replace(".", "/") + "/") and not p.endswith("__main__.py")
    ]
    code = f"import importlib\nfor m in {modules!r}: importlib.import_module(m)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles of `graph` (module -> modules it imports), each once, from its least module."""
    found = set()

    def walk(path: list[str]) -> None:
        for target in graph.get(path[-1], ()):
            if target == path[0]:
                found.add(tuple(path))
            elif target not in path and target > path[0]:
                walk([*path, target])

    for module in sorted(graph):
        walk([module])
    return [list(cycle) for cycle in sorted(found)]


def _targets(module: str, source: str, modules: set[str]) -> set[str]:
    """The modules of `modules` that `module` (whose text is `source`) imports: every name of a
    `from package import a, b` that is a module, and the module named by any import (which runs it).
    The packages holding `module` are left out: Python runs them before `module` in any case."""
    targets = set()
    for _, imported, names in _imports(source):
        targets |= ({imported} | {f"{imported}.{n}" for n in names}) & modules
    return {t for t in targets if t != module and not module.startswith(t + ".")}


def _graph() -> dict[str, set[str]]:
    """Module -> the lakegate modules it imports (anywhere in the file, TYPE_CHECKING blocks too)."""
    modules = {_module(p): p for p in _sources()}
    return {m: _targets(m, (ROOT / p).read_text(encoding="utf-8"), set(modules)) for m, p in modules.items()}


def test_every_imported_name_is_read() -> None:
    """`from lakegate.dialect import a, b` imports both a and b (not only the first name)."""
    modules = {"lakegate.dialect", "lakegate.dialect.a", "lakegate.dialect.b", "lakegate.dialect.c"}
    source = "from lakegate.dialect import a, b\nfrom lakegate.dialect.c import name\n"
    assert _targets("lakegate.gateway.x", source, modules) == modules


def test_no_two_modules_import_each_other() -> None:
    """No import cycle between modules, even one hidden behind TYPE_CHECKING: each module's
    knowledge has one home, and what two modules share lives in a third."""
    assert _cycles(_graph()) == []


def test_a_cycle_is_reported() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


# -- the lake's files go through one filesystem layer (lake/storage.py) ----------------------------

#: File operations a module does on a path itself, rather than through `lake.storage`.
_FILE_FUNCTIONS = {("os", name) for name in ("replace", "rename", "link", "remove", "unlink", "open")} | {
    ("shutil", name) for name in ("move", "rmtree", "copytree", "copyfile")
}
_FILE_METHODS = {"unlink", "rmdir", "glob", "rglob", "iterdir", "symlink_to"}
_FILE_METHODS |= {"read_text", "read_bytes", "write_text", "write_bytes"}
#: Receivers that are the filesystem layer itself (`storage.read_text(...)`, `LOCAL.is_file(...)`).
_STORAGE_NAMES = {"storage", "LOCAL"}
#: (module, function) -> why its file operations are not on the lake's files.
_FILE_IO_ALLOWED = {
    ("lake/storage.py", "*"): "the filesystem layer itself",
    ("lake/config.py", "expand_config_paths"): "expands the user's --metrics-config-path globs",
    ("lake/config_yaml.py", "FileReader.compose"): "config files: the user's, or a stored version's local copy",
    ("lake/emitter.py", "Emitter.__init__"): "the emissions file a job writes: a user path",
    ("lake/ingest/scan.py", "read_blocks"): "reads the user's emissions file",
    ("lake/mcap_import.py", "message_count"): "reads the user's MCAP file",
    ("lake/mcap_import.py", "_messages"): "reads the user's MCAP file",
    ("lake/branch_configs.py", "BranchConfigs.store"): "reads the user's config files to store them",
    ("lake/branch_configs.py", "BranchConfigs.store_config"): "a temporary file (tempfile) of a config built in code",
    ("lake/branch_configs.py", "_template_files"): "reads the user's template files to store them",
    ("gateway/cli/config.py", "schema_command"): "writes the user's --output file",
    ("gateway/cli/trino_ddl.py", "trino_ddl_command"): "writes the user's --output file",
    ("gateway/cli/query.py", "_write_binary"): "writes the user's --output file (its .partial twin first)",
    ("gateway/cli/import_mcap.py", "import_mcap_command"): "writes the user's emissions file",
    ("gateway/cli/debug.py", "debug_command"): "removes its own temporary lake (tempfile)",
    ("gateway/dashboard/config_edits.py", "FileConfig.read"): "reads the user's config files",
    ("gateway/dashboard/debug_session.py", "DashboardSession._with_edits"): "temporary files (tempfile)",
    ("gateway/metrics/custom.py", "_template"): "a template file found beside a loaded (local) config",
    ("gateway/metrics/evaluation.py", "_file_lines"): "lines of a loaded (local) config file",
    ("gateway/metrics/report.py", "write_report"): "writes the user's report file",
    ("gateway/metrics/trends.py", "write_trends"): "writes the user's trends file",
    ("gateway/metrics/compare_page.py", "write_compare"): "writes the user's comparison page",
    ("gateway/server/auth.py", "Users.load"): "reads the user's users file",
    ("gateway/engine/process_memory.py", "statm"): "reads a process's memory size from /proc",
}


def _file_operations(source: str) -> list[tuple[int, str, str]]:
    """(line, function, operation) of every file operation in `source` not done through the storage."""
    found = []

    def visit(node: ast.AST, scope: list[str]) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                visit(child, [*scope, child.name])
                continue
            if isinstance(child, ast.Call):
                operation = _file_operation(child.func)
                if operation is not None:
                    found.append((child.lineno, ".".join(scope) or "<module>", operation))
            visit(child, scope)

    visit(ast.parse(source), [])
    return found


def _file_operation(func: ast.expr) -> str | None:
    if isinstance(func, ast.Name):
        return "open" if func.id == "open" else None
    if not isinstance(func, ast.Attribute):
        return None
    receiver = func.value
    if isinstance(receiver, ast.Name) and (receiver.id, func.attr) in _FILE_FUNCTIONS:
        return f"{receiver.id}.{func.attr}"
    name = receiver.id if isinstance(receiver, ast.Name) else getattr(receiver, "attr", None)
    return f".{func.attr}" if func.attr in _FILE_METHODS and name not in _STORAGE_NAMES else None


def _unrouted(path: str, source: str) -> list[str]:
    """The file operations of the module at `path` that neither go through the storage nor are allowed."""
    return [
        f"{path}:{line}: {function} calls {operation}; use lakegate.lake.storage (or allow it, saying why)"
        for line, function, operation in _file_operations(source)
        if (path, "*") not in _FILE_IO_ALLOWED and (path, function) not in _FILE_IO_ALLOWED
    ]


@pytest.mark.parametrize("path", _sources())
def test_lake_files_go_through_the_storage(path: str) -> None:
    assert _unrouted(path, (ROOT / path).read_text(encoding="utf-8")) == []


def test_file_operations_outside_the_storage_are_reported() -> None:
    source = (
        "import os, shutil\n"
        "def publish(a, b):\n"
        "    os.replace(a, b)\n"
        "class Registry:\n"
        "    def versions(self):\n"
        "        return [p for p in self.root.iterdir()] + [open(self.root / 'x').read()]\n"
        "    def stored(self):\n"
        "        return self.storage.read_text(self.root) + LOCAL.read_text(self.root)\n"
    )
    assert _unrouted("lake/probe.py", source) == [
        "lake/probe.py:3: publish calls os.replace; use lakegate.lake.storage (or allow it, saying why)",
        "lake/probe.py:6: Registry.versions calls .iterdir; use lakegate.lake.storage (or allow it, saying why)",
        "lake/probe.py:6: Registry.versions calls open; use lakegate.lake.storage (or allow it, saying why)",
    ]


def test_every_allowed_file_operation_is_still_there() -> None:
    """No stale allowance: each allowed (module, function) still does a file operation itself."""
    stale = [
        key
        for key in _FILE_IO_ALLOWED
        if key[1] != "*"
        and key[1] not in {f for _, f, _ in _file_operations((ROOT / key[0]).read_text(encoding="utf-8"))}
    ]
    assert stale == []


# -- modules small enough to read in one sitting --------------------------------------------------

#: No hand-written module is longer than this many lines.
MAX_MODULE_LINES = 800


def _scripts(*folders: str) -> list[str]:
    """The Python files under `folders` (paths relative to the repository), skipping hidden folders
    (bench/.work holds the benches' lakes)."""
    return sorted(
        str(p.relative_to(ROOT))
        for folder in folders
        for p in (ROOT / folder).rglob("*.py")
        if not any(part.startswith(".") for part in p.relative_to(ROOT).parts)
    )


def test_no_module_is_too_long() -> None:
    """The package's modules, the repository's tools and benches, and the test modules."""
    paths = [*_sources(), *_scripts("tools", "bench", "tests")]
    long = {p for p in paths if len((ROOT / p).read_text(encoding="utf-8").splitlines()) > MAX_MODULE_LINES}
    assert sorted(long) == []


# -- one name, one thing -----------------------------------------------------------------------------

#: Module names held by more than one module because they are one thing seen from several sides: the
#: name, the exact set of paths holding it, and why. A new module taking one of these names fails too.
_SHARED_NAMES: dict[str, tuple[frozenset[str], str]] = {
    "compare.py": (
        frozenset({"gateway/metrics/compare.py", "gateway/cli/compare.py", "bench/compare.py"}),
        "build comparison: its work (metrics), its `lakegate compare` command, its benchmark",
    ),
    "config.py": (
        frozenset({"lake/config.py", "gateway/cli/config.py"}),
        "the metrics config: its model (lake), its `lakegate config check|schema` command",
    ),
    "import_mcap.py": (
        frozenset({"gateway/cli/import_mcap.py", "bench/import_mcap.py"}),
        "MCAP import: its `lakegate import-mcap` command, its benchmark",
    ),
    "ingest.py": (
        frozenset({"gateway/cli/ingest.py", "bench/ingest.py"}),
        "ingestion (lake/ingest/): its `lakegate ingest` command, its benchmark",
    ),
    "metrics.py": (
        frozenset({"gateway/cli/metrics.py", "bench/metrics.py"}),
        "metrics evaluation (gateway/metrics/): its `lakegate metrics` command, its benchmark",
    ),
    "translate.py": (
        frozenset({"dialect/translate.py", "bench/translate.py"}),
        "translating Trino SQL: the dialect's entry point, its benchmark",
    ),
    "trino_ddl.py": (
        frozenset({"gateway/engine/trino_ddl.py", "gateway/cli/trino_ddl.py"}),
        "the lake's tables registered in a Trino cluster: the work (engine), its `lakegate trino-ddl` command",
    ),
    "session.py": (
        frozenset({"gateway/engine/session.py", "dialect/functions/session.py"}),
        "the client's session: read from the request headers (engine), reported by the functions of "
        "Trino's functions/session.md (a page module, named for its page)",
    ),
    "run.py": (
        frozenset({"tools/trino_fuzz/run.py", "tools/trino_corpus/run.py"}),
        "the entry point of each differential tool package (`dev.py fuzz`, `dev.py corpus`), as __main__ would be",
    ),
}


def _shared_names(paths: list[str]) -> dict[str, frozenset[str]]:
    """Module basenames held by more than one path, but a command's parser (gateway/cli/parsers/X.py)
    beside its command (gateway/cli/X.py) counts once: the two halves of one command, split so that
    `--help` loads none of the work."""
    holders: dict[str, set[str]] = {}
    for path in paths:
        name = path.rsplit("/", 1)[-1]
        if name == "__init__.py":
            continue
        if path.startswith("gateway/cli/parsers/") and f"gateway/cli/{name}" in paths:
            continue
        holders.setdefault(name, set()).add(path)
    return {name: frozenset(held) for name, held in holders.items() if len(held) > 1}


def _clashes(paths: list[str]) -> list[str]:
    return sorted(
        f"{name}: {', '.join(sorted(held))} (rename to say what each is, or allow it in _SHARED_NAMES, saying why)"
        for name, held in _shared_names(paths).items()
        if _SHARED_NAMES.get(name, (frozenset(),))[0] != held
    )


def _every_module() -> list[str]:
    return [*_sources(), *_scripts("tools", "bench")]


def test_no_two_modules_share_a_name_for_different_things() -> None:
    assert _clashes(_every_module()) == []


def test_a_module_name_clash_is_reported() -> None:
    paths = [*_every_module(), "gateway/server/errors.py", "gateway/cli/parsers/serve.py", "bench/config.py"]
    assert _clashes(paths) == [
        "config.py: bench/config.py, gateway/cli/config.py, lake/config.py (rename to say what each is, "
        "or allow it in _SHARED_NAMES, saying why)",
        "errors.py: dialect/errors.py, gateway/server/errors.py (rename to say what each is, "
        "or allow it in _SHARED_NAMES, saying why)",
    ]


def test_every_shared_name_is_still_shared() -> None:
    """No stale allowance: each allowed name is still held by exactly its paths."""
    shared = _shared_names(_every_module())
    assert sorted(name for name, (held, _) in _SHARED_NAMES.items() if shared.get(name) != held) == []


def _public_classes() -> dict[str, list[str]]:
    """Each public class name of the package (lake, dialect, gateway, sdk) and where it is defined."""
    found: dict[str, list[str]] = {}
    for path in _sources():
        for node in ast.parse((ROOT / path).read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                found.setdefault(node.name, []).append(f"{path}:{node.lineno}")
    return found


def test_no_two_classes_share_a_name() -> None:
    """Within the package, a class name says one thing (tools/ and bench/ are programs of their own)."""
    assert {name: where for name, where in _public_classes().items() if len(where) > 1} == {}
