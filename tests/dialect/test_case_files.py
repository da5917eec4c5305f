"""The conformance case files, ordered by page of Trino's function reference and by SQL construct,
lost no case in the move: every (sql, session) pair of the case files before it (read from git) is
still a case, and the new files are named for pages and constructs."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
from functions_doc import CASES_DIR, load_cases

REPO = Path(__file__).resolve().parents[2]
#: main just before the case files were ordered by page (they were named by when they were written).
BEFORE_THE_MOVE = "5160d1f415a65ee69131a715ce74da6fa3105ac3"
#: (sql, session) pairs of the case files at BEFORE_THE_MOVE (1569 cases, 6 of them repeating a pair).
PAIRS_BEFORE_THE_MOVE = 1563
#: Cases of BEFORE_THE_MOVE whose SQL had to change since, each with the case that holds it now: a
#: refusal whose answer, once translated, depends on the day the suite runs.
REWRITTEN = {
    ("SELECT CAST(TIME '01:02:03' AS timestamp)", "UTC"): "cast-time-to-timestamp-on-the-session-date",
}


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, check=True, timeout=60).stdout


def _old_case_files(target: Path) -> None:
    """The case files of BEFORE_THE_MOVE, written into `target`."""
    folder = "tests/dialect/cases"
    for name in _git("ls-tree", "--name-only", f"{BEFORE_THE_MOVE}:{folder}").split():
        (target / name).write_text(_git("show", f"{BEFORE_THE_MOVE}:{folder}/{name}"), encoding="utf-8")


def test_no_case_was_lost_in_the_move(tmp_path):
    if (
        shutil.which("git") is None
        or subprocess.run(
            ["git", "cat-file", "-e", f"{BEFORE_THE_MOVE}^{{commit}}"], cwd=REPO, capture_output=True
        ).returncode
    ):
        pytest.skip(f"needs the git history holding {BEFORE_THE_MOVE}")
    _old_case_files(tmp_path)
    before = {(case.sql, case.time_zone) for case in load_cases(tmp_path)}
    now = {(case.sql, case.time_zone) for case in load_cases()}
    assert len(before) == PAIRS_BEFORE_THE_MOVE
    assert sorted(before - now - set(REWRITTEN)) == []


def test_case_files_are_named_for_what_they_test():
    """One file per page of Trino's function reference or per SQL construct: no wave prefixes."""
    names = sorted(path.stem for path in CASES_DIR.glob("*.yaml"))
    assert [n for n in names if n.startswith(("cov_", "zw_")) or any(ch.isdigit() for ch in n)] == []
    assert {"array", "map", "string", "json", "datetime", "aggregate", "window", "joins", "subqueries"} <= set(names)
