"""`lakegate --help` lists every command without importing any of them (so it answers at once; the
time is measured by bench/cli_startup.py), and each command's own parser is the one its module adds."""

from __future__ import annotations

import subprocess
import sys

from lakegate.gateway.cli.main import COMMANDS, build_parser

#: Modules a command needs and `lakegate --help` must not load (each costs a large part of a second).
HEAVY = ("duckdb", "pyarrow", "sqlglot", "numpy", "fastapi", "plotly", "lakegate.lake.config")


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


def test_a_command_parses_with_its_own_module_only(tmp_path):
    args = build_parser("flakes").parse_args(["flakes", "--lake", str(tmp_path), "--branch", "main"])
    assert args.command == "flakes" and callable(args.func)
