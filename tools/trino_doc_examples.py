"""Run the example queries of Trino's function documentation through lakegate and sort them: answered
as the documentation states, answered otherwise, refused in Trino's words, or refused with a message
that leaks sqlglot or DuckDB internals.

    python tools/trino_doc_examples.py            # figures, then every example that is not right
    python tools/trino_doc_examples.py --all      # every example with its outcome

The examples are tests/dialect/trino_doc_examples.yaml: per page of trinodb/trino
docs/src/main/sphinx/functions/, each `SELECT` of the page with the result the page states
(`-- result`), copied by hand. tests/dialect/test_trino_doc_examples.py runs the same sorting.
No network: the engine runs without a lake (the examples read no table).
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import yaml
from trino_answers import Answer

from lakegate.dialect.errors import DialectError
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.trino_values import encode_rows

EXAMPLES = Path(__file__).resolve().parent.parent / "tests" / "dialect" / "trino_doc_examples.yaml"

#: Refusal texts that name sqlglot's classes or leak DuckDB's errors instead of Trino's words.
LEAKS = re.compile(
    r"j_s_o_n|parse_json|JSONVALUE|HEXSTRING|GROUPINGSETS|dereference|UNICODESTRING|"
    r"Binder Error|Conversion Error|Could not convert|Mismatch Type|Catalog Error|Parser Error|"
    r"Invalid Input Error|Not implemented Error|_[a-z]+_[a-z]+\(|syntax [A-Z]{4,}",
)


@dataclass(frozen=True)
class Outcome:
    page: str
    sql: str
    expected: str
    kind: str  # right, wrong, noted (the page's result is not compared), refused, leak
    got: str
    note: str = ""


def render(value: object) -> str:
    """A protocol value as Trino's docs write results: [a, b], {k=v}, NULL, true."""
    if value is None:
        return "NULL"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return "[" + ", ".join(render(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{render(k)}={render(v)}" for k, v in value.items()) + "}"
    return str(value)


def normalized(text: str, ordered: bool = True) -> str:
    """Results compared loosely: quotes, ROW(...) and `->` of the docs' own spellings dropped; the
    entries of a map, and the rows of a query without ORDER BY, in any order."""
    text = re.sub(r"\bJSON\s+'", "'", text)  # JSON '1' is the docs' spelling of a json value
    text = re.sub(r"\bROW\(", "[", text, flags=re.IGNORECASE).replace(" -> ", "=")
    text = re.sub(r"(?<=\[)([^\[\]]*)\)", r"\1]", text)  # ROW(a, b) -> [a, b]
    text = re.sub(r"[\s'\"]", "", text).lower()
    if text.startswith("{") and text.endswith("}") and text.count("{") == 1:
        text = "{" + ",".join(sorted(text[1:-1].split(","))) + "}"
    return text if ordered else ";".join(sorted(text.split(";")))


def answer(engine: Engine, sql: str) -> Answer:
    """lakegate's answer to one query in the session zone UTC, as its server would send it (a DuckDB
    error that escaped the translator has the error name LEAK)."""
    try:
        result = engine.execute(sql, engine.session(time_zone="UTC"))
        rows = [row for batch in result.batches for row in encode_rows(result.columns, batch)]
    except DialectError as error:
        return Answer(error=error.error_name, message=error.message)
    except Exception as error:  # noqa: BLE001 - a DuckDB error that escaped the translator
        return Answer(error="LEAK", message=f"{type(error).__name__}: {error}")
    return Answer(columns=tuple(result.columns), rows=tuple(rows))


def run(engine: Engine, sql: str) -> tuple[str, str]:
    """(kind, text) of one query: the rendered first column of each row, or the refusal."""
    got = answer(engine, sql)
    if got.error == "LEAK":
        return "leak", got.message
    if got.error is not None:
        text = f"{got.error}: {got.message}"
        return ("leak" if LEAKS.search(text) else "refused"), text
    return "answered", "; ".join(", ".join(render(v) for v in row) for row in got.rows)


def outcomes(path: Path = EXAMPLES) -> list[Outcome]:
    pages = yaml.safe_load(path.read_text(encoding="utf-8"))
    engine = Engine.open(None)
    try:
        found = []
        for page, examples in pages.items():
            for sql, expected, *note in examples:
                kind, got = run(engine, sql)
                if kind == "answered":
                    ordered = "ORDER BY" in sql.upper()
                    same = normalized(got, ordered) == normalized(str(expected), ordered)
                    kind = "noted" if note else "right" if same else "wrong"
                found.append(Outcome(page, sql, str(expected), kind, got, "".join(note)))
        return found
    finally:
        engine.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--all", action="store_true", help="list every example, not only those not right")
    parser.add_argument("--examples", type=Path, default=EXAMPLES)
    args = parser.parse_args(argv)
    found = outcomes(args.examples)
    kinds = ("right", "wrong", "noted", "refused", "leak")
    counts = {kind: sum(1 for o in found if o.kind == kind) for kind in kinds}
    print(f"{len(found)} examples: " + ", ".join(f"{n} {kind}" for kind, n in counts.items()))
    for o in found:
        if args.all or o.kind != "right":
            print(f"[{o.kind}] {o.page}: {o.sql}\n    doc: {o.expected}\n    got: {o.got}")
            if o.note:
                print(f"    note: {o.note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
