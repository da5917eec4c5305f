"""Shared fixtures of the gateway tests.

Debug dashboard (`nav_jobs`, `run_lakegate`, `debug_processes`): a generated navigation batch of
three jobs with the fixture config, the `lakegate` CLI as a subprocess, and running
`lakegate metrics debug` processes stopped with Ctrl+C (SIGINT).

SQL endpoint (`server_lake`, `start_server`, `lake_server`): a small real lake and real
`lakegate serve` processes on 127.0.0.1 (a free port each), stopped cleanly at the end of the
session. The lake: branch `main` holds a generated navigation batch (fixtures/generate.py): jobs 0 and 1
in batch `b1`, job 2 in batch `b2`. Branch `feature/all-types` holds one topic, `sample`, with a
field of every topic type (two rows, values in ALL_TYPES_ROWS) in batch `b1`, job `j1`.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import uvicorn

from lakegate.fixtures.generate import CONFIG_PATH, GeneratedJob, generate_batch
from lakegate.lake.config import load_config
from lakegate.lake.ingest import ingest_job
from lakegate.lake.metadata import load_metadata_file

CLI = [sys.executable, "-m", "lakegate.gateway.cli"]


class Output:
    """The lines a subprocess prints on its standard output, read by a thread until it closes (so
    the pipe never fills up)."""

    def __init__(self, process: subprocess.Popen):
        self.lines: list[str] = []
        self._changed = threading.Condition()
        self._closed = False
        threading.Thread(target=self._read, args=(process.stdout,), daemon=True).start()

    def _read(self, stream) -> None:
        for line in stream:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                self._changed.notify_all()
        with self._changed:
            self._closed = True
            self._changed.notify_all()

    def wait_for(self, prefix: str, timeout: float) -> str | None:
        """The first line containing `prefix`, waiting up to `timeout` seconds (None: not printed)."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                line = next((line for line in self.lines if prefix in line), None)
                remaining = deadline - time.monotonic()
                if line is not None or self._closed or remaining <= 0:
                    return line
                self._changed.wait(remaining)


# --- debug dashboard ----------------------------------------------------------------------------


@dataclass
class NavJobs:
    """Generated jobs (job 0 PASSED, 1 WARNING, 2 BLOCKER under the fixture metrics) and a copy of
    the fixture config."""

    jobs: list[GeneratedJob]
    config: Path


@pytest.fixture(scope="session")
def nav_jobs(tmp_path_factory) -> NavJobs:
    root = tmp_path_factory.mktemp("nav")
    jobs = generate_batch(root / "jobs", jobs=3)
    config = root / "config.resim.yaml"
    config.write_text(CONFIG_PATH.read_text())
    shutil.copytree(CONFIG_PATH.parent / "templates", root / "templates")  # its custom template
    return NavJobs(jobs, config)


@pytest.fixture
def run_lakegate() -> Callable[[list[str], Path], subprocess.CompletedProcess]:
    """Run `lakegate ARGS` in `cwd` as a subprocess and return its completed process (text output)."""

    def run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
        return subprocess.run([*CLI, *args], cwd=cwd, capture_output=True, text=True, timeout=300)

    return run


@dataclass
class DebugProcess:
    """A running `lakegate metrics debug`: its dashboard URL and the lines it printed until then."""

    process: subprocess.Popen
    url: str
    lines: list[str]

    def stop(self) -> int:
        """Ctrl+C (SIGINT), then the exit code (killed if it does not stop in time)."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        return self.process.returncode


@pytest.fixture
def debug_processes() -> Callable[[list[str], Path], DebugProcess]:
    """Start `lakegate metrics debug --no-browser ARGS` in `cwd` and wait for its `Dashboard: URL`
    line; every process started is stopped after the test."""
    started: list[DebugProcess] = []

    def start(args: list[str], cwd: Path, timeout: float = 120) -> DebugProcess:
        process = subprocess.Popen(
            [*CLI, "metrics", "debug", "--no-browser", *args],
            cwd=cwd,
            text=True,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        )
        output = Output(process)
        line = output.wait_for("Dashboard: ", timeout)
        if line is None:
            process.kill()
            process.wait()
            raise RuntimeError("lakegate metrics debug did not start:\n" + "\n".join(output.lines))
        debug = DebugProcess(process, line.split(" ", 1)[1].strip(), output.lines)
        started.append(debug)
        return debug

    yield start
    for debug in started:
        debug.stop()


# --- SQL endpoint -------------------------------------------------------------------------------

ALL_TYPES_BRANCH = "feature/all-types"
ALL_TYPES_CONFIG = """\
version: 1
topics:
  sample:
    schema: {flag: boolean, n: int, x: float, s: string, st: status, img: image, tags: "string[]", metrics: "metric[]"}
"""
ALL_TYPES_ROWS = [
    {
        "flag": True,
        "n": 2**62,
        "x": 1.5,
        "s": "héllo, wörld",
        "st": "PASSED",
        "img": "a.png",
        "tags": ["a", "b"],
        "metrics": [{"name": "m", "type": "scalar", "value": "1.5", "status": "PASSED"}],
    },
    {"flag": False, "n": -1, "x": -0.25, "s": "", "st": "BLOCKER", "img": "b.png", "tags": [], "metrics": []},
]
#: (batch, job index in the generated batch) of branch main.
MAIN_JOBS = (("b1", 0), ("b1", 1), ("b2", 2))
#: A query that keeps DuckDB busy for far longer than any test runs (10^12 rows, no output).
ENDLESS = (
    "SELECT count(*) FROM UNNEST(sequence(1, 10000)) AS a(x) CROSS JOIN UNNEST(sequence(1, 10000)) AS b(y) "
    "CROSS JOIN UNNEST(sequence(1, 10000)) AS c(z) WHERE a.x + b.y + c.z = 7"
)


def build_server_lake(root: Path) -> Path:
    """The lake the server tests read (see the module docstring)."""
    lake = root / "lake"
    generated = generate_batch(root / "generated", jobs=len(MAIN_JOBS), samples_per_goal=5)
    config = load_config([CONFIG_PATH])
    for (batch, _index), job in zip(MAIN_JOBS, [generated[i] for _, i in MAIN_JOBS]):
        ingest_job(
            lake,
            "main",
            batch,
            job.job_id,
            [job.emissions_path],
            config=config,
            metadata=load_metadata_file(job.metadata_path),
            logs=job.logs_dir,
        )
    config_file = root / "all-types.resim.yaml"
    config_file.write_text(ALL_TYPES_CONFIG)
    emissions = root / "all-types.jsonl"
    emissions.write_text(
        "".join(
            json.dumps({"$metadata": {"topic": "sample", "timestamp": i}, "$data": row}) + "\n"
            for i, row in enumerate(ALL_TYPES_ROWS)
        )
    )
    ingest_job(
        lake,
        ALL_TYPES_BRANCH,
        "b1",
        "j1",
        [emissions],
        config=load_config([config_file]),
        metadata={"experience_name": "all types"},
    )
    return lake


@dataclass
class Server:
    """One running `lakegate serve` process."""

    process: subprocess.Popen
    url: str
    log: Path
    args: list[str] = field(default_factory=list)

    @property
    def host(self) -> str:
        return "127.0.0.1"

    @property
    def port(self) -> int:
        return int(self.url.rsplit(":", 1)[1])

    def stop(self) -> int:
        """SIGTERM, then the exit code (the process is killed if it does not stop in time)."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        return self.process.returncode


def serve(lake: Path, log: Path, *args: str, timeout: float = 60) -> Server:
    """Start `lakegate serve --lake LAKE --port 0 ARGS` and wait for its `serving ... at URL` line."""
    command = [*CLI, "serve", "--lake", str(lake), "--port", "0", *args]
    with open(log, "w") as stderr:
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=stderr, text=True)
    line = Output(process).wait_for(" at ", timeout)
    if line is None:
        process.kill()
        process.wait()
        raise RuntimeError(f"lakegate serve did not start: {log.read_text()}")
    return Server(process, line.split(" at ", 1)[1].split()[0], log, list(args))


@pytest.fixture(scope="session")
def endless() -> str:
    """ENDLESS: a query that keeps DuckDB busy for far longer than any test runs."""
    return ENDLESS


@pytest.fixture(scope="session")
def all_types() -> tuple[str, list[dict]]:
    """The branch with a field of every topic type, and the rows of its `sample` topic."""
    return ALL_TYPES_BRANCH, ALL_TYPES_ROWS


@pytest.fixture(scope="session")
def server_lake(tmp_path_factory) -> Path:
    return build_server_lake(tmp_path_factory.mktemp("server-lake"))


@pytest.fixture(scope="session")
def start_server(server_lake, tmp_path_factory) -> Callable[..., Server]:
    """Start a server on the test lake with extra `lakegate serve` arguments; every server started
    is stopped at the end of the session, and must exit cleanly (code 0)."""
    servers: list[Server] = []

    def start(*args: str) -> Server:
        log = tmp_path_factory.mktemp("server-log") / "stderr.log"
        server = serve(server_lake, log, *args)
        servers.append(server)
        return server

    yield start
    codes = {server.url: server.stop() for server in servers}
    unclean = {url: code for url, code in codes.items() if code != 0}
    assert not unclean, f"servers that did not stop cleanly: {unclean}"


@pytest.fixture(scope="session")
def lake_server(start_server) -> Server:
    """The shared server: default limits, 4 concurrent queries."""
    return start_server("--max-concurrent-queries", "4")


def write_self_signed_certificate(folder: Path, name: str = "lakegate test") -> tuple[Path, Path]:
    """A self-signed certificate for 127.0.0.1 (usable as its own CA bundle) and its key, as PEM files."""
    import datetime as dt
    import ipaddress

    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    now = dt.datetime.now(dt.UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(days=1))
        .not_valid_after(now + dt.timedelta(days=1))
        .add_extension(x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]), critical=False)
        .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
        .sign(key, hashes.SHA256())
    )
    cert_file, key_file = folder / "cert.pem", folder / "key.pem"
    cert_file.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    key_file.write_bytes(
        key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption())
    )
    return cert_file, key_file


@pytest.fixture(scope="session")
def make_certificate() -> Callable[..., tuple[Path, Path]]:
    """`write_self_signed_certificate(folder, name)`, for the TLS tests."""
    return write_self_signed_certificate


# --- Java clients (the official Trino JDBC driver and CLI) --------------------------------------


def _needs(what: str, fix: str, error: str) -> None:
    """Fail under CI=true (the machine must provide `what`), else skip with the command that fixes it."""
    if os.environ.get("CI") == "true":
        pytest.fail(f"CI needs {what}: {error}")
    pytest.skip(f"needs {what}: {fix}")


@pytest.fixture(scope="session")
def jdk() -> Path:
    """A JDK with javac: the one Trino runs on (tools/trino_server.py java_home(), 24 or newer),
    else the newest under /usr/lib/jvm (17 is enough for the driver)."""
    import trino_server

    try:
        home = trino_server.java_home()
    except trino_server.TrinoError as error:
        home, reason = None, str(error)
    else:
        reason = f"{home} has no javac"
    if home is not None and (home / "bin" / "javac").exists():
        return home
    jvm = Path("/usr/lib/jvm")
    for candidate in sorted(jvm.iterdir(), reverse=True) if jvm.is_dir() else []:
        if (candidate / "bin" / "javac").exists():
            return candidate
    _needs("a JDK (javac)", "apt-get install openjdk-17-jdk-headless", reason)


@pytest.fixture(scope="session")
def trino_jar() -> Callable[[str], Path]:
    """`trino_jar(name)`: the jar io.trino:<name>:476 (trino-jdbc, trino-cli), fetched with Maven once."""
    import trino_server

    def fetch(name: str) -> Path:
        try:
            return trino_server.jar(name)
        except trino_server.TrinoError as error:
            _needs(f"the jar io.trino:{name}:476", f"python3 dev.py trino jar {name}", str(error))

    return fetch


@contextmanager
def served_in_thread(app, start_seconds: float = 30, *, check_stopped: bool = False) -> Iterator[str]:
    """`app` served by uvicorn in a thread on a free loopback port; its base URL. Stops it after
    (`check_stopped`: and asserts the server's thread ended within 30 s)."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(64)
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning", lifespan="on"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    deadline = time.monotonic() + start_seconds
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.02)
    try:
        yield f"http://127.0.0.1:{sock.getsockname()[1]}"
    finally:
        server.should_exit = True
        thread.join(30)
        sock.close()
    if check_stopped:
        assert not thread.is_alive()
