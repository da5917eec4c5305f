"""The differential run over Trino 476's own function tests (tools/trino_corpus, `python3 dev.py corpus`):
its fixed smoke sample answers the same on lakegate and on the real Trino, or is refused by lakegate, or
fails on both. A difference not on tools/trino_corpus/known.py fails, and so does a listed one that is
gone (then take it off the list). The reading of the compiled tests is checked on a class of the jar."""

from __future__ import annotations

import pytest
import trino_differential as differential
from trino_corpus import known
from trino_corpus.bytecode import Call, calls, unescape
from trino_corpus.probes import Probe, load, sql_of
from trino_corpus.run import SMOKE, deterministic, judge, sample, summary, unexpected

JAVAP = (
    """\
public class io.trino.operator.scalar.TestArrayCombinationsFunction {
  public void testBasic();
    Code:
         0: aload_0
         1: getfield      #7 // Field assertions:L{QA};
         4: ldc #47 // String combinations
         6: iconst_2
         7: anewarray     #49 // class java/lang/String
        10: dup
        11: iconst_0
        12: ldc #51 // String ARRAY[\\'bar\\', \\'foo\\']
        14: aastore
        15: dup
        16: iconst_1
        17: ldc #53 // String 0
        19: aastore
        20: invokevirtual #55 // Method {QA}.function:({S}[{S}){P}
        23: invokestatic  #59 // Method org/assertj/A.assertThat:(Ljava/lang/Object;)Ljava/lang/Object;
        26: aload_0
        27: getfield      #7 // Field assertions:L{QA};
        30: ldc #60 // String a + b
        32: invokevirtual #61 // Method {QA}.expression:({S}){P}
        35: ldc #62 // String a
        37: ldc #63 // String 1
        39: invokevirtual #64 // Method {QA}$ExpressionAssertProvider.binding:({S}{S}){P}
        42: ldc #65 // String b
        44: aload_1
        45: invokevirtual #64 // Method {QA}$ExpressionAssertProvider.binding:({S}{S}){P}
        48: aload_0
        49: getfield      #7 // Field assertions:L{QA};
        52: getstatic #66 // Field io/trino/spi/function/OperatorType.SUBTRACT:Lio/trino/spi/function/OperatorType;
        55: iconst_2
        56: anewarray     #49 // class java/lang/String
        59: dup
        60: iconst_0
        61: ldc #63 // String 1
        63: aastore
        64: dup
        65: iconst_1
        66: ldc #67 // String -2
        68: aastore
        69: invokevirtual #68 // Method {QA}.operator:(Lio/trino/spi/function/OperatorType;[{S}){P}
""".replace("{P}", "Lio/trino/sql/query/QueryAssertions$ExpressionAssertProvider;")
    .replace("{QA}", "io/trino/sql/query/QueryAssertions")
    .replace("{S}", "Ljava/lang/String;")
)


def test_the_sql_of_each_call_is_rebuilt_from_javap():
    found = calls(JAVAP.splitlines())
    assert [(c.where, c.kind) for c in found] == [
        ("TestArrayCombinationsFunction.testBasic", "function"),
        ("TestArrayCombinationsFunction.testBasic", "expression"),
        ("TestArrayCombinationsFunction.testBasic", "operator"),
    ]
    assert sql_of(found[0]) == "SELECT combinations(ARRAY['bar', 'foo'], 0)"
    assert found[1].computed and sql_of(found[1]) is None  # `b` is bound to a variable, not a constant
    assert sql_of(found[2]) == "SELECT (1) - (-2)"
    bound = Call("T.m", "expression", "a + b", bindings=[("a", "1"), ("b", "'x'")])
    assert sql_of(bound) == "SELECT a + b FROM (VALUES ROW(1, 'x')) t(a, b)"
    assert sql_of(Call("T.m", "operator", "HASH_CODE", arguments=["1"])) is None  # no SQL syntax
    assert unescape(r"it\'s \"q\" \u007f\n") == 'it\'s "q" \x7f\n'


def test_the_smoke_sample_is_fixed_and_spread():
    probes = list(range(1000))
    assert sample(probes, 4) == [0, 250, 500, 750]
    assert sample(probes[:3], 4) == [0, 1, 2]
    kept = deterministic([Probe("T.m", "functions", sql) for sql in ("SELECT random(1)", "SELECT abs(1)")])
    assert [p.sql for p in kept] == ["SELECT abs(1)"]


@pytest.mark.slow
@pytest.mark.timeout(1800)  # a minute or two on a quiet machine, far more when it is shared
def test_trinos_own_function_tests_answer_as_trino_does(trino_url):
    probes = load()  # the tests jar from Maven Central, disassembled with javap (cached)
    assert len(probes) > 15_000
    assert "SELECT combinations(ARRAY['bar', 'foo', 'baz', 'foo'], 0)" in {p.sql for p in probes}
    chosen = sample(deterministic(probes), SMOKE)
    verdicts = judge(chosen, trino_url)
    print(summary("smoke", verdicts))
    failures = unexpected(verdicts)
    assert not failures, f"{len(failures)} differ from the real Trino:\n" + "\n".join(map(str, failures[:20]))
    sampled = {p.sql for p in chosen}
    gone = [
        sql
        for sql in known.KNOWN
        if sql in sampled and not any(v.sql == sql and v.kind in differential.FAILURES for v in verdicts)
    ]
    assert not gone, "these listed queries now answer as Trino does: take them off known.py:\n" + "\n".join(gone)
