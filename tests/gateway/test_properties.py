"""Properties of the whole path, checked on generated data (hypothesis): what an `Emitter` emits, once
ingested into a lake, is what a query of the DuckDB backend returns, value for value and with the Trino
type of each field."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lakegate.gateway.engine.backend import DuckDBBackend
from lakegate.lake.config import Config, load_config
from lakegate.lake.emitter import Emitter
from lakegate.lake.ingest import ingest_job

#: field type -> (its Trino type, valid values of it)
TEXT = st.text(st.characters(blacklist_categories=["Cs"]), max_size=10)
FIELDS = {
    "int": ("bigint", st.integers(-(2**63), 2**63 - 1)),
    "float": ("double", st.floats(allow_nan=False, allow_infinity=False)),
    "boolean": ("boolean", st.booleans()),
    "string": ("varchar", TEXT),
    "status": ("varchar", st.sampled_from(["PASSED", "WARNING", "BLOCKER"]) | TEXT),
    "image": ("varchar", TEXT),
    "string[]": ("array(varchar)", st.lists(TEXT, max_size=4)),
}
TOPIC = {kind.replace("[]", "_list"): kind for kind in FIELDS}  # column name -> field type
CONFIG = f"version: 1\ntopics:\n  sample:\n    schema: {json.dumps(TOPIC)}\n"


@pytest.fixture(scope="module")
def config_path(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("config") / "config.resim.yaml"
    path.write_text(CONFIG)
    return path


@pytest.fixture(scope="module")
def config(config_path) -> Config:
    return load_config(config_path)


records = st.fixed_dictionaries({column: FIELDS[kind][1] for column, kind in TOPIC.items()})
#: (timestamp, record) pairs with distinct timestamps, so that ORDER BY timestamp gives them back in order
emissions = st.lists(st.tuples(st.integers(0, 2**63 - 1), records), max_size=8, unique_by=lambda pair: pair[0])


def same(a: Any, b: Any) -> bool:
    """Equal values of equal types; floats by their bits (-0.0 is not 0.0)."""
    if isinstance(a, float) or isinstance(b, float):
        return type(a) is type(b) and a == b and math.copysign(1, a) == math.copysign(1, b)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(emitted=emissions, as_series=st.booleans())
def test_a_query_returns_what_the_emitter_emitted(tmp_path, config_path, config, emitted, as_series):
    with tempfile.TemporaryDirectory(dir=tmp_path) as folder:
        output = Path(folder) / "emissions.jsonl"
        with Emitter(config_path, output) as emitter:
            if as_series and emitted:
                columns = {column: [record[column] for _, record in emitted] for column in TOPIC}
                emitter.emit_series("sample", columns, [stamp for stamp, _ in emitted])
            for stamp, record in [] if as_series else emitted:
                emitter.emit("sample", record, stamp)
        lake = Path(folder) / "lake"
        report = ingest_job(lake, "main", "b1", "j1", [output], config=config)
        assert report.rows.get("sample", 0) == len(emitted) and report.bad_lines == 0
        columns = ", ".join(f'"{column}"' for column in TOPIC)
        result = DuckDBBackend(lake).execute(f"SELECT timestamp, {columns} FROM sample ORDER BY timestamp")
        assert result.columns == [("timestamp", "bigint")] + [(c, FIELDS[kind][0]) for c, kind in TOPIC.items()]
        want = [
            (stamp, *(record[column] for column in TOPIC))
            for stamp, record in sorted(emitted, key=lambda pair: pair[0])
        ]
        got = result.rows()
        assert len(got) == len(want)
        for row, expected in zip(got, want):
            assert all(same(g, w) for g, w in zip(row, expected)), f"{row!r} != {expected!r}"
