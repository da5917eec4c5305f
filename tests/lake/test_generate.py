"""The fixture generator: deterministic files, the promised job outcomes, metadata and images."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import uuid
import zlib
from collections import defaultdict
from datetime import datetime
from pathlib import Path

import pytest
import yaml

from lakegate.fixtures.generate import generate_batch
from lakegate.lake.config import load_config

CONFIG = load_config([Path(__file__).resolve().parents[2] / "fixtures" / "config.resim.yaml"])
METADATA_COLUMNS = [
    "org_id",
    "project_id",
    "branch_name",
    "build_id",
    "build_name",
    "build_version",
    "build_creation_timestamp",
    "experience_id",
    "experience_name",
    "experience_tag_ids",
    "experience_tag_names",
    "test_suite_id",
    "test_suite_name",
    "test_suite_revision",
    "job_status",
    "custom_field_keys",
    "custom_field_values",
    "time",
]


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    return generate_batch(tmp_path_factory.mktemp("batch"))


def rows(path: Path) -> dict[str, list[dict]]:
    """Lines of an emissions file by topic, each `$data` plus `timestamp` (and `event`)."""
    topics = defaultdict(list)
    for line in path.read_text().splitlines():
        record = json.loads(line)
        meta = record["$metadata"]
        row = {**record["$data"], "timestamp": meta["timestamp"], "event": meta.get("event", False)}
        topics[meta["topic"]].append(row)
    return topics


def expected_status(topics: dict[str, list[dict]]) -> str:
    """The fixture metrics by hand: fewer than 3 goals or an error above 1.0 m block; above 0.5 m warns."""
    goals = len(topics["time_to_goal"])
    worst = max(row["position_diff_m"] for row in topics["pose_difference"])
    if goals < 3 or worst > 1.0:
        return "BLOCKER"
    return "WARNING" if worst > 0.5 else "PASSED"


def test_same_arguments_give_identical_files(tmp_path: Path):
    first = generate_batch(tmp_path / "a", jobs=3, seed=11, samples_per_goal=20)
    second = generate_batch(tmp_path / "b", jobs=3, seed=11, samples_per_goal=20)
    for one, two in zip(first, second):
        assert one.job_id == two.job_id
        for name in ("emissions_path", "metadata_path"):
            assert getattr(one, name).read_bytes() == getattr(two, name).read_bytes()
        images = [{p.name: p.read_bytes() for p in job.logs_dir.iterdir()} for job in (one, two)]
        assert images[0] == images[1]
    other = generate_batch(tmp_path / "c", jobs=3, seed=12, samples_per_goal=20)
    assert other[0].emissions_path.read_bytes() != first[0].emissions_path.read_bytes()


def test_regenerating_into_the_same_folder_replaces_the_files(tmp_path: Path):
    first = generate_batch(tmp_path, jobs=1, samples_per_goal=5)[0].emissions_path.read_bytes()
    assert generate_batch(tmp_path, jobs=1, samples_per_goal=5)[0].emissions_path.read_bytes() == first


def test_batch_has_passed_warning_and_blocker_jobs(batch):
    statuses = [expected_status(rows(job.emissions_path)) for job in batch]
    assert {"PASSED", "WARNING", "BLOCKER"} <= set(statuses)
    for job, status in zip(batch, statuses):
        topics = rows(job.emissions_path)
        worst = max(row["position_diff_m"] for row in topics["pose_difference"])
        if status == "WARNING":
            assert len(topics["time_to_goal"]) == 3 and 0.5 < worst <= 1.0
        if status == "PASSED":
            assert worst <= 0.5


def test_every_topic_is_emitted_with_plausible_data(batch):
    within = []
    for job in batch:
        topics = rows(job.emissions_path)
        assert set(topics) == set(CONFIG.topics)
        for topic, records in topics.items():
            assert all(set(r) - {"timestamp", "event"} == set(CONFIG.topics[topic].fields) for r in records)
            assert all(isinstance(r["timestamp"], int) and r["timestamp"] >= 0 for r in records)
            assert all(r["event"] == CONFIG.topics[topic].event for r in records)
        by_goal = defaultdict(list)
        for r in topics["goal_distance"]:
            by_goal[r["goal_name"]].append((r["timestamp"], r["distance_m"]))
        for points in by_goal.values():
            distances = [d for _, d in sorted(points)]
            assert all(a > b for a, b in zip(distances, distances[1:])), "distance to a goal decreases over time"
        reached = len(topics["time_to_goal"])
        assert len(topics["goal_reached"]) == reached and 1 <= reached <= 3
        states = [r["state"] for r in sorted(topics["goal_status"], key=lambda r: r["timestamp"])]
        assert states[0] == "WAITING" and states.count("REACHED") == reached and "NAVIGATING" in states
        assert len(topics["camera_gif"]) == 1
        within += [r["within_1_sigma"] for r in topics["covariance_accuracy"]]
        assert all(r["within_1_sigma"] == int(r["error_m"] <= r["sigma_m"]) for r in topics["covariance_accuracy"])
    assert 0.6 < sum(within) / len(within) < 0.76  # about 68 %


def test_events_carry_tags_and_scalar_text_image_metrics(batch):
    for job in batch:
        for event in rows(job.emissions_path)["goal_reached"]:
            assert event["tags"] and event["status"] == "PASSED"
            assert sorted(m["type"] for m in event["metrics"]) == ["image", "scalar", "text"]
            (image,) = [m for m in event["metrics"] if m["type"] == "image"]
            for name in image["value"]:
                png = (job.logs_dir / name).read_bytes()
                assert decode_png(png) == (32, 32)


def test_metadata_files(batch):
    job_ids = set()
    names = set()
    for job in batch:
        meta = yaml.safe_load(job.metadata_path.read_text())
        assert list(meta) == METADATA_COLUMNS
        assert meta["experience_name"] == job.experience_name and meta["job_status"] == "SUCCEEDED"
        for key in ("org_id", "project_id", "build_id", "experience_id", "test_suite_id"):
            uuid.UUID(meta[key])
        assert len(meta["experience_tag_ids"]) == len(meta["experience_tag_names"])
        assert len(meta["custom_field_keys"]) == len(meta["custom_field_values"])
        assert isinstance(meta["test_suite_revision"], int)
        datetime.fromisoformat(meta["build_creation_timestamp"].replace("Z", "+00:00"))
        datetime.fromisoformat(meta["time"].replace("Z", "+00:00"))
        tags = meta["experience_tag_names"]
        prefixed = [t for t in tags if t.startswith("my_prefix_")]
        assert len(prefixed) == ("my_tag" in tags), "every my_tag job has exactly one my_prefix_ tag"
        job_ids.add(str(uuid.UUID(job.job_id)))
        names.add(job.experience_name)
    assert len(job_ids) == len(batch) and len(names) > 3
    tagged = [("my_tag" in yaml.safe_load(j.metadata_path.read_text())["experience_tag_names"]) for j in batch]
    assert any(tagged) and not all(tagged)


def test_camera_gif_is_a_real_animation(batch):
    for job in batch:
        (row,) = rows(job.emissions_path)["camera_gif"]
        frames = gif_frames((job.logs_dir / row["filename"]).read_bytes())
        assert 2 <= frames <= 4


def test_samples_per_goal_scales_the_rows(tmp_path: Path):
    (small,) = generate_batch(tmp_path / "s", jobs=1, samples_per_goal=10)
    (large,) = generate_batch(tmp_path / "l", jobs=1, samples_per_goal=100)
    count = lambda job: len(job.emissions_path.read_text().splitlines())  # noqa: E731
    assert count(small) == 6 * 3 * 10 + 14 and count(large) == 6 * 3 * 100 + 14  # + 7 states, 3 times, camera, 3 events


def test_command_line(tmp_path: Path):
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "lakegate.fixtures.generate",
            str(tmp_path),
            "--jobs",
            "2",
            "--seed",
            "3",
            "--samples-per-goal",
            "5",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert len(lines) == 2 and all("emissions.resim.jsonl" in line for line in lines)
    assert (tmp_path / "job_01" / "metadata.yaml").is_file()


def decode_png(data: bytes) -> tuple[int, int]:
    """Check a PNG's chunks (CRCs, pixel data size) and return its size."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, {}
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        assert struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])[0] == zlib.crc32(kind + body)
        chunks[kind] = body
        pos += 12 + length
    width, height, depth, color = struct.unpack(">IIBB", chunks[b"IHDR"][:10])
    assert (depth, color) == (8, 3) and b"IEND" in chunks
    assert len(zlib.decompress(chunks[b"IDAT"])) == height * (width + 1)
    return width, height


def gif_frames(data: bytes) -> int:
    """Walk a GIF's blocks and count its frames (each LZW stream must end with the end code)."""
    assert data[:6] == b"GIF89a" and data[-1:] == b";"
    width, height, flags = struct.unpack("<HHB", data[6:11])
    pos, frames = 13 + 3 * 2 ** ((flags & 7) + 1), 0
    while data[pos] != 0x3B:
        if data[pos] == 0x21:  # extension: label, then sub-blocks
            pos += 2
        else:
            assert data[pos] == 0x2C and struct.unpack("<HH", data[pos + 5 : pos + 9]) == (width, height)
            frames += 1
            pos += 11  # descriptor (10) + LZW minimum code size (1)
        while data[pos]:
            pos += data[pos] + 1
        pos += 1
    return frames
