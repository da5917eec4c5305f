"""`lakegate metrics debug`: ingest one emissions file as a debug job and serve the dashboard on it.

    lakegate metrics debug --emissions-file emissions.resim.jsonl \\
        --metrics-config-path .resim/metrics/config.resim.yaml --metrics-set "My Metrics"

The file is ingested as the only job of a new batch (`debug-<time>`) on branch `debug` of a
scratch lake (a temporary folder, removed on exit) or of `--lake DIR`. The job's log files
(the images image metrics name) are `--logs-dir`, else the `logs` folder beside the emissions
file, else only the files beside it that the emissions name in `image` fields and image event
metrics (copied into the lake: the rest of that folder is never served). The dashboard is served
on 127.0.0.1 (Host and Origin checked, see `host_check`) until Ctrl+C; its URL is printed
as `Dashboard: http://127.0.0.1:PORT/dashboard/?session=...`. When the config file changes,
reloading the page shows the new config (and ingests the emissions again if its topics or the
emissions file changed); edits made in the page stay layered on top.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import json
import os
import shutil
import signal
import socket
import sys
import tempfile
import uuid
import webbrowser
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from lakegate.gateway.cli.command_errors import (
    UserError,
    existing_configs,
    print_config_warnings,
)
from lakegate.gateway.server.auth import is_loopback
from lakegate.lake import paths
from lakegate.lake.config import Config, ConfigError, load_config
from lakegate.lake.ingest import IngestError, ingest_job
from lakegate.lake.metadata import MetadataError, load_metadata_file
from lakegate.lake.paths import LakePathError
from lakegate.lake.storage import LakeStorage

#: Seconds open requests get to finish once the server is stopped.
SHUTDOWN_SECONDS = 3


def _one_line(error: ConfigError) -> str:
    more = len(error.problems) - 1
    extra = f" (and {more} more problem{'s' if more > 1 else ''}; see 'lakegate config check')" if more else ""
    return f"invalid config: {error.problems[0]}{extra}"


def referenced_files(emissions: Path, config: Config) -> set[str]:
    """The file names the emissions give in `image` fields and in image metrics of events."""
    images = {t.name: [f for f, kind in t.fields.items() if kind == "image"] for t in config.topics.values()}
    metrics = {t.name: [f for f, kind in t.fields.items() if kind == "metric[]"] for t in config.topics.values()}
    names: set[str] = set()
    with emissions.open(encoding="utf-8", errors="replace") as lines:
        for line in lines:
            try:
                record = json.loads(line)
                topic, data = record["$metadata"]["topic"], dict(record["$data"])
            except (ValueError, TypeError, KeyError):
                continue  # ingest reports bad lines
            values = [data.get(f) for f in images.get(topic, ())]
            for item in (m for f in metrics.get(topic, ()) for m in data.get(f) or () if isinstance(m, dict)):
                if item.get("type") == "image":
                    value = item.get("value")
                    values.extend(value if isinstance(value, list) else [value])
            names.update(v for v in values if isinstance(v, str))
    return names


def copy_referenced(source: Path, names: set[str], storage: LakeStorage, target: Path) -> None:
    """Copy the files `names` of folder `source` (only those inside it) to `target` in the lake, replacing it."""
    storage.delete_tree(target)
    storage.make_dirs(target)
    root = source.resolve()
    for name in sorted(n for n in names if "\0" not in n):
        path = (root / name).resolve()
        if path.is_relative_to(root) and path != root and path.is_file():
            storage.put(path, target / path.relative_to(root))


class DebugJob:
    """The debug job: its emissions file ingested into the lake, again whenever the file or the
    config's topics change (`refresh`, called by the session on every reload). Without `logs_dir`,
    its logs are the files beside the emissions file that they reference (`referenced_files`)."""

    def __init__(self, lake: Path, branch: str, emissions: Path, logs_dir: Path | None, metadata: dict[str, Any]):
        self.lake, self.branch, self.emissions = lake, branch, emissions
        self.logs_dir, self.metadata = logs_dir, metadata
        self.batch_id = "debug-" + dt.datetime.now().strftime("%Y%m%d-%H%M%S") + "-" + uuid.uuid4().hex[:4]
        self.job_id = str(uuid.uuid4())
        self._ingested: object = None

    def _stamp(self, config: Config) -> object:
        topics = sorted((t.name, t.event, tuple(t.fields.items())) for t in config.topics.values())
        try:
            stat = self.emissions.stat()
            return topics, stat.st_mtime_ns, stat.st_size
        except OSError:
            return topics, None, None

    def ingest(self, config: Config) -> int:
        """Ingest the emissions file (replacing the job); returns the rows written. ValueError if it fails."""
        stamp = self._stamp(config)
        try:
            report = ingest_job(
                self.lake,
                self.branch,
                self.batch_id,
                self.job_id,
                [self.emissions],
                config=config,
                metadata=self.metadata,
            )
        except IngestError as error:
            if error.problems:
                more = error.total - 1
                raise ValueError(
                    f"bad emissions file: {error.problems[0]}"
                    + (f" (and {more} more bad line{'s' if more > 1 else ''})" if more else "")
                ) from None
            raise ValueError(error.summary) from None
        except MetadataError as error:
            raise ValueError(f"bad metadata: {error.problems[0]}") from None
        self._ingested = stamp
        logs = paths.logs_dir(self.lake, self.branch, self.batch_id, self.job_id)
        storage = LakeStorage(self.lake)
        if self.logs_dir is None:
            copy_referenced(self.emissions.parent, referenced_files(self.emissions, config), storage, logs)
        elif not storage.exists(logs):
            storage.make_dirs(logs.parent)
            try:
                storage.symlink(logs, self.logs_dir.resolve())
            except OSError:
                storage.put(self.logs_dir, logs)
        return sum(report.rows.values())

    def refresh(self, config: Config) -> bool:
        """Ingest again if the emissions file or the config's topics changed; True if it did."""
        if self._stamp(config) == self._ingested:
            return False
        self.ingest(config)
        return True


def _logs_dir(args: argparse.Namespace) -> Path | None:
    if args.logs_dir is not None:
        if not args.logs_dir.is_dir():
            raise UserError(f"logs folder {str(args.logs_dir)!r} does not exist")
        return args.logs_dir
    beside = args.emissions_file.parent / "logs"
    return beside if beside.is_dir() else None


def _listen(host: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as error:
        sock.close()
        raise UserError(f"cannot listen on {host}:{port}: {error.strerror or error}") from None
    sock.listen(128)
    return sock


def _can_open_browser() -> bool:
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def debug_command(args: argparse.Namespace) -> int:
    # the web stack is imported here, so that other commands start without it
    from lakegate.gateway.dashboard.config_edits import FileConfig, SessionError
    from lakegate.gateway.dashboard.debug_session import DashboardSession
    from lakegate.gateway.dashboard.landing import pages_router
    from lakegate.gateway.dashboard.routes import DashboardState
    from lakegate.gateway.engine.engine import Engine
    from lakegate.gateway.server.app import create_app

    if not is_loopback(args.host):
        raise UserError(
            f"refusing to serve the dashboard on {args.host}: it has no authentication; listen on a "
            "loopback address such as 127.0.0.1"
        )
    emissions = args.emissions_file
    if not emissions.is_file():
        raise UserError(f"emissions file {str(emissions)!r} does not exist or is not a file")
    config_paths = [path.resolve() for path in existing_configs(args.config_paths)]
    try:
        config = load_config(config_paths, strict=args.strict)
    except ConfigError as error:
        raise UserError(_one_line(error)) from None
    print_config_warnings(config)
    if args.metrics_set is not None:
        try:
            config.metrics_in_set(args.metrics_set)
        except KeyError as error:
            raise UserError(str(error.args[0])) from None
    try:
        metadata = load_metadata_file(args.metadata) if args.metadata else {}
    except (MetadataError, OSError) as error:
        raise UserError(f"bad metadata file: {str(error).splitlines()[0]}") from None
    metadata.setdefault("experience_name", emissions.resolve().parent.name or "debug")
    logs_dir = _logs_dir(args)
    scratch = None if args.lake is not None else Path(tempfile.mkdtemp(prefix="lakegate-debug-"))
    lake = (args.lake if args.lake is not None else scratch / "lake").resolve()
    sock = None
    state = None
    # SIGTERM ends the command as Ctrl+C does while the job is prepared, so the scratch lake is
    # removed either way; once serving, both just stop the server (`_stop_on_signals`).
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        job = DebugJob(lake, args.branch, emissions.resolve(), logs_dir, metadata)
        try:
            rows = job.ingest(config)
        except (ValueError, LakePathError) as error:
            raise UserError(str(error)) from None
        state = DashboardState(lake, Engine.open(lake, isolated=True))
        try:
            session = DashboardSession(
                state.new_id(),
                state.evaluator,
                branch=args.branch,
                batch_id=job.batch_id,
                source=FileConfig(config_paths),
                metrics_set=args.metrics_set,
                debug=True,
                refresh_data=job.refresh,
            )
        except SessionError as error:
            raise UserError(str(error.problems[0] if error.problems else error)) from None
        state.add(session, debug=True)
        sock = _listen(args.host, args.port)
        host, port = sock.getsockname()[:2]
        shown_host = f"[{host}]" if ":" in host else host
        url = f"http://{shown_host}:{port}/dashboard/?session={session.id}"
        results = [r for per_job in session.results.values() for r in per_job.values()]
        counts = {s: sum(1 for r in results if r["status"] == s) for s in ("PASSED", "WARNING", "BLOCKER", "ERROR")}
        print(
            f"ingested {emissions} as job {job.job_id} of batch {job.batch_id} on branch {args.branch!r} "
            f"({rows:,} rows) in {'a scratch lake' if scratch else 'the lake'} {lake}"
        )
        print(
            f"metrics set {args.metrics_set or '(all metrics)'}: {len(results)} evaluated ("
            + ", ".join(f"{n} {s}" for s, n in counts.items() if n)
            + f") in {session.seconds:.2f} s"
        )
        server = _server(create_app(state.engine, dashboard_router=pages_router(state)))
        with _stop_on_signals(server):  # from here on Ctrl+C and SIGTERM stop the server, never interrupt
            print(
                f"SQL endpoint (Trino protocol): http://{shown_host}:{port} (catalog lake, schema {args.branch!r})",
                flush=True,
            )
            print(f"Dashboard: {url}", flush=True)
            print("Press Ctrl+C to stop.", flush=True)
            if not args.no_browser and _can_open_browser():
                webbrowser.open(url)
            server.run(sockets=[sock])
    finally:
        signal.signal(signal.SIGTERM, previous)
        if sock is not None:
            sock.close()
        if state is not None:
            state.close()
            state.engine.close()
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)
    return 0


def _server(app: Any) -> Any:
    """A uvicorn server for `app` that gives open requests at most SHUTDOWN_SECONDS once stopped."""
    import uvicorn

    from lakegate.gateway.engine.limits import Limits
    from lakegate.gateway.server.http_limits import server_config

    return uvicorn.Server(server_config(app, Limits(), timeout_graceful_shutdown=SHUTDOWN_SECONDS))


@contextlib.contextmanager
def _stop_on_signals(server: Any) -> Iterator[None]:
    """SIGINT and SIGTERM make `server` stop (uvicorn takes them over while it runs, and raises them
    again when it has stopped: they land here too), instead of raising in the middle of whatever runs."""

    def stop(signum: int, frame: Any) -> None:
        server.should_exit = True

    previous = {sig: signal.signal(sig, stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt
