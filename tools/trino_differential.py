"""Differential conformance: the conformance cases (tests/dialect/cases/*.yaml) and Trino's documented
examples (tests/dialect/trino_doc_examples.yaml) judged by the real Trino 476.

A case states lakegate's answer (tests/dialect/test_conformance.py holds lakegate to it), so a case is
judged by comparing what it states with what Trino answers; a documented example is run on both.
Each query gets one verdict:

- `equal`: both answer, with the same values and result types (or both raise the same error);
- `refused`: lakegate refuses (NOT_SUPPORTED, FUNCTION_NOT_FOUND), Trino answers: listed, not failed;
- `both errored`: both raise, with different error names;
- `different`: both answer, differently (values or types) - a failure;
- `trino raises`: lakegate answers (or raises an error Trino does not) where Trino raises - a failure;
- `not run on Trino`: a case that says why it is not sent to Trino (`not_on_trino:`, e.g. it would
  exhaust the judge's heap).

`render` writes the counts and the `refused` list as docs/trino-differential.md (kept true by
tests/dialect/test_trino_differential.py; `LAKEGATE_WRITE_DIFFERENTIAL=1` there rewrites it).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from answer_compare import has_order_by, rows_match, types_match
from functions_doc import Case, called_names
from trino_answers import Answer

OUTPUT = Path(__file__).resolve().parent.parent / "docs" / "trino-differential.md"
#: lakegate's refusals of what it does not translate (as opposed to errors Trino raises too).
REFUSALS = frozenset({"NOT_SUPPORTED", "FUNCTION_NOT_FOUND"})
FAILURES = ("different", "trino raises")
KINDS = ("equal", "refused", "both errored", "not run on Trino", "open", *FAILURES)

#: Cases where lakegate still answers otherwise than the real Trino (a silent wrong answer, or an
#: answer where Trino raises), each to be fixed or refused by name: case id -> what Trino does. The
#: verdict on these is `open` (listed on the page) instead of a failure; a listed case that agrees
#: with Trino again fails the test until it is taken off this list.
OPEN: dict[str, str] = {
    "select/trailing-semicolon": "SELECT 1; is a SYNTAX_ERROR",
}


@dataclass(frozen=True)
class Verdict:
    """How lakegate's answer to one query compares with Trino's."""

    where: str  # the case id or the documentation page
    sql: str
    kind: str  # one of KINDS
    lakegate: str
    trino: str

    def __str__(self) -> str:
        return f"[{self.kind}] {self.where}: {self.sql.strip()}\n  lakegate: {self.lakegate}\n  trino:    {self.trino}"


#: Statements that change something (lakegate refuses them, PERMISSION_DENIED): never sent to the judge.
_CHANGES = re.compile(
    r"\s*(?:--[^\n]*\n\s*|/\*.*?\*/\s*)*(INSERT|CREATE|DELETE|UPDATE|DROP|ALTER|MERGE|TRUNCATE|CALL|GRANT|REVOKE|"
    r"DENY|COMMENT|ANALYZE|REFRESH|SET|RESET|USE|COPY|ATTACH|DETACH|EXPORT|IMPORT|INSTALL|LOAD|PRAGMA|START|"
    r"COMMIT|ROLLBACK|PREPARE|EXECUTE|DEALLOCATE|VACUUM|CHECKPOINT)\b",
    re.IGNORECASE | re.DOTALL,
)


#: Functions of the plugin trino-teradata-functions, which the judge (tools/trino_server.py) does not load.
TERADATA = frozenset({"char2hexint", "index", "to_char", "to_date", "to_timestamp"})


def not_on_trino(case: Case) -> str | None:
    """Why `case` is not sent to the real Trino (None: it is): the case says so, its statement would
    change the judge's catalog or session, or it calls a function of a plugin the judge lacks."""
    if case.not_on_trino is not None:
        return case.not_on_trino
    teradata = sorted(called_names(case.sql) & TERADATA)
    if teradata:
        return f"{teradata[0]}: a function of the plugin trino-teradata-functions, which the judge does not load"
    match = _CHANGES.match(case.sql)
    if match:
        return f"{match.group(1).upper()}: a statement that changes data or the session is not sent to the judge"
    return None


def judge_case(case: Case, trino: Answer | None, refuses: Callable[[Case], str | None]) -> Verdict:
    """The verdict on one case (`open` instead of a failure for a case of OPEN)."""
    verdict = _judge_case(case, trino, refuses)
    if case.id in OPEN and verdict.kind in FAILURES:
        return Verdict(verdict.where, verdict.sql, "open", verdict.lakegate, verdict.trino)
    return verdict


def _judge_case(case: Case, trino: Answer | None, refuses: Callable[[Case], str | None]) -> Verdict:
    """The verdict on one case: its stated answer against Trino's (None: not asked, `not_on_trino`).
    `refuses(case)` is lakegate's refusal of a result case (an error text) or None when lakegate
    answers it."""
    if trino is None:
        return Verdict(case.id, case.sql, "not run on Trino", str(not_on_trino(case)), "")
    if case.errors:
        stated = " or ".join(case.errors) + (f" ({case.message})" if case.message else "")
        if trino.error is None:  # lakegate raises where Trino answers: fine only as a refusal by name
            kind = "refused" if set(case.errors) <= REFUSALS else "different"
            return Verdict(case.id, case.sql, kind, stated, str(trino))
        kind = "equal" if trino.error in case.errors else "both errored"
        return Verdict(case.id, case.sql, kind, stated, str(trino))
    stated = str(Answer(columns=case.columns, rows=tuple(list(r) for r in case.rows)))
    refusal = refuses(case)
    if trino.error is not None:
        return Verdict(case.id, case.sql, "both errored" if refusal else "trino raises", refusal or stated, str(trino))
    ordered = case.ordered if case.ordered is not None else has_order_by(case.sql)
    if not (
        types_match(case.columns, trino.columns)
        and rows_match(case.rows, trino.rows, ordered=ordered, tolerance=case.tolerance)
    ):
        return Verdict(case.id, case.sql, "different", stated, str(trino))
    return Verdict(case.id, case.sql, "refused" if refusal else "equal", refusal or stated, str(trino))


def judge_answers(where: str, sql: str, lakegate: Answer, trino: Answer) -> Verdict:
    """The verdict on a query both answered (or refused): exact values and types."""
    if lakegate.error is not None:
        kind = "refused" if trino.error is None else "equal" if lakegate.error == trino.error else "both errored"
        return Verdict(where, sql, kind, str(lakegate), str(trino))
    if trino.error is not None:
        return Verdict(where, sql, "trino raises", str(lakegate), str(trino))
    same = types_match(lakegate.columns, trino.columns) and rows_match(
        lakegate.rows, trino.rows, ordered=has_order_by(sql)
    )
    return Verdict(where, sql, "equal" if same else "different", str(lakegate), str(trino))


def counts(verdicts: Sequence[Verdict]) -> str:
    """`N queries: E equal, R refused, ...`."""
    tally = ", ".join(f"{sum(v.kind == kind for v in verdicts)} {kind}" for kind in KINDS)
    return f"{len(verdicts)} queries: {tally}"


def section(title: str, verdicts: Sequence[Verdict]) -> str:
    """The part of the page about one set of queries: counts and the queries Trino answers that
    lakegate refuses."""
    lines = [f"## {title}", "", counts(verdicts) + ".", ""]
    tables = (
        ("open", "Open (lakegate answers otherwise than Trino: to fix)", "lakegate", "trino"),
        ("refused", "Refused by lakegate, answered by Trino", "lakegate", None),
        ("not run on Trino", "Not run on Trino", "lakegate", None),
    )
    for kind, heading, _first, second in tables:
        listed = [v for v in verdicts if v.kind == kind]
        if listed:
            columns = ["where", "query", "lakegate" if kind != "not run on Trino" else "why not"]
            columns += ["trino"] if second else []
            lines += [f"### {heading}", "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
            for v in listed:
                cells = [v.where, f"`{_cell(v.sql)}`", _cell(v.lakegate)] + ([_cell(v.trino)] if second else [])
                lines.append("| " + " | ".join(cells) + " |")
            lines.append("")
    return "\n".join(lines)


def _cell(text: str) -> str:
    text = " ".join(text.split()).replace("|", "\\|").replace("`", "'")
    return text if len(text) <= 200 else text[:197] + "..."


HEADER = """# lakegate against the real Trino 476

<!-- Generated by tests/dialect/test_trino_differential.py (LAKEGATE_WRITE_DIFFERENTIAL=1 rewrites it).
     Do not edit by hand. -->

Every conformance case (`tests/dialect/cases/*.yaml`) and every documented example
(`tests/dialect/trino_doc_examples.yaml`) also runs on a real Trino 476 (`python3 dev.py trino start`),
over the very same Parquet files registered as external tables of its hive catalog. A case is judged
by what it states (the conformance runner holds lakegate to it); an example is run on both. **equal**:
same values and result types, or the same error; **refused**: lakegate refuses it by name, Trino
answers (listed below); **both errored**: both raise, under different error names; **different** and
**trino raises** (lakegate answers, or raises what Trino does not, where Trino answers otherwise or
raises) fail the test, so they are 0 here. Trino's answers are recorded in
`tests/dialect/trino_recorded/` (tools/trino_record.py): a test run asks the real Trino what the record
lacks and a random sample of 100 of each file, and fails when a sampled answer changed;
`LAKEGATE_WRITE_DIFFERENTIAL=1` asks every query again and rewrites record and page.
"""


def page(sections: Sequence[str]) -> str:
    return HEADER + "\n" + "\n".join(sections)


def section_of(text: str, title: str) -> str:
    """The section `## title` of a page written by `page` (empty when it has none)."""
    match = re.search(rf"^## {re.escape(title)}\n.*?(?=^## |\Z)", text, re.MULTILINE | re.DOTALL)
    return match.group(0) if match else ""
