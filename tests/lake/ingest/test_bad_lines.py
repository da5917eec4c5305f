"""Bad lines: each reported with its file, line and reason (or quarantined with --skip-bad-lines),
and the limits on a line's length and nesting depth."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lakegate.lake import paths
from lakegate.lake.emitter import Emitter
from lakegate.lake.ingest import IngestError, check_line, ingest_job, rules, scan
from tests.lake.ingest.lines import GOAL, count, line, odom, query, write_lines

# -- bad lines ---------------------------------------------------------------------------

BAD = [
    # (line text, reason fragment)
    ('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": }}', "bad JSON at column"),
    ("[1, 2]", "expected a JSON object with $metadata and $data, got list"),
    ('{"$data": {"x": 1.0, "y": 2.0, "z": 3.0}}', "missing $metadata"),
    ('{"$metadata": {"topic": "odom", "timestamp": 1}}', "missing $data"),
    (line("odometry", 1, {"x": 1.0, "y": 2.0, "z": 3.0}), "unknown topic 'odometry' (did you mean 'odom'?)"),
    (line("odom", 1, {"x": "1.5", "y": 2.0, "z": 3.0}), "topic 'odom', field 'x': expected float, got str"),
    (
        line("plain", 1, {"i": 1.0, "f": 1.0, "b": True, "s": "", "tags": []}),
        "topic 'plain', field 'i': expected int, got float",
    ),
    (line("plain", 1, {"i": 1, "f": 1.0, "b": 1, "s": "", "tags": []}), "field 'b': expected boolean, got int"),
    (
        line("plain", 1, {"i": 1, "f": 1.0, "b": True, "s": "", "tags": ["a", 2]}),
        "field 'tags': expected a list of strings",
    ),
    (line("plain", 1, {"i": 2**63, "f": 1.0, "b": True, "s": "", "tags": []}), "int out of the 64-bit range"),
    (line("odom", 1, {"x": 1.0, "y": 2.0}), "topic 'odom': missing field 'z'"),
    (line("odom", 1, {"x": 1.0, "y": 2.0, "z": 3.0, "w": 4.0}), "topic 'odom': unexpected field 'w'"),
    # every problem of a line, each unexpected field with the likeliest missing one
    (
        line("odom", 1, {"x": "1", "y": 2.0, "zz": 3.0, "w": 4.0}),
        "topic 'odom': missing field 'z'; unexpected field 'zz' (did you mean 'z'?); unexpected field 'w'; "
        "field 'x': expected float, got str",
    ),
    (line("odom", -1, {"x": 1.0, "y": 2.0, "z": 3.0}), "bad timestamp: expected an integer number of nanoseconds"),
    (line("odom", 1.5, {"x": 1.0, "y": 2.0, "z": 3.0}), "bad timestamp"),
    (line("odom", "5", {"x": 1.0, "y": 2.0, "z": 3.0}), "bad timestamp"),
    (
        '{"$metadata": {"topic": "odom"}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}',
        "bad timestamp: $metadata has no timestamp",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": NaN, "y": 2.0, "z": 3.0}}',
        "NaN is not valid JSON",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1e400, "y": 2.0, "z": 3.0}}',
        "expected a finite float, got inf",
    ),
    ('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0,}}', "bad JSON"),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "x": 2.0, "y": 2.0, "z": 3.0}}',
        "duplicate key 'x'",
    ),
    (line("odom", 1, {"x": 1.0, "y": 2.0, "z": 3.0}, event=True), "topic 'odom' is not an event topic"),
    (line("plain", 1, {"i": 1, "f": 1.0, "b": True, "s": "\ud800", "tags": []}), "lone surrogate"),
    (
        line(
            "goal_reached",
            1,
            {**GOAL, "metrics": [{"name": "m", "type": "text", "value": "v", "unit": "\ud800"}]},
            True,
        ),
        "field 'metrics': metric 0: key(s) 'unit': string holds a lone surrogate",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1, "colour": "red"}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}',
        "unexpected key 'colour' in $metadata",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}, "extra": 1}',
        "unexpected key 'extra'",
    ),
    ('{"$metadata": {"topic": "odom", "timestamp": 007}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}', "bad JSON"),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 9223372036854775808}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}',
        "bad timestamp",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0} {"x": 1.0}}',
        "bad JSON",
    ),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}, "w": {}}',
        "unexpected key 'w'",
    ),
    ('{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": 3.0}}}', "bad JSON"),
    (
        '{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": 1.0, "y": 2.0, "z": "}\\n{\\"x\\": 1"}}',
        "field 'z': expected float",
    ),
    (
        line(
            "sample",
            1,
            {
                "i": 1,
                "f": 1.0,
                "b": True,
                "s": "",
                "st": "",
                "im": "",
                "vi": "",
                "tags": [],
                "metrics": [{"name": "m", "type": "chart", "value": 1}],
            },
        ),
        "field 'metrics': metric 0: type must be one of",
    ),
]


def bad_file(tmp_path):
    """Good odom lines with every kind of bad line between them, an invalid UTF-8 line and a truncated last line."""
    texts, expected = [], []
    for number, (text, reason) in enumerate(BAD):
        texts += [odom(number), text]
        expected.append((2 * number + 2, reason))
    data = (
        "".join(t + "\n" for t in texts).encode()
        + b'{"$metadata": {"topic": "odom", "timestamp": 1}, "$data": {"x": "\xff"}}\n'
    )
    expected.append((len(texts) + 1, "invalid UTF-8 at byte"))
    data += (odom(99) + "\n").encode() + b'{"$metadata": {"topic": "odom", "times'
    expected.append((len(texts) + 3, "truncated last line (no newline at the end of the file): bad JSON"))
    path = tmp_path / "bad.jsonl"
    path.write_bytes(data)
    return path, expected, len(BAD) + 1


def test_every_bad_line_is_reported_with_file_line_and_reason_and_nothing_is_written(tmp_path, config):
    path, expected, good = bad_file(tmp_path)
    with pytest.raises(IngestError) as caught:
        ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config)
    error = caught.value
    assert [(p.line, p.path) for p in error.problems] == [(n, str(path)) for n, _ in expected]
    for problem, (number, reason) in zip(error.problems, expected):
        assert reason in problem.reason, (number, problem.reason)
        assert str(problem).startswith(f"{path}:{number}: ")
    assert error.total == len(expected)
    assert "nothing was written" in str(error) and "--skip-bad-lines" in str(error)
    lake_branch = paths.branch_dir(tmp_path / "lake", "main")
    assert not list(lake_branch.glob("*/batch_id=*/job_id=*/*.parquet"))
    assert not paths.quarantine_file(tmp_path / "lake", "main", "b1", "j1").exists()


def test_a_failed_ingest_leaves_the_earlier_ingest_of_the_job_intact(tmp_path, config):
    lake = tmp_path / "lake"
    good = write_lines(tmp_path / "good.jsonl", [odom(i) for i in range(10)])
    ingest_job(lake, "main", "b1", "j1", [good], config=config, metadata={"experience_name": "first"})
    path, _, _ = bad_file(tmp_path)
    with pytest.raises(IngestError):
        ingest_job(lake, "main", "b1", "j1", [path], config=config, metadata={"experience_name": "second"})
    assert count(lake, "odom") == 10
    assert query(lake, "SELECT experience_name FROM metadata") == [("first",)]


def test_skip_bad_lines_keeps_good_rows_and_quarantines_the_rest(tmp_path, config):
    lake = tmp_path / "lake"
    path, expected, good = bad_file(tmp_path)
    report = ingest_job(lake, "main", "b1", "j1", [path], config=config, skip_bad_lines=True)
    assert report.bad_lines == len(expected) and report.rows["odom"] == good
    assert count(lake, "odom") == good
    assert report.quarantine == paths.quarantine_file(lake, "main", "b1", "j1")
    kept = [json.loads(t) for t in report.quarantine.read_text().splitlines()]
    assert [(k["file"], k["line"]) for k in kept] == [(str(path), n) for n, _ in expected]
    assert all(reason in k["reason"] for k, (_, reason) in zip(kept, expected))
    raw_lines = path.read_bytes().split(b"\n")
    for k in kept:  # the bad line itself, byte for byte (invalid UTF-8 as surrogate escapes)
        assert k["text"].encode("utf-8", "surrogateescape") == raw_lines[k["line"] - 1]
    # a clean re-ingest of the job removes its quarantine file
    clean = write_lines(tmp_path / "clean.jsonl", [odom(1)])
    assert ingest_job(lake, "main", "b1", "j1", [clean], config=config).quarantine is None
    assert not report.quarantine.exists()


def test_many_blocks_many_files_and_long_lines_keep_line_numbers(tmp_path, config, monkeypatch):
    monkeypatch.setattr(scan, "BLOCK_SIZE", 700)  # a few lines per block; some lines are longer than a block
    long_tags = [f"tag{i}" for i in range(200)]
    first = write_lines(
        tmp_path / "a.jsonl",
        [odom(i) for i in range(40)]
        + [line("odom", 1, {"x": 1})]
        + [line("plain", i, {"i": i, "f": 0.5, "b": False, "s": "x" * 1500, "tags": long_tags}) for i in range(5)],
    )
    second = write_lines(
        tmp_path / "b.jsonl", [odom(i) for i in range(30)] + ['{"broken'] + [odom(i) for i in range(3)]
    )
    with pytest.raises(IngestError) as caught:
        ingest_job(tmp_path / "lake", "main", "b1", "j1", [first, second], config=config)
    assert [(Path(p.path).name, p.line) for p in caught.value.problems] == [("a.jsonl", 41), ("b.jsonl", 31)]
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [first, second], config=config, skip_bad_lines=True)
    assert report.rows["odom"] == 73 and report.rows["plain"] == 5 and report.lines == 80
    assert query(tmp_path / "lake", "SELECT COUNT(*), MIN(length(s)), MAX(len(tags)) FROM plain") == [(5, 1500, 200)]
    # rows keep the order of the lines within a topic
    xs = [r[0] for r in query(tmp_path / "lake", "SELECT x FROM odom")]
    assert xs == [i + 0.5 for i in range(40)] + [i + 0.5 for i in range(30)] + [i + 0.5 for i in range(3)]


def test_other_json_layouts_blank_lines_and_crlf_are_read_the_same(tmp_path, config):
    texts = [
        '{"$metadata":{"topic":"odom","timestamp":1},"$data":{"x":1,"y":2.5,"z":-3e2}}',
        '{"$data": {"z": 0.0, "y": 1.0, "x": 2.0}, "$metadata": {"timestamp": 2, "topic": "odom"}}',
        '   {  "$metadata" : { "timestamp" : 3 , "topic" : "odom" } , "$data" : { "x" : 3 , "y" : 3 , "z" : 3 } }   ',
        "",
        "  \t ",
        '{"$metadata": {"topic": "od\\u006fm", "timestamp": 4}, "$data": {"x": 4, "y": 4, "z": 4}}',
        '{"$metadata": {"event": false, "topic": "odom", "timestamp": 5}, "$data": {"x": 5, "y": 5, "z": 5}}',
        '{"$metadata": {"topic": "odom", "timestamp": 6, "event": null}, "$data": {"x": 6, "y": 6, "z": 6}}',
        '{"$metadata": {"topic": "stop", "timestamp": 7}, "$data": {"name": "no event flag", "speed": 1}}',
    ]
    path = tmp_path / "layouts.jsonl"
    path.write_bytes("".join(t + "\r\n" for t in texts).encode())
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config)
    assert report.bad_lines == 0 and report.rows["odom"] == 6 and report.rows["stop"] == 1
    assert query(tmp_path / "lake", "SELECT timestamp, x, y, z FROM odom ORDER BY timestamp") == [
        (1, 1.0, 2.5, -300.0),
        (2, 2.0, 1.0, 0.0),
        (3, 3.0, 3.0, 3.0),
        (4, 4.0, 4.0, 4.0),
        (5, 5.0, 5.0, 5.0),
        (6, 6.0, 6.0, 6.0),
    ]


# --- line limits: length and nesting depth ---------------------------------------------------


def test_deeply_nested_line_is_a_bad_line_not_a_crash(tmp_path, config):
    """100k `[` used to raise RecursionError out of ingest, even with skip_bad_lines."""
    deep = line("plain", 2, {"i": 1, "f": 1.0, "b": True, "s": "x", "tags": []}).replace(
        '"tags": []', '"tags": ' + "[" * 100_000
    )
    path = write_lines(tmp_path / "deep.jsonl", [odom(1), deep, odom(3)])
    with pytest.raises(IngestError) as caught:
        ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config)
    assert [(p.line, p.reason) for p in caught.value.problems] == [
        (2, "nested too deep: more than 256 levels of arrays and objects, the limit of an emissions line")
    ]
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config, skip_bad_lines=True)
    assert report.rows["odom"] == 2 and report.bad_lines == 1


@pytest.mark.parametrize("depth", [252, 253])
def test_emitter_and_ingest_agree_on_the_depth_limit(tmp_path, config_path, config, depth):
    """A Plotly object `depth` deep in a metric makes a line depth + 4 deep: both accept 256, refuse 257."""
    figure: dict = {}
    for _ in range(depth - 1):
        figure = {"a": figure}
    record = {
        "name": "g",
        "description": "d",
        "status": "PASSED",
        "tags": [],
        "metrics": [{"name": "m", "type": "plotly", "value": figure}],
    }
    raw = line("goal_reached", 1, record, event=True).encode()
    with Emitter(config_path, tmp_path / "emissions.jsonl") as em:
        if depth == 252:
            assert check_line(raw, config.topics) is not None
            em.emit_event("goal_reached", record, 1)
        else:
            with pytest.raises(ValueError, match="nested too deep"):
                check_line(raw, config.topics)
            with pytest.raises(ValueError, match="nested too deep"):
                em.emit_event("goal_reached", record, 1)


def test_overlong_lines_are_refused_without_being_held_whole(tmp_path, config, monkeypatch):
    monkeypatch.setattr(scan, "BLOCK_SIZE", 256)
    for module in (rules, scan):  # the limit of the exact check and of the block reader
        monkeypatch.setattr(module, "MAX_LINE_BYTES", 150)
    long_in_a_block = line("plain", 1, {"i": 1, "f": 1.0, "b": True, "s": "y" * 120, "tags": []})  # 190 bytes
    across_blocks = line("plain", 2, {"i": 1, "f": 1.0, "b": True, "s": "z" * 2000, "tags": []})
    path = write_lines(tmp_path / "long.jsonl", [odom(1), long_in_a_block, odom(3), across_blocks, odom(5)])
    with path.open("a") as handle:
        handle.write(across_blocks)  # and one more as the last line, without a newline
    report = ingest_job(tmp_path / "lake", "main", "b1", "j1", [path], config=config, skip_bad_lines=True)
    assert report.rows["odom"] == 3 and report.rows["plain"] == 0 and report.lines == 6
    assert [(p.line, p.reason) for p in report.problems] == [
        (2, f"line too long: {len(long_in_a_block):,} bytes, more than the limit of 150 bytes of an emissions line"),
        (4, f"line too long: {len(across_blocks):,} bytes, more than the limit of 150 bytes of an emissions line"),
        (6, f"line too long: {len(across_blocks):,} bytes, more than the limit of 150 bytes of an emissions line"),
    ]
    assert [x for (x,) in query(tmp_path / "lake", "SELECT x FROM odom")] == [1.5, 3.5, 5.5]
