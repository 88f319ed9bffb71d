"""The solver's helper thread: one per process, and a new one in a forked child.

A child forked from a process whose helper exists inherits the executor object but not its
thread; without the per-process check a submission there would wait forever (here: time out).
"""

from __future__ import annotations

import multiprocessing
import os
import threading

from worker.solver import side_thread


def _where() -> tuple[int, str]:
    return os.getpid(), threading.current_thread().name


def _submit_in_child() -> tuple[int, tuple[int, str]]:
    return os.getpid(), side_thread.submit(_where).result(timeout=10)


def test_work_runs_on_the_helper_thread_of_this_process() -> None:
    pid, name = side_thread.submit(_where).result(timeout=10)
    assert pid == os.getpid()
    assert name.startswith("solver-side") and name != threading.current_thread().name


def test_a_forked_child_gets_its_own_helper_thread() -> None:
    side_thread.submit(_where).result(timeout=10)  # the parent's helper exists before the fork
    with multiprocessing.get_context("fork").Pool(1) as pool:
        child, (pid, name) = pool.apply(_submit_in_child)
    assert child == pid != os.getpid()
    assert name.startswith("solver-side")


def test_completed_holds_its_value() -> None:
    future = side_thread.completed(42)
    assert future.done() and future.result() == 42
