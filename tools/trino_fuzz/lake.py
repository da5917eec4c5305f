"""The fuzzer's small lake, written the way users write one: Emitter -> ingest -> metrics run.

Two batches of jobs on branch `main`. Topic `samples` (doubles, a bigint, non-ASCII text, a
boolean, an array of text; bigint nanosecond timestamps); its field `w` exists only in the jobs
ingested with the second config version, so earlier jobs read it as NULL. Event topic `alerts`
(arrays of metric rows), the `events` and `metadata` tables (arrays of tags and custom fields,
timestamps), and `metric_results`, whose `scalar_value` holds NaN, +-Infinity, NULL and finite
doubles (the scalar metrics of config.resim.yaml compute them).
"""

from __future__ import annotations

import random
import shutil
from datetime import UTC, datetime, timedelta
from pathlib import Path

import yaml

from lakegate.gateway.metrics.evaluation import MetricsEngine, select_metrics
from lakegate.lake.config import load_config
from lakegate.lake.emitter import Emitter
from lakegate.lake.ingest import ingest_job

CONFIG = Path(__file__).resolve().with_name("config.resim.yaml")
BRANCH = "main"
#: (batch, job, experience name, whether the job has field `w`)
JOBS = (
    ("b1", "job-a", "Entrepôt Nord", False),
    ("b1", "job-b", "Bureau 東京", False),
    ("b1", "job-c", "Quai ünd Straße", True),
    ("b2", "job-d", "Entrepôt Nord", True),
    ("b2", "job-e", "Ωmega Field", True),
)
LABELS = ("alpha", "Ärger", "été", "東京", "", "naïve", "ZEBRA", "a_b%c")
TAGS = ("nav", "indoor", "ß", "gps", "λ")
BASE_NS = 1_750_000_000_000_000_000
#: Bumped whenever the lake's content changes (the folder keeps a stamp of it).
VERSION = "1"


def _wide_config(folder: Path) -> Path:
    """The config with the extra float field `samples.w` (the second config version)."""
    config = yaml.safe_load(CONFIG.read_text())
    config["topics"]["samples"]["schema"]["w"] = "float"
    path = folder / "config.wide.resim.yaml"
    path.write_text(yaml.safe_dump(config, allow_unicode=True, sort_keys=False))
    return path


def _emit_job(emitter: Emitter, rng: random.Random, index: int, wide: bool) -> None:
    rows = 6 + index
    for i in range(rows):
        ts = BASE_NS + index * 10**12 + i * 250_000_000 + rng.randrange(1000)
        x = rng.choice([0.0, -0.0, 1.5, -2.25, 1e-9, 3.0, rng.uniform(-10, 10), 1e15])
        data = {
            "x": x,
            "y": float(rng.randint(-3, 3)),
            "n": rng.choice([0, 1, -1, 7, 42, 2**40, -(2**31), i]),
            "label": rng.choice(LABELS),
            "ok": rng.random() < 0.5,
            "tags": rng.sample(TAGS, rng.randint(0, 3)),
        }
        if wide:
            data["w"] = rng.choice([0.5, -1.0, 2.0, 1e-3])
        emitter.emit("samples", data, ts)
    for i in range(2):
        metrics = [
            {"name": "speed", "type": "scalar", "value": rng.choice([1.5, 0, -3])},
            {"name": "note", "type": "text", "value": rng.choice(["ok", "ça va", "停止"]), "unit": "m"},
        ][: 1 + (index + i) % 2]
        emitter.emit_event(
            "alerts",
            {
                "name": rng.choice(["stop", "slow", "Stopp"]),
                "description": rng.choice(["obstacle", "Hindernis äh", ""]),
                "status": rng.choice(["PASSED", "WARNING", "BLOCKER"]),
                "tags": rng.sample(TAGS, rng.randint(0, 2)),
                "metrics": metrics,
            },
            BASE_NS + index * 10**12 + i * 500_000_000,
        )


def _metadata(index: int, experience: str) -> dict:
    start = datetime(2025, 7, 1, 12, 0, tzinfo=UTC) + timedelta(hours=index, milliseconds=123 * index)
    keys = ["robot", "map", "größe"][: 1 + index % 3]
    return {
        "build_name": "Nav stack",
        "build_version": f"1.{index % 2}.0",
        "build_creation_timestamp": start.isoformat().replace("+00:00", "Z"),
        "experience_name": experience,
        "experience_tag_names": list(TAGS[: index % 4]),
        "test_suite_name": "Nav Régression",
        "test_suite_revision": index,
        "job_status": "FAILED" if index == 3 else "SUCCEEDED",
        "custom_field_keys": keys,
        "custom_field_values": [f"v{index}", "ü", "x"][: len(keys)],
        "time": (start + timedelta(minutes=5)).isoformat().replace("+00:00", "Z"),
    }


def build(lake: Path) -> Path:
    """Build the lake at `lake` (reused when it was built by this version) and return it."""
    stamp = lake / ".fuzz-lake-version"
    if stamp.exists() and stamp.read_text() == VERSION:
        return lake
    if lake.exists():
        shutil.rmtree(lake)
    inputs = lake.parent / f"{lake.name}-inputs"
    shutil.rmtree(inputs, ignore_errors=True)
    inputs.mkdir(parents=True)
    wide_path = _wide_config(inputs)
    configs = {False: load_config(CONFIG), True: load_config(wide_path)}
    rng = random.Random(19)
    for index, (batch, job, experience, wide) in enumerate(JOBS):
        emissions = inputs / f"{job}.resim.jsonl"
        with Emitter(wide_path if wide else CONFIG, emissions) as emitter:
            _emit_job(emitter, rng, index, wide)
        ingest_job(lake, BRANCH, batch, job, [emissions], config=configs[wide], metadata=_metadata(index, experience))
    with MetricsEngine(lake) as engine:
        for batch in sorted({batch for batch, *_ in JOBS}):
            engine.evaluate_batch(BRANCH, batch, select_metrics(configs[True], None, all_metrics=True))
    shutil.rmtree(inputs)
    stamp.write_text(VERSION)
    return lake
