"""Wall-clock ticks against absolute deadlines, with the clock's own timing health.

Each tick has the deadline ``t0 + k·period`` (never ``last + period``, so lateness does not
accumulate). The clock sleeps until ``spin_s`` before the deadline, then spins on
``perf_counter`` for the last part: ``time.sleep`` alone overshoots by ~50-100 µs and misses
every few seconds on a shared machine (see the project's measurements). When the process may,
the stepping thread runs SCHED_FIFO; when it may not, the record says so.

What the process holds when the run starts is frozen for the run (``gc.freeze``): a full
collection walks every tracked object, ~84,000 on the sowing-depth rig (numpy, scipy, canopen,
cantools …), and took 46-50 ms in the middle of a run, a stall that alone made a run
``invalid-bench``. Frozen, those objects are left out of every collection, which then walk only
what the run itself made. Collection stays on (cycles made during the run are still collected);
``stop`` unfreezes, and the next full collection sees everything again. Freezing costs nothing
(it moves lists); collecting first would not: in a test process it takes 100 ms or more, with
the GIL, while other threads of the process may be timing something.
"""

from __future__ import annotations

import contextlib
import gc
import os
import threading
import time
from array import array

import numpy as np

from hil.clock.base import Clock, TimingHealth, TimingLimits

_frozen_lock = threading.Lock()
_frozen_runs = 0


def _freeze() -> None:
    """``gc.freeze()`` for a run; runs may overlap (threads of one process), so the heap is
    unfrozen only when the last of them stops."""
    global _frozen_runs
    with _frozen_lock:
        _frozen_runs += 1
        gc.freeze()     # also for the 2nd run: what the 1st made meanwhile is frozen too


def _unfreeze() -> None:
    global _frozen_runs
    with _frozen_lock:
        _frozen_runs = max(0, _frozen_runs - 1)
        if _frozen_runs == 0:
            gc.unfreeze()


class RealtimeClock(Clock):
    mode = "realtime"

    def __init__(self, period_s: float = 0.001, *, spin_s: float = 0.0002,
                 fifo_priority: int | None = 10, limits: TimingLimits | None = None,
                 miss_threshold_s: float | None = None,
                 stall_threshold_s: float | None = None) -> None:
        super().__init__(period_s)
        self.spin_s = spin_s
        self.fifo_priority = fifo_priority
        self.limits = limits or TimingLimits()
        self.miss_threshold_s = miss_threshold_s if miss_threshold_s is not None else period_s / 2
        self.stall_threshold_s = (stall_threshold_s if stall_threshold_s is not None
                                  else max(2 * period_s, 0.002))
        self.scheduler = "not started"
        self._t0 = 0.0
        self._lateness = array("d")
        self._previous_policy: tuple[int, int] | None = None
        self._frozen = False

    def _on_start(self) -> None:
        self._lateness = array("d")
        self.scheduler = self._raise_priority()
        _freeze()
        self._frozen = True
        self._t0 = time.perf_counter()

    def _raise_priority(self) -> str:
        if self.fifo_priority is None:
            return "SCHED_OTHER (SCHED_FIFO not requested)"
        if not hasattr(os, "sched_setscheduler"):
            return "SCHED_OTHER (this OS has no sched_setscheduler)"
        try:
            self._previous_policy = (os.sched_getscheduler(0),
                                     os.sched_getparam(0).sched_priority)
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.fifo_priority))
        except OSError as exc:
            self._previous_policy = None
            return f"SCHED_OTHER (SCHED_FIFO not permitted: {exc.strerror})"
        return f"SCHED_FIFO priority {self.fifo_priority}"

    def _on_stop(self) -> None:
        if self._frozen:
            self._frozen = False
            _unfreeze()
        if self._previous_policy is not None:
            policy, priority = self._previous_policy
            with contextlib.suppress(OSError):
                os.sched_setscheduler(0, policy, os.sched_param(priority))
            self._previous_policy = None

    @property
    def elapsed_s(self) -> float:
        """Wall time since start (for the rig's diagnostics, not for physics)."""
        return time.perf_counter() - self._t0

    def now(self) -> float:
        return self.elapsed_s

    def _wait_for(self, tick: int) -> None:
        deadline = self._t0 + tick * self.period_s
        remaining = deadline - time.perf_counter()
        if remaining > self.spin_s:
            time.sleep(remaining - self.spin_s)
        now = time.perf_counter()
        while now < deadline:
            now = time.perf_counter()
        self._lateness.append(now - deadline)

    def lateness(self) -> np.ndarray:
        return np.frombuffer(self._lateness, dtype=np.float64).copy()

    def health(self) -> TimingHealth:
        return TimingHealth.from_lateness(self.lateness(), period_s=self.period_s,
                                          scheduler=self.scheduler, limits=self.limits,
                                          miss_threshold_s=self.miss_threshold_s,
                                          stall_threshold_s=self.stall_threshold_s)
