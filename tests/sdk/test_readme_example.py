"""The README's example of the SDK ("The SDK: Batch and Test") runs as written, with a config split in three."""

from __future__ import annotations

import base64
import os
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[2] / "README.md"
PNG = base64.b64decode(
    "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg=="
)
FILES = {
    "topics.resim.yml": """version: 1
topics:
  speed:
    schema: {v: float}
  goal_reached:
    event: true
    schema: {name: string, description: string, status: status, tags: "string[]"}
""",
    "metrics.resim.yml": """version: 1
metrics:
  Max Speed:
    type: test
    query_string: SELECT max(v) FROM speed
    template: scalar
    status: {query_string: "SELECT 1 FROM speed WHERE v > ?", block: 5, warn: 2.5}
  Speed:
    type: test
    query_string: SELECT 'v', timestamp, v FROM speed
    template_type: custom
    template_file: speed.liquid
""",
    "sets.resim.yml": "version: 1\nmetrics sets:\n  Nav Metrics: {metrics: [Max Speed, Speed]}\n",
}
LIQUID = '{"data": [{"type": "scatter", "x": {{ timestamp | json }}, "y": {{ v | json }}}], "layout": {}}\n'


def example() -> str:
    section = README.read_text().split("### The SDK: Batch and Test", 1)[1]
    return section.split("```python\n", 1)[1].split("```", 1)[0]


def test_the_readme_example_runs(tmp_path):
    folder = tmp_path / ".resim" / "metrics"
    (folder / "templates").mkdir(parents=True)
    for name, text in FILES.items():
        (folder / name).write_text(text)
    (folder / "templates" / "speed.liquid").write_text(LIQUID)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "front.png").write_bytes(PNG)
    run = subprocess.run(
        [sys.executable, "-c", example()], cwd=tmp_path, capture_output=True, text=True, timeout=300, env=os.environ
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout == "WARNING {'Lobby': 'PASSED', 'Ward 3': 'WARNING'}\n"
    assert (tmp_path / "lake" / "main" / "_lake.sqlite").is_file()
