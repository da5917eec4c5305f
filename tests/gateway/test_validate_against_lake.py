"""`lakegate metrics validate --lake L --branch B`: a config checked against what a real lake made by
ingest stores (its topics' fields and types, its tables), every finding at its file:line:column."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from lakegate.gateway.cli.main import main
from lakegate.lake.config import load_config
from lakegate.lake.emitter import Emitter
from lakegate.lake.ingest import ingest_job

STORED = """\
version: 1
topics:
  pose:
    schema:
      x: float
      label: string
  bump:
    event: true
    schema:
      name: string
      description: string
      status: status
      tags: string[]
      metrics: metric[]
metrics:
  Max X:
    type: test
    query_string: SELECT MAX(x) AS value FROM pose
    template: scalar
"""


@pytest.fixture(scope="module")
def lake(tmp_path_factory) -> Path:
    """A lake whose branch `main` holds one job ingested with the STORED config."""
    root = tmp_path_factory.mktemp("validate")
    (root / "stored.resim.yaml").write_text(STORED)
    emissions = root / "job" / "emissions.resim.jsonl"
    emissions.parent.mkdir()
    with Emitter(root / "stored.resim.yaml", emissions) as emitter:
        emitter.emit_series("pose", {"x": [1.0, 2.0], "label": ["a", "b"]}, timestamps=[0, 10**6])
    config = load_config([root / "stored.resim.yaml"])
    ingest_job(root / "lake", "main", "b1", "job-1", [emissions], config=config, metadata={"experience_name": "E"})
    return root / "lake"


def validate(capsys, config: Path, *args: str) -> tuple[int, str, str]:
    code = main(["metrics", "validate", "--metrics-config-path", str(config), *args])
    out, err = capsys.readouterr()
    return code, out, err


def write(folder: Path, text: str) -> Path:
    path = folder / "config.resim.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def test_a_config_that_only_grows_the_branch_passes(lake, tmp_path, capsys):
    grown = STORED.replace("      label: string\n", "      label: string\n      y: float\n") + (
        "  Labels:\n"
        "    type: batch\n"
        "    query_string: SELECT COUNT(DISTINCT label) AS value FROM pose p JOIN metadata m ON p.job_id = m.job_id\n"
        "    template: scalar\n"
        "  Runs Evaluated:\n"
        "    type: dashboard\n"
        "    query_string: SELECT current_user AS who, COUNT(*) AS runs FROM metric_results\n"
        "    template: table\n"
    )
    grown = grown.replace("topics:\n", "topics:\n  speed:\n    schema:\n      v: float\n", 1)
    config = write(tmp_path, grown)
    code, out, _ = validate(capsys, config, "--lake", str(lake), "--branch", "main")
    assert code == 0, out
    assert out == f"ok: 3 topics, 3 metrics, 0 metrics sets ({config}; matches branch 'main' of lake {lake})\n"


def test_removed_and_retyped_fields_and_unknown_tables_are_named_with_their_place(lake, tmp_path, capsys):
    config = write(
        tmp_path,
        """\
        version: 1
        topics:
          pose:
            schema:
              x: string
          bump:
            schema:
              name: string
        metrics:
          Max X:
            type: test
            query_string: SELECT MAX(x) AS value FROM pose
            template: scalar
          Speed:
            type: test
            query_string: |
              SELECT MAX(speed)
              FROM robot_speed
            template: scalar
          Slow:
            type: test
            query_string: SELECT COUNT(*) AS value FROM pose
            template: scalar
            status:
              query_string: SELECT 1 FROM pose WHERE y > ?
              block: 1
          Container:
            type: test
            query_string: SELECT 1 AS value FROM container_performance
            template: scalar
        """,
    )
    code, out, _ = validate(capsys, config, "--lake", str(lake), "--branch", "main")
    assert code == 1
    assert out.splitlines() == [
        f"{config}:5:7: topic 'pose' field 'x' is declared string, but the lake holds it as float (config version 1); "
        "SignalFlag refuses retyping a column",
        f"{config}:3:3: topic 'pose' leaves out field 'label', which the lake holds as string (config version 1); "
        "a branch's topics only grow (SignalFlag refuses removing a column)",
        f"{config}:6:3: topic 'bump' is declared a plain topic, but the lake holds it as an event topic (config "
        "version 1); a topic cannot change kind",
        *(
            f"{config}:6:3: topic 'bump' leaves out field '{name}', which the lake holds as {kind} (config version "
            "1); a branch's topics only grow (SignalFlag refuses removing a column)"
            for name, kind in [("description", "string"), ("status", "status"), ("tags", "string[]")]
            + [("metrics", "metric[]")]
        ),
        f"{config}:18:12: query of metric 'Speed': Table 'robot_speed' does not exist",
        f"{config}:25:46: status query of metric 'Slow': Column 'y' cannot be resolved",
    ]  # `Container` reads a platform table, which every branch has
    # `Max X` reads `x` as the config declares it (varchar): MAX of text is fine, so no query finding there


def test_lake_and_branch_go_together_and_name_what_is_missing(lake, tmp_path, capsys):
    config = write(tmp_path, STORED)
    assert validate(capsys, config)[0] == 0  # no lake: the file alone
    assert validate(capsys, config, "--lake", str(lake))[:2] == (1, "")
    code, _, err = validate(capsys, config, "--lake", str(lake), "--branch", "dev")
    assert code == 1 and "branch 'dev' of lake" in err and "has no stored config (branches: 'main')" in err
    code, _, err = validate(capsys, config, "--lake", str(tmp_path / "nowhere"), "--branch", "main")
    assert code == 1 and f"no lake at {str(tmp_path / 'nowhere')!r}" in err
