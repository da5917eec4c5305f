"""Custom templates (`template_type: custom`): a Liquid template turns a query result into a Plotly figure.

The template (`template_file`, found next to the config file that declares the metric, else in
its `templates/` folder: `Metric.template_path`) is rendered with python-liquid. It receives
each result column as an array named after the column (values as JSON: numbers, strings,
ISO timestamps, NULL as nil), plus `name` and `description` (the metric's; a column of that
name wins) and `units`. Its output must be a Plotly figure as JSON, `{"data": [...],
"layout": {...}}`; the `json` filter writes a value as JSON (`"x": {{ time | json }}`).
Errors name the template file with the line and column in it.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import liquid.extra
from liquid import Environment, StrictUndefined
from liquid.exceptions import LiquidError
from liquid.token import Token

from lakegate.gateway.metrics.templates import Rendered, TemplateError, json_value
from lakegate.lake.config import Metric

CUSTOM = "custom"


def _environment() -> Environment:
    env = Environment(undefined=StrictUndefined)  # a misspelt column name is an error, not an empty array
    liquid.extra.add_filters(env)  # json, and the other filters Shopify's Liquid has
    return env


_ENV = _environment()


@functools.lru_cache(maxsize=64)
def _template(path: str, stamp: float, shown_as: str) -> Any:
    return _ENV.from_string(Path(path).read_text(encoding="utf-8"), name=shown_as)


def render_custom(metric: Metric, columns: list[tuple[str, str]], rows: list[tuple]) -> Rendered:
    """Render a query result with the metric's Liquid template; TemplateError naming the file and line."""
    shown_as = metric.template_file or ""
    path = metric.template_path()
    if path is None:
        where = "the config file's folder or its templates/ folder" if metric.location else "the config's folder"
        raise TemplateError(f"metric {metric.name!r}: custom template {shown_as!r} not found in {where}")
    data: dict[str, Any] = {"name": metric.name, "description": metric.description, "units": metric.units}
    for index, (column, _) in enumerate(columns):
        data[column] = [json_value(row[index]) for row in rows]
    try:
        template = _template(str(path), path.stat().st_mtime, shown_as)
        output = template.render(**data)
    except LiquidError as error:
        raise TemplateError(f"metric {metric.name!r}: {shown_as}{_position(error.token)}: {error.message}") from None
    except (OSError, UnicodeDecodeError) as error:
        raise TemplateError(
            f"metric {metric.name!r}: cannot read custom template {shown_as!r}: "
            f"{getattr(error, 'strerror', None) or error}"
        ) from None
    figure = _figure(metric, shown_as, output)
    traces = figure["data"]
    return Rendered(
        template=CUSTOM, figure=figure, text=f"{len(traces)} trace{'s' if len(traces) != 1 else ''} from {shown_as}"
    )


def _position(token: Token | None) -> str:
    """`:line:column` of a Liquid token in its template ('' when the error has no token)."""
    if token is None:
        return ""
    before = token.source[: token.start_index]
    line = before.count("\n") + 1
    return f":{line}:{token.start_index - (before.rfind(chr(10)) + 1) + 1}"


def _figure(metric: Metric, shown_as: str, output: str) -> dict:
    """The template's output as a Plotly figure dict, or a TemplateError saying what is wrong with it."""
    try:
        figure = json.loads(output)
    except json.JSONDecodeError as error:
        raise TemplateError(
            f"metric {metric.name!r}: the output of {shown_as} is not JSON "
            f"(output line {error.lineno}, column {error.colno}: {error.msg})"
        ) from None
    if (
        not isinstance(figure, dict)
        or not isinstance(figure.get("data"), list)
        or not all(isinstance(trace, dict) for trace in figure["data"])
        or not isinstance(figure.get("layout", {}), dict)
    ):
        raise TemplateError(
            f"metric {metric.name!r}: the output of {shown_as} is not a Plotly figure "
            f'(expected an object {{"data": [{{...}}, ...], "layout": {{...}}}})'
        )
    return figure
