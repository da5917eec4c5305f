"""Metric templates: a query result rendered as a Plotly figure, a table, a scalar, or files of the
job's logs (images, videos, artifacts).

`render` first checks that the result has the shape its template needs and raises a
`TemplateError` naming the metric, the template and what it got. It is pure: no
database, no lake, no network. Figures are plain JSON-safe dicts in Plotly's figure
format (`{"data": [...], "layout": {...}}`), built directly rather than through
`plotly.graph_objects`, which is several times slower on 100k-point traces; the tests
check them against Plotly's schema. The HTML pages are made in `figures_html`.
"""

from __future__ import annotations

import datetime as dt
import math
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from lakegate.gateway.metrics.plotly_arrays import typed_array
from lakegate.gateway.metrics.result_columns import NOT_A_NUMBER, ResultColumns, TemplateError, number, plural
from lakegate.lake import template_kinds
from lakegate.lake.storage import LOCAL
from lakegate.lake.template_kinds import TEMPLATES

#: The columns of `Rendered.table` of a kind that shows files of the job's logs named by the result's
#: one column (`TemplateKind.files`): the files found.
FILE_COLUMNS = ["file", "path", "bytes", "type"]

#: Badge colours of metric and job statuses; every chart whose categories are statuses (a pie of
#: `job_conflated_status`, a state timeline of statuses, bars per status) draws them in these colours.
STATUS_COLOURS = {
    "PASSED": "#2e7d32",
    "WARNING": "#e08e00",
    "BLOCKER": "#c62828",
    "ERROR": "#6a1b9a",
    "NOT_RUN": "#757575",
    "NO_DATA": "#90a4ae",
}

#: Colours of the other states of a state timeline (see `state_colours`): distinct, saturated (a short
#: segment still shows), none a status colour.
PALETTE = (
    "#1f77b4",
    "#ff7f0e",
    "#17becf",
    "#e377c2",
    "#8c564b",
    "#bcbd22",
    "#9467bd",
    "#393b79",
    "#637939",
    "#7b4173",
    "#843c39",
    "#3182bd",
    "#e6550d",
    "#756bb1",
    "#d6616b",
    "#e7ba52",
    "#6baed6",
    "#a55194",
    "#636363",
    "#00897b",
)

_IMAGE_MAGIC = (
    (b"\x89PNG\r\n\x1a\n", "image/png"),
    (b"GIF87a", "image/gif"),
    (b"GIF89a", "image/gif"),
    (b"\xff\xd8\xff", "image/jpeg"),
)
_WEBM_MAGIC = b"\x1a\x45\xdf\xa3"  # EBML, the container of WebM
_EPOCH = dt.datetime(1970, 1, 1)


@dataclass
class Rendered:
    """One metric's result as its template shows it."""

    template: str
    #: Plotly figure as a JSON-safe dict; None for scalar and image results.
    figure: dict | None = None
    #: {"columns": [...], "rows": [[...]]} with JSON-safe cells: the table template's
    #: result, a state timeline's segments, an image list's files.
    table: dict | None = None
    #: The scalar template's value as the query returned it (numpy types made Python).
    scalar: Any = None
    #: One-line human summary, e.g. "12.5 s" or "2 series, 300 points".
    text: str = ""
    #: Image template: resolved paths of the image files found.
    images: list[str] = field(default_factory=list)
    #: Non-fatal issues, e.g. missing image files or values that cannot be drawn.
    problems: list[str] = field(default_factory=list)
    #: Image, video and artifact: the query named files and none of them is in the job's logs.
    files_missing: bool = False

    @property
    def shows(self) -> str:
        """How the result is shown: its kind's `TemplateKind.shows` (a chart for a custom figure)."""
        return template_kinds.shows(self.template)


def render(
    metric_name: str,
    template: str,
    columns: list[tuple[str, str]],
    rows: Sequence[tuple] | pa.Table,
    *,
    units: str | None = None,
    logs_dir: Path | None = None,
) -> Rendered:
    """Render a query result (`columns` as (name, Trino type) pairs, `rows` of Python values or the
    query's Arrow table, `result_columns`) with a system template (custom templates are
    `custom.render_custom`).

    `units` are shown after a scalar; `logs_dir` is where the image, video and artifact
    templates find files.
    """
    if template not in TEMPLATES:
        raise TemplateError(
            f"metric {metric_name!r}: unknown template {template!r} (expected one of {', '.join(TEMPLATES)})"
        )
    return _RENDERERS[template](ResultColumns(metric_name, template, columns, rows), units, logs_dir)


def state_colours(states: Iterable[str]) -> dict[str, str]:
    """The colour of each state of one chart: distinct within the chart, and the same for a state
    in every chart, job, page and process as far as distinctness allows.

    A state named as a status (PASSED, WARNING, ...) takes its badge colour; any other state takes
    the `PALETTE` slot of its name's CRC-32, or, when a state earlier in name order holds that slot
    in this chart, the next free one (so only states whose names share a slot can differ between
    charts). With more states than colours, colours repeat.
    """
    names = set(states)
    colours = {state: STATUS_COLOURS[state] for state in names if state in STATUS_COLOURS}
    taken: set[int] = set()
    for state in sorted(names - set(colours)):
        slot = zlib.crc32(state.encode("utf-8")) % len(PALETTE)
        for step in range(len(PALETTE)):
            if (slot + step) % len(PALETTE) not in taken:
                slot = (slot + step) % len(PALETTE)
                break
        taken.add(slot)
        colours[state] = PALETTE[slot]
    return colours


def status_colours(labels: Sequence[str]) -> list[str] | None:
    """The badge colour of each label when every one is a status name (None otherwise, or for none)."""
    if not labels or not all(label in STATUS_COLOURS for label in labels):
        return None
    return [STATUS_COLOURS[label] for label in labels]


def image_mime(path: Path) -> str | None:
    """The MIME type of a PNG, GIF or JPEG file, from its first bytes; None for anything else."""
    head = LOCAL.read_head(path, 8)
    return next((mime for magic, mime in _IMAGE_MAGIC if head.startswith(magic)), None)


def public_file_table(table: dict | None) -> dict:
    """The files of a video or artifact result's table as a table without the server's paths:
    [file, bytes, type]."""
    rows = table["rows"] if table else []
    return {"columns": ["file", "bytes", "type"], "rows": [[name, size, mime] for name, _, size, mime in rows]}


def video_mime(path: Path) -> str | None:
    """The MIME type of an MP4, WebM or GIF file, from its first bytes; None for anything else."""
    head = LOCAL.read_head(path, 12)
    if head[4:8] == b"ftyp":
        return "video/mp4"
    if head.startswith(_WEBM_MAGIC):
        return "video/webm"
    return "image/gif" if head.startswith((b"GIF87a", b"GIF89a")) else None


@dataclass(frozen=True)
class _LogFileKind:
    """What a kind showing files of the job's logs expects: what a value of its column is, the MIME
    type of a file it can show (None when it cannot), what a file it cannot show is not, and the noun
    counting the files found."""

    wanted: str
    mime_of: Callable[[Path], str | None]
    unshowable: str
    noun: str


def format_number(value: int | float | Decimal) -> str:
    """A number for people: integers in full, others rounded to 6 significant digits
    but never losing integer digits below 1e15 (12.500000000001 -> "12.5", 1234567.8 -> "1234568")."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return str(int(value))
    if isinstance(value, np.floating):
        value = float(value)
    if math.isnan(value):
        return "NaN"
    if math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    if value == 0:
        return "0"
    magnitude = abs(value)
    if magnitude >= 1e15 or magnitude < 1e-4:
        return f"{value:.6g}"
    digits = max(0, 6 - (math.floor(math.log10(magnitude)) + 1))
    text = f"{value:.{digits}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def display_value(value: Any) -> str:
    """A result value as a table cell or label shows it (Trino CLI style: NULL, true, [a, b])."""
    if value is None:
        return "NULL"
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, float, Decimal, np.integer, np.floating)):
        return format_number(value)
    if isinstance(value, str):
        return value
    if isinstance(value, (dt.date, dt.time)):
        return value.isoformat(sep=" ") if isinstance(value, dt.datetime) else value.isoformat()
    if isinstance(value, (bytes, bytearray, memoryview)):
        return bytes(value).hex(" ")
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(display_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{display_value(k)}={display_value(v)}" for k, v in value.items()) + "}"
    return str(value)


def json_value(value: Any) -> Any:
    """A result value as JSON, the way Trino's client protocol sends it: exact decimals and
    NaN / Infinity as strings, temporal values as ISO text, arrays as lists, rows as objects."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.generic):
        return json_value(value.item())
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else format_number(value)
    if isinstance(value, Decimal):
        return str(value)
    if isinstance(value, (list, tuple, np.ndarray)):
        return [json_value(v) for v in value]
    if isinstance(value, dict):
        return {str(k): json_value(v) for k, v in value.items()}
    return display_value(value)


def _plot_time(value: dt.date) -> str:
    """A date or timestamp as Plotly's date axis reads it (wall-clock time, zone dropped)."""
    if isinstance(value, dt.datetime):
        return value.replace(tzinfo=None).isoformat(sep=" ")
    return value.isoformat()


def _layout(x_title: str | None = None, y_title: str | None = None, **extra: Any) -> dict:
    layout: dict[str, Any] = {"margin": {"l": 60, "r": 20, "t": 30, "b": 50}}
    if x_title is not None:
        layout["xaxis"] = {"title": {"text": x_title}}
    if y_title is not None:
        layout["yaxis"] = {"title": {"text": y_title}}
    layout.update(extra)
    return layout


#: The row indexes of one series: every row (a range), or some rows in order.
Indexes = range | Sequence[int] | np.ndarray


def _series(result: ResultColumns, column: int | None) -> dict[str, Indexes]:
    """Row indexes per distinct series label, in first-appearance order (one series when column is None)."""
    if column is None:
        return {"": range(result.count)}
    encoded = result.codes(column)
    if encoded is None:
        groups: dict[str, list[int]] = {}
        label = _labeller()
        for index, value in enumerate(result.values(column)):
            groups.setdefault(label(value), []).append(index)
        return groups
    distinct, codes = encoded  # distinct values in order of first appearance, so are their labels
    numbers: dict[str, int] = {}  # label -> its series' number (values with one label make one series)
    series_of = np.array([numbers.setdefault(display_value(value), len(numbers)) for value in distinct], np.intp)
    if len(numbers) == 1:
        return {next(iter(numbers)): range(result.count)}
    of_rows = series_of[codes]
    order = np.argsort(of_rows, kind="stable")  # each series' rows, in row order
    bounds = np.cumsum(np.bincount(of_rows, minlength=len(numbers)))[:-1]
    return dict(zip(numbers, np.split(order, bounds)))


#: A column of a chart: a list of values, or a NumPy array of finite numbers (`ResultColumns.array`).
Plotted = list | np.ndarray


def _pick(values: Plotted, indexes: Indexes) -> list | dict:
    """The values at `indexes`, as a figure holds them: a typed array of an array's numbers
    (`plotly_arrays`), a list otherwise."""
    whole = isinstance(indexes, range) and len(indexes) == len(values)
    if isinstance(values, np.ndarray):
        picked = values if whole else values[np.asarray(indexes, np.intp)]
        typed = typed_array(picked)
        return typed if typed is not None else picked.tolist()
    if whole:
        return list(values)
    if isinstance(indexes, np.ndarray):
        indexes = indexes.tolist()
    return list(map(values.__getitem__, indexes))


def _plotted(result: ResultColumns, column: int, wanted: str) -> tuple[Plotted, list[str]]:
    """A column of numbers to plot, and its problems (`ResultColumns.numbers`): as an array when every
    value is a finite number."""
    found = result.array(column)
    return (found, []) if found is not None else result.numbers(column, wanted)


def _labeller() -> Callable[[Any], str]:
    """`display_value` remembering its answers: series and state names repeat on every row."""
    labels: dict[tuple[type, Any], str] = {}

    def label(value: Any) -> str:
        try:
            return labels[type(value), value]
        except KeyError:
            text = labels[type(value), value] = display_value(value)
            return text
        except TypeError:  # unhashable, e.g. an array
            return display_value(value)

    return label


#: The optional last column of a bar or line result: where each point links to (ReSim's `link_path`).
LINK_PATH = "link_path"


def _chart_columns(result: ResultColumns, *, two: bool) -> tuple[int | None, int, int]:
    """(series, x, y) column indexes of a bar or line result: `[series, x, y]`, with an optional 4th
    `link_path` column; a bar may also be `[x, y]` (one unnamed series), or `[x, y, link_path]`."""
    names = [name.lower() for name in result.names]
    linked = len(names) in (3, 4) and names[-1] == LINK_PATH and (len(names) == 4 or two)
    width = len(names) - linked
    if width == 3:
        return 0, 1, 2
    if width == 2 and two:
        return None, 0, 1
    got = f"got {len(names)} ({', '.join(result.names)})"
    if len(names) == 4:
        raise result.error(f"takes a 4th column only named {LINK_PATH}, {got}")
    wanted = "2 or 3 columns [x, y] or [series, x, y]" if two else "exactly 3 columns [series, x, y]"
    raise result.error(f"needs {wanted} (and an optional {LINK_PATH} column), {got}")


def _link_meta(result: ResultColumns, groups: dict[str, Indexes]) -> dict:
    """The `link_path` values of each trace's points, for the pages to link (figures_html)."""
    if result.names[-1].lower() != LINK_PATH or len(result.names) < 3:
        return {}
    links = [json_value(value) for value in result.values(len(result.names) - 1)]
    return {"meta": {LINK_PATH: [_pick(links, indexes) for indexes in groups.values()]}}


def _line(result: ResultColumns) -> Rendered:
    series, x, y = _chart_columns(result, two=False)
    ys, problems = _plotted(result, y, "numeric y values")
    categorical = _is_text(result.types[x])  # ReSim draws text x values as categories
    numeric = result.is_numeric(x)
    raw_x = [] if numeric else result.values(x)
    dates = not categorical and not numeric and any(isinstance(v, dt.date) for v in raw_x)
    xs: Plotted
    if categorical:
        xs = raw_x
    elif dates:
        xs = [_plot_time(v) if isinstance(v, dt.date) else None for v in raw_x]
        for row_number, v in enumerate(raw_x, 1):
            if v is not None and not isinstance(v, dt.date):
                raise result.bad_value(row_number, x, "numeric or timestamp x values")
    else:
        xs, x_problems = _plotted(result, x, "numeric or timestamp x values")
        problems += x_problems
    traces = []
    groups = _series(result, series)
    for name, indexes in groups.items():
        traces.append(
            {
                "type": "scatter",
                "mode": "lines" if len(indexes) > 1 else "markers",
                "name": name,
                "x": _pick(xs, indexes),
                "y": _pick(ys, indexes),
            }
        )
    _colour_statuses(traces, "line")
    layout = _layout(result.names[x], result.names[y], hovermode="closest", **_link_meta(result, groups))
    if dates or categorical:
        layout["xaxis"]["type"] = "date" if dates else "category"
    return Rendered(
        template="line",
        figure={"data": traces, "layout": layout},
        text=f"{plural(len(traces), 'series', 'series')}, {plural(result.count, 'point')}",
        problems=problems,
    )


def _colour_statuses(traces: list[dict], part: str) -> None:
    """Give each trace its status's badge colour (its `part`, marker or line) when every trace is named as a status."""
    colours = status_colours([trace["name"] for trace in traces])
    for trace, colour in zip(traces, colours or []):
        trace[part] = {"color": colour}


def _bar(result: ResultColumns) -> Rendered:
    series, x, y = _chart_columns(result, two=True)
    ys, problems = result.numbers(y, "numeric y values")
    raw_x = result.values(x)
    categorical = any(v is not None and number(v) is NOT_A_NUMBER and not isinstance(v, dt.date) for v in raw_x)
    if categorical:
        xs: list[Any] = [display_value(v) for v in raw_x]
    elif any(isinstance(v, dt.date) for v in raw_x):
        xs = [None if v is None else _plot_time(v) for v in raw_x]
    else:
        xs, x_problems = result.numbers(x, "x values")
        problems += x_problems
    groups = _series(result, series)
    traces = [
        {"type": "bar", "name": name, "x": _pick(xs, indexes), "y": _pick(ys, indexes)}
        for name, indexes in groups.items()
    ]
    _colour_statuses(traces, "marker")
    if len(traces) == 1 and categorical and (colours := status_colours(traces[0]["x"])) is not None:
        traces[0]["marker"] = {"color": colours}
    layout = _layout(result.names[x], result.names[y], barmode="group", **_link_meta(result, groups))
    if categorical:
        layout["xaxis"]["type"] = "category"
    return Rendered(
        template="bar",
        figure={"data": traces, "layout": layout},
        text=f"{plural(len(traces), 'series', 'series')}, {plural(result.count, 'bar')}",
        problems=problems,
    )


def _table(result: ResultColumns) -> Rendered:
    if not result.names:
        raise result.error("needs at least 1 column, got 0")
    cells = [[display_value(v) for v in result.values(c)] for c in range(len(result.names))]
    figure = {
        "data": [
            {
                "type": "table",
                "header": {"values": list(result.names), "align": "left"},
                "cells": {"values": cells, "align": "left"},
            }
        ],
        "layout": _layout(),
    }
    return Rendered(
        template="table",
        figure=figure,
        table={"columns": list(result.names), "rows": [[json_value(v) for v in row] for row in result.rows]},
        text=(len(result.names) == 2 and _inline([tuple(row) for row in result.rows]))
        or f"{plural(len(result.rows), 'row')}, {plural(len(result.names), 'column')}",
    )


def _scalar(result: ResultColumns, units: str | None) -> Rendered:
    if not result.names:
        raise result.error("needs at least 1 column, got 0")
    if not result.rows:
        raise result.error(f"needs 1 row, but the query returned no rows (columns: {', '.join(result.names)})")
    value = result.rows[0][0]
    if isinstance(value, np.generic):
        value = value.item()
    problems = []
    if len(result.rows) > 1 or len(result.names) > 1:
        problems.append(
            f"the query returned {plural(len(result.rows), 'row')} and {plural(len(result.names), 'column')}; "
            f"only the first value is shown"
        )
    text = display_value(value)
    return Rendered(template="scalar", scalar=value, text=f"{text} {units}" if units else text, problems=problems)


def _log_files(result: ResultColumns, logs_dir: Path | None, kind: _LogFileKind) -> Rendered:
    """Image, video or artifact: the files of the job's logs the one column names; files that
    cannot be shown are problems grouped by cause (never fatal)."""
    wanted, mime_of, unshowable = kind.wanted, kind.mime_of, kind.unshowable
    result.need_columns((1,), f"[{wanted}]")
    root = logs_dir.resolve() if logs_dir is not None else None
    found: list[list[Any]] = []  # FILE_COLUMNS
    failed: dict[str, list[str]] = {}  # what went wrong -> the files (or rows) it went wrong for
    for row_number, (name,) in enumerate(result.rows, 1):
        if name is None:
            failed.setdefault("NULL file name", []).append(f"row {row_number}")
            continue
        if not isinstance(name, str):
            raise result.bad_value(row_number, 0, f"{wanted}s")
        if root is None:
            failed.setdefault("no log directory to look in", []).append(name)
            continue
        path = (root / name).resolve()
        if not path.is_relative_to(root):
            failed.setdefault(f"outside the job's logs ({root})", []).append(name)
        elif not LOCAL.is_file(path):
            failed.setdefault(f"missing from the job's logs ({root})", []).append(name)
        elif (mime := mime_of(path)) is None:
            failed.setdefault(unshowable, []).append(name)
        else:
            found.append([name, str(path), LOCAL.stat(path).size, mime])
    files_missing = bool(result.rows) and not found and unshowable not in failed
    text = plural(len(found), kind.noun)
    count = sum(len(names) for names in failed.values())
    if count:
        text += f", {plural(count, 'problem')}"
    return Rendered(
        template=result.template,
        table={"columns": FILE_COLUMNS, "rows": found},
        text=text,
        images=[path for _, path, _, _ in found] if template_kinds.shows(result.template) == "images" else [],
        problems=[_grouped_problem(what, names) for what, names in failed.items()],
        files_missing=files_missing,
    )


def _grouped_problem(what: str, names: list[str], shown: int = 3) -> str:
    """One line for every file with the same problem: `a.gif: what`, or `200 files: what (a.gif, b.gif, ...)`."""
    if len(names) == 1:
        return f"{names[0]}: {what}"
    listed = ", ".join(names[:shown]) + (f" and {len(names) - shown} more" if len(names) > shown else "")
    return f"{len(names)} {'rows' if names[0].startswith('row ') else 'files'}: {what} ({listed})"


def _nanoseconds(value: Any) -> int | float | None:
    """A timestamp as nanoseconds: integers as they are, timestamps from the Unix epoch (naive = UTC)."""
    if isinstance(value, dt.datetime):
        if value.tzinfo is not None:
            value = value.astimezone(dt.UTC).replace(tzinfo=None)
        return (value - _EPOCH) // dt.timedelta(microseconds=1) * 1000
    found = number(value)
    if found is None or found is NOT_A_NUMBER or not math.isfinite(found):
        return None
    return found


def _state_timeline(result: ResultColumns) -> Rendered:
    result.need_columns((3,), "[system, timestamp, state]")
    samples: dict[str, list[tuple[int | float, str]]] = {}
    label = _labeller()
    for row_number, (system, timestamp, state) in enumerate(result.rows, 1):
        ns = timestamp if type(timestamp) is int else _nanoseconds(timestamp)
        if ns is None:
            raise result.bad_value(row_number, 1, "timestamps in nanoseconds")
        samples.setdefault(label(system), []).append((ns, label(state)))
    if not samples:
        figure = {"data": [], "layout": _layout("Elapsed time (s)", result.names[0])}
        return Rendered(
            template="state_timeline",
            figure=figure,
            table={"columns": [result.names[0], "state", "start (s)", "end (s)"], "rows": []},
            text="no states",
        )
    first = min(ns for points in samples.values() for ns, _ in points)
    last = max(ns for points in samples.values() for ns, _ in points)
    segments: list[list[Any]] = []  # [system, state, start s, end s]
    for system, points in samples.items():
        points.sort(key=lambda point: point[0])
        run_start, run_state = points[0]
        for ns, state in points[1:]:
            if state != run_state:
                segments.append([system, run_state, (run_start - first) / 1e9, (ns - first) / 1e9])
                run_start, run_state = ns, state
        segments.append([system, run_state, (run_start - first) / 1e9, (last - first) / 1e9])
    span = (last - first) / 1e9
    min_width = span / 200 if span > 0 else 1.0  # a state seen only at the very end stays visible
    traces: dict[str, dict] = {}
    for system, state, start, end in segments:
        trace = traces.setdefault(
            state,
            {
                "type": "bar",
                "orientation": "h",
                "name": state,
                "y": [],
                "x": [],
                "base": [],
                "customdata": [],
                "hovertemplate": (
                    "%{y}: %{fullData.name}<br>%{customdata[0]:.3f} s to %{customdata[1]:.3f} s<extra></extra>"
                ),
            },
        )
        trace["y"].append(system)
        trace["base"].append(start)
        trace["x"].append(max(end - start, min_width))
        trace["customdata"].append([start, end])
    for state, colour in state_colours(traces).items():
        traces[state]["marker"] = {"color": colour}
    systems = list(samples)
    layout = _layout(
        "Elapsed time (s)",
        result.names[0],
        barmode="overlay",
        height=140 + 50 * len(systems),
        legend={"title": {"text": result.names[2]}},
    )
    layout["yaxis"].update(
        type="category", categoryorder="array", categoryarray=systems, autorange="reversed", automargin=True
    )
    layout["yaxis"]["title"]["standoff"] = 12  # with automargin: the title clear of the systems' names
    return Rendered(
        template="state_timeline",
        figure={"data": list(traces.values()), "layout": layout},
        table={"columns": [result.names[0], "state", "start (s)", "end (s)"], "rows": segments},
        text=f"{plural(len(systems), 'system')}, {plural(len(segments), 'segment')}, {plural(len(traces), 'state')}",
    )


def _is_text(type_name: str) -> bool:
    return type_name.startswith(("varchar", "char"))


def _histogram_columns(result: ResultColumns) -> tuple[int, int | None]:
    """(value column, series column): [value], [value, series], or [group, value] as ReSim's
    own examples write it (`group_name` first), told apart by the columns' types."""
    if len(result.names) == 1:
        return 0, None
    if _is_text(result.types[0]) and not _is_text(result.types[1]):
        return 1, 0
    return 0, 1


def _histogram(result: ResultColumns) -> Rendered:
    result.need_columns((1, 2), "[value], [value, series] or [group, value]")
    value_column, series_column = _histogram_columns(result)
    values, problems = _plotted(result, value_column, "numeric values")
    with_series = series_column is not None
    groups = _series(result, series_column)
    traces = []
    for name, indexes in groups.items():
        trace = {"type": "histogram", "x": _pick(values, indexes)}
        if with_series:
            trace.update(name=name, opacity=0.6)
        traces.append(trace)
    if with_series:
        _colour_statuses(traces, "marker")
    listed = isinstance(values, list)  # else every value is a finite number
    counted = len(values) - values.count(None) if listed else len(values)
    nulls = result.values(value_column).count(None) if listed else 0
    if nulls:
        problems.append(f"{plural(nulls, 'NULL value')} not counted")
    return Rendered(
        template="histogram",
        figure={"data": traces, "layout": _layout(result.names[value_column], "Count", barmode="overlay")},
        text=plural(counted, "value") + (f" in {plural(len(groups), 'series', 'series')}" if with_series else ""),
        problems=problems,
    )


def _pie(result: ResultColumns) -> Rendered:
    result.need_columns((2,), "[label, value]")
    labels: list[str] = []
    values: list[int | float] = []
    problems: list[str] = []
    for row_number, (label, raw) in enumerate(result.rows, 1):
        value = number(raw)
        if value is None:
            problems.append(f"row {row_number}: NULL value, slice {display_value(label)!r} left out")
            continue
        if value is NOT_A_NUMBER or not math.isfinite(value) or value < 0:
            raise result.bad_value(row_number, 1, "non-negative numeric values")
        labels.append(display_value(label))
        values.append(value)
    trace: dict[str, Any] = {"type": "pie", "labels": labels, "values": values, "sort": False, "name": result.names[1]}
    colours = status_colours(labels)
    if colours is not None:
        trace["marker"] = {"colors": colours}
    figure = {"data": [trace], "layout": _layout()}
    text = _inline(list(zip(labels, values))) or plural(len(labels), "slice")
    return Rendered(template="pie", figure=figure, text=text, problems=problems)


#: A pie of at most this many slices, or a two-column table of at most this many rows, is summed up
#: by its values (`label: value; ...`) rather than by its size.
INLINE_ROWS = 6


def _inline(pairs: list[tuple[Any, Any]]) -> str:
    """`a: 1; b: 2` for 1 to INLINE_ROWS (label, value) pairs, else ''."""
    if not 0 < len(pairs) <= INLINE_ROWS:
        return ""
    return "; ".join(f"{display_value(label)}: {display_value(value)}" for label, value in pairs)


#: A renderer: the result, the metric's units, the job's logs folder.
Renderer = Callable[[ResultColumns, "str | None", "Path | None"], Rendered]


def _of_result(renderer: Callable[[ResultColumns], Rendered]) -> Renderer:
    """A renderer that needs nothing but the result."""
    return lambda result, units, logs_dir: renderer(result)


def _scalar_with_units(result: ResultColumns, units: str | None, logs_dir: Path | None) -> Rendered:
    return _scalar(result, units)


def _files_in_logs(kind: _LogFileKind) -> Renderer:
    """A renderer of files of the job's logs of `kind`."""
    return lambda result, units, logs_dir: _log_files(result, logs_dir, kind)


#: The renderer of each kind of `template_kinds.TEMPLATES` (the one dispatch on a kind's name).
_RENDERERS: dict[str, Renderer] = {
    "line": _of_result(_line),
    "bar": _of_result(_bar),
    "table": _of_result(_table),
    "scalar": _scalar_with_units,
    "image": _files_in_logs(_LogFileKind("image file name", image_mime, "not a PNG, GIF or JPEG image", "image")),
    "state_timeline": _of_result(_state_timeline),
    "histogram": _of_result(_histogram),
    "pie": _of_result(_pie),
    "video": _files_in_logs(_LogFileKind("video file name", video_mime, "not an MP4, WebM or GIF video", "video")),
    "artifact": _files_in_logs(_LogFileKind("artifact file name", lambda path: "application/octet-stream", "", "file")),
}
