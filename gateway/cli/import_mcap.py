"""`lakegate import mcap`: the messages of an MCAP log -> emissions, or straight into a job of the lake."""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from tqdm import tqdm

from lakegate.gateway.cli.errors import UserError, existing_configs, writable_lake
from lakegate.gateway.cli.ingest import summary
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import ConfigError, load_config
from lakegate.lake.emitter import Emitter
from lakegate.lake.ingest import IngestError, ingest_job
from lakegate.lake.mcap_import import (
    ImportReport,
    MappingError,
    McapImportError,
    TopicMapping,
    import_mcap,
    load_mapping,
    message_count,
)

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
    parser.set_defaults(func=import_mcap_command)


def _config_files(args: argparse.Namespace) -> list[Path]:
    if not args.config_paths and args.lake is not None:
        registry = BranchConfigs(args.lake, args.branch)
        version = registry.current_version()
        if version is not None:
            return [Path(p) for p in registry.files(version)]
    return existing_configs(args.config_paths)


def import_mcap_command(args: argparse.Namespace) -> int:
    if (args.output is None) == (args.lake is None):
        raise UserError("give either --output FILE or --lake DIR (with --batch and --job)")
    if args.lake is not None and not (args.batch and args.job):
        raise UserError("--lake needs --batch and --job")
    if not args.mcap.is_file():
        raise UserError(f"MCAP file {str(args.mcap)!r} does not exist or is not a file")
    if args.lake is not None:
        writable_lake(args.lake)
    files = _config_files(args)
    try:
        config = load_config(files)
        mappings = load_mapping(args.mapping, config.topics)
    except ConfigError as exc:
        raise UserError(f"the config does not load: {exc.problems[0]}") from None
    except MappingError as exc:
        print(f"lakegate: the mapping has {len(exc.problems)} problem(s):", file=sys.stderr)
        for problem in exc.problems:
            print(f"  {problem}", file=sys.stderr)
        return 1
    # beside --output, so that the finished file replaces it in one rename
    scratch = Path(tempfile.mkdtemp(prefix=".lakegate-import-", dir=args.output.parent if args.output else None))
    emissions = scratch / "emissions.resim.jsonl"
    try:
        report = _emit(args, files, mappings, emissions)
        if args.output is not None:
            os.replace(emissions, args.output)
            rows = ", ".join(f"{name}: {count:,}" for name, count in report.rows.items())
            print(
                f"wrote {sum(report.rows.values()):,} rows from {report.messages:,} messages to {args.output} ({rows})"
            )
            return 0
        metadata = {
            k: v for k, v in (("build_version", args.build_version), ("experience_name", args.experience_name)) if v
        }
        ingested = ingest_job(
            args.lake, args.branch, args.batch, args.job, [emissions], config=config, metadata=metadata
        )
        print(summary(ingested))
        return 0
    except McapImportError as exc:
        raise UserError(str(exc)) from None
    except IngestError as exc:
        raise UserError(exc.summary) from None
    finally:
        emissions.unlink(missing_ok=True)
        scratch.rmdir()


def _emit(args: argparse.Namespace, files: list[Path], mappings: list[TopicMapping], emissions: Path) -> ImportReport:
    """Emit the mapped messages into `emissions`, with a progress bar when asked."""
    show = sys.stderr.isatty() if args.progress is None else args.progress
    total = message_count(args.mcap, {m.source for m in mappings}) if show else None
    with tqdm(total=total, unit="msg", disable=not show, file=sys.stderr) as bar:
        with Emitter(config_path=files, output_path=emissions) as emitter:
            return import_mcap(args.mcap, mappings, emitter, on_message=bar.update if show else None)
