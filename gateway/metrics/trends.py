"""Dashboard and report metrics: metrics over many batches of a branch, and their trends page.

* A `type: dashboard` metric runs once over every batch of the branch, or over a `Window` of
  them: the batches whose time is within the last N days (`30d`), or the last N batches (`10`).
  A batch's time is the earliest `time` of its jobs' `metadata` rows (when it started); batches
  are ordered by it, then by id.
* A `type: report` metric runs once over a list of batches given by name.

Either way the metric's queries (its status check included) run in `Scope(batches=...)`
(dialect/scope.py): every lake table, `metadata` and `metric_results` included, shows every job of
those batches and nothing else, so `JOIN metadata m ON t.batch_id = m.batch_id AND t.job_id =
m.job_id ... GROUP BY m.build_version` shows a trend from build to build. Nothing is written to
the lake.

The trends page (`trends_html`) is one offline page: the batches evaluated, then every metric
drawn by its template. In a table, a `link_path` column's values become links to that batch's
page of the dashboard (`B`, or `B/J` for one job of it: `/dashboard/?branch=..&batch=B&job=J`).
"""

from __future__ import annotations

import datetime as dt
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlencode

from lakegate.dialect.scope import Scope
from lakegate.gateway.metrics.evaluation import MetricResult, MetricsEngine, worst
from lakegate.gateway.metrics.figures_html import report_html
from lakegate.gateway.metrics.report import Item, metric_item
from lakegate.gateway.metrics.templates import render
from lakegate.lake.config import Config, Metric


@dataclass(frozen=True)
class Window:
    """Which batches of a branch a dashboard shows: those of the last `days` days, or the last `count`."""

    days: int | None = None
    count: int | None = None

    @classmethod
    def parse(cls, text: str) -> Window:
        """`30d` (the last 30 days) or `10` (the last 10 batches); ValueError otherwise."""
        found = re.fullmatch(r"\s*([0-9]+)\s*(d?)\s*", text)
        if found is None or int(found[1]) < 1:
            raise ValueError(
                f"expected a window like '30d' (the last 30 days) or '10' (the last 10 batches), got {text!r}"
            )
        return cls(days=int(found[1])) if found[2] else cls(count=int(found[1]))

    def __str__(self) -> str:
        return f"last {self.days} days" if self.days is not None else f"last {self.count} batches"


@dataclass(frozen=True)
class BatchInfo:
    """One batch of a branch: its time (the earliest of its jobs'), jobs and build versions."""

    batch_id: str
    time: dt.datetime | None
    jobs: int
    builds: tuple[str, ...]


def branch_batches(engine: MetricsEngine, branch: str) -> list[BatchInfo]:
    """Every batch of a branch that has jobs, by time, then id."""
    answer = engine.query("SELECT batch_id, time, build_version FROM metadata", branch, None)
    jobs: dict[str, list[tuple[dt.datetime | None, str | None]]] = {}
    for batch_id, started, build in answer.rows():
        jobs.setdefault(batch_id, []).append((started, build))
    found = [
        BatchInfo(
            batch_id,
            min((t for t, _ in rows if t is not None), default=None),
            len(rows),
            tuple(sorted({b for _, b in rows if b is not None})),
        )
        for batch_id, rows in jobs.items()
    ]
    return sorted(found, key=lambda b: (b.time is None, b.time or dt.datetime.min, b.batch_id))


def in_window(batches: Sequence[BatchInfo], window: Window | None, now: dt.datetime | None = None) -> list[BatchInfo]:
    """The batches of `window` (all of them for None); `batches` in time order, `now` naive UTC."""
    if window is None:
        return list(batches)
    if window.count is not None:
        return list(batches[-window.count :])
    now = now or dt.datetime.now(dt.UTC).replace(tzinfo=None)
    days = min(window.days or 0, (now - dt.datetime.min).days)  # more days than the calendar has: every batch
    since = now - dt.timedelta(days=days)
    return [b for b in batches if b.time is not None and b.time >= since]


def metrics_of(config: Config, kind: str, metrics_set: str | None = None) -> list[Metric]:
    """The `kind` metrics of a metrics set (KeyError naming the known sets if unknown), or of the config."""
    listed = config.metrics_in_set(metrics_set) if metrics_set else config.metrics.values()
    return [metric for metric in listed if metric.type == kind]


@dataclass
class TrendsEvaluation:
    """Dashboard or report metrics evaluated once over some batches of a branch."""

    branch: str
    kind: str  # "dashboard" or "report"
    batches: list[BatchInfo]
    window: Window | None
    results: list[MetricResult]
    config_version: int | None
    seconds: float = 0.0

    @property
    def status(self) -> str:
        """The worst status of the metrics."""
        return worst(r.status for r in self.results)

    @property
    def which_batches(self) -> str:
        """Which batches these are, in words: "every batch", "the last 10 batches", "the batches given"."""
        if self.kind == "report":
            return "the batches given"
        return "every batch" if self.window is None else f"the {self.window}"

    def as_dict(self) -> dict[str, Any]:
        return {
            "branch": self.branch,
            "kind": self.kind,
            "window": None if self.window is None else str(self.window),
            "config_version": self.config_version,
            "status": self.status,
            "batches": [
                {
                    "batch_id": b.batch_id,
                    "time": None if b.time is None else b.time.isoformat() + "Z",
                    "jobs": b.jobs,
                    "build_versions": list(b.builds),
                }
                for b in self.batches
            ],
            "metrics": [_result_dict(r) for r in self.results],
        }


def _result_dict(result: MetricResult) -> dict[str, Any]:
    """A metric's JSON: as in `metrics run` (without batch and job), plus its table or figure."""
    rendered = result.rendered
    found = {k: v for k, v in result.as_dict().items() if k not in ("batch_id", "job_id")}
    return {
        **found,
        "table": None if rendered is None else rendered.table,
        "figure": None if rendered is None else rendered.figure,
    }


def evaluate_trends(
    engine: MetricsEngine,
    branch: str,
    metrics: Sequence[Metric],
    batches: Sequence[BatchInfo],
    *,
    kind: str,
    window: Window | None = None,
    config_version: int | None = None,
) -> TrendsEvaluation:
    """Evaluate each of `metrics` (of type `kind`) once over every job of `batches`."""
    started = time.perf_counter()
    scope = Scope(batches=tuple(b.batch_id for b in batches))
    results = [engine.evaluate(metric, branch, scope) for metric in metrics]
    return TrendsEvaluation(
        branch, kind, list(batches), window, results, config_version, seconds=time.perf_counter() - started
    )


def batch_link(branch: str, value: Any, base: str = "") -> str | None:
    """The dashboard URL of the batch (`B`) or job (`B/J`) a `link_path` value names, under `base`."""
    if value is None or str(value) == "":
        return None
    batch, _, job = str(value).partition("/")
    query = {"branch": branch, "batch": batch, **({"job": job} if job else {})}
    return f"{base.rstrip('/')}/dashboard/?{urlencode(query)}"


def _batches_item(evaluation: TrendsEvaluation) -> Item:
    columns = [(name, "varchar") for name in ("Batch", "Started", "Jobs", "Build versions")]
    rows = [
        (b.batch_id, None if b.time is None else b.time.isoformat(sep=" "), b.jobs, ", ".join(b.builds))
        for b in evaluation.batches
    ]
    info = {"description": f"{len(rows)} batches ({evaluation.which_batches})", "link_columns": ("Batch",)}
    return "Batches", render("Batches", "table", columns, rows), info


def trends_html(
    evaluation: TrendsEvaluation, *, link_base: str = "", plotlyjs: str | bool = True, intro: str = "", nav: str = ""
) -> str:
    """The page of an evaluation: its batches, then every metric; links go to `link_base`'s dashboard
    (`intro`: HTML shown under the title; `nav`: the header bar's links)."""
    kind = "Dashboard" if evaluation.kind == "dashboard" else "Report"
    title = f"{kind} of branch {evaluation.branch}: {evaluation.status}"
    sections = [
        ("Batches", [_batches_item(evaluation)]),
        (f"{kind} metrics", [metric_item(r) for r in evaluation.results]),
    ]
    return report_html(
        title,
        [(name, items) for name, items in sections if items],
        link=lambda value: batch_link(evaluation.branch, value, link_base),
        plotlyjs=plotlyjs,
        intro=intro,
        nav=nav,
    )


def write_trends(evaluation: TrendsEvaluation, path: Path, *, link_base: str = "", intro: str = "") -> Path:
    """Write the page of an evaluation to `path` (folders created, plotly.js embedded; `intro`: HTML
    under the title); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(trends_html(evaluation, link_base=link_base, intro=intro), encoding="utf-8")
    return path
