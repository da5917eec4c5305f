"""The parser of `lakegate serve`."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from lakegate.gateway.cli.parsers import Command
from lakegate.gateway.cli.parsers.shared_options import add_backend_arguments, port_number
from lakegate.gateway.cli.parsers.shared_options import positive as _positive
from lakegate.gateway.engine.catalog_name import CATALOG
from lakegate.gateway.engine.limits import Limits

_DEFAULTS = Limits()


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "serve",
        help="serve the lake over the Trino client protocol (trino, SQLAlchemy, pandas, BI tools)",
        description="Serve the lake as a read-only, Trino-compatible SQL endpoint: catalog 'lake' (see --catalog) "
        "with one schema per branch, information_schema and the system catalog. Connect with "
        "e.g. trino.dbapi.connect(host='127.0.0.1', port=8080, user='me', catalog='lake', "
        "schema='main') or the URL trino://me@127.0.0.1:8080/lake/main.",
    )
    parser.add_argument("--lake", type=Path, required=True, metavar="DIR", help="the lake's directory")
    parser.add_argument(
        "--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1; any other needs --users and TLS)"
    )
    parser.add_argument(
        "--port", type=port_number, default=8080, help="port to listen on (default 8080; 0 picks a free one)"
    )
    parser.add_argument(
        "--allowed-host",
        action="append",
        default=[],
        metavar="NAME[:PORT]",
        help="a Host name clients may use besides 127.0.0.1, localhost, [::1] and the address "
        "connected to (e.g. a reverse proxy's name; repeatable); others get 421",
    )
    parser.add_argument(
        "--forwarded-allow-ips",
        default=None,
        metavar="ADDRESSES",
        help="comma-separated addresses or networks (or '*') of reverse proxies whose X-Forwarded-For and "
        "X-Forwarded-Proto headers are trusted (default: none; the connection's own address is the client's)",
    )
    parser.add_argument("--catalog", default=CATALOG, help=f"the lake's catalog name (default: {CATALOG})")
    parser.add_argument(
        "--users",
        type=Path,
        metavar="FILE",
        help="require HTTP Basic authentication against this file of 'user:bcrypt-hash' lines",
    )
    parser.add_argument("--tls-cert", type=Path, metavar="FILE", help="serve https with this PEM certificate (chain)")
    parser.add_argument("--tls-key", type=Path, metavar="FILE", help="the PEM private key of --tls-cert")
    parser.add_argument(
        "--query-timeout",
        type=_positive(float),
        default=_DEFAULTS.query_timeout,
        metavar="S",
        help=f"seconds a query may run before it fails with EXCEEDED_TIME_LIMIT (default {_DEFAULTS.query_timeout:g})",
    )
    parser.add_argument(
        "--max-rows",
        type=_positive(int),
        default=_DEFAULTS.max_rows,
        metavar="N",
        help=f"rows a result may have (default {_DEFAULTS.max_rows})",
    )
    parser.add_argument(
        "--memory-limit",
        default="2GB",
        metavar="SIZE",
        help="DuckDB memory limit of the server, all branches together, e.g. 2GB or 512MB "
        "(default 2GB); a query that needs more fails with EXCEEDED_GLOBAL_MEMORY_LIMIT",
    )
    parser.add_argument(
        "--threads",
        type=_positive(int),
        default=os.cpu_count() or 1,
        metavar="N",
        help="DuckDB threads of the server (all branches together; default: the number of CPUs)",
    )
    parser.add_argument(
        "--max-concurrent-queries",
        type=_positive(int),
        default=_DEFAULTS.max_concurrent_queries,
        metavar="N",
        help=f"queries that run at once; more wait in a queue (default {_DEFAULTS.max_concurrent_queries})",
    )
    parser.add_argument(
        "--max-queries-per-user",
        type=_positive(int),
        default=None,
        metavar="N",
        help="queries one user (X-Trino-User; with --users, the authenticated user) runs at once, as a Trino "
        "resource group's per-user hardConcurrencyLimit; more stay QUEUED, also when no other user is there "
        "(default: --max-concurrent-queries minus 1, at least 1, so that another user always finds a slot)",
    )
    parser.add_argument(
        "--client-timeout",
        type=_positive(float),
        default=_DEFAULTS.client_timeout,
        metavar="S",
        help=f"seconds a query may go without its client asking for results before it fails with "
        f"ABANDONED_QUERY (Trino's query.client.timeout; default {_DEFAULTS.client_timeout:g})",
    )
    parser.add_argument(
        "--heartbeat-timeout",
        type=_positive(float),
        default=_DEFAULTS.heartbeat_timeout,
        metavar="S",
        help=f"seconds a query whose results wait for its client may go without a request from it (a "
        f"GET or HEAD heartbeat of its nextUri) before it fails with ABANDONED_QUERY and frees its slot "
        f"(default {_DEFAULTS.heartbeat_timeout:g}); a queued query is dropped once its client stops polling",
    )
    parser.add_argument(
        "--max-queued-queries",
        type=_positive(int),
        default=_DEFAULTS.max_queued_queries,
        metavar="N",
        help=f"queries that may wait; more fail with QUERY_QUEUE_FULL (default {_DEFAULTS.max_queued_queries})",
    )
    parser.add_argument(
        "--max-body",
        type=_positive(int),
        default=_DEFAULTS.max_body,
        metavar="BYTES",
        help=f"bytes a request body may have; a larger one gets HTTP 413, for /v1/statement with "
        f"QUERY_TEXT_TOO_LARGE (default {_DEFAULTS.max_body:,}, Trino's query.max-length)",
    )
    parser.add_argument(
        "--max-header-bytes",
        type=_positive(int),
        default=_DEFAULTS.max_header_bytes,
        metavar="BYTES",
        help=f"bytes a request's line and headers may have; more get HTTP 431 (default {_DEFAULTS.max_header_bytes:,})",
    )
    parser.add_argument(
        "--request-timeout",
        type=_positive(float),
        default=_DEFAULTS.request_timeout,
        metavar="S",
        help=f"seconds a request's headers and body may take to arrive; a slower one gets HTTP 408 "
        f"and its connection is closed (default {_DEFAULTS.request_timeout:g})",
    )
    parser.add_argument(
        "--max-connections",
        type=_positive(int),
        default=_DEFAULTS.max_connections,
        metavar="N",
        help=f"open connections; more are answered HTTP 503 and closed (default {_DEFAULTS.max_connections})",
    )
    add_backend_arguments(parser)
    parser.set_defaults(func=Command("serve", "serve_command"))
