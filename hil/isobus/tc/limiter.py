"""Answering and logging unsolicited traffic at a bounded rate: a count, not a line per frame.

A peer that floods the Task Controller with process data before its working-set master (or
with malformed messages) must not grow the TC's log by a line per frame, nor have it answer
each one with a negative acknowledgement. :class:`RateLimiter` lets the first occurrence per
source address through in each period; the rest of the period's occurrences are counted and
reported as one count when the period ends. Memory is bounded by the number of addresses (256).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class _Window:
    started_s: float
    suppressed: int = 0


class RateLimiter:
    """At most one occurrence per source per ``period_s`` passes; the others are counted.

    Parameters
    ----------
    period_s : float
        Length of a source's window, from the occurrence that passed.
    """

    def __init__(self, period_s: float = 1.0) -> None:
        if not (math.isfinite(period_s) and period_s > 0):
            raise ValueError(f"period_s must be > 0 s, got {period_s}")
        self.period_s = period_s
        self._windows: dict[int, _Window] = {}
        #: ended windows with counted occurrences, not yet reported: one per source at most
        self._ended: dict[int, _Window] = {}
        #: every occurrence counted, passed or not
        self.total = 0

    def offer(self, source: int, now_s: float) -> bool:
        """Whether this occurrence from ``source`` passes (is answered and logged)."""
        self.total += 1
        window = self._windows.get(source)
        if window is not None and now_s - window.started_s < self.period_s:
            window.suppressed += 1
            return False
        if window is not None and window.suppressed:
            self._report_later(source, window)
        self._windows[source] = _Window(now_s)
        return True

    def _report_later(self, source: int, window: _Window) -> None:
        earlier = self._ended.get(source)
        if earlier is not None:
            window = _Window(earlier.started_s, earlier.suppressed + window.suppressed)
        self._ended[source] = window

    def due(self) -> float:
        """When counted occurrences are next to be reported (``inf``: none)."""
        if self._ended:
            return -math.inf
        return min((w.started_s + self.period_s for w in self._windows.values()
                    if w.suppressed), default=math.inf)

    def ended(self, now_s: float) -> list[tuple[int, int, float]]:
        """``(source, count, since_s)`` of the windows ended by ``now_s`` with occurrences
        counted (each reported once), and forget every ended window."""
        for source, window in list(self._windows.items()):
            if now_s - window.started_s >= self.period_s:
                if window.suppressed:
                    self._report_later(source, window)
                del self._windows[source]
        out = [(source, w.suppressed, w.started_s) for source, w in self._ended.items()]
        self._ended.clear()
        return out
