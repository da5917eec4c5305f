"""Options and argument types several commands' parsers share."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from lakegate.gateway.metrics.defaults import HISTORY, K


def port_number(text: str) -> int:
    """An argparse type: a TCP port number, 0 to 65535 (0: any free port)."""
    try:
        number = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a port number (0 to 65535), got {text!r}") from None
    if not 0 <= number <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port number (0 to 65535; 0 picks a free one), got {text!r}")
    return number


def positive(kind: type) -> Callable[[str], Any]:
    """An argparse `type` that reads a `kind` (int or float) greater than 0."""

    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
        return value

    return parse


#: The help of every `--metrics-config-path` that takes several files.
CONFIG_PATHS_HELP = (
    "repeat it, or separate paths by commas, to merge several files; a glob such as 'metrics/*.yml' takes "
    "every file it matches, in sorted order"
)


def add_strict_option(parser: argparse.ArgumentParser) -> None:
    """`--strict`: what lakegate accepts from ReSim configs with a warning is refused instead."""
    parser.add_argument(
        "--strict",
        action="store_true",
        help="refuse config findings that are only warnings otherwise (ReSim accepts them): unknown keys, "
        "names YAML reads as numbers or booleans, keys the template type does not use, unit and units differing",
    )


def add_trino_connection_arguments(group: argparse._ArgumentGroup) -> None:
    """Add the options that reach a Trino cluster (`--trino-url`, user, credentials, TLS) to `group`."""
    group.add_argument("--trino-url", metavar="URL", help="the cluster's coordinator, http(s)://host:port")
    group.add_argument("--trino-user", default="lakegate", metavar="U", help="the Trino user (default: lakegate)")
    group.add_argument(
        "--trino-password-env",
        metavar="VAR",
        help="HTTP Basic authentication with the password in environment variable VAR (needs https)",
    )
    group.add_argument(
        "--trino-jwt-env",
        metavar="VAR",
        help="JWT authentication with the token in environment variable VAR (needs https)",
    )
    group.add_argument("--trino-ca", type=Path, metavar="FILE", help="CA bundle that signed the cluster's certificate")
    group.add_argument("--trino-insecure", action="store_true", help="do not verify the cluster's TLS certificate")


def add_backend_arguments(parser: argparse.ArgumentParser) -> None:
    """Add `--backend` and the `--trino-*` options to a command's parser."""
    parser.add_argument(
        "--backend",
        choices=("duckdb", "trino"),
        default="duckdb",
        help="where the queries run: embedded DuckDB over the lake (duckdb, the default) or a "
        "Trino cluster that has the lake's tables (trino: see 'lakegate trino-ddl')",
    )
    trino = parser.add_argument_group(
        "forwarding to Trino (--backend trino)",
        "Where the lake's tables are in the cluster: what 'lakegate trino-ddl --apply' recorded in the lake "
        "for this --trino-url, unless one of --trino-catalog, --trino-schema-prefix, --trino-schema-map is "
        "given; else catalog hive, one schema per branch named as 'lakegate trino-ddl' names it.",
    )
    add_trino_connection_arguments(trino)
    trino.add_argument("--trino-catalog", metavar="C", help="the catalog that holds the lake's schemas (default: hive)")
    trino.add_argument(
        "--trino-schema-prefix",
        metavar="P",
        help="the --schema-prefix given to 'lakegate trino-ddl' (default: none)",
    )
    trino.add_argument(
        "--trino-schema-map",
        action="append",
        default=[],
        metavar="BRANCH=SCHEMA",
        help="the schema of a branch, instead of the name 'lakegate trino-ddl' gives it (repeat for "
        "several); '*={branch}' maps every branch to a schema of its own name (another "
        "'lakegate serve', catalog lake)",
    )


def add_alert_arguments(parser: argparse.ArgumentParser, build: str) -> None:
    """--alert-k and --alert-builds: the trend alert (`gateway/metrics/alerts.py`) of `build` (what the
    command checks: 'the latest build', 'the new batch's build')."""
    parser.add_argument(
        "--alert-k",
        type=positive(float),
        default=K,
        metavar="K",
        help=f"trend alert: a scalar metric whose value on {build} lies outside K standard deviations of its "
        f"previous builds (default {K:g})",
    )
    parser.add_argument(
        "--alert-builds",
        type=positive(int),
        default=HISTORY,
        metavar="N",
        help=f"trend alert: compare {build} with the N builds before it (default {HISTORY}; 2 at least)",
    )
