"""The sensor model between an FMU output and the signal a device sends.

Applied in this order: delay (the value ``delay_ms`` ago, from the per-step history the rig
keeps), rate over a window (``(x(t) - x(t - w)) / w``: a flow from a cumulative mass, as a
windowed flow sensor reports it), sample-and-hold (a new sample only every ``hold_ms``), gain
and offset, Gaussian noise (from a stream of the run's seeded generator), quantisation (to a
multiple of ``quantum``).
Everything is a function of the run's time and seed: two runs with one seed send the same.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from hil.ownrig.config import SentSignal


class SensorModel:
    """One signal's sensor.

    Parameters
    ----------
    spec : SentSignal
        The signal's gain, offset, noise, quantum, delay and hold.
    rng : numpy.random.Generator
        The sensor's own stream (spawned from the run's generator in a fixed order).
    """

    def __init__(self, spec: SentSignal, rng: np.random.Generator) -> None:
        self.gain, self.offset = spec.gain, spec.offset
        self.noise_sd, self.quantum = spec.noise_sd, spec.quantum
        self.delay_s, self.hold_s = spec.delay_ms / 1000.0, spec.hold_ms / 1000.0
        self.window_s = spec.rate_window_ms / 1000.0
        self.rng = rng
        #: (time, value) of the source, oldest first (only with a delay)
        self.history: deque[tuple[float, float]] = deque()
        self._held = math.nan
        self._next_sample = -math.inf

    @property
    def needs_history(self) -> bool:
        """The sensor reads its source's past (a delay or a window)."""
        return self.delay_s > 0 or self.window_s > 0

    @property
    def needs_every_step(self) -> bool:
        """Its past is needed at every physics step (a delay); a window alone reads its start
        from the rig's event times (at least every trace period), where its frames are sent."""
        return self.delay_s > 0

    def record(self, time_s: float, value: float) -> None:
        """Keep the source's value at ``time_s`` (every physics step, for a delay or window)."""
        self.history.append((time_s, value))

    def _at(self, when: float, value: float) -> float:
        """The source at ``when`` (its last value at or before), from the newest back."""
        history = self.history
        for t, v in reversed(history):
            if t <= when + 1e-12:
                return v
        return history[0][1] if history else value   # before the history: its first value

    def _prune(self, oldest: float) -> None:
        history = self.history
        while len(history) > 1 and history[1][0] <= oldest + 1e-12:
            history.popleft()

    def sample(self, time_s: float, value: float) -> float:
        """The signal's value at ``time_s`` when the source reads ``value`` now."""
        if self.delay_s > 0 or self.window_s > 0:
            now = time_s - self.delay_s
            self._prune(now - self.window_s)
            latest = self._at(now, value)
            # over the window: from the value at its start (the first one while the run is
            # younger than the window, as a sensor that sums from power-up)
            first = self.history[0][1] if self.history else value
            value = (latest - first) / self.window_s if self.window_s > 0 else latest
        if self.hold_s > 0:
            if time_s + 1e-12 >= self._next_sample:
                self._held = value
                self._next_sample = (math.floor(time_s / self.hold_s + 1e-9) + 1) * self.hold_s
            value = self._held
        value = self.gain * value + self.offset
        if self.noise_sd > 0:
            value += float(self.rng.normal(0.0, self.noise_sd))
        if self.quantum > 0:
            value = round(value / self.quantum) * self.quantum
        return value
