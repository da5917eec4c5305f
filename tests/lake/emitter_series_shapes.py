"""Series shapes for the Emitter's byte-identity test, runnable under the reference Emitters too.

Standard library only, so that the venvs of the references (bench/emit.py) can run it:

    ~/.cache/lakegate/bench-venvs/resim-open-core-1.6.0/bin/python \
        tests/lake/emitter_series_shapes.py resim.metrics.python.emissions OUT

writes the emissions of every shape (emit_series calls, validated against CONFIG) to OUT.
fixtures/emitter_series_shapes.jsonl.gz is that file (gzipped) as resim-open-core 1.6.0 and signalflag 1.8.0
wrote it (the two are byte-identical); tests/lake/test_emitter.py compares lakegate's output to it.
"""

from __future__ import annotations

import importlib
import math
import random
import struct
import sys
import tempfile
from pathlib import Path
from typing import Any

ODD_FIELD = 'odd, [name] "e-5" 0.00001'
CONFIG = f"""version: 1
topics:
  floats:
    schema: {{x: float, y: float, z: float}}
  ints:
    schema: {{i: int}}
  flags:
    schema: {{b: boolean}}
  texts:
    schema: {{s: string, st: status, im: image, v: video}}
  mixed:
    schema: {{n: int, '{ODD_FIELD}': float, ok: boolean, label: string}}
  lists:
    schema: {{tags: "string[]", metrics: "metric[]"}}
"""


def _floats(rng: random.Random, count: int) -> list[float]:
    """Full-precision random doubles, every power of ten, tiny and subnormal values, signed zeros."""
    values = [struct.unpack("<d", struct.pack("<Q", rng.getrandbits(64)))[0] for _ in range(count)]
    values += [sign * 10.0**e for e in range(-323, 308) for sign in (1, -1)]
    values += [rng.uniform(-10, 10) * 10.0**e for e in range(-12, 20) for _ in range(50)]
    values += [0.0, -0.0, 1e-4, -1e-4, 9.999999999999999e-05, 1e16, 9999999999999998.0, 5e-324, 1.7976931348623157e308]
    return [v for v in values if math.isfinite(v)]


def shapes() -> list[tuple[str, dict[str, list[Any]], list[int]]]:
    """(topic, columns, timestamps) of every emit_series call, in order."""
    rng = random.Random(7)
    xs = _floats(rng, 2_000)
    n = len(xs)
    floats = {"x": xs, "y": [rng.uniform(-2, 2) for _ in range(n)], "z": xs[::-1]}
    ints = [-(2**63), 2**63 - 1, 0, -1, 1] + [rng.randrange(-(2**63), 2**63) for _ in range(995)]
    texts = ['quote " backslash \\ slash / comma, [brackets] {braces}', "", "é ✓ 😀 ÿ", "\x00\x01\x02\x03\x1f\x7f"]
    texts += ["\n\r\t\b\f", "中文, 日本語", "a" * 300, "e-5 0.00001 null"]
    texts = texts * 40
    label = [f"label {i}, [{i}]" for i in range(50)]
    metric = {"name": "m", "type": "scalar", "value": 1.5, "description": "d, é"}
    return [
        ("floats", floats, list(range(n))),
        ("floats", {k: v[:3] for k, v in floats.items()}, [5, 6, 7]),  # a short series
        ("floats", {"x": [0.5], "y": [-0.0], "z": [1e-7]}, [2**63 - 1]),
        ("ints", {"i": ints}, [rng.randrange(0, 2**63) for _ in ints]),
        ("flags", {"b": [True, False, False, True] * 3000}, list(range(12_000))),
        ("texts", {"s": texts, "st": texts[::-1], "im": texts, "v": texts}, list(range(len(texts)))),
        (
            "mixed",
            {"n": list(range(-25, 25)), ODD_FIELD: xs[:50], "ok": [i % 3 == 0 for i in range(50)], "label": label},
            list(range(50)),
        ),
        ("lists", {"tags": [["a", "b, c"], [], ["é"]], "metrics": [[metric], [], [metric, metric]]}, [1, 2, 3]),
    ]


def main(module: str, out: str) -> None:
    """Emit every shape with the Emitter of `module` to `out`."""
    emitter_class = importlib.import_module(module).Emitter
    with tempfile.TemporaryDirectory() as folder:
        config = Path(folder) / "config.resim.yaml"
        config.write_text(CONFIG)
        emitter = emitter_class(config_path=str(config), output_path=out)
        for topic, columns, stamps in shapes():
            emitter.emit_series(topic, columns, timestamps=stamps)
        emitter.close()


if __name__ == "__main__":
    main(*sys.argv[1:])
