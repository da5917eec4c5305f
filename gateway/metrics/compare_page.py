"""The page of a build comparison: one offline HTML page (plotly.js embedded, or a local script URL).

Summary counts first (experiences and metrics per tag, significant series changes, flaky
experiences), then the experiences whose job status changed, then every changed metric in severity
order, with base and new drawn in the same Plotly figure: the two sides' traces of a series metric
(line and bar traces, histograms overlaid, state segments counted per state), a scalar as two bars
(base, new) per experience.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

from lakegate.gateway.metrics.compare import TAGS, Comparison, MetricChange
from lakegate.gateway.metrics.figures_html import report_html
from lakegate.gateway.metrics.templates import Rendered, format_number, render
from lakegate.lake.template_kinds import series

#: At most this many changed metrics are drawn (the rest are in the table); the page stays usable.
MAX_FIGURES = 200
_COLOURS = {"base": "#1f77b4", "new": "#d62728"}


def _number(value: float | None) -> str:
    return "" if value is None else format_number(value)


def _percent(value: float | None) -> str:
    return "" if value is None else f"{value * 100:+.1f}%"


def _p(change: MetricChange) -> str:
    return "" if change.series is None else f"{change.series.p_value:.3g}"


def summary_item(comparison: Comparison) -> tuple[str, Rendered, dict[str, Any]]:
    """The counts per tag, of experiences (job statuses) and of metrics, as a table."""
    experiences, metrics = comparison.counts(), comparison.metric_counts()
    rows = [(tag, experiences[tag], metrics[tag]) for tag in TAGS]
    rows.append(("significant series change", "", metrics["significant"]))
    rows.append(("flaky experiences", len(comparison.flaky), ""))
    columns = [("Tag", "varchar"), ("Experiences", "varchar"), ("Metrics", "varchar")]
    description = (
        f"base {comparison.base} (build {', '.join(comparison.base_builds) or '?'}) -> new {comparison.new} "
        f"(build {', '.join(comparison.new_builds) or '?'}); two-sample tests at alpha {comparison.alpha}; "
        f"flaky experiences looked for in the last {comparison.flake_window} batches"
    )
    return "Summary", render("Summary", "table", columns, rows), {"description": description}


def _jobs_item(comparison: Comparison) -> tuple[str, Rendered, dict[str, Any]]:
    columns = [(name, "varchar") for name in ("Tag", "Experience", "Base", "New", "Base runs", "New runs")]
    rows = [
        (j.tag, j.experience, j.base_status, j.new_status, j.base_runs, j.new_runs)
        for j in comparison.jobs
        if j.tag != "same"
    ]
    return "Experiences", render("Experiences", "table", columns, rows), {"description": "job statuses that changed"}


def _metrics_table(changed: list[MetricChange]) -> tuple[str, Rendered, dict[str, Any]]:
    names = ("Tag", "Experience", "Metric", "Base", "New", "Base value", "New value", "Change", "Relative", "p")
    rows = [
        (
            m.tag,
            m.experience or "(batch)",
            m.metric,
            m.base_status,
            m.new_status,
            _number(m.base_value),
            _number(m.new_value),
            _number(m.change),
            _percent(m.relative_change),
            _p(m) + (" *" if m.significant else ""),
        )
        for m in changed
    ]
    return "Changed metrics", render("Changed metrics", "table", [(n, "varchar") for n in names], rows), {}


def _side_traces(change: MetricChange, side: str, values: list) -> list[dict]:
    colour = _COLOURS[side]
    compared = series(change.template)
    if compared == "x":
        return [{"type": "histogram", "x": values, "name": side, "opacity": 0.55, "marker": {"color": colour}}]
    if compared == "states":
        counts = Counter(values)
        return [{"type": "bar", "x": sorted(counts), "y": [counts[s] for s in sorted(counts)], "name": side}]
    return [{"type": "scatter", "mode": "lines+markers", "y": values, "name": side, "line": {"color": colour}}]


def change_figure(change: MetricChange) -> dict:
    """Base and new in one Plotly figure."""
    if change.series is not None:
        data = _side_traces(change, "base", change.base_values) + _side_traces(change, "new", change.new_values)
        compared = series(change.template)
        layout: dict[str, Any] = {"barmode": "overlay" if compared == "x" else "group"}
        if compared == "states":
            layout["yaxis"] = {"title": {"text": "segments"}}
        else:
            layout["xaxis"] = {"title": {"text": "sample"}}
    else:
        data = [
            {"type": "bar", "name": side, "x": [side], "y": [value], "marker": {"color": _COLOURS[side]}}
            for side, value in (("base", change.base_value), ("new", change.new_value))
            if value is not None
        ]
        layout = {"yaxis": {"title": {"text": change.units or "value"}}}
    layout.update(height=320, margin={"t": 30}, legend={"orientation": "h"})
    return {"data": data, "layout": layout}


def _change_item(change: MetricChange) -> tuple[str, Rendered, dict[str, Any]]:
    where = change.experience or "batch metric"
    text = [f"{change.tag}: {change.base_status or '-'} -> {change.new_status or '-'}"]
    if change.change is not None:
        text.append(f"{_number(change.base_value)} -> {_number(change.new_value)} ({_percent(change.relative_change)})")
    if change.series is not None:
        verdict = "significant" if change.significant else "not significant"
        text.append(
            f"{change.series.test} test: statistic {change.series.statistic:.3g}, p = {change.series.p_value:.3g} "
            f"({verdict}; {change.series.base_count} vs {change.series.new_count} values)"
        )
    rendered = Rendered(template="bar", figure=change_figure(change))  # any chart template: drawn as its figure
    return f"{change.metric} ({where})", rendered, {"description": "; ".join(text), "units": change.units}


def compare_html(comparison: Comparison, *, plotlyjs: str | bool = True, intro: str = "", nav: str = "") -> str:
    """The comparison's page; `intro` is HTML put under the title (the served page's form), `nav` the
    header bar's links."""
    changed = [m for m in comparison.metrics if m.changed]
    drawn = [m for m in changed if m.base_value is not None or m.new_value is not None or m.series is not None]
    sections = [("Summary", [summary_item(comparison)])]
    if any(j.tag != "same" for j in comparison.jobs):
        sections.append(("Experiences", [_jobs_item(comparison)]))
    if changed:
        sections.append(("Changed metrics", [_metrics_table(changed)]))
        sections.append(("Base and new", [_change_item(m) for m in drawn[:MAX_FIGURES]]))
    title = f"Compare {comparison.base} -> {comparison.new} on branch {comparison.branch}"
    return report_html(title, sections, plotlyjs=plotlyjs, intro=intro, nav=nav)


def write_compare(comparison: Comparison, path: Path) -> Path:
    """Write the comparison's page to `path` (folders created, plotly.js embedded); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(compare_html(comparison), encoding="utf-8")
    return path
