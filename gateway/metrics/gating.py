"""CI gating as SignalFlag's CLI does it (`--fail-on-states BLOCKER,ERROR,WARNING`): a batch's status, when it
is one of the states given, becomes a distinct exit code; any other status passes (0)."""

from __future__ import annotations

from collections.abc import Iterable

from lakegate.gateway.metrics.statuses import BLOCKER, ERROR, WARNING

#: SignalFlag's exit codes of `--fail-on-states` (its CLI's batch.go: ERROR 2, BLOCKER 7, WARNING 8).
FAIL_EXIT_CODES = {BLOCKER: 7, ERROR: 2, WARNING: 8}
#: The states `--fail-on-states` takes.
FAIL_STATES = tuple(FAIL_EXIT_CODES)


def parse_fail_on_states(value: str | Iterable[str] | None) -> frozenset[str]:
    """`BLOCKER,WARNING` (or a list of names; any letter case, blanks ignored) as a set of states;
    ValueError naming the valid states for any other name."""
    if value is None:
        return frozenset()
    parts = value.split(",") if isinstance(value, str) else [p for item in value for p in str(item).split(",")]
    states = set()
    for part in parts:
        state = part.strip().upper()
        if not state:
            continue
        if state not in FAIL_EXIT_CODES:
            raise ValueError(
                f"unsupported fail-on-states value: {part.strip()!r}; valid states are {', '.join(FAIL_STATES)}"
            )
        states.add(state)
    return frozenset(states)


def fail_exit_code(status: str, fail_on: frozenset[str]) -> int:
    """The exit code of a batch of `status` under `--fail-on-states` `fail_on`: 7 BLOCKER, 2 ERROR, 8 WARNING
    when the status is in `fail_on`, else 0."""
    return FAIL_EXIT_CODES[status] if status in fail_on else 0
