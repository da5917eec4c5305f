"""The import arrows between lakegate's packages (README, Layout), read from the source with `ast`.

cli -> {server, dashboard, metrics, engine}; server -> engine; dashboard -> metrics -> engine;
engine -> dialect, lake. An arrow may be followed further (the dashboard may use the engine the
metrics use), never backwards: nothing imports cli, and nothing in lake or dialect imports gateway.
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
        str(p.relative_to(ROOT)) for folder in ("lake", "dialect", "gateway") for p in (ROOT / folder).rglob("*.py")
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


def _graph() -> dict[str, set[str]]:
    """Module -> the lakegate modules it imports (anywhere in the file, TYPE_CHECKING blocks too)."""
    modules = {_module(p): p for p in _sources()}
    graph = {}
    for module, path in modules.items():
        targets = set()
        for _, imported, names in _imports((ROOT / path).read_text(encoding="utf-8")):
            for name in [f"{imported}.{n}" for n in names] + [imported]:
                if name in modules and name != module:
                    targets.add(name)
                    break
        graph[module] = targets
    return graph


def test_no_two_modules_import_each_other() -> None:
    """No import cycle between modules, even one hidden behind TYPE_CHECKING: each module's
    knowledge has one home, and what two modules share lives in a third."""
    assert _cycles(_graph()) == []


def test_a_cycle_is_reported() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
