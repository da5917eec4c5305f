"""The JSON the dashboard page reads: a metric, its result (evaluated now or stored in the lake) and
the cell of the jobs x metrics table.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from lakegate.gateway.metrics.metric_result import MetricResult
from lakegate.gateway.metrics.templates import json_value, public_file_table
from lakegate.lake.config import Metric
from lakegate.lake.template_kinds import DEFAULT_SHOWS, FILE_SHOWS, shows

# -- results as the page shows them ---------------------------------------------------------------


def _images(paths: list[str], root: Path | None) -> list[str]:
    """Image paths as names inside the job's logs folder (what the logs URL serves)."""
    names = []
    for path in paths:
        try:
            names.append(str(Path(path).relative_to(root)) if root is not None else Path(path).name)
        except ValueError:
            names.append(Path(path).name)
    return names


def _lists_files(shown: str) -> bool:
    """Whether a result shown so is a table of files (images are listed by name instead)."""
    return shown in FILE_SHOWS and shown != "images"


def result_json(result: MetricResult, logs_dir: Path | None) -> dict[str, Any]:
    """One evaluated metric for the page: status, text, figure or table or images, problems, error."""
    rendered = result.rendered
    out: dict[str, Any] = {
        "status": result.status,
        "text": result.value_text,
        "figure": None,
        "table": None,
        "images": [],
        "problems": [],
        "seconds": round(result.seconds, 4),
        "error": None if result.error is None else result.error.as_dict(),
    }
    if rendered is not None:
        out["problems"] = list(rendered.problems)
        if rendered.shows == "table":
            out["table"] = rendered.table
        elif rendered.shows == "images":
            out["images"] = _images(rendered.images, logs_dir.resolve() if logs_dir else None)
        elif _lists_files(rendered.shows):
            out["table"] = public_file_table(rendered.table)
        else:
            out["figure"] = rendered.figure
    return out


def stored_json(row: dict[str, Any], logs_dir: Path | None) -> dict[str, Any]:
    """A stored `metric_results` row in the shape of `result_json`."""
    details = json.loads(row["details_json"]) if row.get("details_json") else {}
    shown = shows(row.get("template"))
    table = details.get("table") if shown == "table" or _lists_files(shown) else None
    error = None
    if row.get("error_message") is not None:
        error = {
            "message": row["error_message"],
            "line": row.get("error_line"),
            "column": row.get("error_column"),
            "location": row.get("error_location"),
            "query": "query" if row.get("error_line") else None,
        }
    return {
        "status": row["status"],
        "text": row.get("value_text"),
        "seconds": None,
        "error": error,
        "figure": json.loads(row["figure_json"]) if row.get("figure_json") and shown != "table" else None,
        "table": public_file_table(table) if _lists_files(shown) else table,
        "images": _images(details.get("images") or [], logs_dir.resolve() if logs_dir else None),
        "problems": details.get("problems") or [],
    }


def metric_json(metric: Metric, origin: str) -> dict[str, Any]:
    """A metric's definition for the page."""
    status = metric.status
    return {
        "name": metric.name,
        "type": metric.type,
        "template": metric.template,
        "shows": shows(metric.template) if metric.template_type == "system" else DEFAULT_SHOWS,
        "template_type": metric.template_type,
        "description": metric.description,
        "units": metric.units,
        "query_string": metric.query_string,
        "origin": origin,
        "location": str(metric.location) if metric.location else None,
        "status": None
        if status is None
        else {"query_string": status.query_string, "block": json_value(status.block), "warn": json_value(status.warn)},
    }


def cell(result: dict[str, Any] | None) -> dict[str, Any] | None:
    if result is None:
        return None
    return {
        "status": result["status"],
        "text": result["text"],
        "error": result["error"]["message"] if result["error"] else None,
    }
