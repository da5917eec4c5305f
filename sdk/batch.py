"""`Batch`: SignalFlag's light batch against a local lake.

    with Batch(branch="main", version="1.4.2", metrics_set_name="Nav Metrics",
               metrics_config_path=["topics.resim.yml", "metrics.resim.yml"], lake="lake") as batch:
        with Test(batch, "Warehouse loop") as test:
            test.emit("speed", {"v": 1.5}, timestamp=0)
    print(batch.status, batch.test_statuses)

Entering stores the merged config as the branch's current config (as SignalFlag's `Batch` syncs
it); each `Test` closed in the block is ingested as one job of the batch; leaving the block closes
the tests still open, evaluates the metrics set on the batch (test metrics on each job, then batch
metrics, results and statuses written to the lake as `lakegate metrics run` writes them) and
compacts the batch. With `fail_on_states`, a batch whose status is one of them raises
`FailedStatesError` carrying SignalFlag's exit code.
"""

from __future__ import annotations

import os
import threading
import uuid
from collections.abc import Iterable, Sequence
from contextlib import AbstractContextManager
from pathlib import Path
from types import TracebackType
from typing import Protocol

from lakegate.gateway.metrics.evaluation import BatchEvaluation, MetricsEngine, select_metrics
from lakegate.gateway.metrics.gating import fail_exit_code, parse_fail_on_states
from lakegate.lake import paths
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.compaction import compact_batch
from lakegate.lake.config import Config, config_path_list, expand_config_paths, load_config

#: SignalFlag's defaults (`.yml`; its `.yaml` twin is taken when only that exists).
DEFAULT_CONFIG_PATH = ".resim/metrics/config.resim.yml"
DEFAULT_TEMPLATES_PATH = ".resim/metrics/templates"


class BatchTest(Protocol):
    """What a batch needs of its tests (`lakegate.sdk.test.Test`)."""

    ingested: bool

    def close(self, status: str = ..., error: str | None = ...) -> None: ...


class FailedStatesError(Exception):
    """The batch ended in a state of `fail_on_states`; `exit_code` is SignalFlag's (7 BLOCKER, 2 ERROR, 8 WARNING)."""

    def __init__(self, batch_id: str, status: str, exit_code: int):
        self.batch_id, self.status, self.exit_code = batch_id, status, exit_code
        super().__init__(f"batch {batch_id!r} is {status} (exit code {exit_code})")


class Batch(AbstractContextManager):
    """A batch of tests on a branch of a local lake; evaluated when the `with` block ends.

    Arguments as SignalFlag's `Batch` (without `client`, `project_*`, `system` and `test_suite`, which
    name server objects): `branch`; `name` (a display name; the batch id is `batch_id`, default a new
    UUID, as SignalFlag assigns one); `version` (the build version of every test); `metrics_set_name`
    (the set evaluated at the end; None: nothing is evaluated); `metrics_config_path` (one config file
    or several, merged; None: the branch's stored config is used and nothing is stored);
    `templates_path` (a folder of custom `.liquid` templates, when it exists); plus `lake` (the lake's
    folder), `fail_on_states` (`"BLOCKER,WARNING"` or a list), `threads` (jobs evaluated at once) and
    `compact` (merge the batch's files afterwards, as `metrics run` does).
    """

    def __init__(
        self,
        branch: str,
        name: str | None = None,
        version: str | None = None,
        metrics_set_name: str | None = None,
        metrics_config_path: str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None = DEFAULT_CONFIG_PATH,
        templates_path: str | os.PathLike[str] | None = DEFAULT_TEMPLATES_PATH,
        *,
        lake: str | os.PathLike[str],
        batch_id: str | None = None,
        fail_on_states: str | Iterable[str] | None = None,
        threads: int = 2,
        compact: bool = True,
    ):
        paths.encode_branch(branch)
        self.branch = branch
        self.name = name
        self.version = version
        self.metrics_set_name = metrics_set_name
        self.metrics_config_path = metrics_config_path
        self.templates_path = templates_path
        self.lake = Path(lake)
        self.id = batch_id if batch_id is not None else str(uuid.uuid4())
        paths.check_segment(self.id, "batch id")
        self.fail_on_states = parse_fail_on_states(fail_on_states)
        self.threads = threads
        self.compact = compact
        #: The merged config, its files as stored in the lake, and its version there (set on entering).
        self.config: Config | None = None
        self.config_paths: list[Path] = []
        self.config_version: int | None = None
        #: The evaluation of the metrics set (set when the block ends and a set was named).
        self.evaluation: BatchEvaluation | None = None
        self._tests: list[BatchTest] = []
        self._lock = threading.Lock()
        self._state = "new"  # new -> open -> closed

    @property
    def friendly_name(self) -> str:
        return self.name or f"batch {self.id}"

    def __enter__(self) -> Batch:
        if self._state != "new":
            raise RuntimeError(f"batch {self.id!r} was entered already")
        registry = BranchConfigs(self.lake, self.branch)
        if self.metrics_config_path is not None:
            files = expand_config_paths(config_path_list(self.metrics_config_path))
            templates = self._templates_folder()
            self.config = load_config(files, templates_path=templates)
            self.config_version = registry.store(files, templates_path=templates)
        else:
            self.config_version = registry.current_version()
            if self.config_version is None:
                raise ValueError(
                    f"branch {self.branch!r} has no stored config in {self.lake}: pass metrics_config_path"
                )
            self.config = registry.load(self.config_version)
        self.config_paths = registry.files(self.config_version)
        if self.metrics_set_name is not None and self.metrics_set_name not in self.config.metrics_sets:
            select_metrics(self.config, self.metrics_set_name)  # raises KeyError naming the known sets
        self._state = "open"
        return self

    def _templates_folder(self) -> Path | None:
        if self.templates_path is None:
            return None
        folder = Path(self.templates_path)
        return folder if folder.is_dir() else None

    def add_test(self, test: BatchTest) -> None:
        """Register a test of this batch (called by `Test`); RuntimeError unless the batch is open."""
        with self._lock:
            if self._state != "open":
                raise RuntimeError(f"batch {self.id!r} is not open: create tests inside its `with` block")
            self._tests.append(test)

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc_value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        """Close the tests still open (as ERROR when the block raised), evaluate the metrics set, compact."""
        with self._lock:
            if self._state != "open":
                return
            self._state = "closed"
            tests = list(self._tests)
        errors = []
        for test in tests:
            try:
                if exc_value is not None:
                    test.close(status="ERROR", error=repr(exc_value))
                else:
                    test.close()
            except Exception as error:  # noqa: BLE001 - the first is raised once every test is closed
                errors.append(error)
        if errors and exc_type is None:
            raise errors[0]
        if self.metrics_set_name is not None and any(t.ingested for t in tests):
            self._evaluate()
        if exc_type is None and self.evaluation is not None:
            code = fail_exit_code(self.evaluation.status, self.fail_on_states)
            if code:
                raise FailedStatesError(self.id, self.evaluation.status, code)

    def _evaluate(self) -> None:
        assert self.config is not None
        metrics = select_metrics(self.config, self.metrics_set_name)
        with MetricsEngine(self.lake, threads=self.threads) as m:
            self.evaluation = m.evaluate_batch(
                self.branch,
                self.id,
                metrics,
                metrics_set=self.metrics_set_name,
                config_version=self.config_version,
                keep_figures=False,
            )
        if self.compact:
            compact_batch(self.lake, self.branch, self.id)

    @property
    def status(self) -> str | None:
        """The batch's status once evaluated (the worst of its batch metrics and its jobs' statuses)."""
        return None if self.evaluation is None else self.evaluation.status

    @property
    def job_statuses(self) -> dict[str, str]:
        """Each evaluated job's conflated status, by job id."""
        return {} if self.evaluation is None else {j.job_id: j.conflated_status for j in self.evaluation.jobs}

    @property
    def test_statuses(self) -> dict[str, str]:
        """Each evaluated test's conflated status, by test name (the job's experience name)."""
        return (
            {}
            if self.evaluation is None
            else {j.experience_name or j.job_id: j.conflated_status for j in self.evaluation.jobs}
        )

    @property
    def exit_code(self) -> int:
        """SignalFlag's exit code of this batch under `fail_on_states` (0 when nothing fails or before evaluation)."""
        return 0 if self.evaluation is None else fail_exit_code(self.evaluation.status, self.fail_on_states)
