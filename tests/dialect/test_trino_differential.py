"""Differential conformance (tools/trino_differential.py): every conformance case and every documented
example also runs on the real Trino 476, over the very same Parquet files (the fixture tables,
registered as external tables of Trino's hive catalog in a schema of this test process). A test fails
when lakegate answers and Trino answers otherwise (values or result types), or raises; the queries
lakegate refuses and Trino answers are counted and listed in docs/trino-differential.md, which this
test keeps true (`LAKEGATE_WRITE_DIFFERENTIAL=1` rewrites the page instead). Trino's answers are
recorded in trino_recorded/ (tools/trino_record.py): a run asks the judge what the record lacks and
a sample of what it holds, and fails when a sampled answer changed; `LAKEGATE_WRITE_DIFFERENTIAL=1`
asks every query again and rewrites the record with the page."""

from __future__ import annotations

import os
import uuid
from pathlib import Path

import pytest
import trino_differential as differential
import yaml
from functions_doc import Case, load_cases
from trino_answers import Answer, TrinoAnswers, single_row_width
from trino_doc_examples import EXAMPLES, answer
from trino_record import RECORD_ENV, RecordedAnswers, StaleRecord

from lakegate.dialect.errors import DialectError
from lakegate.dialect.translate import translate
from lakegate.gateway.engine.engine import Engine

#: Schemas of this test are `<PREFIX><pid>_<random>`; one left by a killed run is dropped later.
PREFIX = "lakegate_conformance_"
CASES_TITLE = "Conformance cases"
RECORDED = Path(__file__).with_name("trino_recorded")
EXAMPLES_TITLE = "Documented examples"


@pytest.fixture(scope="module")
def fixture_schema(trino_url, fixture_lake):
    """The fixture tables as external tables of Trino's hive catalog, in a schema of their own."""
    admin = TrinoAnswers(trino_url)
    admin.drop_orphans(PREFIX)
    schema = f"{PREFIX}{os.getpid()}_{uuid.uuid4().hex[:8]}"
    tables = {table: (fixture_lake.file(table).parent, columns) for table, columns in fixture_lake.schema.items()}
    admin.register(schema, tables)
    yield schema
    admin.drop_schema(schema)


def _check(title: str, verdicts: list[differential.Verdict]) -> None:
    failures = [v for v in verdicts if v.kind in differential.FAILURES]
    assert not failures, f"{len(failures)} differ from the real Trino:\n" + "\n".join(map(str, failures))
    judged = {v.where for v in verdicts if v.kind == "open"}
    fixed = [where for where in differential.OPEN if where not in judged and any(v.where == where for v in verdicts)]
    assert not fixed, f"agree with Trino now, take them off trino_differential.OPEN: {fixed}"
    written = differential.section(title, verdicts)
    committed = differential.OUTPUT.read_text(encoding="utf-8") if differential.OUTPUT.exists() else ""
    if os.environ.get("LAKEGATE_WRITE_DIFFERENTIAL") == "1":
        sections = {
            name: differential.section_of(committed, name) or f"## {name}\n" for name in (CASES_TITLE, EXAMPLES_TITLE)
        }
        sections[title] = written
        differential.OUTPUT.write_text(differential.page(list(sections.values())), encoding="utf-8")
        return
    assert differential.section_of(committed, title).strip() == written.strip(), (
        f"{differential.OUTPUT.name} is stale ({differential.counts(verdicts)}): rewrite it with\n"
        "LAKEGATE_WRITE_DIFFERENTIAL=1 .venv/bin/python -m pytest -n 0 tests/dialect/test_trino_differential.py"
    )


@pytest.mark.slow
@pytest.mark.timeout(900)  # ~1,500 queries on Trino: about a minute on a quiet machine, far more under load
def test_every_case_states_what_trino_answers(trino_url, fixture_schema, fixture_lake):
    cases = load_cases()

    def refuses(case: Case) -> str | None:
        try:
            translate(case.sql, fixture_lake.schema, time_zone=case.time_zone)
        except DialectError as error:
            return f"{error.error_name}: {error}"
        return None

    trino = RecordedAnswers(
        TrinoAnswers(trino_url, schema=fixture_schema), RECORDED / "cases.jsonl", fixture_lake.fingerprint
    )
    answer_of = {}
    for errors in (False, True):  # queries that fail are asked one by one: a failure spoils a batch
        asked = [case for case in cases if differential.not_on_trino(case) is None and bool(case.errors) == errors]
        answers = trino.ask_all([(case.sql, case.time_zone) for case in asked], batch=not errors)
        answer_of.update((case.id, answer) for case, answer in zip(asked, answers))
    trino.save()
    print(f"asked the real Trino {trino.asked} of {len(answer_of)} queries (the rest from {RECORDED.name}/)")
    _check(CASES_TITLE, [differential.judge_case(case, answer_of.get(case.id), refuses) for case in cases])


@pytest.mark.timeout(900)
def test_every_documented_example_answers_as_trino_does(trino_url):
    pages = yaml.safe_load(EXAMPLES.read_text(encoding="utf-8"))
    examples = [(page, example[0]) for page, listed in pages.items() for example in listed]
    engine = Engine.open(None)
    try:
        ours = [answer(engine, sql) for _, sql in examples]
    finally:
        engine.close()
    trino = RecordedAnswers(
        TrinoAnswers(trino_url, catalog="memory", schema="default"), RECORDED / "examples.jsonl", "no tables"
    )
    answers = trino.ask_all([(sql, "UTC") for _, sql in examples])
    trino.save()
    verdicts = [differential.judge_answers(p, sql, o, t) for (p, sql), o, t in zip(examples, ours, answers)]
    _check(EXAMPLES_TITLE, verdicts)


# --- the judging itself, without a Trino ------------------------------------------------------------
def _case(**fields) -> Case:
    return Case(family="f", name="n", sql=fields.pop("sql", "SELECT 1"), **fields)


def test_a_case_is_judged_by_values_types_and_errors():
    answers = Answer(columns=(("_col0", "integer"),), rows=([1],))
    one = _case(columns=(("_col0", "integer"),), rows=((1,),))
    answered = lambda case: None  # noqa: E731 - lakegate answers every case here
    assert differential.judge_case(one, answers, answered).kind == "equal"
    assert differential.judge_case(one, Answer(columns=(("_col0", "bigint"),), rows=([1],)), answered).kind == (
        "different"
    )
    assert differential.judge_case(one, Answer(columns=(("_col0", "integer"),), rows=([2],)), answered).kind == (
        "different"
    )
    assert differential.judge_case(one, Answer(error="DIVISION_BY_ZERO"), answered).kind == "trino raises"
    assert differential.judge_case(one, answers, lambda case: "NOT_SUPPORTED: x").kind == "refused"
    refusal = _case(errors=("NOT_SUPPORTED",))
    assert differential.judge_case(refusal, answers, answered).kind == "refused"
    wrong_error = _case(errors=("INVALID_CAST_ARGUMENT",))
    assert differential.judge_case(wrong_error, answers, answered).kind == "different"
    assert differential.judge_case(wrong_error, Answer(error="INVALID_CAST_ARGUMENT"), answered).kind == "equal"
    assert differential.judge_case(wrong_error, Answer(error="TYPE_MISMATCH"), answered).kind == "both errored"
    assert differential.judge_case(_case(sql="DROP TABLE t", errors=("PERMISSION_DENIED",)), None, answered).kind == (
        "not run on Trino"
    )


def test_an_example_is_judged_by_both_answers():
    ours = Answer(columns=(("_col0", "double"),), rows=([0.1],))
    assert differential.judge_answers("p", "SELECT 0.1e0", ours, ours).kind == "equal"
    other = Answer(columns=(("_col0", "double"),), rows=([0.30000000000000004],))
    assert differential.judge_answers("p", "SELECT 0.1e0", ours, other).kind == "different"
    assert differential.judge_answers("p", "SELECT 1", Answer(error="NOT_SUPPORTED"), ours).kind == "refused"
    assert differential.judge_answers("p", "SELECT 1", ours, Answer(error="SYNTAX_ERROR")).kind == "trino raises"


def test_only_one_row_shapes_are_batched():
    assert single_row_width("SELECT 1, 'a' AS b, ARRAY[2]") == 3
    assert single_row_width("SELECT 1 FROM t") is None
    assert single_row_width("SELECT 1 WHERE false") is None
    assert single_row_width("SELECT 1 UNION ALL SELECT 2") is None
    assert single_row_width("SELECT 1 LIMIT 0") is None


class _Judge:
    """Stands in for TrinoAnswers: answers each query with its `answers` entry, and counts the asking."""

    def __init__(self, answers: dict[str, Answer]):
        self.answers, self.asked = answers, []

    def ask_all(self, queries, *, batch=True):
        self.asked += [sql for sql, _ in queries]
        return [self.answers[sql] for sql, _ in queries]


def test_recorded_answers_are_asked_again_only_when_missing_or_sampled(tmp_path, monkeypatch):
    one, two = Answer(columns=(("_col0", "integer"),), rows=([1],)), Answer(columns=(("x", "integer"),), rows=([2],))
    queries = [("SELECT 1", "UTC"), ("SELECT 2 AS x", "UTC"), ("SELECT 1", "Asia/Tokyo")]
    judge = _Judge({"SELECT 1": one, "SELECT 2 AS x": two})
    monkeypatch.setenv(RECORD_ENV, "1")
    writing = RecordedAnswers(judge, tmp_path / "r.jsonl", "data")
    assert writing.ask_all(queries) == [one, two, one]
    writing.save()
    monkeypatch.delenv(RECORD_ENV)
    judge.asked = []
    assert RecordedAnswers(judge, tmp_path / "r.jsonl", "data", sample=0).ask_all(queries) == [one, two, one]
    assert judge.asked == []  # all recorded, none sampled
    RecordedAnswers(judge, tmp_path / "r.jsonl", "other data", sample=0).ask_all(queries[:1])
    assert judge.asked == ["SELECT 1"]  # other tables: not recorded
    judge.answers["SELECT 2 AS x"] = Answer(columns=(("x", "bigint"),), rows=([2],))
    with pytest.raises(StaleRecord, match="SELECT 2 AS x"):
        RecordedAnswers(judge, tmp_path / "r.jsonl", "data", sample=3).ask_all(queries)
