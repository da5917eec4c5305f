"""Fixtures of the Emitter's tests: an output path under tmp_path and an Emitter validating the fixture config."""

from __future__ import annotations

from pathlib import Path

import pytest

from lakegate.lake.emitter import Emitter
from tests.lake.emitter_support import FIXTURE_CONFIG


@pytest.fixture
def out(tmp_path: Path) -> Path:
    return tmp_path / "out" / "emissions.resim.jsonl"


@pytest.fixture
def emitter(out: Path):
    with Emitter(config_path=FIXTURE_CONFIG, output_path=out) as em:
        yield em
