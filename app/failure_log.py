"""Log a failure that repeats (a database or broker away for a while) without flooding the log.

A loop that retries at every iteration or tick would otherwise write one traceback per retry:
hundreds per minute of outage, per process. Here the first failure of a streak is logged with
its traceback, later ones as one short line each at growing intervals (doubling up to a cap),
counting the failures in between, and the end of the streak as one line.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

FIRST_REPEAT_S = 1.0
"""Shortest gap between two lines of one failure streak."""
LONGEST_REPEAT_S = 60.0
"""Longest gap between two lines of one failure streak."""


class FailureLog:
    """One streak of failures of ``subject`` (e.g. ``"job 1234: database"``) on ``logger``."""

    def __init__(
        self,
        logger: logging.Logger,
        subject: str,
        *,
        first_repeat_s: float = FIRST_REPEAT_S,
        longest_repeat_s: float = LONGEST_REPEAT_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._log = logger
        self._subject = subject
        self._first_repeat_s = first_repeat_s
        self._longest_repeat_s = longest_repeat_s
        self._clock = clock
        self.failures = 0
        """Failures of the current streak (0: none)."""
        self._started = 0.0
        self._next_line = 0.0
        self._gap = first_repeat_s
        self._unlogged = 0
        self._last_kind = ""

    def failed(self, exc: BaseException, doing: str, retry: str = "retrying") -> None:
        """Record a failure while ``doing`` something: the first of a streak is logged with
        its traceback; later ones as one line when the gap has passed (or when the exception's
        type changes), the gap doubling each time."""
        now = self._clock()
        kind = type(exc).__name__
        self.failures += 1
        if self.failures == 1:
            self._started, self._gap, self._unlogged = now, self._first_repeat_s, 0
            self._next_line, self._last_kind = now + self._gap, kind
            self._log.warning(
                "%s: could not %s (%s): %s: %s", self._subject, doing, retry, kind,
                _first_line(exc), exc_info=exc,
            )  # fmt: skip
            return
        self._unlogged += 1
        if now < self._next_line and kind == self._last_kind:
            return
        self._log.warning(
            "%s: still failing after %.0f s (%d failures since the last line; now could not %s, "
            "%s: %s); %s",
            self._subject, now - self._started, self._unlogged, doing, kind,
            _first_line(exc), retry,
        )  # fmt: skip
        self._gap = min(2.0 * self._gap, self._longest_repeat_s)
        self._next_line, self._unlogged, self._last_kind = now + self._gap, 0, kind

    def succeeded(self, what: str = "works again") -> None:
        """End the streak, if any, with one line saying how long it lasted."""
        if self.failures == 0:
            return
        self._log.info(
            "%s: %s after %d failure(s) in %.0f s",
            self._subject,
            what,
            self.failures,
            self._clock() - self._started,
        )
        self.failures = 0


def _first_line(exc: BaseException) -> str:
    """The first line of an exception's message (database errors run over several)."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else ""
