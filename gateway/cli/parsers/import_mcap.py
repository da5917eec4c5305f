"""The parser of `lakegate import mcap`."""

from __future__ import annotations

import argparse
from pathlib import Path

from lakegate.gateway.cli.parsers import Command

EXAMPLE = """\
mapping file (YAML), one entry per MCAP topic:

  /odom:
    topic: odom_linear_velocity        # a topic of the metrics config
    fields: {x: twist.twist.linear.x, y: twist.twist.linear.y, z: twist.twist.linear.z}
    timestamp: log_time                # log_time (default), publish_time, or a path: header.stamp
    decimate: 10                       # optional: keep one message in 10

ROS 2 messages (cdr, with a ros2msg schema), protobuf messages and JSON messages are decoded;
no ROS installation is needed."""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    group = subparsers.add_parser(
        "import",
        help="import robot logs (MCAP) as emissions or into a job of the lake",
        description="Import robot logs as topic rows.",
    )
    kinds = group.add_subparsers(dest="import_kind", metavar="KIND")
    kinds.required = True
    parser = kinds.add_parser(
        "mcap",
        help="the messages of an MCAP file -> emissions (or a job of the lake), by a mapping file",
        description="Turn the messages of an MCAP file into topic rows, as a mapping file says, checked by the "
        "Emitter against the metrics config; write them as an emissions file (--output) or ingest them as "
        "one job (--lake, --batch, --job).",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("mcap", type=Path, metavar="LOG.mcap", help="the MCAP file")
    parser.add_argument("--mapping", required=True, type=Path, metavar="FILE", help="the mapping file (YAML)")
    parser.add_argument("--output", type=Path, metavar="FILE", help="the emissions file to write (replaced)")
    parser.add_argument("--lake", type=Path, metavar="DIR", help="ingest the rows into this lake as one job")
    parser.add_argument("--branch", default="main", metavar="B", help="the job's branch (default: main)")
    parser.add_argument("--batch", metavar="ID", help="the job's batch (with --lake)")
    parser.add_argument("--job", metavar="ID", help="the job's id (with --lake)")
    parser.add_argument("--build-version", help="the version of the build under test (with --lake)")
    parser.add_argument("--experience-name", help="the experience the job ran (with --lake)")
    parser.add_argument(
        "--metrics-config-path",
        action="append",
        type=Path,
        metavar="P",
        dest="config_paths",
        help="config file declaring the topics (repeat to merge several; default: the branch's stored "
        "config with --lake, else .resim/metrics/config.resim.yaml)",
    )
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show a progress bar on standard error (default: when it is a terminal)",
    )
    parser.set_defaults(func=Command("import_mcap", "import_mcap_command"))
