"""Build comparison: what changed between two batches of a branch, and which changes are real.

The jobs of the base and the new batch are paired by experience (its `experience_name`, else its
`experience_id`); repeated runs of one experience in a batch are one group. Everything but the
statistical tests is computed by SQL through the Engine, over the `metadata` and `metric_results`
tables, so it answers alike on the embedded engine and on a Trino backend:

* a group's status is the worst of its runs (PASSED < WARNING < BLOCKER < ERROR; NOT_RUN counts for
  nothing); its scalar value is the mean over its runs;
* tags, per experience (job statuses) and per metric: **new failure** (PASSED on the base, WARNING,
  BLOCKER or ERROR now), **fixed** (the other way round), **still failing** (failing on both),
  **same** (passing on both, or not decided), **new** / **gone** (the experience or the metric is only
  in the new / only in the base batch). A new failure on an experience known to be flaky
  (`flakes.py`, over the last `flake_window` batches of the branch up to the new one) is tagged
  **flaky** instead;
* scalars: base, new, absolute change (new - base) and relative change (over |base|; NULL for a base
  of 0);
* series metrics (line, bar, histogram, state timeline): the values of the base and the new runs
  are compared with a two-sample test from SciPy: for line and bar charts the y values of every
  trace, for histograms the sampled values, with the Kolmogorov-Smirnov test (`ks_2samp`); for state
  timelines the number of segments of each state, with the chi-square test of homogeneity
  (`chi2_contingency`) (one state only, on both sides: p = 1). A change is significant when p <
  `alpha`;
* batch metrics (job_id NULL): base, new, change, and their status tags.

Severity order (terminal table, page): new failure, flaky, still failing, gone, new, fixed, same;
within a tag, significant series changes first, then by the size of the relative change.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import orjson

from lakegate.dialect.scope import Scope
from lakegate.gateway.metrics.defaults import ALPHA, FLAKE_WINDOW
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.flakes import Flake, find_flakes, flaky_experiences, has_results
from lakegate.gateway.metrics.plotly_arrays import plain
from lakegate.gateway.metrics.trends import branch_batches
from lakegate.lake.template_kinds import kinds_where, series

NEW_FAILURE, FLAKY, STILL_FAILING, GONE, NEW, FIXED, SAME = (
    "new failure",
    "flaky",
    "still failing",
    "gone",
    "new",
    "fixed",
    "same",
)
#: Tags from the most to the least severe.
TAGS = (NEW_FAILURE, FLAKY, STILL_FAILING, GONE, NEW, FIXED, SAME)
#: Templates whose values are compared with a two-sample test.
SERIES_TEMPLATES = kinds_where("series")

#: The worst status of a group, as a rank (0 NOT_RUN or NULL .. 4 ERROR), in SQL.
_RANK = "MAX(CASE {c} WHEN 'PASSED' THEN 1 WHEN 'WARNING' THEN 2 WHEN 'BLOCKER' THEN 3 WHEN 'ERROR' THEN 4 ELSE 0 END)"
_STATUS_OF_RANK = (
    "CASE {r} WHEN 1 THEN 'PASSED' WHEN 2 THEN 'WARNING' WHEN 3 THEN 'BLOCKER' WHEN 4 THEN 'ERROR' ELSE 'NOT_RUN' END"
)
#: The tag of a pair of groups, from their worst-status ranks (NULL: the group is missing), in SQL.
_TAG = """CASE
    WHEN b.rnk IS NULL THEN 'new'
    WHEN n.rnk IS NULL THEN 'gone'
    WHEN b.rnk = 1 AND n.rnk >= 2 THEN 'new failure'
    WHEN b.rnk >= 2 AND n.rnk = 1 THEN 'fixed'
    WHEN b.rnk >= 2 AND n.rnk >= 2 THEN 'still failing'
    ELSE 'same' END"""
_CHANGE = """n.value - b.value AS change,
    CASE WHEN b.value <> 0 THEN (n.value - b.value) / abs(b.value) END AS relative_change"""

#: Per experience: job runs, worst conflated status, on each side.
_JOBS_SQL = f"""
WITH side AS (
    SELECT batch_id, COALESCE(experience_name, experience_id) AS experience, COUNT(*) AS runs,
           {_RANK.format(c="job_conflated_status")} AS rnk
    FROM metadata GROUP BY 1, 2
)
SELECT COALESCE(b.experience, n.experience) AS experience,
       {_STATUS_OF_RANK.format(r="b.rnk")} AS base_status, {_STATUS_OF_RANK.format(r="n.rnk")} AS new_status,
       b.runs, n.runs, {_TAG} AS tag
FROM (SELECT * FROM side WHERE batch_id = ?) b
FULL OUTER JOIN (SELECT * FROM side WHERE batch_id = ?) n ON b.experience = n.experience
"""

#: Per experience and test metric, or per batch metric (experience NULL): status, mean scalar, tag.
_METRICS_SQL = f"""
WITH runs AS (
    SELECT r.batch_id, COALESCE(m.experience_name, m.experience_id) AS experience, r.metric_name,
           r.metric_type, r.template, r.units, r.status, r.scalar_value
    FROM metric_results r JOIN metadata m ON r.batch_id = m.batch_id AND r.job_id = m.job_id
    WHERE r.metric_type = 'test'
    UNION ALL
    SELECT batch_id, NULL, metric_name, metric_type, template, units, status, scalar_value
    FROM metric_results WHERE job_id IS NULL
),
side AS (
    SELECT batch_id, experience, metric_name, metric_type, MAX(template) AS template, MAX(units) AS units,
           COUNT(*) AS runs, {_RANK.format(c="status")} AS rnk, AVG(scalar_value) AS value
    FROM runs GROUP BY batch_id, experience, metric_name, metric_type
)
SELECT COALESCE(b.experience, n.experience) AS experience, COALESCE(b.metric_name, n.metric_name) AS metric,
       COALESCE(b.metric_type, n.metric_type) AS metric_type, COALESCE(n.template, b.template) AS template,
       COALESCE(n.units, b.units) AS units,
       {_STATUS_OF_RANK.format(r="b.rnk")} AS base_status, {_STATUS_OF_RANK.format(r="n.rnk")} AS new_status,
       b.runs, n.runs, b.value, n.value, {_CHANGE}, {_TAG} AS tag
FROM (SELECT * FROM side WHERE batch_id = ?) b
FULL OUTER JOIN (SELECT * FROM side WHERE batch_id = ?) n
  ON b.metric_name = n.metric_name AND b.metric_type = n.metric_type
 AND (b.experience = n.experience OR (b.experience IS NULL AND n.experience IS NULL))
"""

#: The figures of the series metrics of both batches, one row per job and metric.
_FIGURES_SQL = f"""
SELECT r.batch_id, COALESCE(m.experience_name, m.experience_id) AS experience, r.metric_name, r.template,
       r.figure_json
FROM metric_results r JOIN metadata m ON r.batch_id = m.batch_id AND r.job_id = m.job_id
WHERE r.metric_type = 'test' AND r.figure_json IS NOT NULL
  AND r.template IN ({", ".join(f"'{t}'" for t in SERIES_TEMPLATES)})
"""


@dataclass
class SeriesTest:
    """A two-sample test of a series metric's values: which test, its statistic and p-value."""

    test: str
    statistic: float
    p_value: float
    base_count: int
    new_count: int

    def as_dict(self) -> dict[str, Any]:
        return {
            "test": self.test,
            "statistic": self.statistic,
            "p_value": self.p_value,
            "base_count": self.base_count,
            "new_count": self.new_count,
        }


@dataclass
class MetricChange:
    """One metric of one experience (`experience` None: a batch metric) on both sides."""

    experience: str | None
    metric: str
    metric_type: str
    template: str | None
    units: str | None
    base_status: str | None
    new_status: str | None
    base_runs: int | None
    new_runs: int | None
    base_value: float | None
    new_value: float | None
    change: float | None
    relative_change: float | None
    tag: str
    series: SeriesTest | None = None
    significant: bool = False
    #: The series values of each side (kept for the page's figures, not in the JSON).
    base_values: Any = None
    new_values: Any = None

    @property
    def changed(self) -> bool:
        """Anything to look at: a status tag other than `same`, a significant test, or a scalar that moved."""
        return self.tag != SAME or self.significant or bool(self.change)

    def as_dict(self) -> dict[str, Any]:
        return {
            "experience": self.experience,
            "metric": self.metric,
            "type": self.metric_type,
            "template": self.template,
            "units": self.units,
            "tag": self.tag,
            "base_status": self.base_status,
            "new_status": self.new_status,
            "base_runs": self.base_runs,
            "new_runs": self.new_runs,
            "base_value": self.base_value,
            "new_value": self.new_value,
            "change": self.change,
            "relative_change": self.relative_change,
            "series_test": None if self.series is None else self.series.as_dict(),
            "significant": self.significant,
        }


@dataclass
class JobChange:
    """One experience's jobs on both sides: runs and worst conflated status."""

    experience: str | None
    base_status: str | None
    new_status: str | None
    base_runs: int | None
    new_runs: int | None
    tag: str

    def as_dict(self) -> dict[str, Any]:
        return {
            "experience": self.experience,
            "tag": self.tag,
            "base_status": self.base_status,
            "new_status": self.new_status,
            "base_runs": self.base_runs,
            "new_runs": self.new_runs,
        }


@dataclass
class Comparison:
    """The comparison of batch `new` with batch `base` of a branch."""

    branch: str
    base: str
    new: str
    base_builds: tuple[str, ...]
    new_builds: tuple[str, ...]
    jobs: list[JobChange]
    metrics: list[MetricChange]
    flakes: list[Flake]
    alpha: float
    flake_window: int
    seconds: float = 0.0
    flaky: set[str] = field(default_factory=set)

    def counts(self) -> dict[str, int]:
        """Experiences per tag (of their job statuses), every tag listed."""
        found = dict.fromkeys(TAGS, 0)
        for job in self.jobs:
            found[job.tag] += 1
        return found

    def metric_counts(self) -> dict[str, int]:
        """Metrics per tag, every tag listed, plus how many series changed significantly."""
        found = dict.fromkeys(TAGS, 0)
        for metric in self.metrics:
            found[metric.tag] += 1
        return {**found, "significant": sum(1 for m in self.metrics if m.significant)}

    def new_failures(self, *, strict: bool = False) -> list[JobChange]:
        """Experiences whose jobs passed on the base and fail now (flaky ones too when `strict`)."""
        tags = (NEW_FAILURE, FLAKY) if strict else (NEW_FAILURE,)
        return [job for job in self.jobs if job.tag in tags]

    def as_dict(self) -> dict[str, Any]:
        return {
            "branch": self.branch,
            "base": {"batch_id": self.base, "build_versions": list(self.base_builds)},
            "new": {"batch_id": self.new, "build_versions": list(self.new_builds)},
            "alpha": self.alpha,
            "flake_window": self.flake_window,
            "counts": {"experiences": self.counts(), "metrics": self.metric_counts()},
            "experiences": [job.as_dict() for job in self.jobs],
            "metrics": [metric.as_dict() for metric in self.metrics],
            "flaky_experiences": sorted(self.flaky),
            "seconds": self.seconds,
        }


def _order(tag: str, significant: bool, relative: float | None, *names: Any) -> tuple:
    size = abs(relative) if relative is not None and math.isfinite(relative) else 0.0
    return (TAGS.index(tag), not significant, -size, *(("" if n is None else str(n)) for n in names))


def series_values(template: str, figure: dict) -> list:
    """The values a series metric's figure compares: y of line and bar traces, x of histograms, and for
    state timelines one state name per segment."""
    values: list = []
    compared = series(template)
    for trace in figure.get("data", []):
        if compared == "states":
            values += [trace.get("name")] * len(plain(trace.get("y", [])))
        else:
            key = "x" if compared == "x" else "y"
            values += [v for v in plain(trace.get(key, [])) if isinstance(v, (int, float)) and not isinstance(v, bool)]
    return values


def two_sample_test(template: str, base: Sequence, new: Sequence) -> SeriesTest | None:
    """The two-sample test of a series metric's values (None when a side has no values)."""
    from scipy import stats  # here: importing SciPy takes a while, and only comparisons need it

    if not base or not new:
        return None
    if series(template) == "states":
        states = sorted({*base, *new}, key=str)
        if len(states) < 2:
            return SeriesTest("chi-square", 0.0, 1.0, len(base), len(new))
        table = [[list(side).count(s) for s in states] for side in (base, new)]
        answer = stats.chi2_contingency(table)
        return SeriesTest("chi-square", float(answer.statistic), float(answer.pvalue), len(base), len(new))
    answer = stats.ks_2samp(base, new)
    return SeriesTest("Kolmogorov-Smirnov", float(answer.statistic), float(answer.pvalue), len(base), len(new))


def _series(engine: MetricsEngine, branch: str, scope: Scope, base: str, new: str) -> dict[tuple, tuple[list, list]]:
    """(experience, metric) -> (base values, new values) of every series metric, over each side's runs."""
    found: dict[tuple, tuple[list, list]] = {}
    for batch_id, experience, metric, template, figure in engine.query(_FIGURES_SQL, branch, scope).rows():
        sides = found.setdefault((experience, metric), ([], []))
        sides[0 if batch_id == base else 1].extend(series_values(template, orjson.loads(figure)))
    return found


def latest_batch_of_build(engine: MetricsEngine, branch: str, build: str) -> str:
    """The latest batch (by time) whose jobs ran build `build`; LookupError naming the builds known."""
    batches = branch_batches(engine, branch)
    found = [b.batch_id for b in batches if build in b.builds]
    if not found:
        known = sorted({v for b in batches for v in b.builds})
        raise LookupError(f"no batch of build {build!r} on branch {branch!r} (builds: {', '.join(known) or 'none'})")
    return found[-1]


def previous_build_batch(engine: MetricsEngine, branch: str, batch: str) -> str:
    """The base a batch is compared with by default: the latest earlier batch (by time) of another build,
    else the batch just before it; LookupError when it is unknown or the branch's first batch."""
    known = branch_batches(engine, branch)
    ids = [b.batch_id for b in known]
    if batch not in ids:
        raise LookupError(f"no batch {batch!r} on branch {branch!r} (batches: {', '.join(ids) or 'none'})")
    earlier = known[: ids.index(batch)]
    if not earlier:
        raise LookupError(f"batch {batch!r} is the first batch of branch {branch!r}: there is nothing to compare with")
    builds = known[ids.index(batch)].builds
    other = [b.batch_id for b in earlier if b.builds != builds]
    return other[-1] if other else earlier[-1].batch_id


def compare_batches(
    engine: MetricsEngine,
    branch: str,
    base: str,
    new: str,
    *,
    alpha: float = ALPHA,
    flake_window: int = FLAKE_WINDOW,
    cv_threshold: float | None = None,
) -> Comparison:
    """Compare batch `new` with batch `base` of `branch` (LookupError naming the batches if one is unknown)."""
    started = time.perf_counter()
    ordered = branch_batches(engine, branch)
    known = [b.batch_id for b in ordered]
    for batch in (base, new):
        if batch not in known:
            raise LookupError(f"no batch {batch!r} on branch {branch!r} (batches: {', '.join(known) or 'none'})")
    if not has_results(engine, branch):
        raise LookupError(f"no batch of branch {branch!r} was evaluated: run 'lakegate metrics run' on both batches")
    builds = {b.batch_id: b.builds for b in ordered}
    scope = Scope(batches=(base, new))
    params = (base, new)
    jobs = [
        JobChange(experience, base_status if b_runs else None, new_status if n_runs else None, b_runs, n_runs, tag)
        for experience, base_status, new_status, b_runs, n_runs, tag in engine.query(
            _JOBS_SQL, branch, scope, params
        ).rows()
    ]
    window = known[max(0, known.index(new) + 1 - flake_window) : known.index(new) + 1]
    flake_args = {} if cv_threshold is None else {"cv_threshold": cv_threshold}
    flakes = find_flakes(engine, branch, window, **flake_args)
    flaky = flaky_experiences(flakes)
    for job in jobs:
        if job.tag == NEW_FAILURE and job.experience in flaky:
            job.tag = FLAKY
    series = _series(engine, branch, scope, base, new)
    metrics = []
    for row in engine.query(_METRICS_SQL, branch, scope, params).rows():
        (experience, metric, kind, template, units, base_status, new_status, b_runs, n_runs) = row[:9]
        change = MetricChange(
            experience,
            metric,
            kind,
            template,
            units,
            base_status if b_runs else None,
            new_status if n_runs else None,
            b_runs,
            n_runs,
            *row[9:],
        )
        if change.tag == NEW_FAILURE and experience in flaky:
            change.tag = FLAKY
        if template in SERIES_TEMPLATES and (experience, metric) in series:
            change.base_values, change.new_values = series[(experience, metric)]
            change.series = two_sample_test(template, change.base_values, change.new_values)
            change.significant = change.series is not None and change.series.p_value < alpha
        metrics.append(change)
    jobs.sort(key=lambda j: _order(j.tag, False, None, j.experience))
    metrics.sort(key=lambda m: _order(m.tag, m.significant, m.relative_change, m.experience, m.metric))
    return Comparison(
        branch,
        base,
        new,
        builds.get(base, ()),
        builds.get(new, ()),
        jobs,
        metrics,
        flakes,
        alpha,
        flake_window,
        seconds=time.perf_counter() - started,
        flaky=flaky,
    )
