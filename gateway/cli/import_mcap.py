"""`lakegate import mcap`: the messages of an MCAP log -> emissions, or straight into a job of the lake."""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from tqdm import tqdm

from lakegate.gateway.cli.command_errors import UserError, existing_configs, writable_lake
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
