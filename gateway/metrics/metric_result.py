"""One metric's result and, when it failed or was skipped, why: what the engine produces and the
results table, the report and the dashboard read."""

from __future__ import annotations

from dataclasses import dataclass
from decimal import Decimal
from typing import Any

import numpy as np

from lakegate.gateway.metrics.templates import Rendered, json_value
from lakegate.lake.config import Location


@dataclass(frozen=True)
class MetricError:
    """Why a metric errored (or was not run): the message and, for query errors, where.

    `line`/`column` are 1-based in the query text; `location` is the same place in the
    config file when it maps exactly. `query` says which query failed: "query" or "status query".
    """

    message: str
    line: int | None = None
    column: int | None = None
    location: Location | None = None
    query: str | None = None

    def __str__(self) -> str:
        what = f"{self.query}: " if self.query else ""
        if self.location is not None:
            return f"{self.location}: {what}{self.message}"
        if self.line is not None and self.column is not None:
            return f"{what}line {self.line}:{self.column}: {self.message}"
        return f"{what}{self.message}"

    def as_dict(self) -> dict[str, Any]:
        return {
            "message": self.message,
            "query": self.query,
            "line": self.line,
            "column": self.column,
            "location": None if self.location is None else str(self.location),
        }


@dataclass
class MetricResult:
    """One metric evaluated on one job (test metrics) or on the whole batch (job_id None)."""

    metric: str
    metric_type: str
    template: str | None
    batch_id: str
    job_id: str | None
    status: str
    rendered: Rendered | None = None
    error: MetricError | None = None
    units: str | None = None
    description: str = ""
    seconds: float = 0.0

    @property
    def scalar_value(self) -> float | None:
        """A scalar template's numeric value as a double (None for anything else)."""
        if self.rendered is None or self.rendered.template != "scalar":
            return None
        value = self.rendered.scalar
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, Decimal, np.number)):
            return None
        return float(value)

    @property
    def value_text(self) -> str | None:
        """The rendered value in words, e.g. "42.98 s" or "2 series, 300 points"."""
        return None if self.rendered is None else self.rendered.text

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: batch, job, metric, type, template, status, scalar value, value, error."""
        scalar = self.scalar_value
        return {
            "batch_id": self.batch_id,
            "job_id": self.job_id,
            "metric": self.metric,
            "type": self.metric_type,
            "template": self.template,
            "status": self.status,
            "scalar_value": None if scalar is None else json_value(scalar),
            "value": self.value_text,
            "units": self.units,
            "problems": list(self.rendered.problems) if self.rendered else [],
            "error": None if self.error is None else self.error.as_dict(),
        }
