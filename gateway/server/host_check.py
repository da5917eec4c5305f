"""Host and Origin checks against DNS rebinding and cross-site requests (ASGI middleware).

A page on another site can make a browser send requests to a server on 127.0.0.1, either
directly (a cross-site form or fetch: its `Origin` names the other site) or through DNS
rebinding (a name of the other site that now resolves to 127.0.0.1: its `Host` is that name).
So every request must name this server in `Host`:

- `127.0.0.1:PORT`, `localhost:PORT`, `[::1]:PORT`, or the address the connection arrived on
  (`ADDRESS:PORT`, e.g. the LAN address of a server bound to 0.0.0.0), where PORT, if given, is the
  port it arrived on;
- or a name given with `--allowed-host` (for a reverse proxy): `NAME` matches it on any port,
  `NAME:PORT` only on that port.

A request with more than one Host header gets 400, and the authority of an absolute-form request
target (`GET http://name/path`, which HTTP/1.1 says wins over Host) must name this server too. A
state-changing request (POST, PUT, PATCH, DELETE) that carries an `Origin` header must come from an
allowed host, over the scheme the server speaks (http or https). Refused requests get 421 (wrong
Host) or 403 (wrong Origin) with a message saying which header was wrong and how to allow it.
"""

from __future__ import annotations

import ipaddress
import json
from collections.abc import Awaitable, Callable, Iterable
from typing import Any
from urllib.parse import urlsplit

LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
STATE_CHANGING = frozenset({"POST", "PUT", "PATCH", "DELETE"})
#: The scope key holding the authority of an absolute-form request target (bytes; set by
#: http_limits.GuardedProtocol), checked as Host is.
TARGET_HOST = "lakegate.target_host"


def _bracketed(address: str) -> str:
    try:
        return f"[{address}]" if ipaddress.ip_address(address).version == 6 else address
    except ValueError:
        return address


def _split(host: str) -> tuple[str, str | None]:
    """(`name`, `port` or None) of `name[:port]`; an IPv6 name keeps its brackets."""
    close = host.find("]") + 1 if host.startswith("[") else 0
    name, colon, port = host[close:].partition(":")
    return host[:close] + name, port if colon else None


def host_allowed(
    host: str, server: tuple[str, int] | None, allowed: Iterable[str] = (), default_port: int | None = None
) -> bool:
    """Whether a `Host` value (`name[:port]`) names this server, reached at `server` (address, port).

    A missing port means `default_port` (an Origin's scheme default), or for a Host header the
    connection's own port (raw HTTP/1.1 clients often omit it; the name is what defeats DNS rebinding).
    """
    host = host.strip().lower()
    name, port = _split(host)
    for extra in allowed:
        extra = extra.strip().lower()
        if host == extra or (_split(extra)[1] is None and name == extra):
            return True
    if not name or server is None:
        return False
    if port is None:
        given = default_port if default_port is not None else server[1]
    else:
        given = int(port) if port.isdigit() else None
    return name in {*LOOPBACK_NAMES, _bracketed(server[0]).lower()} and given == server[1]


class HostCheck:
    """ASGI middleware refusing requests whose Host (or, when state-changing, Origin) is not this server."""

    def __init__(self, app: Callable[..., Awaitable[None]], allowed: Iterable[str] = ()):
        self.app = app
        self.allowed = tuple(allowed)

    async def __call__(self, scope: dict[str, Any], receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":  # lifespan (the app serves no websockets)
            await self.app(scope, receive, send)
            return
        hosts = [value.decode("latin-1") for key, value in scope["headers"] if key.lower() == b"host"]
        if len(hosts) > 1:
            await _refuse(send, 400, f"{len(hosts)} Host headers: a request names its server once")
            return
        headers = {key.decode("latin-1").lower(): value.decode("latin-1") for key, value in scope["headers"]}
        server = scope.get("server")
        host = hosts[0] if hosts else ""
        target = scope.get(TARGET_HOST)
        for value, what in (
            (host, "Host header"),
            (None if target is None else target.decode("latin-1"), "request target"),
        ):
            if value is not None and not host_allowed(value, server, self.allowed):
                await _refuse(
                    send,
                    421,
                    f"{what} {value!r} does not name this server (use "
                    f"127.0.0.1:{server[1] if server else 'PORT'} or localhost; a reverse proxy's "
                    "name must be allowed with --allowed-host)",
                )
                return
        origin = headers.get("origin")
        if origin is not None and scope.get("method") in STATE_CHANGING:
            parts = urlsplit(origin)
            if (
                not parts.netloc
                or parts.scheme != scope.get("scheme", "http")
                or not host_allowed(parts.netloc, server, self.allowed, {"http": 80, "https": 443}[parts.scheme])
            ):
                await _refuse(
                    send,
                    403,
                    f"Origin {origin!r} may not change anything here (cross-site "
                    "requests are refused; allow a proxy's name with --allowed-host)",
                )
                return
        await self.app(scope, receive, send)


async def _refuse(send: Callable, status: int, message: str) -> None:
    body = json.dumps({"detail": message}).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())],
        }
    )
    await send({"type": "http.response.body", "body": body})
