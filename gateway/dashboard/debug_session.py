"""A dashboard session: one batch of a lake, its config, and the metrics edited or added on top.

A session looks at one batch on one branch (the `lakegate metrics debug` job's batch, or any
stored batch under `lakegate serve`) through one config: config files on disk (`FileConfig`,
re-read whenever a file changes) or the branch's stored config (`BranchConfig`, re-read when a
new version is stored). Edits made in the page are kept in the session and layered on top of
the config, so a changed file on disk and the session's edits combine; the session's config
files are the originals with the edits applied by `ruamel.yaml` in round-trip mode (order,
comments and quoting of everything else kept). Every edit is checked by loading the edited
files with `load_config`, so what "Export Config" downloads always loads back.

Evaluation runs the metrics set with the metrics engine (`MetricsEngine.evaluate`): test
metrics on every job of the batch, then batch metrics. A session never writes the lake: the
jobs' statuses it computes are kept in the session and handed to the batch metrics in their
scope (`Scope.statuses`), so a batch metric counting them (`count_if(job_conflated_status =
'PASSED')`) sees what `lakegate metrics run` would write, while `metadata` and `metric_results`
on disk stay as `metrics run` left them. A session on a stored batch first shows the batch's
stored `metric_results` when they were evaluated with the same config version and metrics set
(and nothing was edited).
"""

from __future__ import annotations

import io
import tempfile
import threading
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sqlglot import exp

from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope
from lakegate.gateway.dashboard.config_edits import (
    BranchConfig,
    ConfigFiles,
    FileConfig,
    SessionError,
    clean,
    edited_documents,
)
from lakegate.gateway.dashboard.dashboard_json import cell, metric_json, result_json, stored_json
from lakegate.gateway.metrics.evaluation import EVALUATED_TYPES, MetricsEngine, conflated_status, worst
from lakegate.gateway.metrics.results_table import read_results
from lakegate.gateway.metrics.templates import json_value
from lakegate.lake.config import Config, ConfigError, Metric, load_config
from lakegate.lake.config_schema import SET_METRIC_TYPES
from lakegate.lake.storage import LOCAL
from lakegate.lake.template_kinds import TEMPLATES

#: Rows an ad hoc query shows (the total is always counted).
QUERY_ROWS = 1000


# -- the session ----------------------------------------------------------------------------------


def _row_counts(tables: list[str]) -> exp.Expression:
    """`SELECT 0 AS n, count(*) AS c FROM "t0" UNION ALL ...`: the row count of each table, by position."""
    selects = [
        exp.select(exp.Literal.number(i).as_("n"), exp.Count(this=exp.Star()).as_("c")).from_(
            exp.Table(this=exp.to_identifier(name, quoted=True))
        )
        for i, name in enumerate(tables)
    ]
    return exp.union(*selects, distinct=False) if len(selects) > 1 else selects[0]


class DashboardSession:
    """One batch of a lake seen through a config with the session's edits (see the module docstring).

    `debug`: the batch is a debug job's (its config files are watched, stored results never used).
    `refresh_data(config)` (debug sessions) is called on every refresh with the current config and
    returns True when it re-ingested the job (so everything is evaluated again).
    """

    def __init__(
        self,
        session_id: str,
        evaluator: MetricsEngine,
        *,
        branch: str,
        batch_id: str,
        source: FileConfig | BranchConfig,
        metrics_set: str | None,
        debug: bool = False,
        refresh_data: Callable[[Config], bool] | None = None,
    ):
        self.id = session_id
        self.evaluator = evaluator
        self.branch, self.batch_id = branch, batch_id
        self.source = source
        self.metrics_set = metrics_set
        self.debug = debug
        self.refresh_data = refresh_data
        self.lock = threading.RLock()
        self.edits: dict[str, dict[str, Any]] = {}
        self.added: dict[str, dict[str, Any]] = {}
        self.problems: list[str] = []  # why the config on disk cannot be used (the last good one is)
        self.notices: list[str] = []
        self.files: ConfigFiles | None = None
        self.base: Config | None = None  # the config as its files say
        self.config: Config | None = None  # with the session's edits
        self._stamp: object = object()
        self.jobs: list[dict[str, Any]] = []
        self.results: dict[str | None, dict[str, dict[str, Any]]] = {}  # job id (None: batch) -> metric -> result
        self.origin = "evaluated"
        self.evaluated_at: str | None = None
        self.seconds = 0.0
        with self.lock:
            self.refresh(force=True)

    # -- config ---------------------------------------------------------------------------------

    def _load_base(self) -> None:
        files = self.source.read()
        try:
            base = load_config(files.paths)
        except ConfigError as error:
            raise SessionError("the config has problems", [str(p) for p in error.problems]) from None
        if self.metrics_set is not None and self.metrics_set not in base.metrics_sets:
            known = ", ".join(repr(n) for n in base.metrics_sets) or "none"
            raise SessionError(
                f"no metrics set {self.metrics_set!r} in the config (sets: {known})",
                [f"{files.paths[0]}: no metrics set {self.metrics_set!r} (sets: {known})"],
            )
        dropped = [name for name in self.edits if name not in base.metrics]
        for name in dropped:
            del self.edits[name]
            self.notices.append(f"metric {name!r} is no longer in the config file; its session edit was dropped")
        clashes = [name for name in self.added if name in base.metrics]
        for name in clashes:
            del self.added[name]
            self.notices.append(
                f"metric {name!r} is now defined in the config file; the session's metric of that name was dropped"
            )
        self.config = self._with_edits(files, base, self.edits, self.added)
        self.files, self.base = files, base

    def _with_edits(self, files: ConfigFiles, base: Config, edits: dict, added: dict) -> Config:
        """The config with `edits` and `added` applied, checked by loading the edited files."""
        if not edits and not added:
            return base
        texts = edited_documents(files, base, edits, added, self.metrics_set)
        with tempfile.TemporaryDirectory(prefix="lakegate-session-") as scratch:
            paths = []
            for i, (name, text) in enumerate(zip(files.names, texts)):
                path = Path(scratch) / f"{i:02d}" / name
                path.parent.mkdir()
                path.write_text(text, encoding="utf-8")
                paths.append(path)
            try:
                config = load_config(paths)
            except ConfigError as error:
                raise SessionError(
                    error.problems[0].message,
                    [
                        f"{Path(p.location.path).name}:{p.location.line}:{p.location.column}: {p.message}"
                        for p in error.problems
                    ],
                ) from None
        for name, metric in config.metrics.items():
            if name in edits or name in added:
                metric.location = metric.query_location = None  # the text is the session's, not a file's
                if metric.status is not None:
                    metric.status.location = metric.status.query_location = None
            else:
                config.metrics[name] = base.metrics[name]
        config.paths = [str(p) for p in files.paths]
        return config

    def origin_of(self, name: str) -> str:
        return "added" if name in self.added else "edited" if name in self.edits else "config"

    def metrics(self) -> list[Metric]:
        """The metrics the session evaluates: the set's (with edits), or every test and batch metric."""
        assert self.config is not None
        if self.metrics_set is None:
            return [m for m in self.config.metrics.values() if m.type in SET_METRIC_TYPES]
        return self.config.metrics_in_set(self.metrics_set)

    def refresh(self, *, force: bool = False) -> bool:
        """Re-read the config when its files changed (and the data, for debug sessions); re-evaluate
        if anything changed. Returns whether it did."""
        with self.lock:
            stamp = self.source.stamp()
            changed = force or stamp != self._stamp
            if changed:
                self._stamp = stamp
                try:
                    self._load_base()
                    self.problems = []
                except SessionError as error:
                    self.problems = error.problems or [str(error)]
                    if self.config is None:
                        raise
                    return False
            assert self.config is not None
            if self.refresh_data is not None:
                try:
                    changed = self.refresh_data(self.base) or changed
                except ValueError as error:
                    self.problems = [f"cannot ingest the emissions again: {error}"]
            if changed:
                self.evaluate_all(use_stored=not self.debug and not self.edits and not self.added)
            return changed

    # -- evaluation -----------------------------------------------------------------------------

    def _job_rows(self) -> list[dict[str, Any]]:
        answer = self.evaluator.query(
            "SELECT job_id, experience_name, job_status, job_metrics_status, job_conflated_status "
            "FROM metadata ORDER BY time, job_id",
            self.branch,
            Scope(batch_id=self.batch_id),
        )
        keys = ("job_id", "experience_name", "job_status", "metrics_status", "conflated_status")
        return [dict(zip(keys, row)) for row in answer.rows()]

    def logs_dir(self, job_id: str | None) -> Path | None:
        return None if job_id is None else self.evaluator.logs_dir(self.branch, self.batch_id, job_id)

    def _evaluate(self, metric: Metric, job_id: str | None) -> dict[str, Any]:
        logs = self.logs_dir(job_id)
        if job_id is None:  # a batch metric sees the session's job statuses in `metadata`
            statuses = tuple((job["job_id"], job["metrics_status"], job["conflated_status"]) for job in self.jobs)
            scope = Scope(self.batch_id, statuses=statuses)
        else:
            scope = Scope(self.batch_id, job_id)
        result = self.evaluator.evaluate(metric, self.branch, scope, logs_dir=logs)
        return result_json(result, logs)

    def _judge(self, job: dict[str, Any]) -> None:
        """Set a job's statuses (in the session only) from its test metrics."""
        metrics_status = worst(r["status"] for r in self.results.get(job["job_id"], {}).values())
        job["metrics_status"], job["conflated_status"] = (
            metrics_status,
            conflated_status(job["job_status"], metrics_status),
        )

    def _rejudge(self) -> None:
        """Judge every job again; when a status changed, evaluate the batch metrics again (they may count them)."""
        before = [(job["metrics_status"], job["conflated_status"]) for job in self.jobs]
        for job in self.jobs:
            self._judge(job)
        if before != [(job["metrics_status"], job["conflated_status"]) for job in self.jobs]:
            batch = self.results.setdefault(None, {})
            for metric in self.metrics():
                if metric.type != "test":
                    batch[metric.name] = self._evaluate(metric, None)

    def evaluate_all(self, *, use_stored: bool = False) -> None:
        """Evaluate every metric (test metrics on each job, then batch metrics), or show the batch's
        stored results when `use_stored` and they match the config version and metrics set."""
        with self.lock:
            started = time.perf_counter()
            self.jobs = self._job_rows()
            if use_stored and self._load_stored():
                return
            metrics = self.metrics()
            self.results = {}
            for job in self.jobs:
                self.results[job["job_id"]] = {
                    m.name: self._evaluate(m, job["job_id"]) for m in metrics if m.type == "test"
                }
                self._judge(job)
            self.results[None] = {m.name: self._evaluate(m, None) for m in metrics if m.type != "test"}
            self.origin, self.evaluated_at = "evaluated", time.strftime("%Y-%m-%d %H:%M:%S")
            self.seconds = time.perf_counter() - started

    def _load_stored(self) -> bool:
        assert self.files is not None
        rows = read_results(self.evaluator.lake, self.branch, self.batch_id)
        if not rows or self.files.version is None:
            return False
        if any(r["config_version"] != self.files.version or r["metrics_set"] != self.metrics_set for r in rows):
            return False
        wanted = {m.name for m in self.metrics()}
        if {r["metric_name"] for r in rows} != wanted:
            return False
        self.results = {job["job_id"]: {} for job in self.jobs}
        self.results[None] = {}
        for row in rows:
            job_id = row["job_id"]
            self.results.setdefault(job_id, {})[row["metric_name"]] = stored_json(row, self.logs_dir(job_id))
        self.origin = "stored"
        self.evaluated_at = str(rows[0]["evaluated_at"])[:19]
        self.seconds = 0.0
        return True

    def _rerun(self, name: str) -> None:
        """Evaluate one metric again wherever it applies (every job, or the batch)."""
        assert self.config is not None
        metric = self.config.metrics[name]
        self.origin = "evaluated"
        if metric.type == "test":
            for job in self.jobs:
                self.results.setdefault(job["job_id"], {})[name] = self._evaluate(metric, job["job_id"])
            self._rejudge()
        else:
            self.results.setdefault(None, {})[name] = self._evaluate(metric, None)

    # -- edits ----------------------------------------------------------------------------------

    def _apply(self, edits: dict, added: dict) -> None:
        assert self.files is not None and self.base is not None
        self.config = self._with_edits(self.files, self.base, edits, added)
        self.edits, self.added = edits, added

    def update_metric(self, name: str, fields: dict[str, Any]) -> None:
        """Change a metric's keys (query_string, template, status ...) in the session and run it again."""
        fields = clean(fields)
        with self.lock:
            if name in self.added:
                self._apply(self.edits, {**self.added, name: {**self.added[name], **fields}})
            elif self.base is not None and name in self.base.metrics:
                self._apply({**self.edits, name: {**self.edits.get(name, {}), **fields}}, self.added)
            else:
                raise SessionError(f"no metric {name!r} in the session")
            self._rerun(name)

    def add_metric(self, name: str, spec: dict[str, Any]) -> None:
        """Add a metric to the session (and to its metrics set) and evaluate it."""
        name = (name or "").strip()
        spec = clean(spec)
        with self.lock:
            assert self.config is not None
            if not name:
                raise SessionError("the new metric needs a name")
            if name in self.config.metrics:
                raise SessionError(f"a metric named {name!r} already exists")
            if spec.get("type") not in SET_METRIC_TYPES:
                raise SessionError(f"the metric type must be one of {', '.join(SET_METRIC_TYPES)}")
            spec.setdefault("description", "")
            spec.setdefault("template_type", "system")
            self._apply(self.edits, {**self.added, name: spec})
            self._rerun(name)

    def revert_metric(self, name: str) -> None:
        """Drop the session's edit of a metric (back to the config file) or remove an added metric."""
        with self.lock:
            if name in self.added:
                self._apply(self.edits, {k: v for k, v in self.added.items() if k != name})
                for results in self.results.values():
                    results.pop(name, None)
                self._rejudge()
            elif name in self.edits:
                self._apply({k: v for k, v in self.edits.items() if k != name}, self.added)
                self._rerun(name)
            else:
                raise SessionError(f"metric {name!r} has no session edits")

    # -- views ----------------------------------------------------------------------------------

    def state(self, job_id: str | None = None) -> dict[str, Any]:
        """Everything the page shows for one job of the batch (default: the first)."""
        with self.lock:
            assert self.config is not None and self.files is not None
            job_ids = [job["job_id"] for job in self.jobs]
            if job_id not in job_ids:
                job_id = job_ids[0] if job_ids else None
            metrics = self.metrics()
            items = []
            for metric in metrics:
                where = job_id if metric.type == "test" else None
                items.append(
                    {
                        **metric_json(metric, self.origin_of(metric.name)),
                        "result": self.results.get(where, {}).get(metric.name),
                    }
                )
            test_names = [m.name for m in metrics if m.type == "test"]
            batch_results = self.results.get(None, {})
            batch_status = worst(r["status"] for r in batch_results.values())
            return {
                "id": self.id,
                "debug": self.debug,
                "branch": self.branch,
                "batch_id": self.batch_id,
                "job_id": job_id,
                "jobs": self.jobs,
                "metrics_set": self.metrics_set,
                "metrics_sets": list(self.config.metrics_sets),
                "config": {
                    "files": self.files.names,
                    "paths": [str(p) for p in self.files.paths],
                    "version": self.files.version,
                    "problems": self.problems,
                    "notices": self.notices,
                    "edited": list(self.edits),
                    "added": list(self.added),
                },
                "origin": self.origin,
                "evaluated_at": self.evaluated_at,
                "seconds": round(self.seconds, 3),
                "batch_metrics_status": batch_status,
                "status": worst([batch_status, *(job["conflated_status"] or "PASSED" for job in self.jobs)]),
                "metrics": items,
                "matrix": {
                    "metrics": test_names,
                    "rows": [
                        {**job, "cells": [cell(self.results.get(job["job_id"], {}).get(n)) for n in test_names]}
                        for job in self.jobs
                    ],
                },
                "templates": list(TEMPLATES),
                "types": list(EVALUATED_TYPES),
            }

    def documents(self) -> list[tuple[str, str]]:
        """The session's config files (name, text): the originals with the session's edits applied."""
        with self.lock:
            assert self.files is not None and self.base is not None
            if not self.edits and not self.added:
                return list(zip(self.files.names, self.files.texts))
            texts = edited_documents(self.files, self.base, self.edits, self.added, self.metrics_set)
            return list(zip(self.files.names, texts))

    def export_zip(self) -> bytes:
        """A zip of the session's config files and the custom template files they name; SessionError
        when a template file is not inside the config's folder (only files there are exported)."""
        with self.lock:
            assert self.config is not None and self.files is not None
            templates = self._template_files(self.files.paths[0].parent.resolve())
            documents = self.documents()
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
            for name, text in documents:
                archive.writestr(name, text)
            for name, path in templates.items():
                archive.write(path, name)
        return buffer.getvalue()

    def _template_files(self, folder: Path) -> dict[str, Path]:
        """Name in the zip -> file of every existing `template_file`, each checked to be inside `folder`."""
        assert self.config is not None
        found = {}
        for metric in self.config.metrics.values():
            if not metric.template_file:
                continue
            path = None if "\0" in metric.template_file else (folder / metric.template_file).resolve()
            if path is None or not path.is_relative_to(folder) or path == folder:
                where = (
                    f" ({Path(metric.location.path).name}:{metric.location.line}:{metric.location.column})"
                    if metric.location
                    else ""
                )
                raise SessionError(
                    f"metric {metric.name!r}{where}: template_file {metric.template_file!r} is "
                    "outside the config's folder; only files inside it are exported"
                )
            path = metric.template_path()  # beside the config, else in its templates/ folder
            if path is not None and path.is_relative_to(folder):
                found[path.relative_to(folder).as_posix()] = path
        return found

    def scope(self, scope: str, job_id: str | None) -> Scope:
        """`job` (one job of the batch), `batch` or `branch` (every batch)."""
        if scope == "branch":
            return Scope()
        if scope == "batch":
            return Scope(self.batch_id)
        if scope == "job" and job_id in {job["job_id"] for job in self.jobs}:
            return Scope(self.batch_id, job_id)
        raise SessionError(f"unknown scope {scope!r} (or no job {job_id!r} in the batch)")

    def tables(self, scope: Scope) -> list[dict[str, Any]]:
        """Every table of the branch with its columns and its row count in `scope`."""
        engine = self.evaluator.engine
        schema = engine.system_catalog.tables(engine.catalog, self.branch)
        names = list(schema)
        counts = (
            dict(self.evaluator.query(_row_counts(names).sql(dialect="trino"), self.branch, scope).rows())
            if names
            else {}
        )
        return [
            {
                "name": name,
                "columns": [{"name": c, "type": t} for c, t in schema[name]],
                "rows": counts.get(i, 0),
            }
            for i, name in enumerate(names)
        ]

    def query(self, sql: str, scope: Scope, limit: int = QUERY_ROWS) -> dict[str, Any]:
        """An ad hoc query: the first `limit` rows and the total row count, or the error with its position."""
        started = time.perf_counter()
        try:
            answer = self.evaluator.query(sql, self.branch, scope)
            rows: list[list[Any]] = []
            total = 0
            for batch in answer.batches:
                total += batch.num_rows
                if len(rows) < limit:
                    part = batch.slice(0, limit - len(rows))
                    columns = [column.to_pylist() for column in part.columns]
                    rows.extend([json_value(v) for v in row] for row in zip(*columns))
        except DialectError as error:
            return {
                "error": {
                    "message": error.message,
                    "line": error.line,
                    "column": error.column,
                    "name": error.error_name,
                }
            }
        return {
            "columns": [{"name": n, "type": t} for n, t in answer.columns],
            "rows": rows,
            "total": total,
            "limit": limit,
            "seconds": round(time.perf_counter() - started, 4),
        }

    def events(self, job_id: str) -> list[dict[str, Any]]:
        """The job's events in time order, with their attached metrics."""
        self.scope("job", job_id)  # a job of this batch
        return [event.as_dict() for event in self.evaluator.job_events(self.branch, self.batch_id, job_id)]

    def log_file(self, job_id: str, name: str) -> Path:
        """A file of the job's logs (images); SessionError if it is not one."""
        root = self.logs_dir(job_id)
        if root is None:
            raise SessionError(f"job {job_id!r} has no log files")
        root = root.resolve()
        path = None if "\0" in name else (root / name).resolve()
        if path is None or not path.is_relative_to(root) or not LOCAL.is_file(path):
            raise SessionError(f"no file {name!r} in the logs of job {job_id!r}")
        return path
