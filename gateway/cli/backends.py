"""The backend the command-line options choose (`parsers.shared_options.add_backend_arguments`): embedded
DuckDB over the lake (default) or forwarding to a Trino cluster (`--backend trino --trino-url URL ...`),
shared by the commands that run queries."""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from lakegate.gateway.cli.command_errors import UserError
from lakegate.gateway.engine.backend import Backend
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.engine.isolated_backend import IsolatedBackend
from lakegate.gateway.engine.trino_backend import TrinoBackend
from lakegate.gateway.engine.trino_registration import RegistrationError, read_registration


def _secret(variable: str | None) -> str | None:
    if variable is None:
        return None
    value = os.environ.get(variable)
    if not value:
        raise UserError(f"environment variable {variable} is not set")
    return value


def schema_map(entries: list[str]) -> dict[str, str]:
    """`BRANCH=SCHEMA` entries as a dict (the first `=` separates them)."""
    mapping = {}
    for entry in entries:
        branch, equals, schema = entry.partition("=")
        if not equals or not branch or not schema:
            raise UserError(f"--trino-schema-map {entry!r}: expected BRANCH=SCHEMA")
        mapping[branch] = schema
    return mapping


def trino_connection(args: argparse.Namespace, **placement: Any) -> TrinoBackend:
    """A TrinoBackend for the connection options (`placement`: its catalog and schema options).
    UserError for inconsistent options."""
    if not args.trino_url:
        raise UserError("--backend trino needs --trino-url")
    if args.trino_ca is not None and not args.trino_ca.is_file():
        raise UserError(f"--trino-ca {args.trino_ca}: no such file")
    verify: bool | str = False if args.trino_insecure else str(args.trino_ca) if args.trino_ca else True
    try:
        return TrinoBackend(
            args.trino_url,
            user=args.trino_user,
            password=_secret(args.trino_password_env),
            jwt=_secret(args.trino_jwt_env),
            verify=verify,
            **placement,
        )
    except ValueError as error:
        raise UserError(str(error)) from None


def _placement(args: argparse.Namespace, lake: Path | None) -> dict[str, Any]:
    """The catalog and schemas of the lake's branches in the cluster: the options, else the lake's
    recorded registration for --trino-url, else the defaults of 'lakegate trino-ddl'."""
    given = args.trino_catalog is not None or args.trino_schema_prefix is not None or args.trino_schema_map
    if not given and lake is not None and args.trino_url:
        try:
            registration = read_registration(lake, args.trino_url)
        except RegistrationError as error:
            raise UserError(str(error)) from None
        if registration is not None:
            return {
                "catalog": registration.catalog,
                "schema_prefix": registration.schema_prefix,
                "schema_map": registration.schemas,
                "mapped_only": True,
            }
    return {
        "catalog": args.trino_catalog or "hive",
        "schema_prefix": args.trino_schema_prefix or "",
        "schema_map": schema_map(args.trino_schema_map),
    }


def backend_from_args(args: argparse.Namespace, lake: Path | None) -> Backend:
    """The backend the options choose (the caller closes it). UserError for inconsistent options."""
    if args.backend == "duckdb":
        return IsolatedBackend(lake)
    if not args.trino_url:
        raise UserError("--backend trino needs --trino-url")
    return trino_connection(args, **_placement(args, lake))


def engine_from_args(args: argparse.Namespace, lake: Path | None) -> Engine:
    """An engine over the backend the options choose (it closes the backend with it)."""
    return Engine(backend_from_args(args, lake), owns_backend=True)
