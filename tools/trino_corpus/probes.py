"""The corpus: Trino 476's compiled function tests (Maven Central's io.trino:trino-main:476:jar:tests),
disassembled with the JDK's javap, turned into the SQL each QueryAssertions call runs, cached as JSON
under the judge's cache folder (never in the repository).

How a call becomes SQL (as a newcomer reading the test would write it):
- `function("name", "x", "y")`: `SELECT name(x, y)`;
- `expression("e")`: `SELECT e`; with `.binding("a", "v")`, Trino's own form
  `SELECT e FROM (VALUES ROW(v, ...)) t(a, ...)`;
- `operator(ADD, "x", "y")`: `SELECT (x) + (y)` (operators without SQL syntax are left out);
- `query("q")`: q.

The group `docs` is the documentation's examples instead (tests/dialect/trino_doc_examples.yaml).
"""

from __future__ import annotations

import json
import subprocess
import tempfile
import zipfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import yaml
from trino_doc_examples import EXAMPLES
from trino_server import HOME, fetch, java_home

from trino_corpus.bytecode import Call, calls

#: Packages of the tests jar whose tests are read, and the group each counts in.
GROUPS = {
    "io/trino/operator/": "functions",
    "io/trino/type/": "types",
    "io/trino/sql/query/": "queries",
}
CACHE = HOME / "corpus"
#: Bumped when the way SQL is rebuilt changes (the cache is rebuilt then).
FORMAT = 1
_MARKER = b"io/trino/sql/query/QueryAssertions"
_OPERATORS = {
    "ADD": "({0}) + ({1})",
    "SUBTRACT": "({0}) - ({1})",
    "MULTIPLY": "({0}) * ({1})",
    "DIVIDE": "({0}) / ({1})",
    "MODULUS": "({0}) % ({1})",
    "NEGATION": "-({0})",
    "EQUAL": "({0}) = ({1})",
    "LESS_THAN": "({0}) < ({1})",
    "LESS_THAN_OR_EQUAL": "({0}) <= ({1})",
    "IDENTICAL": "({0}) IS NOT DISTINCT FROM ({1})",
    "SUBSCRIPT": "({0})[{1}]",
}


@dataclass(frozen=True)
class Probe:
    """One query of the corpus: where the test is, its group and the SQL."""

    where: str  # TestClass.method
    group: str  # functions, types or queries
    sql: str


def sql_of(call: Call) -> str | None:
    """The SQL a call runs, or None (a computed string, or an operator without SQL syntax)."""
    if call.computed:
        return None
    if call.kind == "function":
        return f"SELECT {call.text}({', '.join(call.arguments)})"
    if call.kind == "operator":
        shape = _OPERATORS.get(call.text)
        return None if shape is None else "SELECT " + shape.format(*call.arguments)
    if call.kind == "expression":
        if not call.bindings:
            return f"SELECT {call.text}"
        names = ", ".join(name for name, _ in call.bindings)
        values = ", ".join(value for _, value in call.bindings)
        return f"SELECT {call.text} FROM (VALUES ROW({values})) t({names})"
    return call.text


def load(refresh: bool = False) -> list[Probe]:
    """Every probe of the corpus, each SQL once (the first test that runs it), in the jar's order;
    fetched and extracted on first use (about a minute), then read from the cache."""
    cached = CACHE / f"probes-{FORMAT}.json"
    if cached.exists() and not refresh:
        return [Probe(**p) for p in json.loads(cached.read_text(encoding="utf-8"))]
    jar = fetch("trino-main", "jar", HOME / "downloads", classifier="tests")
    probes = extract(jar)
    CACHE.mkdir(parents=True, exist_ok=True)
    cached.write_text(json.dumps([asdict(p) for p in probes], ensure_ascii=False, indent=0), encoding="utf-8")
    return probes


def doc_examples(path: Path = EXAMPLES) -> list[Probe]:
    """The examples of Trino's function documentation as probes of the group `docs`."""
    pages = yaml.safe_load(path.read_text(encoding="utf-8"))
    return [Probe(page, "docs", example[0]) for page, listed in pages.items() for example in listed]


def extract(jar: Path) -> list[Probe]:
    """The probes of the test classes in `jar` that use QueryAssertions."""
    javap = java_home() / "bin" / "javap"
    probes, seen = [], set()
    with tempfile.TemporaryDirectory(prefix="lakegate-corpus-") as folder, zipfile.ZipFile(jar) as archive:
        for prefix, group in GROUPS.items():
            names = [
                n
                for n in archive.namelist()
                if n.startswith(prefix) and n.endswith(".class") and _MARKER in archive.read(n)
            ]
            for name in names:
                archive.extract(name, folder)
            for chunk in range(0, len(names), 100):
                for call in _disassembled(javap, folder, names[chunk : chunk + 100]):
                    sql = sql_of(call)
                    if sql is not None and sql.strip() and sql not in seen:
                        seen.add(sql)
                        probes.append(Probe(call.where, group, sql))
    return probes


def _disassembled(javap: Path, folder: str, names: Sequence[str]) -> list[Call]:
    done = subprocess.run(
        [str(javap), "-J-Dstdout.encoding=UTF-8", "-J-Dfile.encoding=UTF-8", "-c", "-p", "-constants", *names],
        cwd=folder,
        capture_output=True,
        text=True,
        encoding="utf-8",
        errors="replace",
        check=True,
    )
    return calls(done.stdout.splitlines())
