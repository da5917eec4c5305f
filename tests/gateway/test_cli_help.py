"""`lakegate --help` lists every command without importing any of them, `lakegate COMMAND --help` (nested
ones included) imports none of the command's work (so both answer at once; the time is measured by
bench/cli_startup.py), and each command's own parser is the one its module adds."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

from lakegate.gateway.cli.main import COMMANDS, build_parser

#: Modules a command needs and `lakegate --help` must not load (each costs a large part of a second).
HEAVY = ("duckdb", "pyarrow", "sqlglot", "numpy", "fastapi", "plotly", "lakegate.lake.config")
#: What no command's --help may load either: the rest of the commands' dependencies, and the commands'
#: own modules (lakegate.gateway.cli.<command>; their parsers are in lakegate.gateway.cli.parsers).
COMMAND_WORK = (*HEAVY, "scipy", "uvicorn", "starlette", "liquid", "yaml", "tqdm", "trino", "mcap", "bcrypt")
#: Forks one child per command line from a fresh interpreter that has imported only the CLI's entry point:
#: each child runs `main(ARGV + ['--help'])` and reports what it printed and what got imported.
HELP_OF_EACH = """
import io, json, os, sys, contextlib
from lakegate.gateway.cli.main import main
for argv in json.loads(sys.argv[1]):
    read, write = os.pipe()
    if os.fork() == 0:
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            try:
                main([*argv, "--help"])
            except SystemExit as done:
                code = done.code
        answer = {"argv": argv, "code": code, "out": out.getvalue(), "modules": sorted(sys.modules)}
        os.write(write, json.dumps(answer).encode())
        os._exit(0)
    os.close(write)
    with os.fdopen(read) as answer:
        print(answer.read())
    os.wait()
"""


def _subcommands(parser) -> dict[str, object]:
    action = next(a for a in parser._actions if a.dest == "command")
    return {choice.dest: choice for choice in action._choices_actions}


def test_the_help_of_each_command_is_what_its_module_says():
    lazy = {name: action.help for name, action in _subcommands(build_parser()).items()}
    full = {name: action.help for name, action in _subcommands(build_parser("*")).items()}
    assert lazy == full == {name: help_text for name, (_, help_text) in COMMANDS.items()}


def test_help_imports_no_command_module():
    code = (
        "import sys\n"
        "from lakegate.gateway.cli.main import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit as done:\n    assert done.code == 0\n"
        "print(' '.join(sorted(m for m in sys.modules if m.startswith('lakegate') or m.split('.')[0] in "
        f"{HEAVY!r})))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert "usage: lakegate [-h] COMMAND" in done.stdout and "flakes" in done.stdout
    loaded = done.stdout.split("\n")[-2].split()
    assert [m for m in loaded if m in HEAVY or m.split(".")[0] in HEAVY] == []
    assert sorted(loaded) == ["lakegate", "lakegate.gateway", "lakegate.gateway.cli", "lakegate.gateway.cli.main"]


def _command_lines(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()) -> list[list[str]]:
    """Every command line with a parser of its own: `metrics`, `metrics run`, ..."""
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found += [[*prefix, name], *_command_lines(sub, (*prefix, name))]
    return found


def test_the_help_of_every_command_imports_none_of_its_work():
    full = build_parser("*")
    lines = _command_lines(full)
    assert ["metrics", "run"] in lines and ["lake", "compact"] in lines and len(lines) > len(COMMANDS)
    done = subprocess.run(
        [sys.executable, "-c", HELP_OF_EACH, json.dumps(lines)], capture_output=True, text=True, timeout=120, check=True
    )
    answers = [json.loads(line) for line in done.stdout.splitlines() if line]
    assert [answer["argv"] for answer in answers] == lines
    for answer in answers:
        command = " ".join(answer["argv"])
        assert answer["code"] == 0 and answer["out"].startswith(f"usage: lakegate {command} [-h]"), command
        loaded = [m for m in answer["modules"] if m in COMMAND_WORK or m.split(".")[0] in COMMAND_WORK]
        commands = [m for m in answer["modules"] if m.startswith("lakegate.gateway.cli.") and m.count(".") == 3]
        assert (loaded, commands) == ([], ["lakegate.gateway.cli.main", "lakegate.gateway.cli.parsers"]), command


def test_a_command_parses_with_its_own_module_only(tmp_path):
    args = build_parser("flakes").parse_args(["flakes", "--lake", str(tmp_path), "--branch", "main"])
    assert args.command == "flakes" and callable(args.func)
