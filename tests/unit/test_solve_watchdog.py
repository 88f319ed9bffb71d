"""The solve watchdog ends its process at the deadline even from a loop that never returns
to the interpreter's signal handlers, and does nothing once disarmed (real child processes)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

from tests.integration.harness import REPO_ROOT

STUCK = """
import time
from worker.watchdog import SolveWatchdog
SolveWatchdog(0.5).arm()
sum(range(10**12))  # one long call into C: no Python signal handler runs meanwhile
"""

DISARMED = """
import threading, time
from worker.watchdog import SolveWatchdog
dog = SolveWatchdog(0.3)
dog.arm()
dog.disarm()
time.sleep(1.0)
in_thread = SolveWatchdog(0.1)
threading.Thread(target=in_thread.arm).start()  # not the main thread: it does nothing
time.sleep(0.5)
print("alive", in_thread.armed)
"""


def _run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", code], cwd=REPO_ROOT, capture_output=True, text=True, timeout=60
    )


def test_a_stuck_solve_ends_its_process_at_the_deadline() -> None:
    start = time.monotonic()
    done = _run(STUCK)
    assert done.returncode == -signal.SIGALRM, done.stderr
    assert time.monotonic() - start < 20


def test_a_disarmed_watchdog_leaves_the_process_alone() -> None:
    done = _run(DISARMED)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "alive False"
