"""The statuses a metric, job or batch gets, from best to worst; plain names, importable without the engine."""

from __future__ import annotations

PASSED, WARNING, BLOCKER, ERROR, NOT_RUN = "PASSED", "WARNING", "BLOCKER", "ERROR", "NOT_RUN"
NO_DATA = "NO_DATA"
#: Statuses from best to worst; NOT_RUN and NO_DATA are below all and never make anything worse.
SEVERITY = {NOT_RUN: 0, NO_DATA: 0, PASSED: 1, WARNING: 2, BLOCKER: 3, ERROR: 4}
