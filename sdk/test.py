"""`Test`: one job of a `Batch`, an `Emitter` that is ingested into the lake when it closes.

As SignalFlag's `Test`, without the API client: `Test(batch, name)`; `emit`, `emit_series` and
`emit_event` as the `Emitter`'s; `attach_log(path, file_name=None)` adds a file to the job's logs
(copied at once, so the file may change or go afterwards); closing (the end of its `with` block,
`close()`, or the batch's end) ingests the emissions as one job of the batch, named by its test
(`experience_name`), with the batch's build version, and makes the attached files its logs in the
same commit. An exception in the block makes the job's status ERROR (its raw `job_status` FAILED),
adds the traceback to its logs as `stacktrace.log`, and still ingests what was emitted.

Threads may share a Test (emits and `attach_log` from any thread; close it once they are done);
forked children emit into it as into an `Emitter`, and only the process that created it ingests.
"""

from __future__ import annotations

import datetime as dt
import os
import tempfile
import threading
import traceback
import uuid
from pathlib import Path, PurePath
from types import TracebackType
from typing import Any

from lakegate.lake.emitter import Emitter
from lakegate.lake.ingest import IngestReport, ingest_job
from lakegate.lake.storage import LOCAL
from lakegate.sdk.batch import Batch

#: SignalFlag's job statuses, and the raw `job_status` each is stored as.
JOB_STATUSES = {"SUCCEEDED": "SUCCEEDED", "ERROR": "FAILED", "FAILED": "FAILED"}
STACKTRACE_LOG = "stacktrace.log"


class Test(Emitter):
    """One test (a job) of `batch`, named `name`; `metadata` adds columns of the job's metadata row
    (experience_tag_names, build_name ...)."""

    __test__ = False  # not a pytest test class

    def __init__(self, batch: Batch, name: str, *, metadata: dict[str, Any] | None = None):
        self._job_closed = True  # until the job exists, so that close() and __del__ do nothing
        if not isinstance(name, str) or not name:
            raise ValueError(f"a test needs a name, got {name!r}")
        batch.add_test(self)
        self.batch = batch
        self.name = name
        self.job_id = str(uuid.uuid4())
        self.metadata = dict(metadata or {})
        self.report: IngestReport | None = None
        self._pid = os.getpid()
        self._close_lock = threading.Lock()
        self._scratch = Path(tempfile.mkdtemp(prefix="lakegate-test-"))
        self._logs = self._scratch / "logs"
        LOCAL.make_dirs(self._logs)
        try:
            super().__init__(config_path=batch.config_paths, output_path=self._scratch / "emissions.resim.jsonl")
        except BaseException:
            LOCAL.delete_tree(self._scratch)
            raise
        self._job_closed = False

    @property
    def ingested(self) -> bool:
        """Whether the test was closed and its job is in the lake."""
        return self.report is not None

    @property
    def status(self) -> str | None:
        """The job's conflated status once the batch is evaluated."""
        return self.batch.job_statuses.get(self.job_id)

    def attach_log(
        self,
        file_path: str | os.PathLike[str],
        log_type: Any = None,
        file_name: str | None = None,
        *,
        wait: bool = False,
    ) -> None:
        """Add a file to the job's logs as `file_name` (default: its own name); a later file of the same
        name replaces it. The file is copied now (`log_type` and `wait` are accepted for SignalFlag's
        signature: every log is a file of the job's logs folder, and the copy is always made at once)."""
        source = Path(file_path)
        if not source.is_file():
            raise FileNotFoundError(f"log file {str(source)!r} does not exist or is not a file")
        name = source.name if file_name is None else file_name
        if not name or PurePath(name).name != name or name in (".", ".."):
            raise ValueError(f"log file name {name!r} must be a plain file name (no folder)")
        with self._close_lock:
            if self._job_closed:
                raise ValueError(f"test {self.name!r} is closed")
            LOCAL.put(source, self._logs / name)

    def attach_system_log(
        self, file_path: str | os.PathLike[str], file_name: str | None = None, *, wait: bool = False
    ) -> None:
        """As `attach_log` (SignalFlag keeps system logs apart; here they are files of the job's logs too)."""
        self.attach_log(file_path, file_name=file_name, wait=wait)

    def __enter__(self) -> Test:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc_value: BaseException | None, tb: TracebackType | None
    ) -> None:
        """Close the test: ERROR, with the traceback in its logs, when the block raised."""
        if exc_type is None:
            self.close()
            return
        if os.getpid() == self._pid and not self._job_closed:
            text = "".join(traceback.format_exception(exc_type, exc_value, tb))
            LOCAL.write_text(self._logs / STACKTRACE_LOG, text)
        self.close(status="ERROR", error=repr(exc_value))

    def close(self, status: str = "SUCCEEDED", error: str | None = None) -> None:
        """Write the emissions and ingest them, with the attached logs, as the test's job (once; later
        calls, and calls in other processes than the test's, only close the emissions file).

        `status`: SUCCEEDED, or ERROR (the job's raw status is then FAILED: its conflated status ERROR).
        `error` is kept for SignalFlag's signature (the traceback of a failed block is in the logs)."""
        if getattr(self, "_close_lock", None) is None:  # __init__ failed before the job existed
            return
        job_status = JOB_STATUSES.get(str(status).upper())
        if job_status is None:
            raise ValueError(f"unknown test status {status!r}; expected SUCCEEDED or ERROR")
        with self._close_lock:
            mine = os.getpid() == self._pid
            if self._job_closed or not mine:
                Emitter.close(self)
                return
            self._job_closed = True
        try:
            Emitter.close(self)
            metadata = {
                "experience_name": self.name,
                "branch_name": self.batch.branch,
                "time": dt.datetime.now(dt.UTC).replace(tzinfo=None),
                **({"build_version": self.batch.version} if self.batch.version else {}),
                **self.metadata,
                "job_status": job_status,
            }
            assert self.batch.config is not None
            self.report = ingest_job(
                self.batch.lake,
                self.batch.branch,
                self.batch.id,
                self.job_id,
                [self.output_path],
                config=self.batch.config,
                metadata=metadata,
                logs=self._logs,
            )
        finally:
            LOCAL.delete_tree(self._scratch)
