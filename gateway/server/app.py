"""The SQL endpoint: Trino's HTTP client protocol (FastAPI) over an Engine: its routes.

The life of each query (worker threads, pages, the reaper) is gateway/server/query_lifecycle.py.

Routes: /v1/statement, /v1/statement/executing/{id}/{slug}/{token} (GET, HEAD, DELETE),
/v1/query/{id} (GET, DELETE), /v1/spooled/download/{segment} (GET, DELETE) and
/v1/spooled/ack/{segment} (GET) of the spooling protocol (`spooling`), /v1/arrow (POST: a result as
Arrow IPC, `arrow_results`), /v1/info, /v1/info/state. With `users`, every route but /v1/info,
/v1/info/state and the spooled segments needs HTTP Basic credentials (checked by
`http_limits.Guard` before a body is read)."""

from __future__ import annotations

import time
from collections.abc import Sequence
from contextlib import asynccontextmanager

import orjson
from fastapi import APIRouter, FastAPI, Request
from fastapi.responses import PlainTextResponse, Response
from starlette.concurrency import run_in_threadpool
from starlette.routing import Match, Route
from starlette.types import ASGIApp, Receive, Scope, Send

from lakegate.dialect.errors import DialectError
from lakegate.dialect.statements import Statement, read
from lakegate.gateway.engine import session as sessions
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.planner import static_result
from lakegate.gateway.engine.session import Answer, Session
from lakegate.gateway.engine.trino_values import encode_rows
from lakegate.gateway.server import arrow_results, spooling
from lakegate.gateway.server.auth import Users
from lakegate.gateway.server.host_check import HostCheck
from lakegate.gateway.server.http_limits import Guard, authenticated_user
from lakegate.gateway.server.protocol import (
    Failure,
    Progress,
    columns_document,
    info_document,
    results_document,
)
from lakegate.gateway.server.query_lifecycle import SPOOLED_BYTES, Query, QueryManager

JSON = "application/json"


def _immediate(query_id: str, base: str, answer: Answer | None = None, failure: Failure | None = None) -> bytes:
    """The one document of a statement answered at once (session statements, CALL, refusals)."""
    progress = Progress("FAILED" if failure is not None else "FINISHED")
    columns = data = None
    if answer is not None:
        result = static_result(answer)
        columns = columns_document(result.columns)
        data = orjson.dumps([row for batch in result.batches for row in encode_rows(result.columns, batch)])
    return results_document(
        query_id=query_id,
        info_uri=f"{base}/v1/query/{query_id}",
        progress=progress,
        columns=columns,
        data=data,
        failure=failure,
        update_type=answer.update_type if answer is not None else None,
    )


# --- the app ------------------------------------------------------------------------------------


class _Endpoints:
    """The protocol's routes (plain Starlette endpoints: no per-request validation work)."""

    def __init__(self, manager: QueryManager, engine: Engine, users: Users | None):
        self.manager, self.engine, self.limits, self.users = manager, engine, engine.limits, users
        self.started = time.monotonic()

    async def query(self, request: Request, *, slug: bool = True) -> Query | None:
        """The query the path names, if it exists and the authenticated user may see it."""
        user = authenticated_user(request.scope)
        params = request.path_params
        query = self.manager.get(params["query_id"])
        if query is None or (user is not None and query.session.user != user):
            return None
        return query if not slug or query.slug == params["slug"] else None

    async def post_statement(self, request: Request) -> Response:
        session = _session(request)
        if isinstance(session, Response):
            return session
        body = await request.body()
        if not body.strip():
            return PlainTextResponse("SQL statement is empty", 400)
        base = _base_url(request)
        try:
            sql = body.decode("utf-8")
        except UnicodeDecodeError as error:
            failure = Failure(f"the query text is not valid UTF-8 (byte {error.start})", "SYNTAX_ERROR")
            return Response(_immediate(self.manager.ids.next(), base, failure=failure), media_type=JSON)
        statement = read(sql)
        if statement.kind in ("session", "call"):
            return await self._answer(statement, session, base)
        query = self.manager.create(statement, session, spooling.negotiate(request.headers.get(spooling.HEADER)))
        if query.failure is not None:  # refused (queue full)
            return Response(query.first_document(base), media_type=JSON)
        self.manager.start(query)
        return Response(await query.answer(base, self.limits.answer_wait), media_type=JSON)

    async def post_arrow(self, request: Request) -> Response:
        """POST /v1/arrow: the query's result as an Arrow IPC stream (`arrow_results`)."""
        session = _session(request)
        if isinstance(session, Response):
            return session
        try:
            sql = (await request.body()).decode("utf-8")
        except UnicodeDecodeError as error:
            return PlainTextResponse(str(error), 400)
        return await arrow_results.arrow_response(self.engine, sql, session, self.limits)

    async def _answer(self, statement: Statement, session: Session, base: str) -> Response:
        """A session statement or CALL, answered at once by the engine."""
        query_id = self.manager.ids.next()
        try:
            answer = await run_in_threadpool(self.engine.answer, statement, session)
        except DialectError as error:
            return Response(_immediate(query_id, base, failure=Failure.of(error)), media_type=JSON)
        return Response(_immediate(query_id, base, answer), media_type=JSON, headers=dict(answer.headers))

    async def get_results(self, request: Request) -> Response:
        query = await self.query(request)
        token = request.path_params["token"]
        body = None if query is None else await query.fetch(token, _base_url(request), self.limits.wait)
        if body is None:
            return PlainTextResponse(
                f"Query {request.path_params['query_id']} has no document {token} (unknown, finished or expired)", 404
            )
        return Response(body, media_type=JSON)

    async def head_results(self, request: Request) -> Response:
        """A client's heartbeat (HEAD nextUri): the query's client is still there."""
        query = await self.query(request)
        if query is not None:
            query.last_access = time.monotonic()
        return Response(status_code=404 if query is None else 200)

    async def delete(self, request: Request) -> Response:
        """DELETE nextUri or /v1/query/{id}: cancel (204 also for unknown or finished queries)."""
        query = await self.query(request, slug="slug" in request.path_params)
        if query is not None:
            query.fail(Failure("Query was canceled", "USER_CANCELED"))
        return Response(status_code=204)

    async def get_query(self, request: Request) -> Response:
        query = await self.query(request, slug=False)
        if query is None:
            return PlainTextResponse(f"Query {request.path_params['query_id']} not found", 404)
        return Response(orjson.dumps(query.info()), media_type=JSON)

    async def get_segment(self, request: Request) -> Response:
        """A spooled segment's payload (GET its `uri`)."""
        payload = self.manager.segments.get(request.path_params["segment_id"])
        if payload is None:
            return PlainTextResponse("Segment not found (unknown, acknowledged or expired)", 404)
        return Response(payload, media_type="application/octet-stream")

    async def ack_segment(self, request: Request) -> Response:
        """Acknowledge a spooled segment (GET its `ackUri`, or DELETE its `uri`): it is forgotten."""
        if not self.manager.segments.ack(request.path_params["segment_id"]):
            return PlainTextResponse("Segment not found (unknown, acknowledged or expired)", 404)
        return Response(status_code=200)

    async def get_info(self, request: Request) -> Response:
        return Response(info_document(self.started), media_type=JSON)

    async def get_state(self, request: Request) -> Response:
        return Response(b'"ACTIVE"', media_type=JSON)


def _session(request: Request) -> Session | Response:
    """The session of a request that posts a statement, or the reply refusing it: 403 when an
    authenticated user names another user, 400 for a malformed session header."""
    user = authenticated_user(request.scope)
    if user is not None and request.headers.get("x-trino-user") not in (None, user):
        return PlainTextResponse(
            f"Access Denied: User {user} cannot impersonate user {request.headers['x-trino-user']}", 403
        )
    try:
        return sessions.from_headers(request.headers, user)
    except sessions.HeaderError as error:
        return PlainTextResponse(str(error), 400)


def _base_url(request: Request) -> str:
    """The URL the client reached the server at (scheme, host and port, root path), without the
    cost of Starlette's URL parsing."""
    scope = request.scope
    host = request.headers.get("host")
    if host is None:  # HTTP/1.0 without Host: the address the server listens on
        name, port = scope.get("server") or ("127.0.0.1", None)
        host = name if port in (None, {"http": 80, "https": 443}.get(scope["scheme"])) else f"{name}:{port}"
    return f"{scope['scheme']}://{host}{scope.get('root_path', '')}".rstrip("/")


class _App(FastAPI):
    """FastAPI with a short path for the protocol's routes: a request one of them matches in full
    (path and method) goes through the same checks (`HostCheck`, `Guard`) straight to its endpoint,
    past FastAPI's own layers (error pages, telemetry, body limit, exception handlers, exit stack,
    router), which cost a fast query a tenth of the server's CPU. Everything else (a path or method no
    protocol route takes, the dashboard, lifespan) goes through FastAPI as before."""

    protocol_routes: list[Route]
    protocol: ASGIApp

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http":
            for route in self.protocol_routes:
                match, child = route.matches(scope)
                if match is Match.FULL:
                    scope["app"] = self
                    scope.update(child)
                    scope["route"] = route
                    await self.protocol(scope, receive, send)
                    return
        await super().__call__(scope, receive, send)


def create_app(
    engine: Engine,
    *,
    users: Users | None = None,
    dashboard_router: APIRouter | None = None,
    allowed_hosts: Sequence[str] = (),
) -> FastAPI:
    """The SQL endpoint over `engine` (its catalog, backend and limits: `engine.limits` bound queries
    and requests, `http_limits.Guard`).

    With `users`, every request but /v1/info and /v1/info/state needs HTTP Basic credentials of one
    of them. `dashboard_router` is included as it is, behind the same guard. Every request must name
    this server in Host (and Origin, when it changes something): `host_check.HostCheck`, with
    `allowed_hosts` for a proxy. `app.state` holds `engine` and `manager` (QueryManager). Closing the
    app (lifespan shutdown) fails running queries and stops the workers; the engine stays open (its
    owner closes it).
    """
    limits = engine.limits
    segments = spooling.SegmentStore(ttl=limits.client_timeout, max_bytes=SPOOLED_BYTES)
    manager = QueryManager(engine, limits, segments)
    engine.list_queries(
        lambda user: [query.row() for query in manager.queries() if users is None or query.session.user == user]
    )
    engine.kill_queries(
        lambda query_id, message, session: manager.kill(query_id, message, session, owner_only=users is not None)
    )

    @asynccontextmanager
    async def lifespan(_: FastAPI):
        yield
        await run_in_threadpool(manager.close)

    app = _App(title="lakegate", lifespan=lifespan, docs_url=None, redoc_url=None, openapi_url=None)
    app.state.manager, app.state.engine, app.state.segments = manager, engine, segments
    endpoints = _Endpoints(manager, engine, users)
    executing = "/v1/statement/executing/{query_id}/{slug}/{token:int}"
    app.add_route("/v1/statement", endpoints.post_statement, methods=["POST"])
    app.add_route(arrow_results.PATH, endpoints.post_arrow, methods=["POST"])
    app.add_route(executing, endpoints.head_results, methods=["HEAD"])  # before GET, which also matches HEAD
    app.add_route(executing, endpoints.get_results, methods=["GET"])
    app.add_route(executing, endpoints.delete, methods=["DELETE"])
    app.add_route("/v1/query/{query_id}", endpoints.get_query, methods=["GET"])
    app.add_route("/v1/query/{query_id}", endpoints.delete, methods=["DELETE"])
    app.add_route(spooling.SEGMENT_PATH, endpoints.get_segment, methods=["GET"])
    app.add_route(spooling.SEGMENT_PATH, endpoints.ack_segment, methods=["DELETE"])
    app.add_route(spooling.ACK_PATH, endpoints.ack_segment, methods=["GET"])
    app.add_route("/v1/info", endpoints.get_info, methods=["GET"])
    app.add_route("/v1/info/state", endpoints.get_state, methods=["GET"])
    if dashboard_router is not None:
        app.include_router(dashboard_router)

    def statement_error(scope: dict, message: str) -> bytes:
        failure = Failure(message, "QUERY_TEXT_TOO_LARGE")
        return _immediate(manager.ids.next(), _base_url(Request(scope)), failure=failure)

    app.add_middleware(Guard, limits=limits, users=users, statement_error=statement_error)
    app.add_middleware(HostCheck, allowed=allowed_hosts)
    app.protocol_routes = [
        route
        for route in app.router.routes
        if isinstance(route, Route) and getattr(route.endpoint, "__self__", None) is endpoints
    ]
    app.protocol = HostCheck(
        Guard(_handle_matched, limits=limits, users=users, statement_error=statement_error), allowed=allowed_hosts
    )
    return app


async def _handle_matched(scope: Scope, receive: Receive, send: Send) -> None:
    """The response of the protocol route `_App` matched (`scope["route"]`): its endpoint is an
    `_Endpoints` coroutine method, which raises no HTTPException."""
    response = await scope["route"].endpoint(Request(scope, receive, send))
    await response(scope, receive, send)
