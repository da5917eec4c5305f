"""`lakegate config check|schema`, run as a real subprocess."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jsonschema
import yaml

FIXTURE = Path(__file__).resolve().parents[2] / "fixtures" / "config.resim.yaml"
LAKEGATE = Path(sys.executable).parent / "lakegate"


def lakegate(*args: str | Path, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(LAKEGATE), *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=60)


def test_check_valid_fixture_prints_a_summary():
    result = lakegate("config", "check", FIXTURE)
    assert (result.returncode, result.stderr) == (0, "")
    assert result.stdout == f"ok: 10 topics, 15 metrics, 1 metrics set ({FIXTURE})\n"


def test_check_prints_every_problem_with_its_place(tmp_path):
    bad = tmp_path / "bad.resim.yaml"
    bad.write_text(
        "version: 1\n"
        "topics:\n"
        "  nav/odom: {schema: {x: flaot}}\n"
        "metrics:\n"
        "  M: {type: test, description: d, querystring: SELECT 1, template: line}\n"
        "metrics sets:\n"
        "  S: {metrics: [Missing]}\n"
    )
    unknown = f"{bad}:5:35: unknown key 'querystring' in metric 'M' (did you mean 'query_string'?): ignored"
    errors = [
        f"{bad}:3:3: topic 'nav/odom' contains '/', which topic names may not",
        f"{bad}:3:26: unknown field type 'flaot' for field 'x' of topic 'nav/odom' (did you mean 'float'?); "
        "expected one of int, float, boolean, string, status, image, video, string[], metric[], bigint",
        f"{bad}:5:3: missing required key 'query_string' in metric 'M'",
        f"{bad}:7:17: metrics set 'S' names unknown metric 'Missing'",
    ]
    result = lakegate("config", "check", "--strict", bad)
    assert result.returncode == 1
    strict = unknown.removesuffix(": ignored") + " (ReSim accepts this; refused because of --strict)"
    assert result.stdout.splitlines() == [*errors[:3], strict, errors[3]]
    # without --strict the unknown key is ignored, as ReSim does: not among the problems
    result = lakegate("config", "check", bad)
    assert (result.returncode, result.stdout.splitlines()) == (1, errors)


def test_check_warns_about_what_resim_accepts_and_strict_refuses_it(tmp_path):
    config = tmp_path / "resim.yaml"
    config.write_text(
        "version: 1\nmetrics:\n  M: {type: test, query_string: SELECT 1, template: scalar, unit: s, owner: nav-team}\n"
    )
    result = lakegate("config", "check", config)
    warning = f"{config}:3:70: warning: unknown key 'owner' in metric 'M': ignored"
    assert (result.returncode, result.stderr) == (0, warning + "\n")
    assert result.stdout == f"ok: 0 topics, 1 metric, 0 metrics sets, 1 warning(s) ({config})\n"
    result = lakegate("config", "check", "--strict", config)
    assert result.returncode == 1
    assert result.stdout == (
        f"{config}:3:70: unknown key 'owner' in metric 'M' (ReSim accepts this; refused because of --strict)\n"
    )


def test_check_merges_several_files(tmp_path):
    extra = tmp_path / "extra.resim.yaml"
    extra.write_text(
        "version: 1\n"
        "metrics:\n"
        "  Mean Speed: {type: batch, description: d, query_string: SELECT AVG(speed) FROM robot_speed,\n"
        "    template: scalar}\n"
        "metrics sets:\n"
        "  Extra: {metrics: [Mean Speed, Robot Speed]}\n"
    )
    result = lakegate("config", "check", FIXTURE, extra)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout == f"ok: 10 topics, 16 metrics, 2 metrics sets ({FIXTURE}, {extra})\n"

    result = lakegate("config", "check", FIXTURE, FIXTURE)
    assert result.returncode == 1
    duplicate = "duplicate topic name 'odom_linear_velocity' found across config files"
    assert f"{FIXTURE}:7:3: {duplicate} (first defined at {FIXTURE}:7:3)" in result.stdout


def test_check_finds_the_default_config(tmp_path):
    result = lakegate("config", "check", cwd=tmp_path)
    assert result.returncode == 1 and result.stdout == ""
    assert result.stderr.startswith("lakegate: no config file given and no .resim/metrics/config.resim.yaml")

    default = tmp_path / ".resim" / "metrics" / "config.resim.yml"
    default.parent.mkdir(parents=True)
    default.write_text("version: 1\ntopics: {speed: {schema: {v: float}}}\n")
    (tmp_path / "sub").mkdir()
    result = lakegate("config", "check", cwd=tmp_path / "sub")
    assert (result.returncode, result.stdout) == (0, f"ok: 1 topic, 0 metrics, 0 metrics sets ({default})\n")


def test_schema_to_stdout_and_file_validates_configs(tmp_path):
    result = lakegate("config", "schema")
    assert result.returncode == 0, result.stderr
    schema = json.loads(result.stdout)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    jsonschema.Draft202012Validator.check_schema(schema)

    out = tmp_path / "config.schema.json"
    result = lakegate("config", "schema", "-o", out)
    assert (result.returncode, result.stdout) == (0, "")
    assert json.loads(out.read_text()) == schema

    validator = jsonschema.Draft202012Validator(schema)
    assert validator.is_valid(yaml.safe_load(FIXTURE.read_text()))
    assert not validator.is_valid({"version": 1, "topics": {"nav/odom": {"schema": {"x": "float"}}}})
    assert not validator.is_valid(
        {
            "version": 1,
            "metrics": {"M": {"type": "test", "description": "d", "querystring": "SELECT 1", "template": "line"}},
        }
    )


def test_schema_unwritable_output_is_a_user_error(tmp_path):
    result = lakegate("config", "schema", "-o", tmp_path / "no" / "such" / "dir.json")
    assert result.returncode == 1
    assert result.stderr.startswith("lakegate: cannot write ") and "Traceback" not in result.stderr


TOPIC_NAMES = [
    "odom*",
    "a=b",
    "x%41",
    "a\\b",
    "t?",
    "t[1]",
    "{t}",
    "é" * 130,
    "_x",
    ".x",
    "Metadata",
    "a/b",
    "odom.v1-x",
    "é" * 120,
    "Odom Velocity (m/s)2",
]


def test_check_refuses_exactly_the_topic_names_the_lake_cannot_hold(tmp_path):
    """`config check` said ok to names like `odom*` that ingest then refused: it applies the lake's rule now."""
    from lakegate.lake.paths import LakePathError, check_table_name

    config = tmp_path / "names.resim.yaml"
    config.write_text(
        "version: 1\ntopics:\n" + "".join(f"  {json.dumps(name)}: {{schema: {{x: float}}}}\n" for name in TOPIC_NAMES)
    )
    result = lakegate("config", "check", config)
    refused = {}
    for problem in result.stdout.splitlines():
        place, message = problem.split(": ", 1)
        line = int(place.split(":")[-2])
        refused[TOPIC_NAMES[line - 3]] = message  # one topic a line, from line 3
    for name in TOPIC_NAMES:
        try:
            check_table_name(name)
            lake_accepts = True
        except LakePathError:
            lake_accepts = False
        assert (name not in refused) == lake_accepts or name == "Metadata", (name, refused.get(name))
    assert "Metadata" in refused  # SQL table names ignore case: refused even though the lake could store it
    assert result.returncode == 1 and result.stderr == ""
    assert (
        refused["odom*"] == "topic 'odom*' contains one of \\ = % * ? [ ] { }, which the lake's table paths cannot hold"
    )
    assert refused["é" * 130].endswith("is too long (at most 240 bytes)")


def test_a_deeply_nested_or_huge_config_is_refused_with_its_place(tmp_path):
    deep = tmp_path / "deep.resim.yaml"
    deep.write_text("version: 1\nmetrics:\n  M:\n    query_string: " + "[" * 100_000 + "\n")
    result = lakegate("config", "check", deep)
    assert result.returncode == 1 and "Traceback" not in result.stderr + result.stdout
    assert result.stdout == f"{deep}:4:80: mappings and lists nest deeper than 64 levels, the limit of a config file\n"
    huge = tmp_path / "huge.resim.yaml"
    with huge.open("w") as out:  # 70 MB: refused before it is parsed
        out.write("version: 1\nmetrics:\n")
        for i in range(700_000):
            out.write(f"  metric_{i:07d}: {{type: test, query_string: SELECT {i}, template: scalar, d: {'x' * 40}}}\n")
    result = lakegate("config", "check", huge)
    assert result.returncode == 1 and "Traceback" not in result.stderr + result.stdout
    assert result.stdout == f"{huge}: the file is larger than 2,097,152 bytes, the limit of a config file\n"
