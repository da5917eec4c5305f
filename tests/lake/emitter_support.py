"""Helpers shared by the Emitter's tests: the fixture config, strict JSON reading, and error capture."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from lakegate.lake.emitter import Emitter, ValidationError

FIXTURE_CONFIG = Path(__file__).resolve().parents[2] / "fixtures" / "config.resim.yaml"
ODOM = "odom_linear_velocity"

GOAL = {
    "name": "Goal 1 Reached",
    "description": "Robot reached goal 1",
    "status": "PASSED",
    "tags": ["navigation"],
    "metrics": [{"name": "Stereo View", "type": "image", "value": ["goal_1.png"], "status": "PASSED"}],
}


def strict_loads(line: str) -> dict:
    """json.loads that refuses the non-standard NaN/Infinity tokens."""

    def refuse(token: str) -> None:
        raise ValueError(f"non-standard JSON token {token}")

    return json.loads(line, parse_constant=refuse)


def read_lines(path: Path) -> list[dict]:
    return [strict_loads(line) for line in path.read_text().splitlines()]


def write_config(path: Path, topics: dict) -> Path:
    path.write_text(yaml.safe_dump({"version": 1, "topics": topics}, allow_unicode=True, sort_keys=False))
    return path


def rejected(emitter: Emitter, *args, method: str = "emit") -> ValidationError:
    with pytest.raises(ValidationError) as info:
        getattr(emitter, method)(*args)
    return info.value


#: A lone surrogate: not valid Unicode text, so not storable as UTF-8.
LONE = "\ud800"
