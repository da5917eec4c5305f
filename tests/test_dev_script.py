"""dev.py installs only what each command needs: `demo` (and `lakegate`, `trino`) lakegate alone,
`test`, `lint`, `bench` and `fuzz` the test extras too; an installed environment is reused (the
pip commands it would run are recorded instead of run)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def dev(tmp_path, monkeypatch):
    """dev.py as a module, with its .venv in tmp_path (its python present) and its commands recorded."""
    spec = importlib.util.spec_from_file_location("dev_script", ROOT / "dev.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setattr(module, "VENV", tmp_path / ".venv")
    monkeypatch.setattr(module, "BIN", tmp_path / ".venv" / "bin")
    monkeypatch.setattr(module, "PY", tmp_path / ".venv" / "bin" / "python")
    module.PY.parent.mkdir(parents=True)
    module.PY.write_text("")
    module.calls = []

    def run(cmd, env=None):
        module.calls.append([str(c) for c in cmd])
        return 0

    monkeypatch.setattr(module, "_run", run)
    return module


def installs(dev) -> list[str]:
    """What each pip install of the recorded commands installed ('.' or '.[test]'), then forget them."""
    done = [call[-1] for call in dev.calls if call[1:4] == ["-m", "pip", "install"]]
    dev.calls.clear()
    return done


def test_the_demo_installs_lakegate_without_the_test_extras(dev):
    assert dev.main(["demo"]) == 0
    assert installs(dev) == ["."]
    assert dev.main(["demo", "--lake", "x"]) == 0 and installs(dev) == []  # installed: reused
    assert dev.main(["lakegate", "--help"]) == 0 and installs(dev) == []
    assert dev.main(["trino", "status"]) == 0 and installs(dev) == []
    assert dev.main(["test", "-k", "x"]) == 0 and installs(dev) == [".[test]"]
    assert dev.main(["lint"]) == 0 and dev.main(["demo"]) == 0 and installs(dev) == []  # extras kept


def test_a_changed_pyproject_installs_again(dev, monkeypatch, tmp_path):
    assert dev.main(["test"]) == 0 and installs(dev) == [".[test]"]
    changed = tmp_path / "project"
    changed.mkdir()
    (changed / "pyproject.toml").write_text((ROOT / "pyproject.toml").read_text() + "\n# changed\n")
    monkeypatch.setattr(dev, "ROOT", changed)
    assert dev.main(["demo"]) == 0 and installs(dev) == ["."]
    assert dev.main(["test"]) == 0 and installs(dev) == [".[test]"]  # the extras of the old file do not count


def test_install_makes_the_environment_of_test_and_trino(dev):
    """`.ci/run` installs once, then starts Trino and runs the suite without another install."""
    assert dev.main(["install"]) == 0 and len(dev.calls) == 1 and installs(dev) == [".[test]"]  # nothing else runs
    assert dev.main(["trino", "start"]) == 0 and dev.main(["test"]) == 0 and installs(dev) == []


def test_the_readme_commands_and_ci_use_these_commands():
    readme = (ROOT / "README.md").read_text()
    assert "python3 dev.py demo" in readme and "python3 dev.py test" in readme
    ci = (ROOT / ".ci" / "run").read_text()
    assert "python3 dev.py trino start" in ci and "python3 dev.py test" in ci
    assert ci.index("python3 dev.py install") < ci.index("python3 dev.py trino start")


def test_the_suite_runs_on_two_workers_that_steal_work_unless_told_otherwise(dev):
    def pytest_args(*args: str) -> list[str]:
        dev.calls.clear()
        assert dev.main(["test", *args]) == 0
        [call] = [call[3:] for call in dev.calls if call[1:3] == ["-m", "pytest"]]
        return call

    assert pytest_args()[:4] == ["-n", "2", "--dist", "worksteal"]
    assert pytest_args("-n", "3")[:2] == ["--dist", "worksteal"]  # tests/conftest.py orders for worksteal
    assert "worksteal" not in pytest_args("-n", "3", "--dist", "load")
