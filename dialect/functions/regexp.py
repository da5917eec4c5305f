"""Trino's functions/regexp.md. Regular expression functions (Java patterns;
io.trino.operator.scalar.JoniRegexpFunctions).
"""

from __future__ import annotations

import re
import re._parser as re_parser

from sqlglot import exp

from lakegate.dialect import transforms as tf
from lakegate.dialect import trino_types as tt
from lakegate.dialect.functions.arguments import literal_int, literal_str, need
from lakegate.dialect.functions.rendering import call_as, null_if_any_null, sqls
from lakegate.dialect.registry import overload, register
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import Call


# --- regular expressions -------------------------------------------------------------------------
def regexp_call(call: Call, result: TType, arity: tuple[int, ...], *kinds: str) -> TType:
    """Type a regexp_* call: its arity and argument kinds, a literal pattern that RE2 reads as Joni does."""
    if len(call.args) not in arity:
        call.mismatch()
    need(call, *kinds, optional=len(kinds) - len(call.args))
    pattern = literal_str(call, 1)
    if pattern is not None:
        java_only = re.search(r"\(\?<[=!]|\(\?[=!>]|\\[1-9]|[*+?}]\+|\\[zZGhHvRXk]|\\p\{(?:java|Is)", pattern)
        if java_only:
            call.fail(
                f"unsupported in lakegate: regular expression construct '{java_only.group(0)}' "
                "(lakegate uses RE2, which has no lookaround, backreferences or possessive quantifiers)",
                "NOT_SUPPORTED",
            )
        try:
            re.compile(pattern)
        except re.error as error:
            if any(
                word in str(error)
                for word in (
                    "missing",
                    "unbalanced",
                    "unterminated",
                    "nothing to repeat",
                    "multiple repeat",
                    "bad character range",
                )
            ):
                call.fail(f"invalid regular expression '{pattern}': {error}", "INVALID_FUNCTION_ARGUMENT")
    source = call.types[0]
    text = source if source is not None and source.base == "varchar" else tt.VARCHAR
    return {"same": text, "array": tt.array(text)}.get(result, result) if isinstance(result, str) else result


def capturing_groups(pattern: str) -> list[tuple[str, bool, int]]:
    """Each capturing group of a regular expression: (body, optional, index of its opening
    parenthesis), optional when the group may not take part in a match (quantified by ?, * or
    {0,...}, or inside an alternation)."""
    groups: list[tuple[str, bool, int]] = []
    stack: list[tuple[bool, int, int]] = []  # (capturing, body start, index in groups)
    alternation_depths: set[int] = set()
    i = 0
    while i < len(pattern):
        ch = pattern[i]
        if ch == "\\":
            i += 2
            continue
        if ch == "[":
            i += 1
            if i < len(pattern) and pattern[i] == "^":
                i += 1
            if i < len(pattern) and pattern[i] == "]":
                i += 1
            while i < len(pattern) and pattern[i] != "]":
                i += 2 if pattern[i] == "\\" else 1
        elif ch == "(":
            named = pattern.startswith("(?P<", i) or (
                pattern.startswith("(?<", i) and pattern[i + 3 : i + 4] not in "=!"
            )
            capturing = not pattern.startswith("(?", i) or named
            start = pattern.index(">", i) + 1 if named else (i + 1 if capturing else pattern.find(":", i) + 1 or i + 2)
            if capturing:
                groups.append(("", False, i))
            stack.append((capturing, start, len(groups) - 1))
        elif ch == "|":
            alternation_depths.add(len(stack))
        elif ch == ")" and stack:
            capturing, start, index = stack.pop()
            if capturing:
                rest = pattern[i + 1 :]
                optional = rest.startswith(("?", "*", "{0")) or any(d <= len(stack) for d in alternation_depths)
                groups[index] = (pattern[start:i], optional, groups[index][2])
        i += 1
    return groups


def _group_semantics(call: Call, group_index: int) -> None:
    """Record how DuckDB's '' for a group maps to Trino's answer; reject what cannot be told apart."""
    pattern = literal_str(call, 1)
    group = literal_int(call, 2) if len(call.args) > group_index else 0
    if group is None:
        if pattern is None or capturing_groups(pattern):
            call.fail("regexp group must be a literal integer in lakegate", "NOT_SUPPORTED")
        call.node.meta["dynamic_group"] = True  # a pattern without groups: 0 is the only valid group
        return
    if pattern is None:
        if group:
            call.fail("regexp pattern must be a literal string to extract a group in lakegate", "NOT_SUPPORTED")
        return
    groups = capturing_groups(pattern)
    if group < 0 or group > len(groups):
        call.fail(f"Pattern has {len(groups)} groups. Cannot access group {group}", "INVALID_FUNCTION_ARGUMENT")
    if group and groups[group - 1][1]:
        body = groups[group - 1][0]
        try:
            can_be_empty = re.fullmatch(f"(?:{body})", "") is not None
        except re.error:
            can_be_empty = True
        if can_be_empty:
            call.fail(
                f"unsupported in lakegate: regexp group {group} is optional and can match the empty string, "
                "so a missing group cannot be told from an empty one",
                "NOT_SUPPORTED",
            )
        call.node.meta["null_if_empty"] = True


def _regexp_extract(call: Call) -> TType:
    result = regexp_call(call, "same", (2, 3), "string", "string", "integral")
    _group_semantics(call, 2)
    return result


def _regexp_extract_all(call: Call) -> TType:
    result = regexp_call(call, "array", (2, 3), "string", "string", "integral")
    _group_semantics(call, 2)
    return result


def _group(g, node, args, index: int) -> str:
    """The group argument as DuckDB's INTEGER constant (0 for a non-literal group: `_group_checked`)."""
    if len(args) <= index or node.meta.get("dynamic_group"):
        return "0"
    sql = g.sql(args[index])
    return sql if sql.isdigit() else f"CAST({sql} AS INTEGER)"


def _group_checked(g, node, args, sql: str) -> str:
    """`sql` for a non-literal group of a pattern without groups: NULL for a NULL group, Trino's
    error for another group than 0 (DuckDB wants a constant group)."""
    if not node.meta.get("dynamic_group"):
        return sql
    group = g.sql(args[2])
    error = g.fail(f"{tf.string('Pattern has 0 groups. Cannot access group ')} || CAST(({group}) AS VARCHAR)")
    return f"CASE WHEN ({group}) IS NULL THEN NULL WHEN ({group}) <> 0 THEN {error} ELSE {sql} END"


def _render_regexp_extract(g, node, args) -> str:
    value, pattern, group = g.sql(args[0]), g.sql(args[1]), _group(g, node, args, 2)
    extracted = f"regexp_extract({value}, {pattern}, {group})"
    if group.isdigit() and int(group) > 9:  # DuckDB's regexp_extract reads groups 0 to 9 only
        extracted = f"regexp_extract_all({value}, {pattern}, {group})[1]"
    if node.meta.get("null_if_empty"):
        extracted = f"nullif({extracted}, '')"
    return _group_checked(g, node, args, f"CASE WHEN regexp_matches({value}, {pattern}) THEN {extracted} END")


def _render_regexp_extract_all(g, node, args) -> str:
    sql = f"regexp_extract_all({g.sql(args[0])}, {g.sql(args[1])}, {_group(g, node, args, 2)})"
    if node.meta.get("null_if_empty"):
        sql = f'list_transform({sql}, lambda "_e": nullif("_e", \'\'))'
    return _group_checked(g, node, args, sql)


class IllegalGroupReference(ValueError):
    """A replacement names a group the pattern does not have."""


def _replacement_parts(text: str, groups: int | None) -> list[str | int]:
    """A Java replacement string as literal text and group numbers: `\\x` is x, `$` takes as many
    digits as name an existing group (`$10` with one group is group 1 then '0', `$01` is group 1), as
    Trino's JoniRegexpFunctions.appendReplacement does. `groups` is the pattern's group count (None:
    unknown, then only one-digit references are translated). ValueError for what is not translated."""
    parts: list[str | int] = []
    i = 0
    while i < len(text):
        ch = text[i]
        if ch == "\\" and i + 1 < len(text):
            parts.append(text[i + 1])
            i += 2
            continue
        if ch == "$":
            digits = re.match(r"\$(\d+)", text[i:])
            if not digits:
                raise ValueError("named group references in the regexp_replace replacement")
            if groups is None and len(digits.group(1)) > 1:
                raise ValueError("a multi-digit group reference with a non-literal pattern")
            number, used = int(digits.group(1)[0]), 1
            while used < len(digits.group(1)) and number * 10 + int(digits.group(1)[used]) <= groups:
                number, used = number * 10 + int(digits.group(1)[used]), used + 1
            if groups is not None and number > groups:
                raise IllegalGroupReference(f"Illegal group reference: group {number} does not exist")
            parts.append(number)
            i += 1 + used
            continue
        parts.append(ch)
        i += 1
    return parts


def _regexp_replacement(pattern: str | None, replacement: str) -> tuple[str | None, str]:
    """Trino's regexp_replace(s, pattern, replacement) as DuckDB's: the (literal) pattern and an RE2
    rewrite string. RE2 names groups 0 to 9 only, so when the replacement refers to a later group, only
    the referenced groups stay capturing, renumbered from 1 (ValueError if more than nine are)."""
    parts = _replacement_parts(replacement, None if pattern is None else len(capturing_groups(pattern)))
    referenced = sorted({p for p in parts if isinstance(p, int) and p > 0})
    numbering = {n: n for n in referenced}
    if referenced and referenced[-1] > 9:
        if len(referenced) > 9:
            raise ValueError("a replacement that refers to more than nine groups")
        numbering = {n: index for index, n in enumerate(referenced, 1)}
        pattern = _capturing_only(pattern, referenced)
    rewrite = "".join(f"\\{numbering.get(p, 0)}" if isinstance(p, int) else "\\\\" if p == "\\" else p for p in parts)
    return pattern, rewrite


def _capturing_only(pattern: str, kept: list[int]) -> str:
    """`pattern` with every capturing group but those numbered in `kept` made non-capturing."""
    out, last = [], 0
    for number, (_, _, at) in enumerate(capturing_groups(pattern), 1):
        if number in kept:
            continue
        end = pattern.index(">", at) + 1 if pattern.startswith("(?", at) else at + 1  # (?P<name> or (?<name>
        out += [pattern[last:at], "(?:"]
        last = end
    return "".join(out) + pattern[last:]


def _literal_pattern(pattern: exp.Expression) -> str | None:
    return pattern.name if isinstance(pattern, exp.Literal) and pattern.is_string else None


def _regexp_replace(call: Call) -> TType:
    regexp_call(call, tt.VARCHAR, (2, 3), "string", "string", "string")
    x = tt.varchar_length(call.types[0]) if call.types[0].base == "varchar" else None
    if len(call.args) == 3:
        replacement = literal_str(call, 2)
        if replacement is None:
            call.fail("regexp_replace needs a literal replacement string in lakegate", "NOT_SUPPORTED")
        try:
            _regexp_replacement(_literal_pattern(call.args[1]), replacement)
        except IllegalGroupReference as e:
            call.fail(str(e), "INVALID_FUNCTION_ARGUMENT")
        except ValueError as e:
            call.fail(f"unsupported in lakegate: {e}", "NOT_SUPPORTED")
    if x is None:
        return tt.VARCHAR
    if len(call.args) == 2:
        return call.types[0]
    y = tt.varchar_length(call.types[2]) if call.types[2].base == "varchar" else None
    if y is None:
        return tt.VARCHAR
    return tt.varchar(min(2147483647, x + max(x * y // 2, 0) * (x + 1)))


def _render_regexp_replace(g, node, args) -> str:
    value, pattern = g.sql(args[0]), g.sql(args[1])
    if len(args) == 2:
        return f"regexp_replace({value}, {pattern}, '', 'g')"
    literal, rewrite = _regexp_replacement(_literal_pattern(args[1]), args[2].name)
    return f"regexp_replace({value}, {pattern if literal is None else tf.string(literal)}, {tf.string(rewrite)}, 'g')"


def _regexp_split(call: Call) -> TType:
    """Splits at matches. An empty match splits before the next character and '' ends the array at
    both ends (JoniRegexpFunctions.regexpSplit); DuckDB does not, so the empty pattern is written as
    that split between characters and other patterns that can match the empty string are refused."""
    result = regexp_call(call, "array", (2,), "string", "string")
    pattern = literal_str(call, 1)
    if pattern and (re.search(r"\\[bB]|\^|\$", pattern) or _matches_empty(pattern)):
        call.fail(
            "unsupported in lakegate: regexp_split with a pattern that can match the empty string", "NOT_SUPPORTED"
        )
    return result


def _matches_empty(pattern: str) -> bool:
    try:
        return re.fullmatch(pattern, "") is not None
    except re.error:
        return False


def _render_regexp_split(g, node, args) -> str:
    value, pattern = sqls(g, args)
    if _literal_pattern(args[1]) == "":
        characters = f'list_transform(range(length({value})), lambda "_i": substr({value}, "_i" + 1, 1))'
        return null_if_any_null(g, args, f"list_concat([''], {characters}, [''])")
    split = null_if_any_null(g, args, f"regexp_split_to_array({value}, {pattern})")
    if isinstance(args[1], exp.Literal):
        return split
    message = tf.string("unsupported in lakegate: regexp_split with a pattern that can match the empty string")
    return f"CASE WHEN regexp_full_match('', {pattern}) THEN {g.fail(message, 'NOT_SUPPORTED')} ELSE {split} END"


# === regular expressions (io.trino.operator.scalar.JoniRegexpFunctions) =========================
def _regexp_position(call: Call) -> TType:
    regexp_call(call, tt.INTEGER, (2, 3, 4), "string", "string", "integer", "integer")
    if "\\G" in (literal_str(call, 1) or ""):
        call.fail("regexp_position with \\G is not supported in lakegate", "NOT_SUPPORTED")
    return tt.INTEGER


def _search(text: str, pattern: str, start: str) -> str:
    """[begin, next start] of the leftmost match at or after code point `start` ([-1, -1] if none):
    the match begins after the shortest prefix the pattern can follow. From a start past 1 the
    character before it is kept, unmatched, so that \\b and ^ see the text around the start as
    Joni's search from an offset does; the next search starts after the match, or one character on
    after an empty match (JoniRegexpFunctions.getNextStart)."""
    rest = f"substr({text}, greatest({start} - 1, 1))"
    before = f"CASE WHEN {start} > 1 THEN '(?s:.)' ELSE '' END"
    anchored = f"'^' || {before} || '((?s:.*?))(' || {pattern} || ')'"
    begin = f"{start} + length(regexp_extract({rest}, {anchored}, 1))"
    found = f"[{begin}, {begin} + greatest(length(regexp_extract({rest}, {anchored}, 2)), 1)]"
    return f"CASE WHEN regexp_matches({rest}, {anchored}) THEN {found} ELSE [-1, -1] END"


def _render_regexp_position(g, node, args) -> str:
    """JoniRegexpFunctions.regexpPosition: the code point position of the occurrence-th match
    searching from `start`, each search resuming where the last match ended; -1 when there is none."""
    text, pattern = sqls(g, args[:2])
    start = f"CAST({g.sql(args[2])} AS BIGINT)" if len(args) >= 3 else "1"
    occurrence = f"CAST({g.sql(args[3])} AS BIGINT)" if len(args) == 4 else "1"
    resume = '"_at"[2]'
    step = f'lambda "_at", "_n": CASE WHEN "_at"[1] < 0 THEN "_at" ELSE {_search(text, pattern, resume)} END'
    # each match takes at least one step forward, so more occurrences than length + 1 cannot exist
    position = f"list_reduce(range({occurrence}), {step}, [0, {start}])[1]"
    checks = [
        (f"{start} < 1", "start position cannot be smaller than 1"),
        (f"{occurrence} < 1", "occurrence cannot be smaller than 1"),
    ]
    whens = " ".join(f"WHEN {c} THEN {g.fail(tf.string(m))}" for c, m in checks)
    nulls = " OR ".join(f"({g.sql(a)}) IS NULL" for a in args)
    return (
        f"CASE WHEN {nulls} THEN NULL {whens} WHEN {start} > length({text}) OR {occurrence} > length({text}) + 1 "
        f"THEN -1 ELSE CAST({position} AS INTEGER) END"
    )


# --- regexp_replace(string, pattern, function) (JoniRegexpReplaceLambdaFunction) ----------------
def _regexp_replace_lambda(call: Call) -> TType | None:
    """The lambda gets each match's capturing groups as array(varchar). Patterns that can match the
    empty string (Joni then steps one code point on) or have a group that may not take part (Joni
    passes NULL, DuckDB '') are refused."""
    if len(call.args) != 3 or not isinstance(call.args[2], exp.Lambda):
        return None
    call.types[2] = call.lam(2, [tt.array(tt.VARCHAR)])  # the lambda's result stands for it in the checks
    regexp_call(call, tt.VARCHAR, (3,), "string", "string", "string")
    pattern = literal_str(call, 1)
    if pattern is None:
        call.fail("regexp_replace with a lambda needs a literal pattern in lakegate", "NOT_SUPPORTED")
    try:
        empty = re_parser.parse(pattern).getwidth()[0] == 0
    except re.error:
        call.fail(
            f"regexp_replace with a lambda and the pattern '{pattern}' is not supported in lakegate", "NOT_SUPPORTED"
        )
    groups = capturing_groups(pattern)
    if empty or any(optional for _, optional, _ in groups):
        reason = "may match the empty string" if empty else "has a capturing group that may not take part in a match"
        call.fail(f"regexp_replace with a lambda whose pattern {reason} is not supported in lakegate", "NOT_SUPPORTED")
    call.node.meta["group_count"] = len(groups)
    return tt.VARCHAR


def _render_regexp_replace_lambda(g, node, args) -> str:
    """The text between the matches (string_split_regex), each match's groups (regexp_extract_all)
    through the lambda in between; a NULL replacement makes the result NULL."""
    value, pattern = g.sql(args[0]), g.sql(args[1])
    groups = ", ".join(
        f'regexp_extract_all({value}, {pattern}, {k})["_i"]' for k in range(1, node.meta["group_count"] + 1)
    )
    matches = f"len(regexp_extract_all({value}, {pattern}))"
    arrays = f'list_transform(range(1, {matches} + 1), lambda "_i": CAST([{groups}] AS VARCHAR[]))'
    pieces = f"string_split_regex({value}, {pattern})"
    between = f'list_transform(range(1, len("_r") + 1), lambda "_j": "_r"["_j"] || {pieces}["_j" + 1])'
    joined = (
        f'CASE WHEN len(list_filter("_r", lambda "_x": "_x" IS NULL)) > 0 THEN NULL '
        f"ELSE {pieces}[1] || array_to_string({between}, '') END"
    )
    replaced = f"list_transform({arrays}, {g.lambda_(args[2])})"
    return f'CASE WHEN ({value}) IS NULL THEN NULL ELSE list_transform([{replaced}], lambda "_r": {joined})[1] END'


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    register(
        "regexp_like",
        "regexp",
        "regexp_like(string, pattern) -> boolean",
        lambda c: regexp_call(c, tt.BOOLEAN, (2,), "string", "string"),
        call_as("regexp_matches"),
        notes="Patterns run on RE2; Java-only constructs (lookaround, backreferences) are rejected.",
    )
    register(
        "regexp_extract",
        "regexp",
        "regexp_extract(string, pattern[, group]) -> varchar",
        _regexp_extract,
        _render_regexp_extract,
        notes="NULL when the pattern does not match or the group takes no part, as in Trino (DuckDB gives ''); "
        "an optional group that can match '' is rejected.",
    )
    register(
        "regexp_extract_all",
        "regexp",
        "regexp_extract_all(string, pattern[, group]) -> array(varchar)",
        _regexp_extract_all,
        _render_regexp_extract_all,
    )
    register(
        "regexp_replace",
        "regexp",
        "regexp_replace(string, pattern[, replacement]) -> varchar",
        _regexp_replace,
        _render_regexp_replace,
        notes="Replaces every match; Java's $1 group references are translated.",
    )

    register(
        "regexp_split",
        "regexp",
        "regexp_split(string, pattern) -> array(varchar)",
        _regexp_split,
        _render_regexp_split,
        notes="The empty pattern splits between characters, with '' at both ends; another pattern that can "
        "match the empty string is refused.",
    )
    register(
        "regexp_count",
        "regexp",
        "regexp_count(string, pattern) -> bigint",
        lambda c: regexp_call(c, tt.BIGINT, (2,), "string", "string"),
        lambda g, node, args: f"CAST(len(regexp_extract_all({g.sql(args[0])}, {g.sql(args[1])})) AS BIGINT)",
    )

    register(
        "regexp_position",
        "regexp",
        "regexp_position(string, pattern[, start[, occurrence]]) -> integer",
        _regexp_position,
        _render_regexp_position,
    )

    overload(
        "regexp_replace",
        _regexp_replace_lambda,
        _render_regexp_replace_lambda,
        "regexp_replace(string, pattern, function(array(varchar), varchar)) -> varchar",
    )
