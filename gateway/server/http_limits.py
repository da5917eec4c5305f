"""What one HTTP request may cost the server, enforced before the app sees it.

`Guard` is pure ASGI middleware around the whole app (the dashboard's routes included): with a
users file it authenticates every request but the public probes (`/v1/info`, `/v1/info/state`) and
the spooled segments (`/v1/spooled/...`, reached by a 256-bit random name, as Trino's segment
resource is public and the trino client fetches segments without credentials)
before any body is read, then refuses a body over `Limits.max_body` by its Content-Length, or
while it streams in, with HTTP 413. A client that goes away mid-request ends its request quietly.

`GuardedProtocol` (`server_config` gives uvicorn) bounds what a connection may send before the app
sees it: request headers over `Limits.max_header_bytes` get 431 (counted as they arrive and again as
they are parsed, so a request that arrives whole in one read is caught too), a request whose headers
and body have not all arrived `Limits.request_timeout` seconds after it began (or after the
connection opened) gets 408 and is closed, and connections beyond `Limits.max_connections` are
answered 503 and closed at once, so idle or trickling clients cannot hold file descriptors or
memory. A request target in absolute form (`GET http://name/path`) has its authority put in the
scope as `TARGET_HOST` for the Host check (host_check.py); any other target that is not a path
gets 400.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from typing import Any

import httptools
from starlette.concurrency import run_in_threadpool
from starlette.requests import ClientDisconnect
from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.server.auth import LoginFailures, Users, basic_credentials
from lakegate.gateway.server.host_check import TARGET_HOST

log = logging.getLogger("lakegate.server")

#: Paths anyone may read, as in Trino (ServerInfoResource: @ResourceSecurity(PUBLIC)).
PUBLIC_PATHS = frozenset({"/v1/info", "/v1/info/state"})
#: Path prefixes anyone may read (Trino's SegmentResource: @ResourceSecurity(PUBLIC)).
PUBLIC_PREFIXES = ("/v1/spooled/",)
UNAUTHORIZED = "Unauthorized: a valid user name and password are needed (HTTP Basic)"
STATEMENT_PATH = "/v1/statement"

Scope = dict[str, Any]
Receive = Callable[[], Awaitable[dict]]
Send = Callable[[dict], Awaitable[None]]
#: The body of a refused statement: (scope, message) -> a Trino QueryResults document (JSON bytes).
StatementError = Callable[[Scope, str], bytes]


def authenticated_user(scope: Scope) -> str | None:
    """The user `Guard` authenticated for this request (None without a users file, or on a public path)."""
    return scope.get("state", {}).get("user")


async def _respond(
    send: Send,
    status: int,
    body: bytes,
    content_type: bytes = b"text/plain; charset=utf-8",
    headers: tuple[tuple[bytes, bytes], ...] = (),
) -> None:
    """Send a whole response and close the connection (what is left of the request is not read)."""
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", content_type),
                (b"content-length", str(len(body)).encode()),
                (b"connection", b"close"),
                *headers,
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})


class Guard:
    """ASGI middleware: authentication before the body is read, and a cap on the body's size."""

    def __init__(self, app: Callable, *, limits: Limits, users: Users | None, statement_error: StatementError):
        self.app, self.limits, self.users, self.statement_error = app, limits, users, statement_error
        self.failures = LoginFailures()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        path = scope["path"]
        public = path in PUBLIC_PATHS or path.startswith(PUBLIC_PREFIXES)
        if self.users is not None and not public and not await self._login(scope, send):
            return
        length = _content_length(scope)
        if length is not None and length > self.limits.max_body:
            return await self._too_large(scope, send, length)
        await self._run(scope, receive, send, length)

    async def _login(self, scope: Scope, send: Send) -> bool:
        """Authenticate the request (its user goes to scope["state"]); else answer 401 or 429."""
        credentials = basic_credentials(_header(scope, b"authorization"))
        if credentials is not None:
            user, password = credentials
            client = (scope.get("client") or ("", 0))[0]
            if self.users.remembered(user, password):
                scope.setdefault("state", {})["user"] = user
                return True
            wait = self.failures.wait(client, user)
            if wait > 0:
                await _respond(
                    send,
                    429,
                    f"Too many failed logins for {user!r}: retry in {wait} s".encode(),
                    headers=((b"retry-after", str(wait).encode()),),
                )
                return False
            self.failures.attempt(client, user)
            if await run_in_threadpool(self.users.verify, user, password):  # bcrypt: off the event loop
                self.failures.succeeded(client, user)
                scope.setdefault("state", {})["user"] = user
                return True
        await _respond(send, 401, UNAUTHORIZED.encode(), headers=((b"www-authenticate", b'Basic realm="lakegate"'),))
        return False

    async def _too_large(self, scope: Scope, send: Send, length: int | None) -> None:
        limit = self.limits.max_body
        size = f"{length}" if length is not None else f"over {limit}"
        if scope["path"] == STATEMENT_PATH:  # Trino's words for a query text over query.max-length
            message = f"Query text length ({size}) exceeds the maximum length ({limit})"
            await _respond(send, 413, self.statement_error(scope, message), b"application/json")
        else:
            message = f"Request body too large: {size} bytes, the limit is {limit} (lakegate serve --max-body)"
            await _respond(send, 413, message.encode())

    async def _run(self, scope: Scope, receive: Receive, send: Send, length: int | None) -> None:
        """Run the app, counting the body's bytes as it reads them: past the limit it gets
        http.disconnect, and the client 413. An answer given before the body was read whole closes
        the connection (so that the rest is not read either)."""
        received, refused, started = 0, False, False
        unread = (length or 0) > 0 or _header(scope, b"transfer-encoding") is not None

        async def counted() -> dict:
            nonlocal received, refused, unread
            message = await receive()
            if message["type"] == "http.request":
                unread = unread and message.get("more_body", False)
                received += len(message.get("body", b""))
                if received > self.limits.max_body:
                    if not started and not refused:
                        refused = True
                        await self._too_large(scope, send, None)
                    return {"type": "http.disconnect"}
            return message

        async def tracked(message: dict) -> None:
            nonlocal started
            if refused:
                return  # the 413 was the response
            if not started and unread:
                message = {**message, "headers": [*message.get("headers", []), (b"connection", b"close")]}
            started = True
            await send(message)

        try:
            await self.app(scope, counted, tracked)
        except ClientDisconnect:  # the client went away (or sent too much): nobody to answer
            log.debug("client disconnected during %s %s", scope["method"], scope["path"])


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope["headers"]:
        if key == name:
            return value.decode("latin-1")
    return None


def _content_length(scope: Scope) -> int | None:
    value = _header(scope, b"content-length")
    return int(value) if value is not None and value.strip().isdigit() else None


class _Refused(Exception):
    """Raised in a parser callback: the request is answered with `GuardedProtocol._refusal`."""


class GuardedProtocol(HttpToolsProtocol):
    """uvicorn's httptools protocol with caps on connections, header size and request time, and a
    check of the request target's form (the class attributes are set by `guarded_protocol`)."""

    limits = Limits()

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._header_bytes = 0
        self._parsed_bytes = 0  # of the current request's line and headers, as the parser reads them
        self._headers_done = False
        self._refusal: tuple[int, str] | None = None
        self._deadline: asyncio.TimerHandle | None = None
        if len(self.connections) > self.limits.max_connections:
            self._refuse(503, "Too many connections: try again later")
            return
        self._arm()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def data_received(self, data: bytes) -> None:
        if not self._headers_done:
            self._header_bytes += len(data)
            self._arm()
        super().data_received(data)
        if (
            not self._headers_done
            and self._header_bytes > self.limits.max_header_bytes
            and not self.transport.is_closing()
        ):
            self._refuse(431, self._too_large_message())

    def on_message_begin(self) -> None:
        super().on_message_begin()
        self._parsed_bytes = 0
        self._arm()

    def on_url(self, url: bytes) -> None:
        self._count(len(url))
        super().on_url(url)

    def on_header(self, name: bytes, value: bytes) -> None:
        self._count(len(name) + len(value) + 4)  # "name: value\r\n"
        super().on_header(name, value)

    def _count(self, size: int) -> None:
        self._parsed_bytes += size
        if self._parsed_bytes > self.limits.max_header_bytes:
            self._refusal = (431, self._too_large_message())
            raise _Refused

    def _too_large_message(self) -> str:
        return f"Request headers too large (the limit is {self.limits.max_header_bytes} bytes)"

    def on_headers_complete(self) -> None:
        self._headers_done = True
        if not self.url.startswith(b"/") and self.url != b"*":
            try:
                parsed = httptools.parse_url(self.url)
            except httptools.HttpParserInvalidURLError:
                parsed = None
            if parsed is None or parsed.schema not in (b"http", b"https") or not parsed.host:
                self._refusal = (400, "The request target must be a path (/v1/...) or an absolute http(s) URL")
                raise _Refused
            authority = parsed.host if parsed.port is None else b"%s:%d" % (parsed.host, parsed.port)
            if b":" in parsed.host:  # an IPv6 address: brackets as in a Host header
                authority = b"[%s]" % parsed.host + (b"" if parsed.port is None else b":%d" % parsed.port)
            self.scope[TARGET_HOST] = authority  # type: ignore[literal-required]
        super().on_headers_complete()

    def send_400_response(self, msg: str) -> None:
        """A request the parser refused: answered with the refusal a callback chose, if any."""
        refusal, self._refusal = self._refusal, None
        if refusal is None:
            super().send_400_response(msg)
        else:
            self._refuse(*refusal)

    def on_message_complete(self) -> None:
        self._disarm()
        self._header_bytes, self._headers_done = 0, False
        super().on_message_complete()

    def _arm(self) -> None:
        if self._deadline is None:
            self._deadline = self.loop.call_later(self.limits.request_timeout, self._timed_out)

    def _disarm(self) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
            self._deadline = None

    def _timed_out(self) -> None:
        self._deadline = None
        if not self.transport.is_closing():
            self._refuse(408, f"Request not received within {self.limits.request_timeout:g} s")

    def _refuse(self, status: int, message: str) -> None:
        """Answer `status` (unless a response already began) and close the connection."""
        self._disarm()
        cycle = self.cycle
        if cycle is None or cycle.response_complete or not cycle.response_started:
            if cycle is not None and not cycle.response_complete:
                cycle.disconnected = True  # the app's request ends here: it may not answer any more
                cycle.message_event.set()
            phrase = {
                400: "Bad Request",
                408: "Request Timeout",
                431: "Request Header Fields Too Large",
                503: "Service Unavailable",
            }[status]
            body = message.encode()
            self.transport.write(
                f"HTTP/1.1 {status} {phrase}\r\ncontent-type: text/plain; charset=utf-8\r\n"
                f"content-length: {len(body)}\r\nconnection: close\r\n\r\n".encode()
                + body
            )
        self.transport.close()


def guarded_protocol(limits: Limits) -> type[GuardedProtocol]:
    """A GuardedProtocol class that enforces `limits`."""
    return type("GuardedProtocol", (GuardedProtocol,), {"limits": limits})


def server_config(app: Any, limits: Limits, **options: Any) -> Any:
    """The uvicorn.Config that serves `app` within `limits` (`options`: other uvicorn settings)."""
    import uvicorn

    return uvicorn.Config(
        app,
        http=guarded_protocol(limits),
        timeout_keep_alive=limits.keep_alive,
        log_level="warning",
        access_log=False,
        lifespan="on",
        **options,
    )
