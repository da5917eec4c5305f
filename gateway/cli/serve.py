"""`lakegate serve`: the lake as a Trino-compatible SQL endpoint (the Trino HTTP client protocol).

It listens on 127.0.0.1 by default. Listening on any other address needs `--users FILE` (HTTP
Basic against bcrypt hashes) and `--tls-cert/--tls-key`: the trino client sends passwords only
over https, and a lake open to the network needs both. On loopback, `--users` works without TLS
(clients then need `http_scheme='http'` and, for the trino client, `allow_insecure_auth=True`).
Once listening it prints one line, `lakegate: serving <lake> at <url> (catalog C); dashboard <url>/dashboard/;
Ctrl-C stops`, to standard output. `/` is a landing page (gateway/dashboard/landing.py).
SIGINT / SIGTERM stop it within `STOP_GRACE` seconds whatever its queries do: every query fails at
once with SERVER_SHUTTING_DOWN, which each client waiting for one gets (the server keeps answering
for up to `DELIVERY_GRACE` seconds), then it stops with exit code 0, leaving behind any query work
that ignores interrupts. A shutdown that has not finished by STOP_GRACE ends the process with a
message and exit code 1.
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import re
import signal
import socket
import ssl
import sys
import threading
import time

from lakegate.gateway.cli.backends import backend_from_args
from lakegate.gateway.cli.command_errors import UserError
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.server.auth import Users, UsersFileError, check_listen

#: Seconds after the first stop signal when a shutdown still running ends the process.
STOP_GRACE = 3.5
#: Longest the server keeps serving after a stop signal, for clients to fetch SERVER_SHUTTING_DOWN.
DELIVERY_GRACE = 1.0
#: Longest the server waits at start for its query worker processes (it serves anyway after).
WORKERS_READY_SECONDS = 60.0


class _StopSignals:
    """The stop signals (SIGINT, SIGTERM) from the moment the server says it serves: one that comes
    before uvicorn takes them over is kept and stops the server as soon as it exists. (Raising
    KeyboardInterrupt from the handler lost the signal when it landed in a weakref callback, where
    Python ignores exceptions, and the server kept serving.)"""

    def __init__(self) -> None:
        self.received: int | None = None
        self.server = None  # the uvicorn.Server, once its stop is set up

    def __call__(self, signum: int, frame: object) -> None:
        self.received = signum
        if self.server is not None:
            self.server.handle_exit(signum, frame)


def _force_exit() -> None:
    print(
        f"lakegate: stopped: shutdown did not finish within {STOP_GRACE:g}s of the stop signal "
        "(query work still running)",
        file=sys.stderr,
        flush=True,
    )
    os._exit(1)


def _with_stop_deadline(server, backend, manager) -> None:
    """Make the first stop signal of `server` (a uvicorn.Server) fail every query of `manager` with
    SERVER_SHUTTING_DOWN and interrupt the queries of `backend` (DuckDB's or Trino's), keep serving
    until each client waiting for a query got that answer (at most DELIVERY_GRACE seconds), then
    stop; the process ends STOP_GRACE seconds after the signal if it has not stopped by then."""
    handle_exit = server.handle_exit
    stopping = threading.Event()

    def shut_down(sig: int) -> None:
        going = manager.shut_down()
        backend.stop_all()
        deadline = time.monotonic() + DELIVERY_GRACE
        while not all(query.final for query in going) and time.monotonic() < deadline:
            time.sleep(0.02)
        handle_exit(sig, None)

    def stop(sig: int, frame: object) -> None:
        """The signal handler: it may interrupt the main thread holding any lock, so the shutdown
        runs in a thread of its own."""
        if stopping.is_set():
            handle_exit(sig, frame)
            return
        stopping.set()
        timer = threading.Timer(STOP_GRACE, _force_exit)
        timer.daemon = True
        timer.start()
        threading.Thread(target=shut_down, args=(sig,), name="lakegate-stop", daemon=True).start()

    server.handle_exit = stop


def _listen(host: str, port: int) -> socket.socket:
    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
        sock = socket.socket(family, kind, proto)
    except OSError as error:
        raise UserError(f"cannot listen on {host}:{port}: {error}") from None
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(2048)
    except OSError as error:
        sock.close()
        raise UserError(f"cannot listen on {host}:{port}: {error.strerror or error}") from None
    return sock


def _check_options(args: argparse.Namespace) -> Users | None:
    import duckdb

    if not args.lake.is_dir():
        raise UserError(f"no lake at {args.lake} (not a directory)")
    if not re.fullmatch(r"[a-z_][a-z0-9_]*", args.catalog) or args.catalog == "system":
        raise UserError(f"--catalog {args.catalog!r}: a catalog name is a lower-case identifier other than 'system'")
    if args.max_queries_per_user is not None and args.max_queries_per_user > args.max_concurrent_queries:
        raise UserError(
            f"--max-queries-per-user {args.max_queries_per_user}: at most --max-concurrent-queries "
            f"({args.max_concurrent_queries}), the queries that run at once"
        )
    if (args.tls_cert is None) != (args.tls_key is None):
        raise UserError("--tls-cert and --tls-key go together")
    if args.tls_cert is not None:
        try:
            ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER).load_cert_chain(args.tls_cert, args.tls_key)
        except (OSError, ssl.SSLError) as error:
            raise UserError(
                f"cannot use the TLS certificate {args.tls_cert} with key {args.tls_key}: {error}"
            ) from None
    try:
        duckdb.connect(config={"memory_limit": args.memory_limit}).close()
    except duckdb.Error as error:
        raise UserError(f"--memory-limit {args.memory_limit!r} is not a size DuckDB accepts: {error}") from None
    try:
        users = Users.load(args.users) if args.users is not None else None
    except UsersFileError as error:
        raise UserError(str(error)) from None
    for item in (args.forwarded_allow_ips or "").split(","):
        if item.strip() not in ("", "*"):
            try:
                ipaddress.ip_network(item.strip(), strict=False)
            except ValueError:
                raise UserError(
                    f"--forwarded-allow-ips: {item.strip()!r} is not an address or network "
                    "(e.g. 10.0.0.1, 10.0.0.0/8, *)"
                ) from None
    try:
        check_listen(args.host, users=users is not None, tls=args.tls_cert is not None)
    except ValueError as error:
        raise UserError(str(error)) from None
    return users


def serve_command(args: argparse.Namespace) -> int:
    import uvicorn  # the server's imports cost every other command their start-up time: load them here

    from lakegate.gateway.dashboard.landing import pages_router
    from lakegate.gateway.dashboard.routes import DashboardState
    from lakegate.gateway.engine.engine import Engine
    from lakegate.gateway.engine.isolated_backend import IsolatedBackend
    from lakegate.gateway.server.app import create_app
    from lakegate.gateway.server.http_limits import server_config

    users = _check_options(args)
    limits = Limits(
        query_timeout=args.query_timeout,
        max_rows=args.max_rows,
        max_concurrent_queries=args.max_concurrent_queries,
        max_queries_per_user=args.max_queries_per_user,
        max_queued_queries=args.max_queued_queries,
        max_body=args.max_body,
        max_header_bytes=args.max_header_bytes,
        request_timeout=args.request_timeout,
        max_connections=args.max_connections,
        client_timeout=args.client_timeout,
        heartbeat_timeout=args.heartbeat_timeout,
    )
    sock = _listen(args.host, args.port)
    if args.backend == "trino":
        backend = backend_from_args(args, args.lake)
    else:
        backend = IsolatedBackend(  # a worker for each slot, so that a burst of queries waits for none to start
            args.lake,
            memory_limit=args.memory_limit,
            threads=args.threads,
            limits=limits,
            keep=limits.max_concurrent_queries,
        )
        backend.pool.wait_ready(WORKERS_READY_SECONDS)
    engine = Engine(backend, catalog=args.catalog, limits=limits, owns_backend=True)
    dashboard = DashboardState(args.lake, engine)
    stuck = 0
    try:
        app = create_app(
            engine,
            users=users,
            dashboard_router=pages_router(dashboard),
            allowed_hosts=args.allowed_host,
        )
        config = server_config(
            app,
            limits,
            timeout_graceful_shutdown=1,
            proxy_headers=args.forwarded_allow_ips is not None,
            forwarded_allow_ips=args.forwarded_allow_ips,
            ssl_certfile=str(args.tls_cert) if args.tls_cert else None,
            ssl_keyfile=str(args.tls_key) if args.tls_key else None,
        )
        host, port = sock.getsockname()[:2]
        shown = f"[{host}]" if ":" in host else host
        scheme = "https" if args.tls_cert else "http"
        url = f"{scheme}://{shown}:{port}"
        # uvicorn shuts down gracefully on SIGINT / SIGTERM (its handlers, while it runs), then raises the
        # signal again: before and after, these handlers take it
        signals = _StopSignals()
        previous = {number: signal.signal(number, signals) for number in (signal.SIGINT, signal.SIGTERM)}
        print(
            f"lakegate: serving {args.lake.resolve()} at {url} (catalog {args.catalog}); "
            f"dashboard {url}/dashboard/; Ctrl-C stops",
            flush=True,
        )
        try:
            server = uvicorn.Server(config)
            _with_stop_deadline(server, backend, app.state.manager)
            signals.server = server
            if signals.received is None:
                server.run(sockets=[sock])
        finally:
            for number, handler in previous.items():
                signal.signal(number, handler)
        stuck = app.state.manager.working()
    finally:
        if stuck == 0:  # closing the engine under query work that still runs could crash the process
            dashboard.close()
            engine.close()
        sock.close()
    print("lakegate: stopped", file=sys.stderr, flush=True)
    if stuck:  # workers that ignore interrupts (Python functions inside DuckDB): end without them
        sys.stdout.flush()
        os._exit(0)
    return 0
