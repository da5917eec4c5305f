"""The landing page of `lakegate serve`, at `/`: the lake's branches with their latest batches (builds,
jobs, statuses), links to the dashboard, trends and comparison pages, and how to connect a SQL client.

    GET /    the page (HTML, in the style of every lakegate page: figures_html.page_html)
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from urllib.parse import urlencode

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from lakegate.gateway.dashboard.routes import SERVED_NAV, DashboardState, admission, dashboard_router
from lakegate.gateway.metrics.figures_html import page_html, status_badge
from lakegate.gateway.metrics.trends import BatchInfo, branch_batches

#: Batches shown per branch, the newest first.
LATEST_BATCHES = 5


def pages_router(state: DashboardState) -> APIRouter:
    """Every page a server shows over `state`: the landing page at `/` and the dashboard under /dashboard."""
    router = APIRouter()
    router.include_router(dashboard_router(state))
    router.include_router(landing_router(state))
    return router


def landing_router(state: DashboardState) -> APIRouter:
    """The route of `/` over the dashboard's lake and engine."""
    router = APIRouter()

    @router.get("/", include_in_schema=False, dependencies=[admission(state)])
    def landing(request: Request) -> HTMLResponse:
        base = str(request.base_url).rstrip("/")
        return HTMLResponse(landing_html(state, base), headers={"Cache-Control": "no-cache"})

    return router


def landing_html(state: DashboardState, base_url: str) -> str:
    """The page for a server reached at `base_url` (scheme, host and port, as the browser named them)."""
    branches = state.catalog.branches()
    cards = "\n".join(_branch_card(state, branch) for branch in branches)
    body = (
        "<h1>lakegate</h1>\n"
        f'<p class="lg-meta">A Trino-compatible SQL endpoint and metrics dashboard over the lake '
        f"<code>{html.escape(str(state.lake.resolve()))}</code>.</p>\n"
        '<p class="lg-links"><a class="lg-button" href="/dashboard/">Open the dashboard</a>'
        '<a class="lg-button" href="/dashboard/trends/">Trends</a></p>\n'
        f"{_connect(state.engine.catalog, branches[0] if branches else 'main', base_url)}\n"
        "<h2>Branches</h2>\n"
        + (cards or '<p class="lg-meta">The lake has no branches yet: ingest a job (<code>lakegate ingest</code>).</p>')
    )
    return page_html("lakegate", body, nav=SERVED_NAV)


def _connect(catalog: str, schema: str, base_url: str) -> str:
    """How to reach the SQL endpoint: the SQLAlchemy URL, Python's trino client, JDBC and the Trino CLI."""
    scheme, _, address = base_url.partition("://")
    host, _, port = address.rpartition(":")
    if not host:  # the default port of the scheme
        host, port = address, "443" if scheme == "https" else "80"
    host = host.strip("[]")
    lines = [
        ("SQLAlchemy", f"trino://me@{address}/{catalog}/{schema}"),
        (
            "Python",
            f"trino.dbapi.connect(host={host!r}, port={port}, user='me', catalog={catalog!r}, schema={schema!r}"
            + (", http_scheme='https')" if scheme == "https" else ")"),
        ),
        ("JDBC", f"jdbc:trino://{address}/{catalog}/{schema}"),
        ("Trino CLI", f"trino --server {base_url} --catalog {catalog} --schema {schema}"),
    ]
    rows = "".join(f"<tr><th>{name}</th><td><code>{html.escape(text)}</code></td></tr>" for name, text in lines)
    return (
        '<section class="lg-connect"><h2>Connect a SQL client</h2>\n'
        f'<p class="lg-meta">Catalog <code>{html.escape(catalog)}</code>, one schema per branch; any user name '
        "(no password on loopback without <code>--users</code>).</p>\n"
        f'<table class="lg-table" id="connect">{rows}</table></section>'
    )


def _branch_card(state: DashboardState, branch: str) -> str:
    batches = branch_batches(state.evaluator, branch)
    statuses = _statuses(state, branch)
    latest = list(reversed(batches))[:LATEST_BATCHES]
    rows = "".join(_batch_row(branch, batch, statuses.get(batch.batch_id, {})) for batch in latest)
    more = f" (the latest {len(latest)} of {len(batches)})" if len(batches) > len(latest) else ""
    trends = f"/dashboard/trends/?{urlencode({'branch': branch})}"
    return (
        f'<article class="lg-metric lg-branch" data-branch="{html.escape(branch)}">\n'
        f'<h3>{html.escape(branch)} <a class="lg-small" href="{html.escape(trends)}">trends</a></h3>\n'
        f'<p class="lg-meta">{len(batches)} batch{"es" if len(batches) != 1 else ""}{more}</p>\n'
        '<div class="lg-table-wrap"><table class="lg-table"><thead><tr><th>Batch</th><th>Build</th><th>Started</th>'
        f"<th>Jobs</th><th>Job statuses</th><th></th></tr></thead><tbody>{rows}</tbody></table></div>\n"
        "</article>"
    )


def _batch_row(branch: str, batch: BatchInfo, statuses: dict[str | None, int]) -> str:
    page = f"/dashboard/?{urlencode({'branch': branch, 'batch': batch.batch_id})}"
    compare = f"/dashboard/compare/?{urlencode({'branch': branch, 'batch': batch.batch_id})}"
    counts = " ".join(f"{_badge(status)} {count}" for status, count in _in_order(statuses))
    started = batch.time.strftime("%Y-%m-%d %H:%M") if batch.time is not None else ""
    return (
        f'<tr><td><a href="{html.escape(page)}">{html.escape(batch.batch_id)}</a></td>'
        f"<td>{html.escape(', '.join(batch.builds))}</td><td>{started}</td><td>{batch.jobs}</td>"
        f'<td class="lg-statuses">{counts}</td><td><a href="{html.escape(compare)}">compare</a></td></tr>'
    )


def _statuses(state: DashboardState, branch: str) -> dict[str, dict[str | None, int]]:
    """Batch -> job conflated status (None: not evaluated) -> jobs."""
    answer = state.evaluator.query(
        "SELECT batch_id, job_conflated_status, count(*) FROM metadata GROUP BY 1, 2", branch, None
    )
    found: dict[str, dict[str | None, int]] = {}
    for batch_id, status, count in answer.rows():
        found.setdefault(batch_id, {})[status] = count
    return found


def _in_order(statuses: dict[str | None, int]) -> Sequence[tuple[str | None, int]]:
    order = ("PASSED", "WARNING", "BLOCKER", "ERROR")
    return sorted(statuses.items(), key=lambda item: order.index(item[0]) if item[0] in order else len(order))


def _badge(status: str | None) -> str:
    return status_badge(status) if status is not None else status_badge("NOT_RUN", "not evaluated")
