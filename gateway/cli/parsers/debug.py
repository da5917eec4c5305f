"""The parser of `lakegate metrics debug`."""

from __future__ import annotations

import argparse
from pathlib import Path

from lakegate.gateway.cli.parsers import Command
from lakegate.gateway.cli.parsers.shared_options import add_strict_option, port_number

#: The branch of the debug job unless --branch says otherwise.
BRANCH = "debug"


def add_debug_parser(commands: argparse._SubParsersAction) -> None:
    """Add `debug` to the `lakegate metrics` subcommands."""
    debug = commands.add_parser(
        "debug",
        help="serve a live dashboard of a metrics set on one emissions file",
        description="Ingest an emissions file as a debug job (into a scratch lake, or --lake) and serve the "
        "metrics dashboard on it: every metric of the set rendered with its status, queries "
        "editable and re-runnable in place, new metrics, a data explorer, the job's events, and "
        "'Export Config' to download the edited config. Prints the dashboard URL; Ctrl+C stops.",
    )
    debug.add_argument(
        "--emissions-file",
        required=True,
        type=Path,
        metavar="FILE",
        help="the emissions file (JSON lines, as the Emitter writes them)",
    )
    debug.add_argument(
        "--metrics-config-path",
        action="append",
        type=Path,
        metavar="P",
        dest="config_paths",
        help="the config file (repeat to merge several; default: .resim/metrics/config.resim.yaml "
        "in this folder or a parent); changes to it show on reload",
    )
    add_strict_option(debug)
    which = debug.add_mutually_exclusive_group(required=True)
    which.add_argument("--metrics-set", metavar="S", help="the metrics set to show (a name from 'metrics sets')")
    which.add_argument(
        "--all-metrics",
        action="store_true",
        help="show every test and batch metric of the config (for configs without metrics sets)",
    )
    debug.add_argument(
        "--logs-dir",
        "--logs",
        type=Path,
        metavar="DIR",
        help="the job's log files, where image metrics find their files (default: the 'logs' "
        "folder beside the emissions file if there is one, else only the files beside it "
        "that the emissions name in image fields)",
    )
    debug.add_argument(
        "--metadata",
        type=Path,
        metavar="FILE",
        help="YAML mapping of the job's metadata columns (experience_name, build_name, tags ...)",
    )
    debug.add_argument(
        "--lake",
        type=Path,
        metavar="DIR",
        help="ingest into this lake (kept) instead of a scratch lake removed on exit",
    )
    debug.add_argument(
        "--branch", default=BRANCH, metavar="B", help=f"the branch of the debug job (default {BRANCH!r})"
    )
    debug.add_argument(
        "--host",
        default="127.0.0.1",
        help="the loopback address to listen on (default 127.0.0.1; the page has no authentication)",
    )
    debug.add_argument("--port", type=port_number, default=0, metavar="N", help="the port (default 0: any free port)")
    debug.add_argument("--no-browser", action="store_true", help="do not open the dashboard in a web browser")
    debug.set_defaults(func=Command("debug", "debug_command"))
