"""The HTML report of an evaluated batch: one offline page with every metric, job and event.

Sections: an overview of the jobs and their statuses, the batch metrics, then one section per
job with its test metrics and its events (attached scalar and text metrics as a table, images
and Plotly figures drawn). Built from a `BatchEvaluation` with `figures_html.report_html`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from lakegate.gateway.metrics.evaluation import BatchEvaluation, Event, JobOutcome
from lakegate.gateway.metrics.figures_html import report_html
from lakegate.gateway.metrics.metric_result import MetricResult
from lakegate.gateway.metrics.templates import Rendered, TemplateError, render

Item = tuple[str, "Rendered | None", dict[str, Any]]


def short_id(job_id: str) -> str:
    """The first 8 characters of a job id (enough to tell the jobs of a batch apart)."""
    return job_id[:8]


def job_title(job: JobOutcome) -> str:
    """`Warehouse Loop (a05dd957)`, or just the id for a job without an experience name."""
    return f"{job.experience_name} ({short_id(job.job_id)})" if job.experience_name else job.job_id


def metric_item(result: MetricResult) -> Item:
    """A metric's result as the report shows it: (name, rendered, status, description, units, error)."""
    info: dict[str, Any] = {"status": result.status, "description": result.description}
    if result.units and result.template != "scalar":
        info["units"] = result.units
    if result.error is not None:
        info["error"] = str(result.error)
    return result.metric, result.rendered, info


def _overview(evaluation: BatchEvaluation) -> Item:
    columns = [(name, "varchar") for name in ("Job", "Experience", "Job status", "Metrics status", "Conflated status")]
    rows = [
        (job.job_id, job.experience_name, job.job_status, job.metrics_status, job.conflated_status)
        for job in evaluation.jobs
    ]
    info = {
        "description": f"Batch status {evaluation.status} (batch metrics: {evaluation.batch_metrics_status}); "
        f"metrics set {evaluation.metrics_set or '(all metrics)'}, "
        f"config version {evaluation.config_version or '(not stored)'}"
    }
    return "Jobs", render("Jobs", "table", columns, rows), info


def _event_items(event: Event, logs_dir: Path | None) -> list[Item]:
    title = f"{event.name or event.topic} at {event.timestamp / 1e9:.3f} s"
    words = [
        event.description or "",
        f"status {event.status}" if event.status else "",
        f"tags: {', '.join(event.tags)}" if event.tags else "",
    ]
    info: dict[str, Any] = {"description": " · ".join(w for w in words if w)}  # no badge: the summary counts metrics
    texts = [m for m in event.metrics if m.type in ("scalar", "text")]
    table = None
    if texts:
        columns = [(name, "varchar") for name in ("Metric", "Type", "Value", "Status", "Description")]
        rows = [(m.name, m.type, m.value, m.status or "", m.description or "") for m in texts]
        table = render(title, "table", columns, rows)
    items: list[Item] = [(title, table, info)]
    for attached in event.metrics:
        name = f"{title}: {attached.name}"
        extra = {"description": attached.description or "", "contents": False}  # listed with its event
        if attached.type == "image":
            files = attached.value if isinstance(attached.value, list) else [attached.value]
            try:
                items.append(
                    (
                        name,
                        render(name, "image", [("file", "varchar")], [(f,) for f in files], logs_dir=logs_dir),
                        extra,
                    )
                )
            except TemplateError as error:
                items.append((name, None, {**extra, "error": str(error)}))
        elif attached.type == "plotly":
            if isinstance(attached.value, dict):
                items.append((name, Rendered(template="plotly", figure=attached.value), extra))
            else:
                items.append((name, None, {**extra, "error": "the attached Plotly figure is not valid JSON"}))
    return items


def evaluation_report(evaluation: BatchEvaluation, *, title: str | None = None) -> str:
    """The report page of an evaluation (event images are found in each job's logs)."""
    title = title or f"Batch {evaluation.batch_id} on branch {evaluation.branch}: {evaluation.status}"
    sections: list[tuple[str, list[Item]]] = [
        ("Overview", [_overview(evaluation)]),
        ("Batch metrics", [metric_item(r) for r in evaluation.batch_results]),
    ]
    for job in evaluation.jobs:
        items = [metric_item(r) for r in job.results]
        for event in job.events:
            items += _event_items(event, job.logs_dir)
        sections.append((f"Job {job_title(job)}: {job.conflated_status}", items))
    return report_html(title, [(name, items) for name, items in sections if items])


def write_report(evaluation: BatchEvaluation, path: Path) -> Path:
    """Write the report page of an evaluation to `path` (folders created); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(evaluation_report(evaluation), encoding="utf-8")
    return path
