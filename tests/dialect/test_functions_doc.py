"""docs/functions.md is generated from the function registry and the conformance cases, and the
committed file is up to date."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import functions_doc as docs
import pytest

REPO = Path(__file__).resolve().parents[2]
TOOL = REPO / "tools" / "functions_doc.py"

needs_registry = pytest.mark.skipif(
    importlib.util.find_spec("lakegate.dialect.functions") is None,
    reason="lakegate.dialect.functions (the registry) is not written yet",
)


@needs_registry
def test_committed_functions_doc_is_up_to_date():
    result = subprocess.run(
        [sys.executable, str(TOOL), "--check"], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr + "\nregenerate with: python tools/functions_doc.py"


@needs_registry
def test_check_fails_on_a_stale_file(tmp_path):
    stale = tmp_path / "functions.md"
    stale.write_text("# an old page\n", encoding="utf-8")
    result = subprocess.run(
        [sys.executable, str(TOOL), "--check", "--output", str(stale)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 1
    assert "stale" in result.stderr


class _Spec:
    def __init__(self, family: str, signature: str, notes: str = ""):
        self.family, self.signature, self.notes = family, signature, notes


class _Construct:
    def __init__(self, names: tuple[str, ...], refused: str = ""):
        self.family, self.names, self.refused = "literals", names, refused

    def used_by(self, node, sql: str) -> bool:
        return False


def test_generate_lists_statuses_and_counts_calls(tmp_path):
    (tmp_path / "demo.yaml").write_text(
        "family: demo\ntitle: Demo\ndescription: two cases\ncases:\n"
        "  - name: one\n    sql: SELECT cardinality(ARRAY[1]), ngrams(x, 2) FROM t\n    error: NOT_SUPPORTED\n"
        "  - name: two\n    sql: SELECT CARDINALITY(a) FILTER (WHERE b) FROM t AS v(a)\n"
        "    columns: [_col0 bigint]\n    rows: [[1]]\n",
        encoding="utf-8",
    )
    text = docs.generate(
        docs.load_families(tmp_path),
        {"cardinality": _Spec("array", "cardinality(array(E)) -> bigint", "1-based")},
        {"ngrams": "not translated"},
        {"CAST": _Construct(("cast", "try_cast")), "current_time": _Construct(("current_time",), "not translated")},
        {"cardinality": "array", "ngrams": "refused"},
    )
    array = "[array.py](../dialect/functions/array.py)"
    demo = "([demo](../tests/dialect/cases/demo.yaml))"
    assert f"| `cardinality` | supported | {array} | 2 {demo} | `cardinality(array(E)) -> bigint` 1-based |" in text
    assert (
        f"| `ngrams` | rejected (not translated) | [refused.py](../dialect/functions/refused.py) | 1 {demo} |" in text
    )
    assert "| `zip_with` | rejected (not implemented) |  | 0 |" in text
    assert "| `filter` | rejected (not implemented) |  | 0 |" in text  # FILTER (WHERE ...) is not a call
    assert "| [demo](../tests/dialect/cases/demo.yaml) | 2 | Demo: two cases |" in text
    # functions are listed by the page of Trino's reference their module mirrors
    assert text.index("## Array functions and operators (Trino's functions/array.md)") < text.index("`cardinality`")
    # a construct listed among the functions says what its row says, not "not implemented"
    assert "| `cast` | supported as a construct |  | 0 | see the construct CAST |" in text
    assert (
        "| `current_time` | rejected (not translated) as a construct |  | 0 | see the construct current_time |" in text
    )
    assert "| CAST | literals | supported | 0 |" in text


def test_called_names_uses_tokens_not_strings():
    sql = "SELECT upper('lower(x)'), t.\"count\"(1), sum(x) OVER (ORDER BY y) FROM t AS v(c)"
    assert docs.called_names(sql) == {"upper", "sum", "v"}


def test_malformed_case_file_is_reported(tmp_path):
    (tmp_path / "bad.yaml").write_text(
        "family: bad\ncases:\n  - name: x\n    sql: SELECT 1\n    rows: [[1]]\n", encoding="utf-8"
    )
    with pytest.raises(docs.CaseFileError, match="bad.yaml: case 1 \\(x\\)"):
        docs.load_families(tmp_path)
