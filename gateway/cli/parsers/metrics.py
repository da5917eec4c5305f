"""The parser of `lakegate metrics` and its subcommands."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from lakegate.gateway.cli.parsers import Command
from lakegate.gateway.cli.parsers.debug import add_debug_parser
from lakegate.gateway.cli.parsers.shared_options import (
    CONFIG_PATHS_HELP,
    add_alert_arguments,
    add_backend_arguments,
    add_strict_option,
    positive,
)
from lakegate.gateway.metrics.gating import FAIL_STATES, parse_fail_on_states

if TYPE_CHECKING:
    from lakegate.gateway.metrics.trends import Window


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    metrics = subparsers.add_parser(
        "metrics",
        help="store a branch's metrics config, evaluate metrics on a batch or over many batches",
        description="Store a branch's metrics config, evaluate a metrics set on a batch that is in the lake, or "
        "evaluate dashboard and report metrics over many batches.",
    )
    commands = metrics.add_subparsers(dest="metrics_command", metavar="SUBCOMMAND")
    commands.required = True

    sync = commands.add_parser(
        "sync",
        help="store a config as the branch's current metrics config",
        description="Check a config file and store it as the branch's current config (earlier versions are "
        "kept). Later runs and ingests on the branch use it. Prints the version number.",
    )
    _lake_and_branch(sync)
    sync.add_argument(
        "--metrics-config-path",
        action="append",
        type=Path,
        metavar="P",
        dest="config_paths",
        help=f"the config file ({CONFIG_PATHS_HELP}; default: .resim/metrics/config.resim.yaml "
        "in this folder or a parent)",
    )
    _templates_path(sync)
    add_strict_option(sync)
    sync.set_defaults(func=Command("metrics", "sync_command"))

    validate = commands.add_parser(
        "validate",
        help="check config files without storing them (SignalFlag's name for 'config check')",
        description="Load and merge the config files as 'metrics sync' would, without storing anything; print "
        "every problem (file:line:column: message) and exit 1, or a one-line summary and exit 0. The same "
        "as 'lakegate config check'; with --lake and --branch it also checks the config against what the "
        "branch stores: a topic it declares must keep the fields and types the lake holds (a branch's topics "
        "only grow, as in SignalFlag), and every metric's query and status query must run on the branch's "
        "tables (a table or column the lake does not have is named with its place).",
    )
    validate.add_argument(
        "--lake", type=Path, metavar="DIR", help="also check against this lake's branch (with --branch)"
    )
    validate.add_argument("--branch", metavar="B", help="the branch of --lake to check against")
    validate.add_argument(
        "--metrics-config-path",
        action="append",
        type=Path,
        metavar="P",
        dest="config_paths",
        help=f"the config file ({CONFIG_PATHS_HELP}; default: .resim/metrics/config.resim.yaml in this folder "
        "or a parent)",
    )
    _templates_path(validate)
    add_strict_option(validate)
    validate.set_defaults(func=Command("metrics", "validate_command"))

    schema = commands.add_parser(
        "config-schema",
        help="write the JSON Schema of the config file (SignalFlag's name for 'config schema')",
        description="Write the JSON Schema (draft 2020-12) of the metrics config file, for editors. The same "
        "as 'lakegate config schema'.",
    )
    schema.add_argument(
        "-o", "--output", metavar="FILE", type=Path, help="file to write the schema to (default: standard output)"
    )
    schema.set_defaults(func=Command("config", "schema_command"))

    run = commands.add_parser(
        "run",
        help="evaluate a metrics set on a batch in the lake",
        description="Evaluate a metrics set on a batch already in the lake (no re-ingesting): test metrics on "
        "each job, then batch metrics; write the jobs' statuses to their metadata and the results "
        "to the metric_results table (replacing the batch's earlier results). Exit code: 0 nothing "
        "blocks (warnings allowed), 2 a metric is a BLOCKER, 3 a metric errored or a job failed "
        "(and nothing blocks), 1 usage or config error, or the results or report could not be written.",
    )
    _lake_and_branch(run)
    run.add_argument("--batch", required=True, metavar="ID", help="the batch to evaluate")
    which = run.add_mutually_exclusive_group(required=True)
    which.add_argument("--metrics-set", metavar="S", help="the metrics set to evaluate (a name from 'metrics sets')")
    which.add_argument(
        "--all-metrics",
        action="store_true",
        help="evaluate every metric of the config (for configs without metrics sets)",
    )
    _evaluated_config(run)
    add_strict_option(run)
    _fail_on_states(run)
    run.add_argument(
        "--format",
        choices=("table", "json"),
        default="table",
        help="output: a table of job x metric -> status and value (default), or JSON with every "
        "evaluated metric (batch, job, metric, type, template, status, scalar value, error "
        "with line and column)",
    )
    run.add_argument(
        "--report",
        type=Path,
        metavar="FILE.html",
        help="also write an offline HTML report with every figure to this file",
    )
    add_backend_arguments(run)
    run.add_argument("--threads", type=positive(int), default=2, metavar="N", help="jobs evaluated at once (default 2)")
    run.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show a progress bar on standard error (default: when it is a terminal)",
    )
    run.add_argument(
        "--compact",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="merge the batch's per-job files into one file per table afterwards, as `lakegate lake compact` "
        "does (default; --no-compact leaves them)",
    )
    run.set_defaults(func=Command("metrics", "run_command"))

    _add_trends_parsers(commands)

    add_debug_parser(commands)


def _add_trends_parsers(commands: argparse._SubParsersAction) -> None:
    dashboard = commands.add_parser(
        "dashboard",
        help="evaluate the dashboard metrics over the batches of a branch (trends across builds)",
        description="Evaluate the config's 'type: dashboard' metrics once over every batch of the branch, or "
        "the batches of --window: each query sees every job of those batches in every table (metadata "
        "included, so '... GROUP BY m.build_version' shows a trend from build to build). Prints each "
        "metric's status and value, optionally writes an offline HTML page; writes nothing to the lake. "
        "Exit code: 0 nothing blocks, 2 a metric is a BLOCKER, 3 a metric errored, 1 usage or config error.",
    )
    _lake_and_branch(dashboard)
    dashboard.add_argument(
        "--window",
        type=_window,
        metavar="30d|N",
        help="only the batches of the last N days ('30d': a batch's time is its earliest job's metadata "
        "time) or the last N batches ('10'); default: every batch of the branch, or the day_range of --name",
    )
    dashboard.add_argument(
        "--name",
        metavar="N",
        help="a dashboard of the config's 'dashboards:' section: its metrics_set's dashboard metrics over the "
        "batches of its day_range (instead of --metrics-set)",
    )
    add_alert_arguments(dashboard, "the latest build")
    dashboard.add_argument(
        "--fail-on",
        choices=("regression",),
        help="exit 5 when a trend alert fires (and nothing blocks or errs)",
    )
    report = commands.add_parser(
        "report",
        help="evaluate the report metrics over a list of batches",
        description="Evaluate the config's 'type: report' metrics once over every job of the batches given: "
        "each query sees every job of those batches in every table (metadata included). Prints each "
        "metric's status and value, optionally writes an offline HTML page; writes nothing to the lake. "
        "Exit code: 0 nothing blocks, 2 a metric is a BLOCKER, 3 a metric errored, 1 usage or config error.",
    )
    _lake_and_branch(report)
    report.add_argument(
        "--batches", required=True, type=_batch_list, metavar="A,B,...", help="the batches, separated by commas"
    )
    for parser in (dashboard, report):
        parser.add_argument(
            "--metrics-set",
            metavar="S",
            help="only the metrics of this set (default: every metric of its type in the config)",
        )
        _evaluated_config(parser)
        parser.add_argument(
            "--format",
            choices=("table", "json"),
            default="table",
            help="output: a table of metric -> status and value (default), or JSON with the batches and "
            "every evaluated metric",
        )
        parser.add_argument(
            "--report",
            type=Path,
            metavar="FILE.html",
            help="also write an offline HTML page with the batches and every figure to this file",
        )
        parser.add_argument(
            "--link-base",
            default="http://127.0.0.1:8080",
            metavar="URL",
            help="where the page's links (link_path columns, batch ids) point: the 'lakegate serve' that "
            "shows the batches (default: http://127.0.0.1:8080, serve's default address)",
        )
        _fail_on_states(parser)
        add_strict_option(parser)
        add_backend_arguments(parser)
        parser.set_defaults(func=Command("metrics", "trends_command"))


def _window(text: str) -> Window:
    from lakegate.gateway.metrics.trends import Window  # read when the command runs, not for its --help

    try:
        return Window.parse(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _batch_list(text: str) -> list[str]:
    batches = [name.strip() for name in text.split(",") if name.strip()]
    if not batches:
        raise argparse.ArgumentTypeError(f"expected batch ids separated by commas, got {text!r}")
    return list(dict.fromkeys(batches))


def _evaluated_config(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--metrics-config-path",
        action="append",
        type=Path,
        metavar="P",
        dest="config_paths",
        help=f"evaluate this config instead of the branch's stored one ({CONFIG_PATHS_HELP})",
    )
    _templates_path(parser)


def _templates_path(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--templates-path",
        "--metrics-templates-path",
        type=Path,
        metavar="DIR",
        dest="templates_path",
        help="a folder of custom .liquid templates, searched after the config files' own folders and their "
        "templates/ folders (SignalFlag's default .resim/metrics/templates is used when it exists)",
    )


def _fail_states(text: str) -> frozenset[str]:
    try:
        return parse_fail_on_states(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _fail_on_states(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--fail-on-states",
        type=_fail_states,
        metavar=",".join(FAIL_STATES),
        help="SignalFlag's CI gating: exit 7 when the batch's status is BLOCKER, 2 when ERROR, 8 when WARNING, "
        "if that state is listed, else 0 (instead of the exit codes above)",
    )


def _lake_and_branch(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--lake", required=True, type=Path, metavar="DIR", help="the lake's directory")
    parser.add_argument("--branch", required=True, metavar="B", help="the branch (any name)")
