"""Name resolution and Trino type inference over a parsed Trino query.

`analyze(tree, schema, sql)` walks the whole tree once: it resolves every table and column
against the schema (CTEs, derived tables, VALUES, UNNEST, joins, correlated subqueries, lambda
parameters), expands `*`, computes the Trino type of every expression (stored in `node.meta["t"]`)
and the output columns of every query, and rejects what Trino would reject (unknown names, type
mismatches) or what lakegate cannot answer identically (unsupported syntax and functions), always
with the position in the original SQL text. The generator in `translate.py` then reads the types.

The analysis by concern: analyzer.py (the Analyzer and the dispatch of expressions by kind),
name_resolution.py (queries, relations, joins and the columns names refer to), star_expansion.py
(`*` and `row.*`), analysis_checks.py (the checks Trino makes at analysis), type_rules.py (what a
type rule sees) and the type rules of infer_operators.py, infer_casts.py and infer_calls.py.
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import infer_calls, infer_casts, infer_operators, zones
from lakegate.dialect import trino_types as tt
from lakegate.dialect.analyzer import Analyzer
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import OutCol

#: The modules whose rules (`type_rules.handles`) type each kind of expression; the function
#: pages (lakegate.dialect.functions) add the rules of the JSON expressions.
TYPE_RULES = (infer_operators, infer_casts, infer_calls)


def analyze(
    tree: exp.Expression, schema: dict[str, list[tuple[str, TType]]], sql: str, time_zone: str = zones.UTC
) -> list[OutCol]:
    """Resolve names and infer Trino types over the statement `tree` in the session zone `time_zone`;
    its output columns."""
    analyzer = Analyzer(schema, sql, time_zone)
    outputs = analyzer.query(tree, None)
    for name, _, t in outputs:
        _check_output_zone(analyzer, tree, name, t)
    return outputs


def _check_output_zone(a: Analyzer, tree: exp.Expression, name: str | None, t: TType) -> None:
    """A result column shows each timestamp with time zone in its zone: refuse one whose values do not all
    carry one zone, and zoned values other than UTC nested in an array, map or row (shown in UTC)."""
    if t.base == "timestamp_tz":
        a.zone(t, tree, f"the result column {name or ''}".rstrip())
    for inner in tt.inner_types(t):
        if inner.base == "timestamp_tz" and tt.zone_of(inner) != zones.UTC:
            a.unsupported(
                f"a result column of type {t} holding timestamps with time zone "
                f"{tt.zone_of(inner) or 'of several zones'} (lakegate shows nested ones in UTC only)",
                tree,
            )
