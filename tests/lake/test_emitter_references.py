"""The Emitter's output byte for byte against the reference Emitters (resim-open-core 1.6.0, signalflag 1.8.0)."""

from __future__ import annotations

import gzip
from pathlib import Path

from lakegate.lake.emitter import Emitter
from tests.lake.emitter_support import FIXTURE_CONFIG

# --- byte identity with the reference Emitters ------------------------------------------------


def load_shapes():
    """tests/lake/emitter_series_shapes.py as a module (a script the references' venvs run too)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("shapes", Path(__file__).with_name("emitter_series_shapes.py"))
    shapes = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(shapes)
    return shapes


def pinned_shape_lines() -> bytes:
    """What resim-open-core 1.6.0 and signalflag 1.8.0 wrote for the shapes."""
    return gzip.decompress((FIXTURE_CONFIG.parent / "emitter_series_shapes.jsonl.gz").read_bytes())


def test_series_are_byte_identical_to_the_references_and_take_the_column_path(tmp_path: Path, monkeypatch):
    """emit_series writes, byte for byte, what resim-open-core 1.6.0 and signalflag 1.8.0 wrote for the same
    calls (fixtures/emitter_series_shapes.jsonl.gz, made by tests/lake/emitter_series_shapes.py under their
    venvs), and every shape of scalar fields is built by the column-by-column path, not record by record."""
    from lakegate.lake import emitter as emitter_module

    shapes = load_shapes()
    by_record = []
    original = emitter_module.SeriesLines.encode

    def spy(self, stamps, columns):
        blocks = original(self, stamps, columns)
        if blocks is None:
            by_record.append(len(stamps))
        return blocks

    monkeypatch.setattr(emitter_module.SeriesLines, "encode", spy)
    out = tmp_path / "emissions.resim.jsonl"
    shapes.main("lakegate.lake.emitter", str(out))
    assert out.read_bytes() == pinned_shape_lines()
    assert by_record == [3]  # only the string[]/metric[] series


def test_emit_of_interleaved_topics_is_byte_identical_to_the_references(tmp_path: Path, monkeypatch):
    """emit() of every record of the shapes writes the references' lines (their emit_series writes each record
    as their emit does). The shapes' records are emitted round robin, so that the rows queued by the numeric
    topics and the lines of the text and list topics share every chunk; each numeric record takes the row path."""
    from lakegate.lake import emitter as emitter_module

    shapes = load_shapes()
    rows_written = []
    original = emitter_module.rows_text

    def spy(rows):
        rows_written.append(len(rows))
        return original(rows)

    monkeypatch.setattr(emitter_module, "rows_text", spy)
    calls = shapes.shapes()
    pinned = pinned_shape_lines().splitlines(keepends=True)
    records, expected, at = [], [], 0
    for topic, columns, stamps in calls:
        records.append([(topic, {k: v[i] for k, v in columns.items()}, stamp) for i, stamp in enumerate(stamps)])
        expected.append(pinned[at : at + len(stamps)])
        at += len(stamps)
    assert at == len(pinned)
    config = tmp_path / "config.resim.yaml"
    config.write_text(shapes.CONFIG)
    out = tmp_path / "emissions.resim.jsonl"
    order = [(k, i) for i in range(max(map(len, records))) for k in range(len(records)) if i < len(records[k])]
    with Emitter(config, out, flush_interval=3600) as em:
        for k, i in order:
            em.emit(*records[k][i])
    assert out.read_bytes() == b"".join(expected[k][i] for k, i in order)
    numeric = sum(len(stamps) for topic, _, stamps in calls if topic in ("floats", "ints", "flags"))
    assert sum(rows_written) == numeric and len(rows_written) > 3  # runs of rows between the other topics' lines
