"""The parser of `lakegate ingest` and `lakegate lake` (`ls`, `compact`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from lakegate.gateway.cli.parsers import Command, compact
from lakegate.gateway.cli.parsers.shared_options import CONFIG_PATHS_HELP, add_strict_option

#: The raw job statuses `--job-status` takes (the product guide's `job_status` values).
JOB_STATUSES = ("SUCCEEDED", "FAILED")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    ingest = subparsers.add_parser(
        "ingest",
        help="ingest the emissions files of one job into the lake",
        description="Validate the emissions files (JSON lines) of one job against the branch's topics and write "
        "them to the lake as Parquet, with the job's metadata row and events. Re-ingesting a job "
        "replaces it. A bad line fails the job (nothing is written) unless --skip-bad-lines.",
    )
    ingest.add_argument(
        "emissions",
        nargs="+",
        type=Path,
        metavar="EMISSIONS",
        help="emissions files of the job (JSON lines, as the Emitter writes them); the platform's files "
        "resource_metrics.resim.jsonl and test_length_metric.resim.jsonl in their folders are read too (the "
        "tables container_performance and test_length_seconds)",
    )
    ingest.add_argument("--lake", required=True, type=Path, metavar="DIR", help="the lake's directory")
    ingest.add_argument("--branch", required=True, metavar="B", help="the branch the job ran on (any name)")
    ingest.add_argument("--batch", required=True, metavar="ID", help="the id of the job's batch")
    ingest.add_argument("--job", required=True, metavar="ID", help="the job's id")
    ingest.add_argument(
        "--metadata",
        type=Path,
        metavar="FILE",
        help="YAML mapping of metadata columns to values (experience_name, build_version, "
        "experience_tag_names, time ...); flags below override it",
    )
    ingest.add_argument(
        "--metrics-config-path",
        action="append",
        type=Path,
        metavar="P",
        dest="config_paths",
        help=f"config file declaring the topics ({CONFIG_PATHS_HELP}; default: the branch's "
        "current config in the lake, else .resim/metrics/config.resim.yaml)",
    )
    add_strict_option(ingest)
    ingest.add_argument(
        "--logs",
        type=Path,
        metavar="DIR",
        help="a folder of the job's log files (the images, videos and files its metrics show), copied into the "
        "lake with the job, in the same commit (default: a 'logs' folder beside the first emissions file, if "
        "there is one; without either the job keeps the logs it had)",
    )
    ingest.add_argument("--experience-name", help="the experience (scenario) the job ran")
    ingest.add_argument("--build-name", help="the name of the build under test")
    ingest.add_argument("--build-version", help="the version of the build under test")
    ingest.add_argument(
        "--tag",
        action="append",
        dest="tags",
        metavar="TAG",
        help="an experience tag name (repeatable); sets experience_tag_names",
    )
    ingest.add_argument(
        "--job-status",
        type=str.upper,
        choices=JOB_STATUSES,
        help="the job's raw status: SUCCEEDED (the default) or FAILED (makes its conflated status ERROR)",
    )
    ingest.add_argument(
        "--skip-bad-lines",
        action="store_true",
        help="write the good rows and put bad lines, with reasons, in a quarantine file",
    )
    ingest.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show a progress bar on standard error (default: when it is a terminal)",
    )
    ingest.set_defaults(func=Command("ingest", "ingest_command"))

    lake = subparsers.add_parser("lake", help="look at what is in a lake", description="Look at what is in a lake.")
    commands = lake.add_subparsers(dest="lake_command", metavar="SUBCOMMAND")
    commands.required = True
    ls = commands.add_parser(
        "ls",
        help="list branches, or a branch's batches, jobs and tables with row counts",
        description="Without --branch, list the lake's branches; with it, the branch's batches, jobs and "
        "tables (columns and row counts).",
    )
    ls.add_argument("--lake", required=True, type=Path, metavar="DIR", help="the lake's directory")
    ls.add_argument("--branch", metavar="B", help="the branch to describe")
    ls.set_defaults(func=Command("ingest", "ls_command"))
    compact.add_parser(commands)
