"""lakegate's answers to the corpus, embedded (translate and DuckDB in-process, no lake), in worker
processes: a query that outlives its time (a Python function DuckDB cannot interrupt) has its worker
killed and replaced, and counts as EXCEEDED_TIME_LIMIT."""

from __future__ import annotations

import multiprocessing
import queue
import threading
from collections.abc import Sequence

from trino_answers import Answer

#: Seconds one query may take on lakegate.
SECONDS = 20.0


def _serve(requests: multiprocessing.Queue, replies: multiprocessing.Queue) -> None:
    from trino_doc_examples import answer

    from lakegate.gateway.engine.engine import Engine
    from lakegate.gateway.engine.limits import Limits

    engine = Engine.open(None, limits=Limits(query_timeout=SECONDS))
    while (item := requests.get()) is not None:
        index, sql = item
        replies.put((index, answer(engine, sql)))


class _Worker:
    def __init__(self, context):
        self.context = context
        self.requests, self.replies = context.Queue(), context.Queue()
        self.process = context.Process(target=_serve, args=(self.requests, self.replies), daemon=True)
        self.process.start()

    def ask(self, index: int, sql: str) -> Answer:
        self.requests.put((index, sql))
        try:
            got, answer = self.replies.get(timeout=SECONDS + 30)
        except queue.Empty:
            self.process.kill()
            self.process.join()
            self.__init__(self.context)
            return Answer(error="EXCEEDED_TIME_LIMIT", message=f"no answer within {SECONDS + 30:.0f} s")
        assert got == index
        return answer

    def close(self) -> None:
        self.requests.put(None)
        self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()


def answers(sqls: Sequence[str], workers: int = 2) -> list[Answer]:
    """lakegate's answer to each query, in order, `workers` queries at a time."""
    context = multiprocessing.get_context("spawn")
    pool = [_Worker(context) for _ in range(workers)]
    found: list[Answer | None] = [None] * len(sqls)
    lock, position = threading.Lock(), iter(range(len(sqls)))

    def drive(worker: _Worker) -> None:
        while True:
            with lock:
                index = next(position, None)
            if index is None:
                return
            found[index] = worker.ask(index, sqls[index])

    threads = [threading.Thread(target=drive, args=(worker,)) for worker in pool]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for worker in pool:
        worker.close()
    return found  # type: ignore[return-value]
