"""Flaky experiences: experiences whose status or metric values vary across runs of one build.

Runs of one experience on one build are its jobs with the same `build_version` and experience (its
`experience_name`, else its `experience_id`) in the batches looked at: repeated jobs of one batch,
or jobs of several batches of that build. Both scores are computed by SQL through the Engine (so
they answer alike on the embedded engine and on a Trino backend), over `metadata` and
`metric_results`:

* status flip rate: of the runs in time order (then batch, job), the share of consecutive pairs
  whose `job_conflated_status` differs (jobs never evaluated are left out): 0 when every run had
  the same status, 1 when each run differs from the one before;
* coefficient of variation of each scalar test metric over the runs (sample standard deviation
  over the absolute mean; NULL below two values or for a mean of 0); the largest one is reported
  with its metric.

An experience is flaky when its status flipped at least once (flip rate > 0) or one of its scalars
varies by more than the CV threshold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from lakegate.dialect.scope import Scope
from lakegate.gateway.metrics.defaults import CV_THRESHOLD
from lakegate.gateway.metrics.evaluation import MetricsEngine

#: Runs per (build, experience), their status flips, distinct statuses, and the statuses seen.
_STATUS_SQL = """
WITH runs AS (
    SELECT build_version AS build, COALESCE(experience_name, experience_id) AS experience,
           job_conflated_status AS status,
           LAG(job_conflated_status) OVER (
               PARTITION BY build_version, COALESCE(experience_name, experience_id)
               ORDER BY time, batch_id, job_id) AS previous
    FROM metadata
    WHERE job_conflated_status IS NOT NULL
)
SELECT build, experience, COUNT(*) AS runs,
       SUM(CASE WHEN previous IS NOT NULL AND previous <> status THEN 1 ELSE 0 END) AS flips,
       array_join(array_sort(array_agg(DISTINCT status)), ',') AS statuses
FROM runs
GROUP BY build, experience
"""

#: The coefficient of variation of each scalar test metric per (build, experience), over 2+ values.
_CV_SQL = """
SELECT m.build_version AS build, COALESCE(m.experience_name, m.experience_id) AS experience,
       r.metric_name, COUNT(r.scalar_value) AS n, AVG(r.scalar_value) AS mean,
       STDDEV_SAMP(r.scalar_value) AS sd
FROM metric_results r JOIN metadata m ON r.batch_id = m.batch_id AND r.job_id = m.job_id
WHERE r.metric_type = 'test' AND r.scalar_value IS NOT NULL
GROUP BY 1, 2, 3
HAVING COUNT(r.scalar_value) >= 2
"""


@dataclass(frozen=True)
class Flake:
    """One experience on one build over the batches looked at, and how much it varies."""

    build: str | None
    experience: str | None
    runs: int
    flips: int
    statuses: tuple[str, ...]
    #: The largest coefficient of variation of its scalars, and that metric (None: no scalar ran twice).
    cv: float | None
    cv_metric: str | None
    cv_threshold: float

    @property
    def flip_rate(self) -> float:
        """Status changes per consecutive pair of runs (0 for a single run)."""
        return self.flips / (self.runs - 1) if self.runs > 1 else 0.0

    @property
    def flaky(self) -> bool:
        return self.flips > 0 or (self.cv is not None and self.cv > self.cv_threshold)

    def as_dict(self) -> dict[str, Any]:
        return {
            "build": self.build,
            "experience": self.experience,
            "runs": self.runs,
            "status_flips": self.flips,
            "flip_rate": self.flip_rate,
            "statuses": list(self.statuses),
            "max_cv": self.cv,
            "max_cv_metric": self.cv_metric,
            "flaky": self.flaky,
        }


def has_results(engine: MetricsEngine, branch: str) -> bool:
    """Whether the branch has a `metric_results` table (some batch of it was evaluated)."""
    return bool(engine.query("SHOW TABLES LIKE 'metric_results'", branch, None).rows())


def find_flakes(
    engine: MetricsEngine, branch: str, batches: Sequence[str], *, cv_threshold: float = CV_THRESHOLD
) -> list[Flake]:
    """Every (build, experience) with runs in `batches`, flakiest first (flip rate, then CV)."""
    if not batches:
        return []
    scope = Scope(batches=tuple(batches))
    worst_cv: dict[tuple[Any, Any], tuple[float, str]] = {}
    cv_rows = engine.query(_CV_SQL, branch, scope).rows() if has_results(engine, branch) else []
    for build, experience, metric, _, mean, sd in cv_rows:
        if sd is None or not mean:
            continue
        cv = float(sd) / abs(float(mean))
        key = (build, experience)
        if key not in worst_cv or cv > worst_cv[key][0]:
            worst_cv[key] = (cv, metric)
    found = []
    for build, experience, runs, flips, statuses in engine.query(_STATUS_SQL, branch, scope).rows():
        cv, metric = worst_cv.get((build, experience), (None, None))
        found.append(
            Flake(build, experience, int(runs), int(flips or 0), tuple(statuses.split(",")), cv, metric, cv_threshold)
        )
    return sorted(found, key=lambda f: (-f.flip_rate, -(f.cv or 0.0), str(f.build), str(f.experience)))


def flaky_experiences(flakes: Sequence[Flake]) -> set[str]:
    """The experiences flaky on some build."""
    return {f.experience for f in flakes if f.flaky and f.experience is not None}
