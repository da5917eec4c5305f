"""Fixtures of the ingestion tests: the config every test ingests with."""

from __future__ import annotations

import pytest

from lakegate.lake.config import load_config
from tests.lake.ingest.lines import CONFIG


@pytest.fixture
def config_path(tmp_path):
    path = tmp_path / "config.resim.yaml"
    path.write_text(CONFIG)
    return path


@pytest.fixture
def config(config_path):
    return load_config(config_path)
