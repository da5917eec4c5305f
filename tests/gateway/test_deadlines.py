"""The process's one thread of scheduled calls (query time limits): calls come in time order, a
canceled one never comes, and a call that fails does not stop the later ones."""

from __future__ import annotations

import threading

from lakegate.gateway.engine.deadlines import Deadlines


def test_calls_come_in_time_order_and_canceled_ones_never():
    deadlines, calls, done = Deadlines(), [], threading.Event()
    deadlines.at(0.6, lambda: (calls.append("last"), done.set()))  # far enough apart for a loaded machine
    deadlines.at(0.05, lambda: calls.append("first"))
    canceled = deadlines.at(0.1, lambda: calls.append("canceled"))
    deadlines.at(0.1, lambda: 1 / 0)  # fails: logged, the thread goes on
    deadlines.at(0.12, lambda: calls.append("second"))
    canceled.cancel()
    assert done.wait(10)
    assert calls == ["first", "second", "last"]


def test_many_canceled_calls_are_forgotten():
    deadlines = Deadlines()
    for _ in range(1000):
        deadlines.at(300, lambda: None).cancel()
    assert len(deadlines._heap) < 100
