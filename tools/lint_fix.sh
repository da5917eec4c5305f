#!/usr/bin/env bash
# Bring the whole tree to the ruff settings of pyproject.toml, once, after the branches are merged:
# `ruff format`, then ruff's safe fixes, then list what is left for a person (see below).
# Run from anywhere: bash tools/lint_fix.sh   (needs .venv: python3 dev.py lint creates it)
set -euo pipefail
cd "$(dirname "$0")/.."
RUFF=.venv/bin/ruff
[ -x "$RUFF" ] || { echo "no $RUFF: run 'python3 dev.py lint' first" >&2; exit 1; }

"$RUFF" format .
"$RUFF" check --fix . || true

# What ruff cannot fix by itself (found on main at c7b45d6 after the two steps above); fix by hand:
#   E501 line-too-long (~24): long string literals and comments ruff format does not split; split the
#        string (implicit concatenation) or shorten the comment.
#   UP031 printf-string-formatting (11: bench/ingest.py, tests/lake/test_ingest.py): use f-strings.
#   B023 function-uses-loop-variable (10: bench/server.py, bench/translate.py, dialect/functions.py,
#        gateway/engine/backend.py): closures called inside the loop; bind the variable as a default
#        argument (lambda match, pad=pad: ...) or hoist a small named function.
#   B904 raise-without-from-inside-except (3: bench/server.py, gateway/engine/backend.py,
#        gateway/server/system_tables.py): add `from None` (or `from error`).
#   B007 unused-loop-control-variable (3: tests/gateway/conftest.py, tests/lake/test_emitter.py,
#        tests/lake/test_ingest.py): rename to `_name` or drop the enumerate.
#   E741 ambiguous-variable-name (3: tests/gateway/test_ingest_command.py, `l`): rename to `line`.
#   E731 lambda-assignment (1: gateway/engine/backend.py): a small def.
echo
echo "left for a person (see the notes in tools/lint_fix.sh):"
"$RUFF" check --output-format concise . && echo "nothing: python3 dev.py lint is clean"
