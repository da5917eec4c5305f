"""`lakegate config check|schema`: check config files, or write the config's JSON Schema."""

from __future__ import annotations

import argparse
import json

from lakegate.gateway.cli.command_errors import UserError, print_config_warnings
from lakegate.lake.config import ConfigError, find_default_config, load_config
from lakegate.lake.config_schema import json_schema


def check_command(args: argparse.Namespace) -> int:
    paths = list(args.paths)
    if not paths:
        found = find_default_config()
        if found is None:
            raise UserError(
                "no config file given and no .resim/metrics/config.resim.yaml (or .yml) found "
                "in this folder or its parents"
            )
        paths = [str(found)]
    try:
        config = load_config(paths, strict=args.strict)
    except ConfigError as exc:
        for problem in exc.problems:
            print(problem)
        return 1
    print_config_warnings(config)
    warned = f", {len(config.warnings)} warning(s)" if config.warnings else ""
    print(f"ok: {config.summary()}{warned} ({', '.join(paths)})")
    return 0


def schema_command(args: argparse.Namespace) -> int:
    text = json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"
    if args.output is None:
        print(text, end="")
        return 0
    try:
        args.output.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise UserError(f"cannot write {args.output}: {exc.strerror}") from None
    return 0
