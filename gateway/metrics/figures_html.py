"""HTML for rendered metrics: one metric as a page or fragment, or a report of many metrics.

Pages work offline: plotly.js comes from the installed plotly package and is embedded at
most once per page, images, videos and artifacts are embedded as data URIs (videos play in an
HTML5 <video> player, artifacts are download links with their sizes), and nothing is loaded
from the network. Tables are HTML tables (readable with many columns, copyable); charts are
Plotly figures drawn by `Plotly.newPlot`.
"""

from __future__ import annotations

import base64
import functools
import html
import json
import uuid
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from plotly.offline import get_plotlyjs

from lakegate.gateway.metrics.templates import (
    LINK_PATH,
    STATUS_COLOURS,
    Rendered,
    display_value,
    format_number,
    image_mime,
)
from lakegate.lake.storage import LOCAL

#: Rows of a table template shown in HTML; the full result stays in `Rendered.table`.
MAX_TABLE_ROWS = 2000
#: Larger image, video and artifact files are not embedded (the page would become unwieldy).
MAX_IMAGE_BYTES = 20 * 1024 * 1024
#: Table columns whose values a page may turn into links (ReSim's `link_path`).
LINK_COLUMNS = ("link_path",)

#: A table cell's value -> the URL it links to (None: no link).
Linker = Callable[[Any], "str | None"]

#: Images of image metrics, the same in the report and the dashboard: scaled to at least MIN_IMAGE_WIDTH
#: pixels wide (a 32 px image is not a few dots) and at most the card, pixels kept sharp; a click shows
#: the original, at its own size.
MIN_IMAGE_WIDTH = 240
IMAGE_CSS = f"""
.lg-images img {{ min-width: {MIN_IMAGE_WIDTH}px; max-width: 100%; max-height: 360px; border: 1px solid #dde1e6;
                  image-rendering: pixelated; cursor: zoom-in; }}
.lg-original {{ position: fixed; inset: 0; z-index: 100; background: rgba(20, 24, 31, .82); display: flex;
                align-items: center; justify-content: center; cursor: zoom-out; overflow: auto; }}
.lg-original figure {{ margin: auto; text-align: center; color: #fff; font-size: .85rem; }}
.lg-original img {{ image-rendering: pixelated; background: #fff; }}
"""
#: The pages' style, shared by the report, trends, comparison, landing and index pages (the dashboard's
#: own stylesheet, gateway/dashboard/static/dashboard.css, uses the same fonts, colours and header bar).
CSS = (
    """
:root { --fg: #1b1b1b; --muted: #5f6368; --line: #dde1e6; --bg-soft: #f5f7fa; --accent: #1f5fbf; }
* { box-sizing: border-box; }
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 0; color: var(--fg); }
main { margin: 0 auto; max-width: 1200px; padding: .5rem 2rem 2rem; }
a { color: var(--accent); }
.lg-top { display: flex; flex-wrap: wrap; align-items: center; gap: .5rem 1.5rem; padding: .7rem 1.5rem;
          border-bottom: 1px solid var(--line); background: #fbfcfd; }
.lg-top .lg-brand { font-weight: 700; font-size: 1.15rem; color: var(--fg); text-decoration: none; }
.lg-top nav { display: flex; gap: 1rem; margin-left: auto; }
.lg-top nav a { text-decoration: none; }
h1 { font-size: 1.5rem; margin: 1rem 0 .3rem; }
h2 { font-size: 1.25rem; margin: 1.6rem 0 .4rem; display: flex; align-items: baseline; gap: 1rem; }
h2 .lg-up { font-size: .8rem; font-weight: 400; margin-left: auto; text-decoration: none; }
.lg-summary span { margin-right: .8rem; }
.lg-toc { border: 1px solid var(--line); border-radius: 6px; background: var(--bg-soft); padding: .5rem 1rem;
          margin: 1rem 0; font-size: .9rem; }
.lg-toc h2 { margin: .2rem 0 .4rem; font-size: 1rem; }
.lg-toc ol { margin: 0; padding-left: 1.3rem; }
.lg-toc li { margin: .15rem 0; }
.lg-toc .lg-toc-items { color: var(--muted); font-size: .85rem; }
.lg-toc .lg-toc-items a { color: var(--muted); }
.lg-metric { border: 1px solid var(--line); border-radius: 6px; padding: .6rem 1rem; margin: 1rem 0; }
.lg-metric h3 { margin: .2rem 0; }
.lg-badge { display: inline-block; color: #fff; border-radius: 4px; padding: 0 .45rem; font-size: .8rem;
            font-weight: 600; vertical-align: middle; margin-left: .5rem; }
.lg-meta { color: var(--muted); font-size: .9rem; margin: .2rem 0; }
.lg-scalar { font-size: 2rem; font-weight: 600; margin: .4rem 0; }
.lg-error { background: #fdecea; color: #8a1c1c; padding: .5rem; white-space: pre-wrap; }
.lg-problems { color: #8a5a00; }
.lg-table-wrap { max-height: 32rem; overflow: auto; }
.lg-table { border-collapse: collapse; font-size: .9rem; }
.lg-table th, .lg-table td { border: 1px solid var(--line); padding: .2rem .5rem; text-align: left;
                             vertical-align: top; }
.lg-table th { background: #eef2f7; position: sticky; top: 0; }
.lg-list li { margin: .3rem 0; }
select, input, button { font: inherit; font-size: .9rem; padding: .25rem .4rem; border: 1px solid #b9c0c9;
                        border-radius: 4px; background: #fff; }
button { padding: .3rem .8rem; cursor: pointer; }
.lg-links { display: flex; gap: .6rem; margin: 1rem 0; }
.lg-button { display: inline-block; padding: .4rem .9rem; border: 1px solid var(--accent); border-radius: 5px;
             text-decoration: none; color: #fff; background: var(--accent); }
.lg-button + .lg-button { background: #fff; color: var(--accent); }
.lg-small { font-size: .8rem; font-weight: 400; margin-left: .5rem; }
.lg-statuses .lg-badge { margin-left: 0; }
.lg-connect th { white-space: nowrap; }
.lg-images figure { display: inline-block; margin: .3rem; vertical-align: top; }
.lg-images figcaption { font-size: .8rem; color: var(--muted); }
.lg-images video { max-width: 100%; max-height: 480px; }
"""
    + IMAGE_CSS
)
#: A click on an image of `.lg-images` shows the original at its own size over the page; a click closes it.
ORIGINAL_IMAGE_JS = """
document.addEventListener("click", function (event) {
  var open = document.querySelector(".lg-original");
  if (open) { open.remove(); return; }
  var img = event.target.closest ? event.target.closest(".lg-images img") : null;
  if (!img) return;
  var box = document.createElement("div"), figure = document.createElement("figure");
  var original = document.createElement("img"), caption = document.createElement("figcaption");
  box.className = "lg-original"; box.title = "click to close";
  original.src = img.currentSrc || img.src; original.alt = img.alt;
  original.width = img.naturalWidth; original.height = img.naturalHeight;
  caption.textContent = img.alt + " (original, " + img.naturalWidth + " x " + img.naturalHeight + " px)";
  figure.append(original, caption); box.append(figure); document.body.append(box);
});
"""


@functools.cache
def _plotlyjs() -> str:
    return get_plotlyjs()


def figure_html(rendered: Rendered, *, title: str, include_plotlyjs: str | bool = True, full_html: bool = True) -> str:
    """One rendered metric as HTML under a heading `title`.

    `include_plotlyjs`: True embeds plotly.js (only when the metric has a chart), False
    leaves it to the page, a string is a local script URL (e.g. "/static/plotly.min.js");
    network URLs and "cdn" are refused. `full_html=False` returns a fragment for a page.
    """
    body = f"<h1>{html.escape(title)}</h1>\n" + _metric_body(rendered, f"lg-{uuid.uuid4().hex[:12]}")
    script = _plotly_script(include_plotlyjs) if _has_chart(rendered) else ""
    if not full_html:
        return script + body
    return page_html(title, body, head_script=script)


def report_html(
    title: str,
    sections: list[tuple[str, list[tuple[str, Rendered | None, dict]]]],
    *,
    link: Linker | None = None,
    plotlyjs: str | bool = True,
    intro: str = "",
    nav: str = "",
) -> str:
    """One offline page showing many metrics, grouped in titled sections (`intro`: HTML shown
    under the title and the status counts, e.g. a served page's links; `nav`: links of the header bar).

    Each metric is (name, rendered or None when it has no result, info) where info may hold
    "status" (PASSED, WARNING, BLOCKER, ERROR, NOT_RUN or NO_DATA), "description", "units", "error" and
    "link_columns" (default `LINK_COLUMNS`) and "contents" (False: not listed in the table of
    contents, e.g. an event's attached metric): with `link`, a table's cells in those columns are
    links to `link(value)`. `plotlyjs` is `figure_html`'s `include_plotlyjs` (True: embedded).
    A page of several sections starts with their table of contents (each section's metrics and
    events linked), and each section's heading links back to the top.
    """
    counts: dict[str, int] = {}
    parts: list[str] = []
    contents: list[str] = []
    figure_number = 0
    for number, (section_title, metrics) in enumerate(sections, 1):
        section_id = f"lg-section-{number}"
        parts.append(
            f'<section id="{section_id}">\n<h2>{html.escape(section_title)}'
            '<a class="lg-up" href="#top">back to top</a></h2>'
        )
        entries: list[str] = []
        for name, rendered, info in metrics:
            status = info.get("status")
            if status is not None:
                counts[status] = counts.get(status, 0) + 1
            figure_number += 1
            div_id = f"lg-figure-{figure_number}"
            parts.append(_metric_article(name, rendered, info, div_id, link))
            if info.get("contents", True):
                entries.append(f'<a href="#{div_id}-card">{html.escape(name)}</a>')
        parts.append("</section>")
        if [name for name, _, _ in metrics] == [section_title]:
            entries = []  # a section of one item named as itself
        contents.append(
            f'<li><a href="#{section_id}">{html.escape(section_title)}</a>'
            f'<div class="lg-toc-items">{" · ".join(entries)}</div></li>'
        )
    summary = " ".join(
        f"<span>{status_badge(status)} {count}</span>" for status, count in sorted(counts.items(), key=_status_order)
    )
    toc = ""
    if len(sections) > 1:
        toc = f'<nav class="lg-toc" aria-label="Contents"><h2>Contents</h2><ol>{"".join(contents)}</ol></nav>\n'
    charts = any(_has_chart(rendered) for _, metrics in sections for _, rendered, _ in metrics if rendered)
    body = f'<h1>{html.escape(title)}</h1>\n<p class="lg-summary">{summary}</p>\n{intro}{toc}' + "\n".join(parts)
    return page_html(title, body, head_script=_plotly_script(plotlyjs) if charts else "", nav=nav)


def _status_order(item: tuple[str, int]) -> int:
    return list(STATUS_COLOURS).index(item[0])


def page_html(title: str, body: str, *, head_script: str = "", nav: str = "") -> str:
    """A whole page in the style of every lakegate page: a header bar (with `nav`'s links; the brand then
    links to `/`), then `body`; images of `.lg-images` show their original on a click (the only script
    of a page without charts)."""
    brand = '<a class="lg-brand" href="/">lakegate</a>' if nav else '<span class="lg-brand">lakegate</span>'
    images = f"<script>{ORIGINAL_IMAGE_JS}</script>\n" if 'class="lg-images"' in body else ""
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{html.escape(title)}</title>\n<style>{CSS}</style>\n{head_script}</head>\n"
        f'<body>\n<header class="lg-top" id="top">{brand}<nav>{nav}</nav></header>\n<main>\n{body}\n</main>\n'
        f"{images}</body>\n</html>\n"
    )


def _plotly_script(include_plotlyjs: str | bool) -> str:
    if include_plotlyjs is True:
        return f'<script type="text/javascript">{_plotlyjs()}</script>\n'
    if include_plotlyjs is False:
        return ""
    if include_plotlyjs == "cdn" or "://" in include_plotlyjs or include_plotlyjs.startswith("//"):
        raise ValueError(
            f"include_plotlyjs={include_plotlyjs!r} would load plotly.js from the network; "
            f"pass True to embed it or a local script path"
        )
    return f'<script src="{html.escape(include_plotlyjs)}"></script>\n'


def status_badge(status: str, text: str | None = None) -> str:
    """A status as a badge of its colour (`text`: other words on it, e.g. "not evaluated")."""
    colour = STATUS_COLOURS.get(status)
    if colour is None:
        raise ValueError(f"unknown metric status {status!r} (expected one of {', '.join(STATUS_COLOURS)})")
    return f'<span class="lg-badge" style="background:{colour}">{html.escape(text or status)}</span>'


def _metric_article(name: str, rendered: Rendered | None, info: dict, div_id: str, link: Linker | None) -> str:
    status = info.get("status")
    badge = status_badge(status) if status else ""
    parts = [f'<article class="lg-metric" id="{div_id}-card">\n<h3>{html.escape(name)}{badge}</h3>']
    if info.get("description"):
        parts.append(f'<p class="lg-meta">{html.escape(info["description"])}</p>')
    if info.get("units"):
        parts.append(f'<p class="lg-meta">Units: {html.escape(info["units"])}</p>')
    if info.get("error"):
        parts.append(f'<pre class="lg-error">{html.escape(str(info["error"]))}</pre>')
    if rendered is not None:
        links = (link, info.get("link_columns", LINK_COLUMNS)) if link is not None else None
        parts.append(_metric_body(rendered, div_id, links))
    parts.append("</article>")
    return "\n".join(parts)


def _has_chart(rendered: Rendered) -> bool:
    return rendered.figure is not None and rendered.shows != "table"


def _metric_body(rendered: Rendered, div_id: str, links: tuple[Linker, Sequence[str]] | None = None) -> str:
    """The result itself: a chart, a table (cells of `links`' columns linked), a scalar or images,
    then any problems."""
    problems = list(rendered.problems)
    if rendered.shows == "table" and rendered.table is not None:
        body = _table(rendered, links)
    elif _has_chart(rendered):
        body = _chart(rendered.figure, div_id, links[0] if links is not None else None)
    elif rendered.shows == "images":
        body, image_problems = _images(rendered.images)
        problems += image_problems
    elif rendered.shows == "videos":
        body, video_problems = _videos(rendered.table["rows"])
        problems += video_problems
    elif rendered.shows == "files":
        body = _artifacts(rendered.table["rows"])
    else:
        body = f'<div class="lg-scalar">{html.escape(rendered.text)}</div>'
    if problems:
        items = "".join(f"<li>{html.escape(p)}</li>" for p in problems)
        body += f'\n<ul class="lg-problems">{items}</ul>'
    return body


def script_json(value: object) -> str:
    """JSON that is safe inside a <script> element (no "</script>", no HTML comment openers)."""
    text = json.dumps(value, allow_nan=False, separators=(",", ":"), ensure_ascii=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _chart(figure: dict, div_id: str, link: Linker | None = None) -> str:
    """A Plotly chart; with `link`, a click on a bar or point of a chart with `link_path` values
    (templates.LINK_PATH, kept per trace in the layout's meta) opens the page its value links to."""
    layout = figure.get("layout", {})
    height = layout.get("height", 420)
    html_text = (
        f'<div id="{div_id}" style="height:{int(height)}px"></div>\n'
        f'<script>Plotly.newPlot("{div_id}", {script_json(figure.get("data", []))}, '
        f'{script_json(layout)}, {{"responsive": true, "displaylogo": false}});</script>'
    )
    values = (layout.get("meta") or {}).get(LINK_PATH) if isinstance(layout.get("meta"), dict) else None
    if link is None or not values:
        return html_text
    targets = [[link(value) if value is not None else None for value in trace] for trace in values]
    return html_text + (
        f'\n<script>document.getElementById("{div_id}").on("plotly_click", function (event) {{'
        f"var point = event.points[0], targets = {script_json(targets)}; "
        "var target = (targets[point.curveNumber] || [])[point.pointNumber]; "
        "if (target) { window.location.href = target; } });</script>"
    )


def _cell(value: Any, link: Linker | None) -> str:
    text = html.escape(display_value(value))
    target = link(value) if link is not None else None
    return f'<td><a href="{html.escape(target)}">{text}</a></td>' if target else f"<td>{text}</td>"


def _table(rendered: Rendered, links: tuple[Linker, Sequence[str]] | None = None) -> str:
    columns, rows = rendered.table["columns"], rendered.table["rows"]
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in columns)
    linkers = [links[0] if links is not None and str(c) in links[1] else None for c in columns]
    body = "".join(
        "<tr>" + "".join(_cell(v, link) for v, link in zip(row, linkers)) + "</tr>" for row in rows[:MAX_TABLE_ROWS]
    )
    more = ""
    if len(rows) > MAX_TABLE_ROWS:
        more = f'<p class="lg-meta">Showing the first {MAX_TABLE_ROWS} of {len(rows)} rows.</p>'
    return (
        f'<div class="lg-table-wrap"><table class="lg-table"><thead><tr>{head}</tr></thead>'
        f"<tbody>{body}</tbody></table></div>{more}"
    )


def _images(paths: list[str]) -> tuple[str, list[str]]:
    figures: list[str] = []
    problems: list[str] = []
    for name in paths:
        path = Path(name)
        try:
            size = LOCAL.stat(path).size
            mime = image_mime(path)
        except OSError as exc:
            problems.append(f"{path.name}: cannot be read ({exc.strerror})")
            continue
        if mime is None:
            problems.append(f"{path.name}: not a PNG, GIF or JPEG image")
            continue
        if size > MAX_IMAGE_BYTES:
            problems.append(f"{path.name}: {size} bytes, too large to embed (limit {MAX_IMAGE_BYTES})")
            continue
        data = base64.b64encode(LOCAL.read_bytes(path)).decode("ascii")
        caption = html.escape(path.name)
        figures.append(
            f'<figure><img src="data:{mime};base64,{data}" alt="{caption}"><figcaption>{caption}</figcaption></figure>'
        )
    return f'<div class="lg-images">{"".join(figures)}</div>', problems


def _data_uri(path: Path, mime: str) -> str:
    return f"data:{mime};base64,{base64.b64encode(LOCAL.read_bytes(path)).decode('ascii')}"


def _too_large(name: str, size: int) -> str:
    return f"{name}: {size} bytes, too large to embed (limit {MAX_IMAGE_BYTES})"


def _videos(rows: list[list]) -> tuple[str, list[str]]:
    """Each video in a <video> player (a GIF as an image: browsers do not play it as video)."""
    figures: list[str] = []
    problems: list[str] = []
    for name, path, size, mime in rows:  # FILE_COLUMNS
        if size > MAX_IMAGE_BYTES:
            problems.append(_too_large(name, size))
            continue
        source, caption = _data_uri(Path(path), mime), html.escape(name)
        if mime.startswith("video/"):
            player = f'<video controls preload="metadata" src="{source}" title="{caption}"></video>'
        else:
            player = f'<img src="{source}" alt="{caption}">'
        figures.append(f"<figure>{player}<figcaption>{caption}</figcaption></figure>")
    return f'<div class="lg-images">{"".join(figures)}</div>', problems


def _artifacts(rows: list[list]) -> str:
    """The files as a table of download links with their sizes (files over the limit by name only)."""
    cells = []
    for name, path, size, mime in rows:  # FILE_COLUMNS
        label = html.escape(name)
        if size <= MAX_IMAGE_BYTES:
            download = html.escape(Path(name).name)
            label = f'<a href="{_data_uri(Path(path), mime)}" download="{download}">{label}</a>'
        else:
            label += " (too large to embed)"
        cells.append(f"<tr><td>{label}</td><td>{html.escape(file_size(size))}</td></tr>")
    return (
        '<div class="lg-table-wrap"><table class="lg-table"><thead><tr><th>File</th><th>Size</th></tr></thead>'
        f"<tbody>{''.join(cells)}</tbody></table></div>"
    )


def file_size(size: int) -> str:
    """A file size for people: `512 B`, `1.5 KiB`, `20 MiB`."""
    units = ("B", "KiB", "MiB", "GiB", "TiB")
    value, power = float(size), 0
    while value >= 1024 and power < len(units) - 1:
        value, power = value / 1024, power + 1
    return f"{format_number(size if power == 0 else round(value, 1))} {units[power]}"
