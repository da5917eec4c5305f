"""The real Trino's answers, recorded: a JSON-lines file of what the judge answered to each query over
the same data, so that a test run asks it again only what the file lacks and a random sample of what
it holds (each planned query costs Trino about 0.2 s of CPU on a 2-core machine, and the conformance
cases are thousands).

A line is `{"key": ..., "answer": {...}}`; the key is a hash of Trino's version, the data's
fingerprint (what the tables hold), the session zone and the SQL. A sampled answer whose column
types, rows or error name are no longer Trino's fails the run (names and messages may differ: a
column asked within a batch is named by its place there, a message may name a test run's schema):
the record is stale, rewrite it (`RECORD_ENV=1`, which asks every query again and writes the file
anew).
"""

from __future__ import annotations

import hashlib
import json
import os
import random
from collections.abc import Sequence
from pathlib import Path

from answer_compare import has_order_by, rows_match, types_match
from trino_answers import Answer, TrinoAnswers
from trino_server import VERSION

#: Setting this environment variable to 1 asks the judge every query and rewrites the record.
RECORD_ENV = "LAKEGATE_WRITE_DIFFERENTIAL"
#: Recorded answers asked again in each run, to find a stale record.
SAMPLE = 100


class StaleRecord(AssertionError):
    """A recorded answer that the real Trino no longer gives."""


class RecordedAnswers:
    """Trino's answers over data of `fingerprint`, from the record at `path` where it holds them and
    from `trino` otherwise (see the module's docstring)."""

    def __init__(self, trino: TrinoAnswers, path: Path, fingerprint: str, *, sample: int = SAMPLE):
        self.trino, self.path, self.fingerprint, self.sample = trino, path, fingerprint, sample
        self.rewrite = os.environ.get(RECORD_ENV) == "1"
        self.asked = 0  # queries asked of the real Trino in this run
        self._written: dict[str, dict] = {}

    def key(self, sql: str, time_zone: str) -> str:
        text = json.dumps([VERSION, self.fingerprint, time_zone, sql])
        return hashlib.sha256(text.encode()).hexdigest()[:32]

    def ask_all(self, queries: Sequence[tuple[str, str]], *, batch: bool = True) -> list[Answer]:
        """Trino's answers to (sql, time zone) queries, in their order (as TrinoAnswers.ask_all)."""
        keys = [self.key(sql, zone) for sql, zone in queries]
        recorded = {} if self.rewrite else _read(self.path)
        answers = [_decode(recorded[key]) if key in recorded else None for key in keys]
        held = [i for i, answer in enumerate(answers) if answer is not None]
        seed = random.randrange(1 << 32)
        checked = sorted(random.Random(seed).sample(held, min(self.sample, len(held))))
        missing = [i for i, answer in enumerate(answers) if answer is None]
        asked = missing + checked
        fresh = self.trino.ask_all([queries[i] for i in asked], batch=batch) if asked else []
        self.asked += len(asked)
        changed = [
            (i, a) for i, a in zip(asked, fresh) if answers[i] is not None and not _same(queries[i][0], answers[i], a)
        ]
        again = self.trino.ask_all([queries[i] for i, _ in changed], batch=batch) if changed else []
        stale = [  # not a query whose answer changes from one asking to the next (current_time, shuffle)
            f"{queries[i][0]!r} (zone {queries[i][1]}): recorded {answers[i]}, Trino now {answer}"
            for (i, answer), second in zip(changed, again)
            if _same(queries[i][0], second, answer)
        ]
        if stale:
            raise StaleRecord(
                f"{len(stale)} of {len(checked)} sampled answers in {self.path.name} (sample seed {seed}) are no "
                f"longer the real Trino's; rewrite it with {RECORD_ENV}=1:\n" + "\n".join(stale[:10])
            )
        for i, answer in zip(asked, fresh):
            answers[i] = _decode(_encode(answer))  # as a recorded one reads (maps keyed by text, rows as lists)
        self._written.update((key, _encode(answer)) for key, answer in zip(keys, answers))
        return answers  # type: ignore[return-value]

    def save(self) -> None:
        """With RECORD_ENV=1: write the answers of this run's queries as the record (sorted by key)."""
        if self.rewrite:
            lines = [
                json.dumps({"key": k, "answer": self._written[k]}, ensure_ascii=False) for k in sorted(self._written)
            ]
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.write_text("".join(line + "\n" for line in lines), encoding="utf-8")


def _read(path: Path) -> dict[str, dict]:
    if not path.exists():
        return {}
    lines = path.read_text(encoding="utf-8").splitlines()
    return {entry["key"]: entry["answer"] for entry in map(json.loads, lines)}


def _encode(answer: Answer) -> dict:
    """The answer as its record line holds it (JSON values: what the client protocol carried)."""
    if answer.error is not None:
        return {"error": answer.error, "message": answer.message}
    return json.loads(json.dumps({"columns": answer.columns, "rows": answer.rows}, allow_nan=False))


def _same(sql: str, one: Answer, other: Answer) -> bool:
    """Whether two answers are alike as the differential run judges them: column types, rows (in any
    order without ORDER BY) and error name."""
    one, other = _decode(_encode(one)), _decode(_encode(other))
    if one.error is not None or other.error is not None:
        return one.error == other.error
    ordered = has_order_by(sql)
    return types_match(one.columns, other.columns) and rows_match(one.rows, other.rows, ordered=ordered)


def _decode(data: dict) -> Answer:
    if "error" in data:
        return Answer(error=data["error"], message=data["message"])
    return Answer(columns=tuple(tuple(c) for c in data["columns"]), rows=tuple(data["rows"]))
