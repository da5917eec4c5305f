"""Scope values bound into a translation: one translation of a query serves every job (or batch).

A one-batch or one-job scope reaches a translation only as string literals in the filters
`scope.restrict` adds (`batch_id = 'B' AND job_id = 'J'`). So `translate_in_scope` translates the
query with stand-in values and makes a job's translation from it by replacing each stand-in's
literal with the job's value as a SQL string literal (quotes doubled, as both generators write
them: the value is never pasted unquoted). The cache then holds one entry per query instead of one
per job, and a metrics run translates each metric once instead of once per job.

The stand-in translation is used only when a second one, with other stand-ins, proves that the text
depends on the values in no other way: it must equal the first with the stand-ins swapped, and
every stand-in must sit inside its quoted literal. Otherwise (and for any error) the query is
translated with the scope's own values, as `translate` does.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope
from lakegate.dialect.translate import Translation, translate

#: Two sets of (batch, job) stand-ins: plain words, written unchanged by every generator.
_STAND_INS = (
    ("lakegatestandinbatchqx", "lakegatestandinjobqx"),
    ("lakegatestandinbatchzw", "lakegatestandinjobzw"),
)


def quoted(value: str) -> str:
    """`value` as a SQL string literal (Trino and DuckDB alike: quotes doubled, nothing else escaped)."""
    return "'" + value.replace("'", "''") + "'"


def translate_in_scope(sql: str, schema: object, *, scope: Scope | None = None, **options: object) -> Translation:
    """`translate(sql, schema, scope=scope, **options)`, made from the query's translation with
    stand-in scope values when that is provably the same text (see the module docstring)."""
    if scope is None or scope.batches is not None or scope.statuses or not scope.conditions():
        return translate(sql, schema, scope=scope, **options)
    values = (scope.batch_id, scope.job_id)
    texts = (sql, *(value for value in values if value is not None))
    if any(word in text for text in texts for pair in _STAND_INS for word in pair):
        return translate(sql, schema, scope=scope, **options)
    try:
        first, second = (translate(sql, schema, scope=_stand_in_scope(scope, pair), **options) for pair in _STAND_INS)
    except DialectError:  # the scope's own translation says what it is
        return translate(sql, schema, scope=scope, **options)
    if not _only_in_literals(first, _STAND_INS[0], values) or _bound(first, _STAND_INS[0], _STAND_INS[1]) != second:
        return translate(sql, schema, scope=scope, **options)
    return _bound(first, _STAND_INS[0], values)


def _stand_in_scope(scope: Scope, pair: tuple[str, str]) -> Scope:
    batch, job = pair
    return Scope(
        batch_id=batch if scope.batch_id is not None else None, job_id=job if scope.job_id is not None else None
    )


def _texts(translation: Translation) -> tuple[str, str]:
    return translation.duckdb_sql, translation.trino_sql


def _only_in_literals(translation: Translation, pair: tuple[str, str], values: Sequence[str | None]) -> bool:
    """Whether every stand-in of a scope value in the texts is the whole of a string literal."""
    for text in _texts(translation):
        for word, value in zip(pair, values):
            if value is not None and text.count(word) != text.count(quoted(word)):
                return False
    return True


def _bound(translation: Translation, pair: tuple[str, str], values: Sequence[str | None]) -> Translation:
    """The translation with each stand-in's literal replaced by its value's literal."""
    texts = []
    for text in _texts(translation):
        for word, value in zip(pair, values):
            if value is not None:
                text = text.replace(quoted(word), quoted(value))
        texts.append(text)
    return dataclasses.replace(translation, duckdb_sql=texts[0], trino_sql=texts[1])
