"""The metrics engine: evaluate a metrics set on a batch of the lake, judge statuses, store the results.

How a batch is evaluated (`MetricsEngine.evaluate_batch`):

1. Every `type: test` metric runs once per job of the batch, restricted to that job
   (`Scope(batch_id, job_id)`: it never sees another job's rows). Jobs are evaluated on a few
   threads, each query on its own cursor; the scope stays per job (each query is translated once
   for every job: the job's values are bound into that translation, `dialect/scope_values.py`).
2. A job's `job_metrics_status` is the worst status of its test metrics; its
   `job_conflated_status` is ERROR when its `job_status` is FAILED, else its metrics status
   (so a metric ERROR makes the job ERROR: its pass/fail could not be decided). Both are
   staged as the job's new `metadata` row, which batch metrics already see (DuckDB backend),
   so they can count them (`count_if(job_conflated_status = 'PASSED')`).
3. Every `type: batch` metric runs once, restricted to the batch (`Scope(batch_id)`).
4. The batch's `batch_metrics_status` is the worst of its batch metrics; its overall
   `status` folds in every job: the worst of the batch metrics and the jobs' conflated statuses.
5. The results replace the batch's rows of the `metric_results` table, and the staged statuses
   the jobs' metadata rows, in one commit of the branch's record (`results`), under the
   batch's lock: two runs of a batch take turns, and a run that dies changes nothing. The commit
   is made only if no job of the batch changed since the evaluation began (re-ingested, added,
   removed: the record's job versions); else nothing is written and the batch is evaluated again
   (`BatchEvaluation.restarts` says why), at most STALE_ATTEMPTS times before StaleJobsError.

Statuses, from best to worst: PASSED < WARNING < BLOCKER < ERROR; NOT_RUN (skipped or not
supported) counts for nothing. One metric:

* the query fails (refused, invalid, or fails while running): ERROR with the message and
  the position (line, column) in the query, and in the config file when it can be mapped
  exactly (e.g. `config.resim.yaml:57:9`); the rest of the set still runs;
* the result does not fit the template: ERROR with the template's message;
* no rows and `skip_if_no_data: true`: NOT_RUN;
* no rows, or one row of NULLs only (`MIN(x)` over no rows), and `skip_if_no_data: false`: NO_DATA,
  and the status check does not run (SignalFlag's config reference); NO_DATA, like NOT_RUN, never
  makes a job or batch worse;
* `type: dashboard | report` metrics run over many batches (`gateway/metrics/trends.py`): in a
  batch they are NOT_RUN naming the command that runs them (they never fail a batch);
* `template_type: custom`: the result is rendered by the metric's Liquid template (`custom`);
* otherwise the status check, if any: the status query runs with `block` (when given) bound to its one
  `?` (a typed query parameter, never pasted text); any row means BLOCKER; else with `warn`
  (when given): any row means WARNING; else PASSED. No status check: PASSED.

Events (`JobOutcome.events`, `job_events`): the rows of the `events` table for one job (topics
with `event: true`), with their attached metrics parsed (image lists and Plotly JSON).
"""

from __future__ import annotations

import contextlib
import datetime as dt
import functools
import json
import sys
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa
from tqdm import tqdm

from lakegate.dialect.errors import DialectError
from lakegate.dialect.scope import Scope
from lakegate.gateway.engine.backend import DuckDBBackend, QueryResult
from lakegate.gateway.engine.engine import Engine
from lakegate.gateway.metrics.custom import CUSTOM, render_custom
from lakegate.gateway.metrics.job_media import names_jobs, render_job_media
from lakegate.gateway.metrics.metric_result import MetricError, MetricResult
from lakegate.gateway.metrics.result_columns import result_table, table_rows
from lakegate.gateway.metrics.results_table import ResultsWriter
from lakegate.gateway.metrics.statuses import BLOCKER, ERROR, NO_DATA, NOT_RUN, PASSED, SEVERITY, WARNING
from lakegate.gateway.metrics.template_settings import apply_template_settings, unused_settings
from lakegate.gateway.metrics.templates import Rendered, TemplateError, render
from lakegate.lake import paths
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import Config, Location, Metric, setting_names
from lakegate.lake.record import StaleJobsError, job_logs_dir
from lakegate.lake.storage import LakeStorage

#: Evaluations of a batch begun before one is stored or given up (each restarted because a job changed).
STALE_ATTEMPTS = 3
#: Metric types a batch evaluates (`evaluate_batch`).
EVALUATED_TYPES = ("test", "batch")
#: Metric types that run over many batches (`Scope.batches`, gateway/metrics/trends.py), and the
#: command that runs them; `evaluate_batch` reports them NOT_RUN saying so.
MULTI_BATCH_COMMANDS = {
    "dashboard": "lakegate metrics dashboard",
    "report": "lakegate metrics report --batches A,B,...",
}


def worst(statuses: Sequence[str] | Any) -> str:
    """The worst of some statuses; PASSED when there are none (or only NOT_RUN and NO_DATA)."""
    found = max(statuses, key=SEVERITY.__getitem__, default=PASSED)
    return PASSED if SEVERITY[found] == 0 else found


def conflated_status(job_status: str | None, metrics_status: str) -> str:
    """A job's combined status: ERROR for a FAILED job, else its metrics status."""
    return ERROR if (job_status or "").upper() == "FAILED" else metrics_status


# -- results ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class EventMetric:
    """A metric attached to an event: `value` is text (scalar, text), a list of file names
    (image) or a Plotly figure dict (plotly)."""

    name: str
    type: str
    value: Any
    description: str | None = None
    status: str | None = None


@dataclass(frozen=True)
class Event:
    """One event of a job (a row of the `events` table)."""

    timestamp: int  # nanoseconds
    topic: str
    name: str | None
    description: str | None
    status: str | None
    tags: list[str]
    metrics: list[EventMetric]

    def as_dict(self) -> dict[str, Any]:
        return {
            "timestamp": self.timestamp,
            "topic": self.topic,
            "name": self.name,
            "description": self.description,
            "status": self.status,
            "tags": list(self.tags),
            "metrics": [
                {"name": m.name, "type": m.type, "value": m.value, "description": m.description, "status": m.status}
                for m in self.metrics
            ],
        }


@dataclass
class JobOutcome:
    """One job of an evaluated batch: its statuses, test metric results and events."""

    job_id: str
    experience_name: str | None
    job_status: str | None
    metrics_status: str
    conflated_status: str
    results: list[MetricResult]
    events: list[Event] = field(default_factory=list)
    logs_dir: Path | None = None  # the job's log files, where image file names are found

    def as_dict(self) -> dict[str, Any]:
        return {
            "job_id": self.job_id,
            "experience_name": self.experience_name,
            "job_status": self.job_status,
            "job_metrics_status": self.metrics_status,
            "job_conflated_status": self.conflated_status,
            "events": [e.as_dict() for e in self.events],
        }


@dataclass
class BatchEvaluation:
    """Everything one evaluation of a batch produced."""

    branch: str
    batch_id: str
    metrics_set: str | None
    config_version: int | None
    evaluated_at: dt.datetime  # UTC, naive
    jobs: list[JobOutcome]
    batch_results: list[MetricResult]
    seconds: float = 0.0
    #: Evaluations started again because a job changed under them (re-ingested, added, removed).
    restarts: list[str] = field(default_factory=list)

    @property
    def batch_metrics_status(self) -> str:
        """The worst status of the batch metrics."""
        return worst(r.status for r in self.batch_results)

    @property
    def status(self) -> str:
        """The batch's overall status: the worst of its batch metrics and its jobs' conflated statuses."""
        return worst([self.batch_metrics_status, *(job.conflated_status for job in self.jobs)])

    def results(self) -> list[MetricResult]:
        """Every evaluated metric: each job's test metrics (jobs in order), then the batch metrics."""
        return [r for job in self.jobs for r in job.results] + self.batch_results

    def count(self, status: str) -> int:
        """How many metric results have `status`."""
        return sum(1 for r in self.results() if r.status == status)

    def as_dict(self) -> dict[str, Any]:
        return {
            "branch": self.branch,
            "batch_id": self.batch_id,
            "metrics_set": self.metrics_set,
            "config_version": self.config_version,
            "evaluated_at": self.evaluated_at.isoformat() + "Z",
            "status": self.status,
            "batch_metrics_status": self.batch_metrics_status,
            "jobs": [job.as_dict() for job in self.jobs],
            "metrics": [r.as_dict() for r in self.results()],
        }


# -- config helpers -----------------------------------------------------------------------------


def select_metrics(config: Config, metrics_set: str | None = None, *, all_metrics: bool = False) -> list[Metric]:
    """The metrics of `metrics_set` (KeyError naming the known sets if unknown), or every metric
    of the config with `all_metrics`."""
    if all_metrics:
        return list(config.metrics.values())
    if metrics_set is None:
        raise ValueError("name a metrics set, or ask for all metrics")
    return config.metrics_in_set(metrics_set)


def no_data(rows: Sequence[tuple] | pa.Table) -> bool:
    """SignalFlag's NO_DATA: a query that returns no rows, or one row of NULLs only (an aggregate
    such as MIN(x) over no rows). COUNT(*) over no rows is a row with a value (0): data."""
    if isinstance(rows, pa.Table):
        return rows.num_rows == 0 or (rows.num_rows == 1 and all(column.null_count == 1 for column in rows.columns))
    return not rows or (len(rows) == 1 and all(value is None for value in rows[0]))


def check_batch_metrics(metrics: Sequence[Metric], metrics_set: str | None) -> None:
    """ValueError when `metrics` hold no test or batch metric: evaluating them on a batch would only
    replace its statuses and results with NOT_RUN rows, so the batch is left alone and the command
    that runs them is named (a set of `type: dashboard` metrics: `lakegate metrics dashboard`)."""
    if any(metric.type in EVALUATED_TYPES for metric in metrics):
        return
    where = f"metrics set {metrics_set!r}" if metrics_set else "the config"
    kinds = sorted({metric.type for metric in metrics})
    commands = "; ".join(
        f"{kind} metrics: {MULTI_BATCH_COMMANDS[kind]}" + (f" --metrics-set {metrics_set!r}" if metrics_set else "")
        for kind in kinds
        if kind in MULTI_BATCH_COMMANDS
    )
    raise ValueError(
        f"{where} holds no test or batch metric ({', '.join(kinds) or 'no'} metrics only), so there is nothing "
        f"to evaluate on a batch; its statuses and results are left as they are"
        + (f" (run {commands})" if commands else "")
    )


def unsupported_reason(metric: Metric, scope: Scope) -> str | None:
    """Why a metric cannot be evaluated in `scope`, or None when it can."""
    if metric.type in MULTI_BATCH_COMMANDS and scope.batches is None:
        return f"a {metric.type} metric runs over many batches: {MULTI_BATCH_COMMANDS[metric.type]}"
    if metric.type in EVALUATED_TYPES and scope.batches is not None:
        return f"a {metric.type} metric runs on one batch: lakegate metrics run"
    return None


@functools.lru_cache(maxsize=32)
def _file_lines(path: str, stamp: float) -> tuple[str, ...]:
    return tuple(Path(path).read_text(encoding="utf-8").splitlines())


def config_position(start: Location | None, sql: str, line: int | None, column: int | None) -> Location | None:
    """Where (line, column) of a query is in the config file, given where its value starts.

    Exact for literal block scalars (`query_string: |`) and single-line values; None when the
    YAML folds or escapes the text so that no exact position exists (or the file changed).
    """
    if start is None or not start.line or line is None or column is None:
        return None
    try:
        lines = _file_lines(start.path, Path(start.path).stat().st_mtime)
        head = lines[start.line - 1][start.column - 1 :]
        wanted = sql.splitlines()[line - 1]
    except (OSError, UnicodeDecodeError, IndexError):
        return None
    if head.startswith("|"):
        first = next((text for text in lines[start.line :] if text.strip()), None)
        if first is None or start.line + line > len(lines):
            return None
        indent = len(first) - len(first.lstrip(" "))
        found = Location(start.path, start.line + line, indent + column)
        exact = lines[found.line - 1][indent:] == wanted
    elif line == 1 and not head.startswith(">"):
        quoted = head.startswith(("'", '"'))
        found = Location(start.path, start.line, start.column + quoted + column - 1)
        exact = head[quoted:].startswith(wanted)
    else:
        return None
    return found if exact else None  # escapes, folding or an edited file: no exact position


# -- the engine ---------------------------------------------------------------------------------


class MetricsEngine:
    """Evaluates metrics on the lake at `lake` through `engine` (default: the embedded DuckDB engine).

    `threads` jobs are evaluated at once. The metrics engine writes to the lake (metadata statuses
    and `metric_results`) directly; queries go through the engine only, as the server's do.
    """

    def __init__(self, lake: Path, engine: Engine | None = None, *, threads: int = 2):
        self.lake = Path(lake)
        self.storage = LakeStorage(self.lake)
        self._owns_engine = engine is None
        self.engine = engine if engine is not None else Engine.open(self.lake)
        self.threads = max(1, threads)

    def close(self) -> None:
        """Close the engine if this made it."""
        if self._owns_engine:
            self.engine.close()

    def query(self, sql: str, branch: str, scope: Scope | None, params: Sequence[object] = ()) -> QueryResult:
        """Run one Trino-dialect query on `branch`, restricted to `scope`, as the server would."""
        return self.engine.execute(sql, self.engine.session(branch=branch, scope=scope), params)

    def __enter__(self) -> MetricsEngine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- one metric -----------------------------------------------------------------------------

    def evaluate(self, metric: Metric, branch: str, scope: Scope, *, logs_dir: Path | None = None) -> MetricResult:
        """Evaluate one metric in one scope: run its query, render it, judge its status."""
        started = time.perf_counter()
        template = CUSTOM if metric.template_type == CUSTOM else metric.template
        result = MetricResult(
            metric=metric.name,
            metric_type=metric.type,
            template=template,
            batch_id=scope.batch_id or "",
            job_id=scope.job_id,
            status=PASSED,
            units=metric.units,
            description=metric.description,
        )
        reason = unsupported_reason(metric, scope)
        if reason is not None:
            result.status, result.error = NOT_RUN, MetricError(reason)
        else:
            self._run(metric, branch, scope, logs_dir, result)
        result.seconds = time.perf_counter() - started
        return result

    def _run(self, metric: Metric, branch: str, scope: Scope, logs_dir: Path | None, result: MetricResult) -> None:
        try:
            answer = self.query(metric.query_string, branch, scope)
            rows = result_table(answer.batches)
        except DialectError as error:
            result.status, result.error = (
                ERROR,
                _query_error(error, metric.query_string, metric.query_location, "query"),
            )
            return
        if not rows and metric.skip_if_no_data:
            result.status = NOT_RUN
            result.error = MetricError("skipped: the query returned no rows (skip_if_no_data)")
            return
        if not metric.skip_if_no_data and no_data(rows):
            what = "no rows" if not rows else "one row of NULLs"
            result.status = NO_DATA
            result.error = MetricError(f"the query returned {what}; the status check does not run (NO_DATA)")
            return
        try:
            if metric.template_type == CUSTOM:
                result.rendered = render_custom(metric, answer.columns, table_rows(rows))
            elif scope.job_id is None and names_jobs(metric.template, answer.columns):
                result.rendered = self._job_media(metric, branch, scope, table_rows(rows))
            else:
                result.rendered = render(
                    metric.name, metric.template or "", answer.columns, rows, units=metric.units, logs_dir=logs_dir
                )
        except TemplateError as error:
            # The status check does not read the figure: it still runs, and its outcome is told
            # beside the template's error (ERROR, the worse of the two, is the metric's status).
            result.status, result.error = ERROR, MetricError(str(error), query="template")
            outcome = self._judge(metric, branch, scope)
            if metric.status is not None:
                told = outcome[0] if outcome[1] is None else f"{outcome[0]} ({outcome[1]})"
                result.error = MetricError(f"{error}; the status check gave {told}", query="template")
            return
        if metric.template_settings and metric.template_type == CUSTOM:  # as in SignalFlag: the template's figure
            names = ", ".join(setting_names(metric.template_settings))
            result.rendered.problems.append(f"template_settings not applied to a custom template: {names}")
        elif metric.template_settings:
            apply_template_settings(result.rendered.figure, metric.template_settings)
            unused = unused_settings(metric.template_settings)
            if unused:
                result.rendered.problems.append(f"template_settings not used by lakegate: {', '.join(unused)}")
        if result.rendered.files_missing:  # a WARNING with the reason, not a silent PASS
            reason = "; ".join(result.rendered.problems)
            result.status, result.error = WARNING, MetricError(f"none of the files the query names is there: {reason}")
        status, error = self._judge(metric, branch, scope)
        if status != PASSED:  # the status check's outcome wins over a missing-files WARNING
            result.status = status
            result.error = error if error is not None else result.error

    def _job_media(self, metric: Metric, branch: str, scope: Scope, rows: list[tuple]) -> Rendered:
        """A batch image or video result of `[label, job_id]` rows (job_media): each job's files."""
        template = metric.template or ""
        config = BranchConfigs(self.lake, branch).current()
        topics = config.topics.values() if config is not None else ()
        media = [(topic.name, name) for topic in topics for name, kind in topic.fields.items() if kind == template]

        def files_of(job_id: str, topic: str, column: str) -> list[str]:
            sql = f"SELECT {_quoted(column)} FROM {_quoted(topic)} WHERE job_id = ? ORDER BY timestamp"
            answer = self.query(sql, branch, Scope(scope.batch_id, job_id), (job_id,))
            return [value for (value,) in answer.rows() if value is not None]

        def logs_dir_of(job_id: str) -> Path | None:
            return self.logs_dir(branch, scope.batch_id or "", job_id)

        return render_job_media(metric.name, template, rows, media, files_of, logs_dir_of)

    def _judge(self, metric: Metric, branch: str, scope: Scope) -> tuple[str, MetricError | None]:
        """The status check's outcome: BLOCKER when the status query finds rows with `block`, else
        WARNING when it finds rows with `warn`, else PASSED (also with no check); ERROR when it fails."""
        check = metric.status
        if check is None:
            return PASSED, None
        try:
            if check.block is not None and self._any_rows(check.query_string, branch, scope, check.block):
                return BLOCKER, None
            if check.warn is not None and self._any_rows(check.query_string, branch, scope, check.warn):
                return WARNING, None
        except DialectError as error:
            return ERROR, _query_error(error, check.query_string, check.query_location, "status query")
        return PASSED, None

    def _any_rows(self, sql: str, branch: str, scope: Scope, threshold: Any) -> bool:
        answer = self.query(sql, branch, scope, (threshold,))
        found = False
        for batch in answer.batches:  # read to the end: the cursor closes when the stream is done
            found = found or batch.num_rows > 0
        return found

    # -- jobs and events ------------------------------------------------------------------------

    def jobs(self, branch: str, batch_id: str) -> list[tuple[str, str | None, str | None]]:
        """(job_id, experience_name, job_status) of every job of a batch, by start time."""
        answer = self.query(
            "SELECT job_id, experience_name, job_status FROM metadata ORDER BY time, job_id",
            branch,
            Scope(batch_id=batch_id),
        )
        return [(job_id, experience, status) for job_id, experience, status in answer.rows()]

    def job_events(self, branch: str, batch_id: str, job_id: str) -> list[Event]:
        """The events of one job, by time (then name)."""
        return self._events(branch, Scope(batch_id=batch_id, job_id=job_id)).get(job_id, [])

    def _events(self, branch: str, scope: Scope) -> dict[str, list[Event]]:
        """Job id -> its events in `scope`, by time (then name)."""
        answer = self.query(
            "SELECT job_id, timestamp, topic, name, description, status, tags, metrics FROM events "
            "ORDER BY job_id, timestamp, name",
            branch,
            scope,
        )
        events: dict[str, list[Event]] = {}
        for job_id, timestamp, topic, name, description, status, tags, metrics in answer.rows():
            events.setdefault(job_id, []).append(
                Event(
                    timestamp,
                    topic,
                    name,
                    description,
                    status,
                    list(tags or []),
                    [_event_metric(m) for m in metrics or []],
                )
            )
        return events

    def logs_dir(self, branch: str, batch_id: str, job_id: str) -> Path | None:
        """The job's log files in the lake (`record.job_logs_dir`), if there are any."""
        directory = job_logs_dir(self.lake, branch, batch_id, job_id)
        return directory if self.storage.is_dir(directory) else None

    # -- a batch --------------------------------------------------------------------------------

    def evaluate_batch(
        self,
        branch: str,
        batch_id: str,
        metrics: Sequence[Metric],
        *,
        metrics_set: str | None = None,
        config_version: int | None = None,
        progress: bool = False,
        store: bool = True,
        keep_figures: bool = True,
    ) -> BatchEvaluation:
        """Evaluate `metrics` on every job of a batch and on the batch (see the module docstring).

        With `store`, replaces the batch's rows of `metric_results` (written job by job while the
        others are evaluated) and the jobs' statuses in their metadata rows, in one commit. Without
        `keep_figures`, each job's Plotly figures are dropped from the returned results once
        stored (they can be large). LookupError when the batch has no jobs; ValueError, before anything
        is read or written, when `metrics` hold no test or batch metric (`check_batch_metrics`).
        """
        check_batch_metrics(metrics, metrics_set)
        started = time.perf_counter()
        evaluated_at = dt.datetime.now(dt.UTC).replace(tzinfo=None)
        restarts: list[str] = []
        while True:
            try:
                outcomes, batch_results = self._evaluate_once(
                    branch,
                    batch_id,
                    metrics,
                    store=store,
                    progress=progress,
                    keep_figures=keep_figures,
                    row={"metrics_set": metrics_set, "config_version": config_version, "evaluated_at": evaluated_at},
                )
                break
            except StaleJobsError as stale:  # nothing was written: evaluate the jobs as they are now
                restarts.append(str(stale))
                if len(restarts) >= STALE_ATTEMPTS:
                    raise StaleJobsError(stale.batch_id, stale.jobs, attempts=len(restarts)) from None
        events = self._events(branch, Scope(batch_id=batch_id))
        for outcome in outcomes:
            outcome.events = events.get(outcome.job_id, [])
        evaluation = BatchEvaluation(
            branch=branch,
            batch_id=batch_id,
            metrics_set=metrics_set,
            config_version=config_version,
            evaluated_at=evaluated_at,
            jobs=outcomes,
            batch_results=batch_results,
            restarts=restarts,
        )
        evaluation.seconds = time.perf_counter() - started
        return evaluation

    def _evaluate_once(
        self,
        branch: str,
        batch_id: str,
        metrics: Sequence[Metric],
        *,
        store: bool,
        progress: bool,
        keep_figures: bool,
        row: dict[str, Any],
    ) -> tuple[list[JobOutcome], list[MetricResult]]:
        """One evaluation of the batch (`evaluate_batch`): the jobs' outcomes and the batch metrics'
        results, stored when `store` (StaleJobsError, nothing stored: a job changed meanwhile)."""
        test_metrics = [m for m in metrics if m.type == "test"]
        batch_metrics = [m for m in metrics if m.type != "test"]
        lock = threading.Lock()

        def advance() -> None:
            with lock:
                bar.update(1)

        def one_job(job: tuple[str, str | None, str | None]) -> JobOutcome:
            return self._evaluate_job(branch, batch_id, job, test_metrics, advance)

        def done(results: list[MetricResult]) -> None:
            if writer is not None:
                writer.write(results)
            if not keep_figures:
                for result in results:
                    if result.rendered is not None:
                        result.rendered.figure = None

        with contextlib.ExitStack() as stack:
            if store:  # one evaluation of a batch at a time: its statuses and results switch together
                stack.enter_context(paths.batch_lock(self.lake, branch, batch_id))
            # the writer reads the jobs' versions before anything of theirs is read
            writer = stack.enter_context(ResultsWriter(self.lake, branch, batch_id, **row)) if store else None
            jobs = self.jobs(branch, batch_id)
            if not jobs:
                raise LookupError(f"batch {batch_id!r} has no jobs on branch {branch!r}")
            bar = stack.enter_context(
                tqdm(
                    total=len(jobs) * len(test_metrics) + len(batch_metrics),
                    desc="evaluating metrics",
                    unit="metric",
                    disable=not progress,
                    file=sys.stderr,
                    leave=False,
                )
            )
            pool = stack.enter_context(ThreadPoolExecutor(self.threads, thread_name_prefix="lakegate-metrics"))
            stack.callback(pool.shutdown, cancel_futures=True)  # on an error, start no further job
            outcomes = []
            for outcome in pool.map(one_job, jobs):  # in job order, as they finish
                done(outcome.results)
                outcomes.append(outcome)
            batch_engine = self._batch_engine(stack, writer, outcomes)
            batch_results = []
            for metric in batch_metrics:
                batch_results.append(batch_engine.evaluate(metric, branch, Scope(batch_id=batch_id)))
                advance()
            done(batch_results)
            if writer is not None:
                writer.commit()
        return outcomes, batch_results

    def _batch_engine(
        self, stack: contextlib.ExitStack, writer: ResultsWriter | None, outcomes: Sequence[JobOutcome]
    ) -> MetricsEngine:
        """Stage the jobs' statuses; the engine for batch metrics, which sees them before they are
        committed with the results (DuckDB backend; another backend gets them committed first)."""
        if writer is None:
            return self
        writer.stage_statuses(
            {
                outcome.job_id: {
                    "job_metrics_status": outcome.metrics_status,
                    "job_conflated_status": outcome.conflated_status,
                }
                for outcome in outcomes
            }
        )
        if not isinstance(self.engine.backend, DuckDBBackend):  # a Trino cluster reads only committed files
            writer.commit_statuses()
            return self
        engine = self.engine.with_pending(writer.pending)
        stack.callback(engine.close)
        return MetricsEngine(self.lake, engine, threads=self.threads)

    def _evaluate_job(
        self,
        branch: str,
        batch_id: str,
        job: tuple[str, str | None, str | None],
        metrics: Sequence[Metric],
        advance: Callable[[], None],
    ) -> JobOutcome:
        job_id, experience, job_status = job
        scope = Scope(batch_id=batch_id, job_id=job_id)
        logs = self.logs_dir(branch, batch_id, job_id)
        job_results = []
        for metric in metrics:
            job_results.append(self.evaluate(metric, branch, scope, logs_dir=logs))
            advance()
        metrics_status = worst(r.status for r in job_results)
        conflated = conflated_status(job_status, metrics_status)
        return JobOutcome(
            job_id=job_id,
            experience_name=experience,
            job_status=job_status,
            metrics_status=metrics_status,
            conflated_status=conflated,
            results=job_results,
            logs_dir=logs,
        )


def _quoted(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def _query_error(error: DialectError, sql: str, start: Location | None, which: str) -> MetricError:
    return MetricError(
        error.message, error.line, error.column, config_position(start, sql, error.line, error.column), which
    )


def _event_metric(item: dict[str, Any]) -> EventMetric:
    kind, value = item.get("type"), item.get("value")
    if kind in ("image", "plotly") and isinstance(value, str):
        try:
            value = json.loads(value)
        except ValueError:
            pass  # shown as the text it is
    if kind == "image" and isinstance(value, str):
        value = [value]
    return EventMetric(
        name=item.get("name") or "",
        type=kind or "",
        value=value,
        description=item.get("description"),
        status=item.get("status"),
    )
