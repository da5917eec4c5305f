"""The ingestion tests' config and emission lines, and queries of the lake they ingest into."""

from __future__ import annotations

import json
import struct

from lakegate.lake.catalog import Catalog

CONFIG = """\
version: 1
topics:
  odom:
    schema: {x: float, y: float, z: float}
  sample:
    schema: {i: int, f: float, b: boolean, s: string, st: status, im: image, vi: video, tags: "string[]",
             metrics: "metric[]"}
  plain:
    schema: {i: int, f: float, b: boolean, s: string, tags: "string[]"}
  goal_reached:
    event: true
    schema: {name: string, description: string, status: status, tags: "string[]", metrics: "metric[]"}
  stop:
    event: true
    schema: {name: string, speed: float}
  never:
    schema: {v: float, w: "string[]"}
"""


def line(topic, timestamp, data, event=False):
    meta = {"topic": topic, "timestamp": timestamp, **({"event": True} if event else {})}
    return json.dumps({"$metadata": meta, "$data": data})


def odom(i):
    return line("odom", i * 1000, {"x": i + 0.5, "y": -i * 0.25, "z": 0.0})


def write_lines(path, lines, end="\n"):
    path.write_text("".join(text + end for text in lines), encoding="utf-8")
    return path


def query(lake, sql, branch="main"):
    return Catalog(lake).connect(branch).execute(sql).fetchall()


def count(lake, table, branch="main"):
    return query(lake, f'SELECT COUNT(*) FROM "{table}"', branch)[0][0]


GOAL = {"name": "g", "description": "d", "status": "PASSED", "tags": []}
#: A stored metric object's fields, all NULL.
NO_METRIC_KEYS = dict.fromkeys(("name", "description", "status", "type", "value", "extra"))


def bits(value):
    return struct.pack("<d", value)
