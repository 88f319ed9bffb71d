"""Kill this process when a solve has not returned by its deadline.

The Celery soft limit is raised into a solve as an exception, which a solve stuck in native code
never sees. The watchdog is a kernel timer whose signal (SIGALRM, default action) ends the
process without any Python code having to run, so even a solve holding the interpreter lock is
ended at its deadline. It is armed for the solve only: once the solve returned, the attempt may
hold its finished result through a database outage for longer (Celery's hard limit, which
includes that hold, is the last backstop then).
"""

from __future__ import annotations

import signal
import threading
from typing import Any

SignalHandler = Any
"""What ``signal.signal`` returns: a callable, ``SIG_DFL``/``SIG_IGN``, or None."""


class SolveWatchdog:
    """Ends the process ``seconds`` after :meth:`arm` unless :meth:`disarm` was called first.

    Only in the main thread of a process that has POSIX interval timers (a Celery prefork pool
    process); elsewhere it does nothing.
    """

    def __init__(self, seconds: float) -> None:
        self._seconds = seconds
        self._previous: SignalHandler = None
        self.armed = False

    def arm(self) -> None:
        """Start the timer (SIGALRM with its default action: the process ends)."""
        if self.armed or self._seconds <= 0 or not _usable():
            return
        self._previous = signal.signal(signal.SIGALRM, signal.SIG_DFL)
        signal.setitimer(signal.ITIMER_REAL, self._seconds)
        self.armed = True

    def disarm(self) -> None:
        """Stop the timer (idempotent) and put back the previous SIGALRM handler."""
        if not self.armed:
            return
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, self._previous or signal.SIG_DFL)
        self.armed = False


def _usable() -> bool:
    return hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
