"""Calls Trino's planner folds to NULL: a function that returns NULL on a NULL argument, called with an
argument that is NULL whatever the row, is NULL without its other arguments being evaluated (so a
failing one fails nothing: `mod(1 / 0, CAST(NULL AS integer))` is NULL in Trino 476).

`FOLDED_ON_NULL` lists the functions of two or more arguments whose every argument the real Trino 476
folds so (each asked with a NULL in one position and a failing expression in the others); functions
with an argument that may be NULL (`coalesce`, `concat_ws`, `format`, `nullif`) or that Trino
evaluates whole (`greatest`, `least`) are not in it.
"""

from __future__ import annotations

from sqlglot import exp

FOLDED_ON_NULL = frozenset(
    """array_except array_intersect array_join array_union arrays_overlap at_timezone atan2 bit_count
    bitwise_and bitwise_left_shift bitwise_or bitwise_right_shift bitwise_right_shift_arithmetic bitwise_xor
    combinations concat contains_sequence cosine_distance cosine_similarity date_add date_diff date_format
    date_parse date_trunc dot_product element_at euclidean_distance format_datetime from_base hamming_distance
    hmac_md5 hmac_sha1 hmac_sha256 hmac_sha512 json_array_contains json_array_get json_extract
    json_extract_scalar json_size levenshtein_distance log lpad ltrim map map_concat mod ngrams parse_datetime
    pow power regexp_count regexp_extract regexp_extract_all regexp_like regexp_position regexp_replace
    regexp_split replace rpad rtrim sequence slice split split_part split_to_map split_to_multimap starts_with
    strpos substr substring to_base translate trim trim_array url_extract_parameter width_bucket
    wilson_interval_lower wilson_interval_upper with_timezone zip""".split()
)

#: Operators that are NULL when an operand is (Trino folds them as it folds the calls above).
_NULL_OPERATORS = (exp.Add, exp.Sub, exp.Mul, exp.Div, exp.Mod, exp.Neg, exp.Paren)


def always_null(node: exp.Expression) -> bool:
    """Whether `node` is NULL on every row by Trino's folding: NULL, CAST(NULL AS t), or an operator
    or a folded call (above) with such an argument."""
    if isinstance(node, exp.Null):
        return True
    if isinstance(node, exp.Cast):  # CAST and TRY_CAST
        return always_null(node.this)
    if isinstance(node, _NULL_OPERATORS):
        return any(always_null(child) for child in (node.args.get("this"), node.args.get("expression")) if child)
    return folds_to_null(node)


def folds_to_null(node: exp.Expression) -> bool:
    """Whether `node` is a call Trino folds to NULL: a function of FOLDED_ON_NULL with an argument
    that is always NULL."""
    return (
        isinstance(node, exp.Anonymous)
        and node.name.lower() in FOLDED_ON_NULL
        and any(always_null(arg) for arg in node.expressions)
        and not any(_groups(sub) for sub in node.walk())
    )


def _groups(node: exp.Expression) -> bool:
    """An aggregate, window or subquery: what keeps a query an aggregation (or reads rows) even when
    the call around it is NULL, so such a call is written whole."""
    if isinstance(node, (exp.Window, exp.Subquery, exp.Select, exp.Filter)):
        return True
    spec = node.meta.get("spec") if isinstance(node, exp.Anonymous) else None
    return spec is not None and spec.kind != "scalar"
