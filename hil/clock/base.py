"""The clock interface and the timing-health record every run carries."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

import numpy as np

from hil.errors import ClockError


class StepParticipant(Protocol):
    """Something the step must wait for (in lockstep) at the end of each tick."""

    def complete(self, tick: int, time_s: float, *, wait: bool) -> None: ...


@dataclass(frozen=True)
class TimingLimits:
    """Bounds on bench timing: a run outside them is an *invalid bench*, not a DUT failure."""

    p99_lateness_s: float = 0.5e-3
    max_miss_fraction: float = 0.005
    max_stall_s: float = 0.05


@dataclass(frozen=True)
class TimingHealth:
    """How well a clock kept its deadlines over a run.

    ``lateness`` is how long after its deadline a tick actually started. A *miss* is a tick
    later than ``miss_threshold_s``; a *stall* one later than ``stall_threshold_s``.
    """

    mode: str
    period_s: float
    ticks: int
    scheduler: str
    lateness_p50_s: float = 0.0
    lateness_p99_s: float = 0.0
    lateness_p999_s: float = 0.0
    lateness_max_s: float = 0.0
    miss_threshold_s: float = 0.0
    misses: int = 0
    stall_threshold_s: float = 0.0
    stalls: int = 0
    longest_stall_s: float = 0.0
    valid: bool = True
    invalid_reasons: tuple[str, ...] = ()
    histogram_edges_s: tuple[float, ...] = field(default=(), repr=False)
    histogram_counts: tuple[int, ...] = field(default=(), repr=False)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_lateness(cls, lateness_s: np.ndarray, *, period_s: float, scheduler: str,
                      limits: TimingLimits, miss_threshold_s: float,
                      stall_threshold_s: float) -> TimingHealth:
        n = int(lateness_s.size)
        if n == 0:
            return cls(mode="realtime", period_s=period_s, ticks=0, scheduler=scheduler,
                       valid=False, invalid_reasons=("no ticks were run",))
        p50, p99, p999 = (float(v) for v in np.percentile(lateness_s, [50, 99, 99.9]))
        worst = float(lateness_s.max())
        misses = int((lateness_s > miss_threshold_s).sum())
        stalls = int((lateness_s > stall_threshold_s).sum())
        reasons = []
        if p99 > limits.p99_lateness_s:
            reasons.append(f"p99 lateness {p99 * 1e6:.0f} us > "
                           f"{limits.p99_lateness_s * 1e6:.0f} us")
        if misses / n > limits.max_miss_fraction:
            reasons.append(f"{misses} of {n} ticks missed (> {limits.max_miss_fraction:.1%})")
        if worst > limits.max_stall_s:
            reasons.append(f"stall of {worst * 1e3:.1f} ms > {limits.max_stall_s * 1e3:.0f} ms")
        edges = np.concatenate([[0.0], np.logspace(-6, np.log10(max(worst, 2e-6) * 1.01), 24)])
        counts, _ = np.histogram(np.clip(lateness_s, 0.0, None), bins=edges)
        return cls(mode="realtime", period_s=period_s, ticks=n, scheduler=scheduler,
                   lateness_p50_s=p50, lateness_p99_s=p99, lateness_p999_s=p999,
                   lateness_max_s=worst, miss_threshold_s=miss_threshold_s, misses=misses,
                   stall_threshold_s=stall_threshold_s, stalls=stalls, longest_stall_s=worst
                   if stalls else 0.0, valid=not reasons, invalid_reasons=tuple(reasons),
                   histogram_edges_s=tuple(float(e) for e in edges),
                   histogram_counts=tuple(int(c) for c in counts))


class Clock(ABC):
    """A run's clock. Ticks are numbered from 0; tick ``k`` is at ``k * period_s``.

    Subclasses fill :meth:`_wait_for` (how to reach a tick) and say whether several ticks may
    be taken at once (:attr:`batches`: only when nothing outside the rig can act between them).
    """

    mode: str = "abstract"
    #: whether the step waits for its participants (lockstep) or only notifies them
    waits_for_participants: bool = False
    #: whether the rig may advance several ticks per call (no outside input between them)
    batches: bool = False

    def __init__(self, period_s: float) -> None:
        if not period_s > 0:
            raise ClockError(f"clock period must be positive, got {period_s}")
        self.period_s = period_s
        self.tick_index = 0
        self._started = False
        self._participants: list[StepParticipant] = []

    def add_participant(self, participant: StepParticipant) -> None:
        self._participants.append(participant)

    def start(self) -> None:
        if self._started:
            raise ClockError(f"{self.mode} clock started twice")
        self._started = True
        self.tick_index = 0
        self._on_start()

    def stop(self) -> TimingHealth:
        if self._started:
            self._on_stop()
            self._started = False
        return self.health()

    def time_of(self, tick: int) -> float:
        return tick * self.period_s

    @property
    def time_s(self) -> float:
        """The current tick's time (virtual in lockstep, nominal in real time)."""
        return self.tick_index * self.period_s

    def now(self) -> float:
        """Run time for stamping frames: virtual in lockstep, elapsed wall time in real time."""
        return self.time_s

    def tick(self, n: int = 1) -> int:
        """Advance ``n`` ticks and return the new tick index (waits in real time)."""
        if not self._started:
            raise ClockError(f"{self.mode} clock ticked before start()")
        if n < 1:
            raise ClockError(f"tick count must be >= 1, got {n}")
        if n > 1 and not self.batches:
            raise ClockError(f"{self.mode} clock advances one tick at a time")
        self.tick_index += n
        self._wait_for(self.tick_index)
        return self.tick_index

    def complete_step(self) -> None:
        """End of the step: participants are told (real time) or waited for (lockstep)."""
        for participant in self._participants:
            participant.complete(self.tick_index, self.time_s, wait=self.waits_for_participants)

    @abstractmethod
    def _wait_for(self, tick: int) -> None: ...

    def _on_start(self) -> None:
        return None

    def _on_stop(self) -> None:
        return None

    @abstractmethod
    def health(self) -> TimingHealth: ...
