"""The query workers' pool (gateway/engine/worker_pool.py) in a process of its own: closed while
a worker is being started, the process exits without a word on stderr (a worker the fork server
had forked but whose task never came printed a traceback into the user's error output)."""

from __future__ import annotations

import subprocess
import sys

#: Closes the pool while a worker is between its fork and the arrival of its task: the fork
#: server's connection is held open a moment longer to make that window wide.
CLOSE_MID_START = """
import threading, time
from multiprocessing import forkserver
from lakegate.gateway.engine.limits import Limits
from lakegate.gateway.engine.worker_pool import WorkerPool

forked = threading.Event()
connect = forkserver.connect_to_new_process

def slow_connect(fds):
    answer = connect(fds)
    forked.set()
    time.sleep(0.5)
    return answer

forkserver.connect_to_new_process = slow_connect
if __name__ == "__main__":
    pool = WorkerPool(None, memory_limit="1GB", threads=1, limits=Limits(), size=1, warm=1, keep=1)
    assert forked.wait(60)
    pool.close()
"""


def test_closing_while_a_worker_starts_leaves_stderr_clean(tmp_path):
    script = tmp_path / "close_mid_start.py"
    script.write_text(CLOSE_MID_START)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert (done.returncode, done.stderr) == (0, "")
