"""The debug dashboard: one web page (gateway/static) and the JSON API behind it, as a FastAPI router.

`dashboard_router(state)` serves, under `/dashboard`:

    GET    /dashboard/                                   the page (plain HTML + JS, no build step)
    GET    /dashboard/static/{file}                      its script and style; plotly.min.js from the
                                                         installed plotly package (never a CDN)
    GET    /dashboard/api/lake                           branches, their batches and jobs
    POST   /dashboard/api/sessions                       open a batch: {branch, batch, metrics_set?}
    GET    /dashboard/api/sessions/{id}?job=J            everything shown for job J (re-reads a changed config)
    POST   /dashboard/api/sessions/{id}/evaluate         evaluate every metric again
    POST   /dashboard/api/sessions/{id}/metrics          add a metric {name, type, template, query_string, status ...}
    PUT    /dashboard/api/sessions/{id}/metrics/{name}   edit a metric (e.g. {query_string}) and run it again
    DELETE /dashboard/api/sessions/{id}/metrics/{name}   drop the session's edit (or the added metric)
    GET    /dashboard/api/sessions/{id}/export           the session's config files as a zip
    GET    /dashboard/api/sessions/{id}/tables?scope=&job=   tables, columns, row counts in the scope
    POST   /dashboard/api/sessions/{id}/query            ad hoc SQL {sql, scope, job}: first 1,000 rows + total
    GET    /dashboard/api/sessions/{id}/events?job=J     the job's events in time order with their metrics
    GET    /dashboard/api/sessions/{id}/logs/{job}/{file}    a job's log file (the images metrics show)
    GET    /dashboard/trends/                            the branches, each linking to its trends page
    GET    /dashboard/trends/?branch=B[&window=30d|N][&set=S]   branch B's dashboard metrics over its
                                                         batches (gateway/metrics/trends.py): the page of
                                                         `lakegate metrics dashboard`, evaluated per request,
                                                         read-only, through the server's limits; a click
                                                         on two chart points (or a form) picks two of its
                                                         batches to compare (compare_picker.py); trend alerts
                                                         (&k=3&builds=10: gateway/metrics/alerts.py)
    GET    /dashboard/compare/?branch=B&batch=Y[&base=X]  the page of `lakegate compare` (base: the latest
                                                         batch of the previous build when not given)
    GET    /dashboard/trends/?branch=B&dashboard=N       the config's dashboard N (`dashboards:`): its set's
                                                         dashboard metrics over its day_range

A session (`debug_session.DashboardSession`) is one batch seen through a config plus the edits
made in the page. `lakegate metrics debug` opens one on its debug job; `lakegate serve` mounts
the same router, and the page opens a session for whichever branch / batch is picked. A session
belongs to the user who opened it (the one the server authenticated; everyone alike without
`--users`): another user opening the same batch gets a session of their own, and another's
session id is answered 404 as if it did not exist. A stored batch's session shows paths in the
lake relative to it, never the server's absolute paths.
"""

from __future__ import annotations

import html
import re
import secrets
import threading
from collections import OrderedDict
from collections.abc import AsyncIterator, Sequence
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import quote, urlencode

from fastapi import APIRouter, Body, Depends, HTTPException, Query, Request
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, RedirectResponse, Response

from lakegate.dialect.errors import DialectError
from lakegate.gateway.dashboard.compare_picker import compare_picker
from lakegate.gateway.dashboard.config_edits import BranchConfig, SessionError
from lakegate.gateway.dashboard.debug_session import DashboardSession
from lakegate.gateway.dashboard.user_slots import UserSlots
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.failures import hide_paths
from lakegate.gateway.metrics.alerts import HISTORY, K, alerts_html, trend_checks
from lakegate.gateway.metrics.compare import compare_batches, previous_build_batch
from lakegate.gateway.metrics.compare_page import compare_html
from lakegate.gateway.metrics.evaluation import MetricsEngine
from lakegate.gateway.metrics.figures_html import IMAGE_CSS, ORIGINAL_IMAGE_JS, page_html
from lakegate.gateway.metrics.results_table import read_results
from lakegate.gateway.metrics.trends import (
    BatchInfo,
    Window,
    branch_batches,
    evaluate_trends,
    in_window,
    metrics_of,
    trends_html,
)
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.catalog import Catalog
from lakegate.lake.config import ConfigError
from lakegate.lake.paths import LakePathError

STATIC = Path(__file__).resolve().parent / "static"
#: Files of the page, by URL name.
PAGE_FILES = {"dashboard.js": "text/javascript", "dashboard.css": "text/css"}
#: What the dashboard shares with the other pages (gateway/metrics/figures_html.py): how images are
#: scaled and open their original on a click.
SHARED_FILES = {"images.css": (IMAGE_CSS, "text/css"), "images.js": (ORIGINAL_IMAGE_JS, "text/javascript")}
#: The header bar's links of every served page.
SERVED_NAV = '<a href="/">Home</a><a href="/dashboard/">Dashboard</a><a href="/dashboard/trends/">Trends</a>'
#: Sessions on stored batches kept at once per user (the user's least recently opened is dropped first).
MAX_SESSIONS = 16


def plotly_js() -> Path:
    """plotly.min.js of the installed plotly package."""
    return Path(str(resources.files("plotly") / "package_data" / "plotly.min.js"))


class DashboardState:
    """The dashboard's sessions over one lake, queried through `engine` (default: the embedded
    DuckDB engine); `evaluator` evaluates their metrics through the same engine."""

    def __init__(self, lake: Path, engine: Engine | None = None):
        self.lake = Path(lake)
        self._owns_engine = engine is None
        self.engine = engine if engine is not None else Engine.open(self.lake)
        self.evaluator = MetricsEngine(self.lake, self.engine)
        self.slots = UserSlots(self.engine.limits.user_slots, self.engine.limits.query_timeout)
        self.catalog = Catalog(self.lake)
        self.sessions: OrderedDict[str, DashboardSession] = OrderedDict()
        self.owners: dict[str, str | None] = {}  # session id -> the user who opened it
        self.debug_session: DashboardSession | None = None
        self._lock = threading.Lock()

    def close(self) -> None:
        """Close the engine if the state made it."""
        if self._owns_engine:
            self.engine.close()

    def new_id(self) -> str:
        return secrets.token_urlsafe(9)

    def add(self, session: DashboardSession, *, debug: bool = False, owner: str | None = None) -> DashboardSession:
        """Keep `session`, opened by `owner` (dropping the owner's least recently opened beyond MAX_SESSIONS)."""
        with self._lock:
            self.sessions[session.id] = session
            self.owners[session.id] = owner
            if debug:
                self.debug_session = session
            stored = [
                sid for sid, s in self.sessions.items() if s is not self.debug_session and self.owners[sid] == owner
            ]
            for sid in stored[: max(0, len(stored) - MAX_SESSIONS)]:
                del self.sessions[sid], self.owners[sid]
        return session

    def session(self, session_id: str, owner: str | None = None) -> DashboardSession:
        """The session `session_id` of `owner` (404 for an unknown one and for another user's)."""
        with self._lock:
            session = self.sessions.get(session_id)
            if session is None or self.owners.get(session_id) != owner:
                raise HTTPException(404, f"no dashboard session {session_id!r} (it may have expired: reload the page)")
            return session

    def open_batch(
        self, branch: str, batch_id: str, metrics_set: str | None = None, owner: str | None = None
    ) -> DashboardSession:
        """`owner`'s session on a stored batch, seen through the branch's current config (reused when open)."""
        with self._lock:
            for session in self.sessions.values():
                if (
                    (session.branch, session.batch_id) == (branch, batch_id)
                    and not session.debug
                    and self.owners[session.id] == owner
                    and (metrics_set is None or session.metrics_set == metrics_set)
                ):
                    self.sessions.move_to_end(session.id)
                    return session
        debug = self.debug_session
        if debug is not None and (debug.branch, debug.batch_id) == (branch, batch_id):
            raise SessionError(
                "this batch is the debug job of 'lakegate metrics debug': open the Dashboard URL it "
                "printed (the one with ?session=...)"
            )
        if branch not in self.catalog.branches():
            raise SessionError(f"no branch {branch!r} in the lake")
        if batch_id not in self.catalog.batches(branch):
            raise SessionError(f"no batch {batch_id!r} on branch {branch!r}")
        source = BranchConfig(self.lake, branch)
        if metrics_set is None:  # the set of the stored results, else the config's first set
            sets = list(source.registry.current().metrics_sets) if source.registry.current_version() else []
            stored = read_results(self.lake, branch, batch_id)
            metrics_set = (
                stored[0]["metrics_set"] if stored and stored[0]["metrics_set"] in sets else sets[0] if sets else None
            )
        session = DashboardSession(
            self.new_id(), self.evaluator, branch=branch, batch_id=batch_id, source=source, metrics_set=metrics_set
        )
        return self.add(session, owner=owner)

    def view(self, session: DashboardSession, job: str | None) -> dict[str, Any]:
        """What the page shows of `session` for `job`: a stored batch's paths relative to the lake."""
        shown = session.state(job)
        return shown if session.debug else _without_paths(shown, self.lake)

    def trends(
        self,
        branch: str,
        window: str | None = None,
        metrics_set: str | None = None,
        dashboard: str | None = None,
        *,
        k: float = K,
        history: int = HISTORY,
    ) -> str:
        """The trends page of a branch: its stored config's dashboard metrics (of `metrics_set`, or of
        the set of the config's `dashboard`) over the batches of `window` (default: the dashboard's
        day_range, else every batch), evaluated now, with the trend alerts (`k` standard deviations of
        the `history` previous builds); SessionError for what cannot be shown."""
        if branch not in self.catalog.branches():
            raise SessionError(f"no branch {branch!r} in the lake")
        chosen = Window.parse(window) if window else None
        source = BranchConfig(self.lake, branch)
        files = source.read()
        try:
            config = source.registry.load(files.version)
            if dashboard is not None:
                if metrics_set is not None:
                    raise SessionError("dashboard and set both choose the metrics: give one")
                named = config.dashboard(dashboard)
                metrics_set = named.metrics_set
                if chosen is None and named.day_range is not None:
                    chosen = Window(days=named.day_range)
            metrics = metrics_of(config, "dashboard", metrics_set)
        except KeyError as error:
            raise SessionError(str(error.args[0])) from None
        if not metrics:
            raise SessionError(f"branch {branch!r} has no 'type: dashboard' metrics in its config")
        batches = in_window(branch_batches(self.evaluator, branch), chosen)
        evaluation = evaluate_trends(
            self.evaluator, branch, metrics, batches, kind="dashboard", window=chosen, config_version=files.version
        )
        ids = [b.batch_id for b in batches]
        form = self.compare_form(branch, ids[-2] if len(ids) > 1 else None, ids[-1] if ids else None, batches)
        alerts = alerts_html(trend_checks(self.evaluator, branch, ids, k=k, history=history))
        intro = form + compare_picker(branch, batches) + alerts
        return trends_html(evaluation, plotlyjs="/dashboard/static/plotly.min.js", intro=intro, nav=SERVED_NAV)

    def compare(self, branch: str, batch: str | None, base: str | None = None) -> str:
        """The comparison page of batch `batch` with `base` (default: the latest batch of the previous
        build), computed now; SessionError for what cannot be shown."""
        if branch not in self.catalog.branches():
            raise SessionError(f"no branch {branch!r} in the lake")
        if not batch:
            raise SessionError("name the batch to compare: /dashboard/compare/?branch=B&batch=Y (&base=X)")
        try:
            base = base or previous_build_batch(self.evaluator, branch, batch)
            comparison = compare_batches(self.evaluator, branch, base, batch)
        except LookupError as error:
            raise SessionError(str(error.args[0])) from None
        intro = self.compare_form(branch, base, batch)
        return compare_html(comparison, plotlyjs="/dashboard/static/plotly.min.js", intro=intro, nav=SERVED_NAV)

    def compare_form(
        self, branch: str, base: str | None, batch: str | None, batches: Sequence[BatchInfo] | None = None
    ) -> str:
        """A form that picks two of `batches` (default: every batch of the branch), base and new, and opens
        their comparison page."""
        batches = branch_batches(self.evaluator, branch) if batches is None else batches

        def select(name: str, chosen: str | None) -> str:
            options = "".join(
                f'<option value="{html.escape(b.batch_id)}"{" selected" if b.batch_id == chosen else ""}>'
                f"{html.escape(b.batch_id)} ({html.escape(', '.join(b.builds) or '?')})</option>"
                for b in batches
            )
            return f'<select name="{name}" id="compare-{name}">{options}</select>'

        batch_page = urlencode({"branch": branch, **({"batch": batch} if batch else {})})
        return (
            f'<form class="lg-compare" method="get" action="/dashboard/compare/">'
            f'<input type="hidden" name="branch" value="{html.escape(branch)}">'
            f"Compare base {select('base', base)} with {select('batch', batch)} "
            '<button type="submit" id="compare-go">Compare</button> · '
            f'<a href="/dashboard/trends/?{urlencode({"branch": branch})}">Trends</a> · '
            f'<a href="/dashboard/?{batch_page}">Batch page</a>'
            "</form>\n"
        )

    def trends_index(self) -> str:
        """A page linking to each branch's trends page (and its named dashboards)."""
        items = "".join(
            f'<li><a href="?{urlencode({"branch": b})}">{html.escape(b)}</a>{self._dashboard_links(b)}</li>'
            for b in self.catalog.branches()
        )
        body = (
            "<h1>Trends: dashboard metrics of each branch</h1>\n"
            '<p class="lg-meta">Each branch\'s <code>type: dashboard</code> metrics over its batches and builds, '
            "evaluated when the page opens.</p>\n"
            f'<ul class="lg-list">{items or "<li>no branches yet</li>"}</ul>\n'
            '<p><a href="../">Batches: the metrics dashboard</a></p>'
        )
        return page_html("lakegate · trends", body, nav=SERVED_NAV)

    def _dashboard_links(self, branch: str) -> str:
        """`: <a>N</a>, ...` for each dashboard of the branch's stored config ('' when it has none or does not load)."""
        try:
            config = BranchConfigs(self.lake, branch).current()
        except ConfigError:
            return ""
        if config is None or not config.dashboards:
            return ""
        links = ", ".join(
            f'<a href="?{html.escape(urlencode({"branch": branch, "dashboard": name}))}">{html.escape(name)}</a>'
            for name in config.dashboards
        )
        return f": {links}"

    def listing(self) -> dict[str, Any]:
        """Branches with their batches and jobs (never a session id: the debug session's is in its URL)."""
        branches = []
        for branch in self.catalog.branches():
            batches: dict[str, list[str]] = {}
            for job in self.catalog.jobs(branch):
                batches.setdefault(job.batch_id, []).append(job.job_id)
            branches.append({"name": branch, "batches": [{"id": b, "jobs": jobs} for b, jobs in batches.items()]})
        return {"branches": branches}


def attachment(filename: str) -> str:
    """A Content-Disposition header value for a download named `filename` (RFC 6266): an ASCII
    fallback with anything but letters, digits, `.`, `_` and `-` replaced, and the exact UTF-8 name."""
    fallback = re.sub(r"[^A-Za-z0-9._-]", "_", filename)
    return f"attachment; filename=\"{fallback}\"; filename*=UTF-8''{quote(filename, safe='')}"


def _error_page(message: str, what: str = "trends") -> str:
    body = (
        f"<h1>Cannot show the {what}</h1>\n"
        f'<p class="lg-error">{html.escape(message)}</p>\n<p><a href="/dashboard/trends/">All branches</a></p>'
    )
    return page_html(f"lakegate · {what}", body, nav=SERVED_NAV)


def _bad_request(error: Exception) -> HTTPException:
    problems = getattr(error, "problems", [])
    return HTTPException(400, {"message": str(error), "problems": problems})


def _user(request: Request) -> str | None:
    """The user the server authenticated for this request (None without a users file)."""
    return getattr(request.state, "user", None)


def _without_paths(value: Any, lake: Path) -> Any:
    """`value` (JSON: dicts, lists, text) with every path under `lake` made relative to it."""
    if isinstance(value, str):
        return hide_paths(value, lake.resolve(), lake)
    if isinstance(value, dict):
        return {key: _without_paths(item, lake) for key, item in value.items()}
    if isinstance(value, list):
        return [_without_paths(item, lake) for item in value]
    return value


def admission(state: DashboardState) -> Any:
    """The dependency of a route that runs queries: it holds one of its user's slots (user_slots.py)."""

    async def admitted(request: Request) -> AsyncIterator[None]:
        async with state.slots.held(_user(request)):
            yield

    return Depends(admitted)


def dashboard_router(state: DashboardState) -> APIRouter:
    """The page and its API (see the module docstring), to mount on the gateway's app."""
    router = APIRouter(prefix="/dashboard")
    queries = [admission(state)]

    def call(function: Any, *args: Any, **kwargs: Any) -> Any:
        try:
            return function(*args, **kwargs)
        except (SessionError, LakePathError, DialectError) as error:
            raise _bad_request(error) from None

    @router.get("", include_in_schema=False)
    def page_redirect() -> RedirectResponse:
        return RedirectResponse("/dashboard/")

    @router.get("/", include_in_schema=False)
    def page() -> FileResponse:
        return FileResponse(STATIC / "dashboard.html", media_type="text/html", headers={"Cache-Control": "no-cache"})

    @router.get("/static/{name}", include_in_schema=False)
    def static(name: str) -> FileResponse:
        if name == "plotly.min.js":
            return FileResponse(plotly_js(), media_type="text/javascript", headers={"Cache-Control": "max-age=86400"})
        if name in SHARED_FILES:
            text, media_type = SHARED_FILES[name]
            return Response(text, media_type=media_type, headers={"Cache-Control": "no-cache"})
        if name not in PAGE_FILES:
            raise HTTPException(404, f"no file {name!r}")
        return FileResponse(STATIC / name, media_type=PAGE_FILES[name], headers={"Cache-Control": "no-cache"})

    @router.get("/trends", include_in_schema=False)
    def trends_redirect() -> RedirectResponse:
        return RedirectResponse("/dashboard/trends/")

    @router.get("/trends/", include_in_schema=False, dependencies=queries)
    def trends(
        branch: str | None = None,
        window: str | None = None,
        metrics_set: str | None = Query(None, alias="set"),
        dashboard: str | None = None,
        k: float = Query(K, gt=0),
        builds: int = Query(HISTORY, ge=2),
    ) -> HTMLResponse:
        if branch is None:
            return HTMLResponse(call(state.trends_index), headers={"Cache-Control": "no-cache"})
        try:
            page = state.trends(branch, window, metrics_set, dashboard, k=k, history=builds)
        except (SessionError, LakePathError, DialectError, ValueError) as error:
            return HTMLResponse(_error_page(str(error)), status_code=400)
        return HTMLResponse(page, headers={"Cache-Control": "no-cache"})

    @router.get("/compare", include_in_schema=False)
    def compare_redirect() -> RedirectResponse:
        return RedirectResponse("/dashboard/compare/")

    @router.get("/compare/", include_in_schema=False, dependencies=queries)
    def compare(branch: str | None = None, batch: str | None = None, base: str | None = None) -> HTMLResponse:
        try:
            if branch is None:
                raise SessionError("name the branch and the batch: /dashboard/compare/?branch=B&batch=Y (&base=X)")
            page = state.compare(branch, batch, base)
        except (SessionError, LakePathError, DialectError) as error:
            return HTMLResponse(_error_page(str(error), "comparison"), status_code=400)
        return HTMLResponse(page, headers={"Cache-Control": "no-cache"})

    @router.get("/api/lake", dependencies=queries)
    def lake() -> dict[str, Any]:
        return call(state.listing)

    @router.post("/api/sessions", dependencies=queries)
    def open_session(request: Request, body: dict[str, Any] = Body(...)) -> dict[str, Any]:
        session = call(
            state.open_batch,
            str(body.get("branch", "")),
            str(body.get("batch", "")),
            body.get("metrics_set") or None,
            owner=_user(request),
        )
        return call(state.view, session, body.get("job"))

    @router.get("/api/sessions/{session_id}", dependencies=queries)
    def session_state(request: Request, session_id: str, job: str | None = None) -> dict[str, Any]:
        session = state.session(session_id, _user(request))
        call(session.refresh)
        return call(state.view, session, job)

    @router.post("/api/sessions/{session_id}/evaluate", dependencies=queries)
    def evaluate(request: Request, session_id: str, job: str | None = None) -> dict[str, Any]:
        session = state.session(session_id, _user(request))
        call(session.evaluate_all)
        return call(state.view, session, job)

    @router.post("/api/sessions/{session_id}/metrics", dependencies=queries)
    def add_metric(
        request: Request, session_id: str, body: dict[str, Any] = Body(...), job: str | None = None
    ) -> dict[str, Any]:
        session = state.session(session_id, _user(request))
        spec = {k: v for k, v in body.items() if k != "name"}
        call(session.add_metric, str(body.get("name") or ""), spec)
        return call(state.view, session, job)

    @router.put("/api/sessions/{session_id}/metrics/{name:path}", dependencies=queries)
    def update_metric(
        request: Request, session_id: str, name: str, body: dict[str, Any] = Body(...), job: str | None = None
    ) -> dict[str, Any]:
        session = state.session(session_id, _user(request))
        call(session.update_metric, name, body)
        return call(state.view, session, job)

    @router.delete("/api/sessions/{session_id}/metrics/{name:path}", dependencies=queries)
    def revert_metric(request: Request, session_id: str, name: str, job: str | None = None) -> dict[str, Any]:
        session = state.session(session_id, _user(request))
        call(session.revert_metric, name)
        return call(state.view, session, job)

    @router.get("/api/sessions/{session_id}/export")
    def export(request: Request, session_id: str) -> Response:
        session = state.session(session_id, _user(request))
        data = call(session.export_zip)
        stem = Path(session.files.names[0]).name.split(".")[0] if session.files else "config"
        return Response(
            data, media_type="application/zip", headers={"Content-Disposition": attachment(f"{stem}-export.zip")}
        )

    @router.get("/api/sessions/{session_id}/tables", dependencies=queries)
    def tables(request: Request, session_id: str, scope: str = "job", job: str | None = None) -> dict[str, Any]:
        session = state.session(session_id, _user(request))
        return {"tables": call(session.tables, call(session.scope, scope, job))}

    @router.post("/api/sessions/{session_id}/query", dependencies=queries)
    def query(request: Request, session_id: str, body: dict[str, Any] = Body(...)) -> JSONResponse:
        session = state.session(session_id, _user(request))
        scope = call(session.scope, str(body.get("scope", "job")), body.get("job"))
        return JSONResponse(call(session.query, str(body.get("sql", "")), scope))

    @router.get("/api/sessions/{session_id}/events", dependencies=queries)
    def events(request: Request, session_id: str, job: str) -> dict[str, Any]:
        session = state.session(session_id, _user(request))
        return {"events": call(session.events, job)}

    @router.get("/api/sessions/{session_id}/logs/{job_id}/{name:path}")
    def log_file(request: Request, session_id: str, job_id: str, name: str) -> FileResponse:
        session = state.session(session_id, _user(request))
        try:
            return FileResponse(session.log_file(job_id, name))
        except (SessionError, LakePathError) as error:
            raise HTTPException(404, str(error)) from None

    return router
