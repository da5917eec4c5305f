#!/usr/bin/env python3
"""Set up and run lakegate on a fresh machine that has only python3.

    python3 dev.py demo [ARGS...]   create .venv, install lakegate (only what it needs), run `lakegate demo`
    python3 dev.py test [ARGS...]   create .venv, install lakegate[test], lint (ruff), run the test suite
    python3 dev.py lint             only the lint: `ruff check` and `ruff format --check`
    python3 dev.py install          only create .venv and install lakegate[test] (what `test` needs)
    python3 dev.py bench NAME       run bench/NAME.py (results go to bench/RESULTS.md)
    python3 dev.py trino start|stop|status
                                    a real Trino 476 on 127.0.0.1, the judge the tests compare with
                                    (fetched with Maven, cached outside the repository; tools/trino_server.py)
    python3 dev.py fuzz --queries N --seed S [--trino URL]
                                    the differential fuzzer: random queries over a small lake, on lakegate and
                                    on the real Trino; prints the counts, writes mismatches (tools/trino_fuzz/)
    python3 dev.py corpus [--smoke | --sample N] [--group G] [--trino URL]
                                    the differential run over Trino 476's own function tests (its compiled
                                    tests jar, fetched with Maven and cached): lakegate vs the real Trino,
                                    one summary line per group, a report file (tools/trino_corpus/)
    python3 dev.py lakegate ARGS    run any lakegate command inside .venv

`demo`, `lakegate` and `trino` install lakegate alone; `install`, `test`, `lint`, `bench` and `fuzz` add
the test extras (pytest, Playwright, pandas, ...). The virtual environment is reinstalled only when
pyproject.toml changes or a command needs extras it lacks.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")
PY = BIN / "python"


def _run(cmd: list[str], env: dict[str, str] | None = None) -> int:
    return subprocess.call([str(c) for c in cmd], cwd=ROOT, env=env)


def ensure_venv(extras: str = "") -> None:
    """Create .venv and install the project into it (editable, with `extras`, e.g. "test") if not done yet."""
    stamp = VENV / ".lakegate-installed"
    digest = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    installed = stamp.read_text().split() if stamp.exists() else []
    if PY.exists() and installed[:1] == [digest] and (not extras or extras in installed[1:]):
        return
    if not PY.exists():
        print(f"creating {VENV} ...", flush=True)
        venv.EnvBuilder(with_pip=True).create(VENV)
    print("installing lakegate and its dependencies into .venv ...", flush=True)
    quiet = ["-q"] if os.environ.get("CI") or not sys.stdout.isatty() else []
    target = f".[{extras}]" if extras else "."
    rc = _run([PY, "-m", "pip", "install", *quiet, "--disable-pip-version-check", "-e", target])
    if rc:
        sys.exit(rc)
    kept = installed[1:] if installed[:1] == [digest] else []  # extras installed before, still there
    stamp.write_text(" ".join([digest, *sorted({*kept, *([extras] if extras else [])})]))


def lint() -> int:
    """`ruff check` and `ruff format --check` over the tree (settings in pyproject.toml); nonzero on findings."""
    checked = _run([BIN / "ruff", "check", "--output-format", "concise", "."])
    formatted = _run([BIN / "ruff", "format", "--check", "."])
    if checked or formatted:
        print("lint: fix the findings above (`.venv/bin/ruff format FILE` formats a file)", file=sys.stderr)
    return checked or formatted


def main(argv: list[str]) -> int:
    if not argv or argv[0] in {"-h", "--help", "help"}:
        print(__doc__)
        return 0
    command, rest = argv[0], argv[1:]
    ensure_venv("" if command in {"demo", "lakegate", "trino"} else "test")
    if command == "trino":
        return _run([PY, ROOT / "tools" / "trino_server.py", *rest])
    if command == "fuzz":
        return _run([PY, "-m", "trino_fuzz.run", *rest], env={**os.environ, "PYTHONPATH": str(ROOT / "tools")})
    if command == "corpus":
        return _run([PY, "-m", "trino_corpus.run", *rest], env={**os.environ, "PYTHONPATH": str(ROOT / "tools")})
    if command == "demo":
        return _run([BIN / "lakegate", "demo", *rest])
    if command == "install":
        return 0  # installed above
    if command == "lint":
        return lint()
    if command == "test":
        linted = lint()
        # two workers by default; worksteal unless another --dist is asked for (tests/conftest.py orders for it)
        workers = [] if any(a.startswith("-n") for a in rest) else ["-n", "2"]
        workers += [] if any(a.startswith(("--dist", "-d")) for a in rest) else ["--dist", "worksteal"]
        return _run([PY, "-m", "pytest", *workers, "--durations=30", *rest]) or linted  # the slowest, for the budget
    if command == "bench":
        names = sorted(p.stem for p in (ROOT / "bench").glob("*.py") if p.stem != "results")
        if not rest or rest[0] not in names:
            print("usage: python3 dev.py bench NAME [ARGS...] [--smoke]  (NAME --help for its options)")
            print("benches: " + ", ".join(names))
            return 0 if rest[:1] in (["--help"], ["-h"]) else 2
        return _run([PY, ROOT / "bench" / f"{rest[0]}.py", *rest[1:]])
    if command == "lakegate":
        return _run([BIN / "lakegate", *rest])
    print(f"unknown command {command!r}\n{__doc__}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
