"""Ingestion: emissions files (JSON lines) of one job -> Parquet files in the lake.

`ingest_job` validates every line against the branch's topics and writes one Parquet file
per topic (columns `timestamp`, the declared fields, `experience_name`, `build_version`),
the job's `events` and its `metadata` row, under the Hive layout of `lake.paths`. Files are
written to `_staging/` and, once the whole job is good, made the job's tables all at once
by one commit of the branch's record (`lake.record`); a bad
line fails the job (nothing written) unless `skip_bad_lines`, which keeps the good rows
and writes the bad lines with their reasons to a quarantine file.

How lines are checked (fast and exact):

* Files are read in blocks of whole lines (memory stays bounded), worked on by a few
  threads. A line longer than `MAX_LINE_BYTES` (16 MiB) is refused without being held
  whole, and one nested deeper than `MAX_JSON_DEPTH` (256) before it is parsed. Each line's
  topic is guessed from its text (`{"$metadata": {"topic": "NAME"` as the Emitter writes it,
  or a looser pattern), and lines are grouped by topic.
* Lines exactly in the Emitter's layout (`{"$metadata": {"topic": T, "timestamp": DIGITS},
  "$data": {...}}`, checked with numpy on the bytes) only need their `$data` object
  parsed; other lines are parsed whole. Either way Arrow's JSON reader parses a topic's
  group with the topic's exact schema. That reader is strict where lakegate is strict
  (standard JSON only, no extra or duplicate keys, no `1.0` for an int, no number for a
  string ...); what it lets through is then checked column by column (row count, topic,
  timestamp, nulls, finite floats, event flag).
* Every line the fast paths do not certainly accept -- and every line of topics with
  `metric[]` fields -- is decided by `check_line`, which applies `lake.types.check_value`
  (the Emitter's rules) to the parsed JSON. So a line is accepted exactly when
  `check_line` accepts it; the fast paths only save time (tests check they agree).

The modules: `rules` (whether one line is accepted, exactly), `scan` (blocks of lines -> per-topic
Arrow tables), `write` (tables -> staged Parquet files, events included), `publish` (`ingest_job`:
the staged files become the job's tables in one record commit).
"""

from lakegate.lake.ingest.publish import IngestReport, ingest_job
from lakegate.lake.ingest.rules import MAX_PROBLEMS, IngestError, LineProblem, check_line

__all__ = ["MAX_PROBLEMS", "IngestError", "IngestReport", "LineProblem", "check_line", "ingest_job"]
