"""`lakegate metrics sync` (store a branch's config), `lakegate metrics run` (evaluate a stored batch), and
`lakegate metrics dashboard` / `metrics report` (dashboard and report metrics over many batches).

Exit codes of `metrics run` (and of `metrics dashboard` / `metrics report`): 0 when nothing
blocks (warnings allowed); 2 when at least one metric is a BLOCKER; 3 when none blocks but a
metric errored or a job failed (ERROR); 1 for usage and config errors (nothing evaluated) and
when the results or the report cannot be written (a read-only or full disk; the lake keeps what
it had). With `--fail-on-states S,...` the exit code is SignalFlag's instead (`gating`): the
batch's status, if it is one of those states, gives 7 (BLOCKER), 2 (ERROR) or 8 (WARNING); any
other status gives 0. `metrics dashboard --fail-on regression`: 5 when nothing blocks or errs but a
trend alert fires (gateway/metrics/alerts.py). Malformed command lines are argparse's: usage on
standard error and exit code 2, like any argparse program.

`metrics validate` and `metrics config-schema` are SignalFlag's names for `config check` and
`config schema`.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from lakegate.dialect.errors import DialectError
from lakegate.gateway.cli import config as config_commands
from lakegate.gateway.cli.backends import engine_from_args
from lakegate.gateway.cli.command_errors import (
    UserError,
    existing_configs,
    os_error_text,
    print_config_warnings,
    writable_lake,
)
from lakegate.gateway.engine.trino_backend import TrinoBackend
from lakegate.gateway.engine.trino_registration import RegistrationError, jobs_seen, sync_local
from lakegate.gateway.metrics.alerts import TrendCheck, alerts_html, trend_checks
from lakegate.gateway.metrics.config_vs_lake import check_against_lake
from lakegate.gateway.metrics.evaluation import (
    BLOCKER,
    ERROR,
    SEVERITY,
    BatchEvaluation,
    MetricResult,
    MetricsEngine,
    check_batch_metrics,
    select_metrics,
)
from lakegate.gateway.metrics.gating import fail_exit_code
from lakegate.gateway.metrics.report import job_title, write_report
from lakegate.gateway.metrics.trends import (
    BatchInfo,
    TrendsEvaluation,
    Window,
    branch_batches,
    evaluate_trends,
    in_window,
    metrics_of,
    write_trends,
)
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.catalog import Catalog
from lakegate.lake.compaction import compact_batch
from lakegate.lake.config import Config, ConfigError, load_config
from lakegate.lake.paths import LakePathError
from lakegate.lake.record import StaleJobsError

EXIT_OK, EXIT_USAGE, EXIT_BLOCKER, EXIT_ERROR, EXIT_REGRESSION = 0, 1, 2, 3, 5


def _templates(args: argparse.Namespace) -> Path | None:
    """--templates-path, else SignalFlag's default folder when it exists; UserError for a missing folder."""
    if args.templates_path is not None:
        if not args.templates_path.is_dir():
            raise UserError(f"templates folder {str(args.templates_path)!r} does not exist")
        return args.templates_path
    default = Path(".resim/metrics/templates")
    return default if default.is_dir() else None


def print_config_problems(error: ConfigError) -> None:
    print(f"lakegate: the config has {len(error.problems)} problem(s):", file=sys.stderr)
    for problem in error.problems:
        print(f"  {problem}", file=sys.stderr)


def sync_command(args: argparse.Namespace) -> int:
    writable_lake(args.lake)
    paths = existing_configs(args.config_paths)
    templates = _templates(args)
    try:
        config = load_config(paths, strict=args.strict, templates_path=templates)
        print_config_warnings(config)
        registry = BranchConfigs(args.lake, args.branch)
        before = registry.current_version()
        version = registry.store(paths, templates_path=templates)
    except ConfigError as error:
        print_config_problems(error)
        return EXIT_USAGE
    except (LakePathError, OSError) as error:
        raise UserError(str(error)) from None
    state = "unchanged: the same as" if version == before else "stored as"
    print(f"branch {args.branch!r}: config {state} version {version} ({config.summary()})")
    return EXIT_OK


def validate_command(args: argparse.Namespace) -> int:
    """`metrics validate`: `config check` of the --metrics-config-path files, and with --lake and --branch
    a check against the branch's stored topics and tables."""
    if (args.lake is None) != (args.branch is None):
        raise UserError("--lake and --branch go together: give both to check the config against a lake's branch")
    if args.lake is not None:
        _check_branch_has_config(args.lake, args.branch)
    templates = _templates(args)
    paths = [str(p) for p in existing_configs(args.config_paths)]
    if templates is None and args.lake is None:
        return config_commands.check_command(argparse.Namespace(paths=paths, strict=args.strict))
    try:
        config = load_config(paths, strict=args.strict, templates_path=templates)
    except ConfigError as error:
        for problem in error.problems:
            print(problem)
        return EXIT_USAGE
    problems: list[Any] = []
    if templates is not None:  # a template folder given: check that every custom template is found
        problems += [
            f"{m.location}: template file {m.template_file!r} of metric '{m.name}' not found"
            for m in config.metrics.values()
            if m.template_file and m.template_path() is None
        ]
    if args.lake is not None:
        problems += check_against_lake(config, args.lake, args.branch)
    for problem in problems:
        print(problem)
    if problems:
        return EXIT_USAGE
    print_config_warnings(config)
    checked = [f"templates {templates}"] if templates is not None else []
    if args.lake is not None:
        checked.append(f"matches branch {args.branch!r} of lake {args.lake}")
    print(f"ok: {config.summary()} ({', '.join(paths)}; {'; '.join(checked)})")
    return EXIT_OK


def _check_branch_has_config(lake: Path, branch: str) -> None:
    """UserError unless `lake` is a lake whose `branch` has a stored config (made by ingest or `metrics sync`)."""
    if not lake.is_dir():
        raise UserError(f"no lake at {str(lake)!r}")
    try:
        registry = BranchConfigs(lake, branch)
        stored = registry.current_version()
    except (LakePathError, OSError) as error:
        raise UserError(str(error)) from None
    if stored is None:
        branches = Catalog(lake).branches()
        raise UserError(
            f"branch {branch!r} of lake {str(lake)!r} has no stored config (branches: "
            f"{', '.join(map(repr, branches)) or 'none'}); 'lakegate ingest' and 'lakegate metrics sync' store one"
        )


def _run_config(args: argparse.Namespace) -> tuple[Config, int | None]:
    """The config to evaluate and its stored version (None for a config given by path)."""
    if args.config_paths:
        config = load_config(existing_configs(args.config_paths), strict=args.strict, templates_path=_templates(args))
        print_config_warnings(config)
        return config, None
    registry = BranchConfigs(args.lake, args.branch)
    version = registry.current_version()
    if version is None:
        raise UserError(
            f"branch {args.branch!r} has no stored config: run 'lakegate metrics sync' or pass --metrics-config-path"
        )
    return registry.load(version), version


def exit_code(evaluation: BatchEvaluation, fail_on: frozenset[str] | None = None) -> int:
    """With `fail_on` (--fail-on-states): SignalFlag's code of the batch's status. Else 2 if any metric
    blocks, else 3 if anything errored (a metric or a failed job), else 0."""
    if fail_on:
        return fail_exit_code(evaluation.status, fail_on)
    if any(r.status == BLOCKER for r in evaluation.results()):
        return EXIT_BLOCKER
    return EXIT_ERROR if evaluation.status == ERROR else EXIT_OK


def _check_lake_and_report(args: argparse.Namespace) -> Catalog:
    """The lake's catalog; UserError when the lake or the branch does not exist, or --report is a folder."""
    if not args.lake.is_dir():
        raise UserError(f"no lake at {str(args.lake)!r}")
    if args.report is not None and args.report.is_dir():
        raise UserError(f"--report {str(args.report)!r} is a directory; name the HTML file to write")
    catalog = Catalog(args.lake)
    try:
        branches = catalog.branches()
    except LakePathError as error:
        raise UserError(str(error)) from None
    if args.branch not in branches:
        raise UserError(
            f"no branch {args.branch!r} in {args.lake} (branches: {', '.join(map(repr, branches)) or 'none'})"
        )
    return catalog


def run_command(args: argparse.Namespace) -> int:
    catalog = _check_lake_and_report(args)
    try:
        config, version = _run_config(args)
        metrics = select_metrics(config, args.metrics_set, all_metrics=args.all_metrics)
        check_batch_metrics(metrics, args.metrics_set)
        batches = catalog.batches(args.branch)
    except ConfigError as error:
        print_config_problems(error)
        return EXIT_USAGE
    except KeyError as error:
        raise UserError(str(error.args[0])) from None
    except (LakePathError, ValueError) as error:
        raise UserError(str(error)) from None
    if args.batch not in batches:
        raise UserError(
            f"no batch {args.batch!r} on branch {args.branch!r} (batches: "
            f"{', '.join(repr(b) for b in batches) or 'none'})"
        )
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    engine = engine_from_args(args, args.lake)
    try:
        if isinstance(engine.backend, TrinoBackend):
            _check_cluster_sees_batch(engine.backend, catalog, args)
        evaluation = MetricsEngine(args.lake, engine, threads=args.threads).evaluate_batch(
            args.branch,
            args.batch,
            metrics,
            metrics_set=args.metrics_set,
            config_version=version,
            progress=progress,
            keep_figures=args.report is not None,
        )
        if args.compact:  # the batch is complete once its batch metrics are evaluated
            compact_batch(args.lake, args.branch, args.batch, progress=progress)
        if isinstance(engine.backend, TrinoBackend):  # the batch's new metric_results partition
            sync_local(args.lake, engine.backend, args.branch)
    except (DialectError, RegistrationError, StaleJobsError) as error:
        raise UserError(str(error)) from None
    except OSError as error:
        raise UserError(f"cannot store the results in the lake: {os_error_text(error)}") from None
    finally:
        engine.close()
    for restart in evaluation.restarts:
        print(f"lakegate: {restart}: evaluated again", file=sys.stderr)
    _show(
        args,
        evaluation,
        format_table,
        lambda path: write_report(evaluation, path),
        " (the results are stored in the lake)",
    )
    return exit_code(evaluation, args.fail_on_states)


def _check_cluster_sees_batch(backend: TrinoBackend, catalog: Catalog, args: argparse.Namespace) -> None:
    """Sync the cluster's partitions of the branch when it lacks jobs of the batch and the lake's
    registration there reads the lake itself; UserError when it still lacks them: the metrics
    would silently read less than the lake has."""
    jobs = len(catalog.jobs(args.branch, args.batch))
    seen = jobs_seen(backend, args.branch, args.batch)
    if seen != jobs and sync_local(args.lake, backend, args.branch):
        seen = jobs_seen(backend, args.branch, args.batch)
    if seen != jobs:
        raise UserError(
            f"the Trino cluster at {backend.url} sees {seen} of the {jobs} job(s) of batch {args.batch!r}: "
            f"register the lake again (lakegate trino-ddl --lake {args.lake} --apply --trino-url {backend.url})"
        )


def _show(
    args: argparse.Namespace,
    evaluation: Any,
    table: Callable[[Any], str],
    write: Callable[[Path], Path],
    note: str = "",
) -> None:
    """Print `evaluation` as JSON or as `table` text, and write its page to --report if asked."""
    if args.format == "json":
        json.dump(evaluation.as_dict(), sys.stdout, ensure_ascii=False, indent=2)
        sys.stdout.write("\n")
    else:
        print(table(evaluation))
    if args.report is not None:
        try:
            path = write(args.report)
        except OSError as error:
            raise UserError(f"cannot write the report {str(args.report)!r}: {os_error_text(error)}{note}") from None
        print(f"report: {path.resolve()}", file=sys.stderr if args.format == "json" else sys.stdout)


def _trends_batches(args: argparse.Namespace, engine: MetricsEngine) -> list[BatchInfo]:
    """The batches a `metrics dashboard` (its window) or `metrics report` (those named) runs over."""
    known = branch_batches(engine, args.branch)
    if args.metrics_command == "dashboard":
        return in_window(known, args.window)
    by_id = {b.batch_id: b for b in known}
    missing = [name for name in args.batches if name not in by_id]
    if missing:
        raise UserError(
            f"no batch {', '.join(map(repr, missing))} on branch {args.branch!r} (batches: "
            f"{', '.join(repr(b.batch_id) for b in known) or 'none'})"
        )
    return [by_id[name] for name in args.batches]


def trends_command(args: argparse.Namespace) -> int:
    """`metrics dashboard` and `metrics report`: metrics of that type over many batches."""
    kind = args.metrics_command
    _check_lake_and_report(args)
    try:
        config, version = _run_config(args)
        if getattr(args, "name", None) is not None:
            if args.metrics_set is not None:
                raise UserError("--name and --metrics-set both choose the metrics: give one")
            dashboard = config.dashboard(args.name)
            args.metrics_set = dashboard.metrics_set
            if args.window is None and dashboard.day_range is not None:
                args.window = Window(days=dashboard.day_range)
        metrics = metrics_of(config, kind, args.metrics_set)
    except ConfigError as error:
        print_config_problems(error)
        return EXIT_USAGE
    except KeyError as error:
        raise UserError(str(error.args[0])) from None
    if not metrics:
        where = f"metrics set {args.metrics_set!r}" if args.metrics_set else "the config"
        raise UserError(f"{where} has no 'type: {kind}' metrics")
    queries = engine_from_args(args, args.lake)
    engine = MetricsEngine(args.lake, queries)
    try:
        batches = _trends_batches(args, engine)
        evaluation = evaluate_trends(
            engine,
            args.branch,
            metrics,
            batches,
            kind=kind,
            window=getattr(args, "window", None),
            config_version=version,
        )
        checks = (
            trend_checks(engine, args.branch, [b.batch_id for b in batches], k=args.alert_k, history=args.alert_builds)
            if kind == "dashboard"
            else []
        )
    except (DialectError, LakePathError) as error:
        raise UserError(str(error)) from None
    finally:
        queries.close()
    shown = _WithAlerts(evaluation, checks) if kind == "dashboard" else evaluation
    _show(
        args,
        shown,
        lambda _: format_trends(evaluation) + format_alerts(checks),
        lambda path: write_trends(evaluation, path, link_base=args.link_base, intro=alerts_html(checks)),
    )
    if args.fail_on_states:
        return fail_exit_code(evaluation.status, args.fail_on_states)
    if any(r.status == BLOCKER for r in evaluation.results):
        return EXIT_BLOCKER
    if evaluation.status == ERROR:
        return EXIT_ERROR
    if getattr(args, "fail_on", None) == "regression" and any(c.alert for c in checks):
        return EXIT_REGRESSION
    return EXIT_OK


class _WithAlerts:
    """A dashboard evaluation and its trend checks, as `--format json` shows them."""

    def __init__(self, evaluation: TrendsEvaluation, checks: list[TrendCheck]):
        self.evaluation, self.checks = evaluation, checks

    def as_dict(self) -> dict[str, Any]:
        return {**self.evaluation.as_dict(), "trend_checks": [c.as_dict() for c in self.checks]}


def format_alerts(checks: list[TrendCheck]) -> str:
    """The trend alerts as text lines after the dashboard's table ("" when no metric has 2 earlier builds)."""
    if not checks:
        return ""
    alerts = [c for c in checks if c.alert]
    lines = [f"trend alerts: {len(alerts)} of {len(checks)} scalar metrics moved beyond their history"]
    lines += [f"  ALERT {c}" for c in alerts]
    return "\n" + "\n".join(lines)


def format_trends(evaluation: TrendsEvaluation) -> str:
    """The results as aligned text: one row per metric (status and value), then a summary line."""
    rows = [(r.status, r.metric, _value(r)) for r in evaluation.results]
    header = ("STATUS", "METRIC", "VALUE")
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(2)]
    lines = [
        "  ".join(cell.ljust(width) for cell, width in zip(row[:2], widths)) + "  " + row[2] for row in [header, *rows]
    ]
    version = f"config version {evaluation.config_version}" if evaluation.config_version else "config not stored"
    lines.append("")
    lines.append(
        f"{evaluation.kind} of branch {evaluation.branch!r}: {evaluation.status} ({len(evaluation.results)} "
        f"metrics over {len(evaluation.batches)} batches, {evaluation.which_batches}: "
        f"{', '.join(b.batch_id for b in evaluation.batches) or 'none'}; {version}; {evaluation.seconds:.1f} s)"
    )
    return "\n".join(line.rstrip() for line in lines)


def _value(result: MetricResult) -> str:
    """The result's one-line summary (the same in JSON, the report and the dashboard), with its problems."""
    if result.error is not None:
        return str(result.error)
    text = result.value_text or ""
    if result.rendered is not None and result.rendered.problems:
        text += f" ({'; '.join(result.rendered.problems)})"
    return text


def format_table(evaluation: BatchEvaluation) -> str:
    """The results as aligned text: one row per job x metric (status and value), then the batch metrics."""
    rows: list[tuple[str, str, str, str]] = []
    for job in evaluation.jobs:
        label = f"{job_title(job)} {job.conflated_status}"
        for i, result in enumerate(job.results):
            rows.append((label if i == 0 else "", result.status, result.metric, _value(result)))
        if not job.results:
            rows.append((label, "", "(no test metrics)", ""))
    for i, result in enumerate(evaluation.batch_results):
        rows.append(
            (f"batch {evaluation.batch_metrics_status}" if i == 0 else "", result.status, result.metric, _value(result))
        )
    header = ("JOB", "STATUS", "METRIC", "VALUE")
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(3)]
    lines = [
        "  ".join(cell.ljust(width) for cell, width in zip(row[:3], widths)) + "  " + row[3] for row in [header, *rows]
    ]
    counts: dict[str, int] = {}
    for job in evaluation.jobs:
        counts[job.conflated_status] = counts.get(job.conflated_status, 0) + 1
    jobs = ", ".join(f"{counts[status]} {status}" for status in sorted(counts, key=SEVERITY.__getitem__))
    metric_set = f"metrics set {evaluation.metrics_set!r}" if evaluation.metrics_set else "all metrics"
    version = f"config version {evaluation.config_version}" if evaluation.config_version else "config not stored"
    lines.append("")
    lines.append(
        f"batch {evaluation.batch_id!r} on branch {evaluation.branch!r}: {evaluation.status} "
        f"({len(evaluation.jobs)} jobs: {jobs}; {len(evaluation.results())} metric results; "
        f"{metric_set}, {version}; {evaluation.seconds:.1f} s)"
    )
    return "\n".join(line.rstrip() for line in lines)
