"""Trend alerts: a metric whose latest build moves beyond its recent history.

For every scalar metric in `metric_results` (test metrics: the mean over the build's jobs; batch
metrics: the mean over the build's batches), its value per build is computed by SQL through the
Engine over the batches looked at; builds are ordered by their first job's `time`. The latest build's
value is compared with the previous `history` builds (at least 2): it is an alert when it lies
outside mean +- k * sample standard deviation of them (with a history that never moved, any
change is outside). The direction is not judged: a metric may be better high or low.
`batch_checks` are the checks of one batch's build, over the batches up to it (`lakegate compare`).
"""

from __future__ import annotations

import html
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from lakegate.dialect.scope import Scope
from lakegate.gateway.metrics.defaults import HISTORY, K
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.flakes import has_results
from lakegate.gateway.metrics.templates import format_number
from lakegate.gateway.metrics.trends import branch_batches

_VALUES_SQL = """
WITH builds AS (
    SELECT batch_id, job_id, build_version, time FROM metadata
),
batch_builds AS (
    SELECT batch_id, MIN(build_version) AS build_version, MIN(time) AS time FROM metadata GROUP BY batch_id
)
SELECT r.metric_name, b.build_version, MIN(b.time) AS started, AVG(r.scalar_value) AS value
FROM metric_results r JOIN builds b ON r.batch_id = b.batch_id AND r.job_id = b.job_id
WHERE r.metric_type = 'test' AND r.scalar_value IS NOT NULL AND b.build_version IS NOT NULL
GROUP BY r.metric_name, b.build_version
UNION ALL
SELECT r.metric_name, b.build_version, MIN(b.time), AVG(r.scalar_value)
FROM metric_results r JOIN batch_builds b ON r.batch_id = b.batch_id
WHERE r.job_id IS NULL AND r.scalar_value IS NOT NULL AND b.build_version IS NOT NULL
GROUP BY r.metric_name, b.build_version
"""


@dataclass(frozen=True)
class TrendCheck:
    """One metric's latest build against its previous builds."""

    metric: str
    build: str
    value: float
    history: tuple[tuple[str, float], ...]  # (build, value) of the earlier builds compared with, oldest first
    k: float

    @property
    def mean(self) -> float:
        return statistics.fmean(v for _, v in self.history)

    @property
    def sd(self) -> float:
        return statistics.stdev(v for _, v in self.history)

    @property
    def alert(self) -> bool:
        return abs(self.value - self.mean) > self.k * self.sd

    def as_dict(self) -> dict[str, Any]:
        return {
            "metric": self.metric,
            "build": self.build,
            "value": self.value,
            "history_builds": [b for b, _ in self.history],
            "mean": self.mean,
            "sd": self.sd,
            "k": self.k,
            "alert": self.alert,
        }

    def __str__(self) -> str:
        return (
            f"{self.metric}: build {self.build} {format_number(self.value)} vs {format_number(self.mean)} +- "
            f"{format_number(self.k)} x {format_number(self.sd)} over builds {', '.join(b for b, _ in self.history)}"
        )


def trend_checks(
    engine: MetricsEngine, branch: str, batches: Sequence[str], *, k: float = K, history: int = HISTORY
) -> list[TrendCheck]:
    """The check of every scalar metric with at least 2 earlier builds in `batches`; alerts first (none
    when no batch of the branch was evaluated)."""
    if not batches or not has_results(engine, branch):
        return []
    series: dict[str, list[tuple[Any, str, float]]] = {}
    for metric, build, started, value in engine.query(_VALUES_SQL, branch, Scope(batches=tuple(batches))).rows():
        series.setdefault(metric, []).append((started, build, float(value)))
    checks = []
    for metric, points in series.items():
        points.sort(key=lambda p: (p[0] is None, p[0], p[1]))
        earlier = points[:-1][-history:]
        if len(earlier) >= 2:
            *_, (_, build, value) = points
            checks.append(TrendCheck(metric, build, value, tuple((b, v) for _, b, v in earlier), k))
    return sorted(checks, key=lambda c: (not c.alert, c.metric))


def batch_checks(
    engine: MetricsEngine, branch: str, batch_id: str, *, k: float = K, history: int = HISTORY
) -> list[TrendCheck]:
    """The trend checks of the build of batch `batch_id`: over the branch's batches up to it in time
    order (none after it), each scalar metric of its build against the `history` builds before; alerts
    first (none when the batch has no jobs)."""
    batches = branch_batches(engine, branch)
    ids = [b.batch_id for b in batches]
    if batch_id not in ids:
        return []
    upto = batches[: ids.index(batch_id) + 1]
    builds = set(upto[-1].builds)
    checks = trend_checks(engine, branch, [b.batch_id for b in upto], k=k, history=history)
    return [c for c in checks if c.build in builds]


def alerts_html(checks: Sequence[TrendCheck]) -> str:
    """The alerts as an HTML list for a page (nothing when no metric moved)."""
    alerts = [c for c in checks if c.alert]
    if not checks:
        return ""
    if not alerts:
        return f'<p class="lg-alerts">Trend alerts: none ({len(checks)} scalar metrics within their history).</p>\n'
    items = "".join(f'<li class="lg-alert">{html.escape(str(c))}</li>' for c in alerts)
    return (
        f'<section class="lg-alerts"><h2>Trend alerts</h2><p>{len(alerts)} of {len(checks)} scalar metrics moved '
        f"beyond k = {format_number(alerts[0].k)} standard deviations of their previous builds:</p>"
        f"<ul>{items}</ul></section>\n"
    )
