"""[F]'s piecewise incremental PID (eq. 11-13) and the open-loop baseline, as pure cores.

The contract is section 1 of ``docs/reference-controllers.md``; the C firmware implements the
same numbers and both replay ``reference_controllers/vectors/fertilizer-*.csv``.

One call of :meth:`PiecewisePid.step` is one control period (0.1 s). The sensor is the loop's
clock: the state changes only on a step with a new report and a measurement, so between
reports the command is held (paper-literal) or recomputed from the held correction and the
current feedforward (physical).

>>> pid = PiecewisePid(PiecewisePidParams.paper_literal())
>>> pid.step(23.0, 20.0, True, True)        # |e| = 3 g/s: medium band, first update: Ki2·e
(0.0045, 2)
>>> pid.step(0.0, 20.0, True, True)         # target 0: reset
(0.0, 0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

Mode = Literal["paper-literal", "physical"]
MODES: tuple[str, ...] = ("paper-literal", "physical")

SEGMENT_NONE, SEGMENT_FINE, SEGMENT_MEDIUM, SEGMENT_COARSE = 0, 1, 2, 3


def _clamp(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


#: physical upper bounds of the positive parameters: a value above one is a unit mistake (g for
#: kg, rpm for r/min, mV for V), not a meter, and would drive the command to a rail
_PHYSICAL_HIGH = {"km": 1000.0, "ff_coeff": 100.0, "ff_exponent": 2.0,
                  "shaft_rpm_per_v": 1000.0, "v_max": 10.0}
_WHY_HIGH = {
    "km": "a correction gain above 1000 V per g/s saturates on any flow error",
    "ff_coeff": "g/s per row at 1 r/min: a fluted roller of [F]'s meter gives 4.6; 100 would be "
                "6 kg per minute per row at one turn a minute",
    "ff_exponent": "flow grows with shaft speed no faster than its square on a fluted roller "
                   "(fitted 0.65)",
    "shaft_rpm_per_v": "meter shaft r/min per volt of command: [F]'s drive gives 6",
    "v_max": "the analog module's full scale is 10 V",
}


@dataclass(frozen=True)
class PiecewisePidParams:
    """Gains, thresholds and scalings of the piecewise PID.

    ``e1``, ``e2`` are g/s in paper-literal mode and fractions of the target in physical
    mode. ``km`` (V per controller unit, [F] eq. 3) is used by paper-literal mode only,
    ``c_max`` (bound of the feedforward correction) and ``settle_periods`` (control periods
    after a target jump during which reports are ignored: their windows still hold the flow
    from before) and ``ki_first`` (the integral's gain on the first update after a reset: the
    meter factor learnt from the first clean report) by physical mode only. The feedforward
    is the meter's nominal map ``q = ff_coeff·n^ff_exponent`` g/s per row (n shaft r/min),
    linear below ``ff_linear_below_rpm`` (0: the power law all the way down), and the
    drive's ``shaft_rpm_per_v``.
    """

    mode: str
    kp1: float
    kp2: float
    kp3: float
    ki1: float
    ki2: float
    kd: float
    e1: float
    e2: float
    km: float = 0.1
    c_max: float = 0.5
    settle_periods: float = 17.0
    ki_first: float = 0.8
    ff_coeff: float = 4.586
    ff_exponent: float = 0.6537
    shaft_rpm_per_v: float = 6.0
    v_max: float = 10.0
    #: below this shaft speed a flute holds all it can: the grams per revolution stop rising
    #: and the map is linear (the meter's own physics, as the rig documents it for its meter;
    #: a power law extrapolated below it asks for ~13 % too little shaft speed at 3 r/min, and
    #: the factor learnt there is wrong again once the speed is back up: issue #16)
    ff_linear_below_rpm: float = 5.0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if not 0.0 < self.e1 < self.e2:
            raise ValueError(f"need 0 < e1 < e2, got e1={self.e1}, e2={self.e2}")
        for name, high in _PHYSICAL_HIGH.items():
            value = getattr(self, name)
            if not 0.0 < value <= high:
                raise ValueError(f"{name} must be > 0 and <= {high:g} ({_WHY_HIGH[name]}), "
                                 f"got {value}")
        if self.c_max < 0.0:
            raise ValueError(f"c_max must be >= 0, got {self.c_max}")
        if not self.ff_linear_below_rpm >= 0.0:
            raise ValueError(f"ff_linear_below_rpm must be >= 0, got {self.ff_linear_below_rpm}")
        if not 0.0 <= self.ki_first <= 1.0:
            raise ValueError(f"ki_first must be within [0, 1], got {self.ki_first}")
        if self.settle_periods < 0.0:
            raise ValueError(f"settle_periods must be >= 0, got {self.settle_periods}")

    @classmethod
    def paper_literal(cls) -> PiecewisePidParams:
        """[F]'s published gains; e1 = 1 g/s, e2 = 5 g/s (not published, section 1a)."""
        return cls(mode="paper-literal", kp1=0.038, kp2=2.089, kp3=212.016, ki1=0.167,
                   ki2=0.015, kd=1.317, e1=1.0, e2=5.0)

    @classmethod
    def physical(cls) -> PiecewisePidParams:
        """Normalized gains tuned on the emulator with the sliding-window flow modules the
        reference profiles are installed with (section 1b and "Tuning results" of the
        contract; ``scripts/tune_piecewise_pid.py``)."""
        return cls(mode="physical", kp1=0.4, kp2=0.4, kp3=0.0, ki1=0.04, ki2=0.04, kd=0.0,
                   e1=0.02, e2=0.10, ki_first=0.8)

    @classmethod
    def default(cls, mode: str) -> PiecewisePidParams:
        """The default set of ``mode``."""
        if mode == "paper-literal":
            return cls.paper_literal()
        if mode == "physical":
            return cls.physical()
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")


def feedforward_volts(target_gps: float, p: PiecewisePidParams) -> float:
    """The command that gives ``target_gps`` per row on the meter's nominal map.

    ``ff(Q) = clamp(n(Q) / k_n, 0, v_max)`` for Q > 0, else 0, where ``n(Q) = (Q / c)^(1/p)``
    (the inverse of the power-law fit of [F]'s 23/34/44 g/s at 12/21/32 r/min) down to the
    knee ``n_k = ff_linear_below_rpm``, and ``n(Q) = Q / (c·n_k^p) · n_k`` below it.
    """
    if not target_gps > 0.0:
        return 0.0
    shaft_rpm = math.pow(target_gps / p.ff_coeff, 1.0 / p.ff_exponent)
    if shaft_rpm < p.ff_linear_below_rpm:
        q_knee = p.ff_coeff * math.pow(p.ff_linear_below_rpm, p.ff_exponent)
        shaft_rpm = target_gps / q_knee * p.ff_linear_below_rpm
    return _clamp(shaft_rpm / p.shaft_rpm_per_v, 0.0, p.v_max)


def segment_of(abs_error: float, e1: float, e2: float) -> int:
    """[F] eq. 13: fine below e1, medium from e1 to below e2, coarse from e2."""
    if abs_error < e1:
        return SEGMENT_FINE
    if abs_error < e2:
        return SEGMENT_MEDIUM
    return SEGMENT_COARSE


class PiecewisePid:
    """The piecewise PID core in the mode its parameters name.

    :meth:`step` returns ``(volts, segment)``; ``segment`` is the band of the latest update
    since the last reset (0 before the first update).
    """

    def __init__(self, params: PiecewisePidParams) -> None:
        self.params = params
        self.reset()

    def reset(self) -> None:
        """Forget everything (target 0): no history, no correction."""
        self.started = False      # an update happened since the last reset
        self.u = 0.0              # paper-literal: controller units (volts = km·u)
        self.e_prev = 0.0
        self.e_prev2 = 0.0
        self.integral = 0.0       # physical: I
        self.correction = 0.0     # physical: c
        self.target_prev = 0.0    # physical: the target of the previous step
        self.since_jump = 0       # physical: steps since the last target jump
        self.learnt = False       # physical: the integral has had its first update
        self.segment = SEGMENT_NONE

    def _gains(self, segment: int) -> tuple[float, float]:
        p = self.params
        if segment == SEGMENT_FINE:
            return p.kp1, p.ki1
        if segment == SEGMENT_MEDIUM:
            return p.kp2, p.ki2
        return p.kp3, 0.0

    def step(self, target_gps: float, measured_gps: float, has_measurement: bool,
             new_report: bool) -> tuple[float, int]:
        """One control period. Returns ``(volts, segment)``."""
        if not target_gps > 0.0:
            self.reset()
            return 0.0, SEGMENT_NONE
        update = bool(new_report) and bool(has_measurement)
        p = self.params
        if p.mode == "paper-literal":
            if update:
                self._update_incremental(target_gps - measured_gps)
            return p.km * self.u, self.segment
        if abs(target_gps - self.target_prev) > p.e2 * self.target_prev:
            # a jump (also the first step after a reset): the sensors' windows still hold the
            # old flow; keep only the integral (P and D were about the old target) and wait
            self.since_jump = 0
            self.started = False
            self.correction = self.integral
        else:
            self.since_jump += 1
        self.target_prev = target_gps
        ff = feedforward_volts(target_gps, p)
        if update and self.since_jump >= p.settle_periods:
            self._update_normalized((target_gps - measured_gps) / target_gps,
                                    saturated=ff * (1.0 + self.correction) >= p.v_max)
        volts = ff * (1.0 + self.correction)
        return _clamp(volts, 0.0, p.v_max), self.segment

    def _update_incremental(self, e: float) -> None:
        """[F] eq. 12-13 literally: Δu = Kp·Δe + Ki·e + Kd·Δ²e, u clamped to [0, v_max/km]."""
        p = self.params
        if not self.started:
            self.e_prev = self.e_prev2 = e
            self.started = True
        self.segment = segment_of(abs(e), p.e1, p.e2)
        kp, ki = self._gains(self.segment)
        du = (kp * (e - self.e_prev) + ki * e
              + p.kd * (e - 2.0 * self.e_prev + self.e_prev2))
        self.u = _clamp(self.u + du, 0.0, p.v_max / p.km)
        self.e_prev2, self.e_prev = self.e_prev, e

    def _update_normalized(self, r: float, saturated: bool) -> None:
        """Section 1b: relative error, position-form P and D, incremental I, all bounded;
        no integration towards a limit the command already sits at (anti-windup)."""
        p = self.params
        if not self.started:
            self.e_prev = r
            self.started = True
        self.segment = segment_of(abs(r), p.e1, p.e2)
        kp, ki = self._gains(self.segment)
        if not (saturated and r > 0.0):
            if not self.learnt:       # the first clean report: learn the meter factor
                ki = p.ki_first
            self.integral = _clamp(self.integral + ki * r, -p.c_max, p.c_max)
            self.learnt = True
        self.correction = _clamp(kp * r + self.integral + p.kd * (r - self.e_prev),
                                 -p.c_max, p.c_max)
        self.e_prev = r


class OpenLoop:
    """[F]'s constant-speed baseline (section 1c): ``volts = ff(Q)``, segment 0, no sensor."""

    def __init__(self, params: PiecewisePidParams) -> None:
        self.params = params

    def reset(self) -> None:
        return None

    def step(self, target_gps: float, measured_gps: float, has_measurement: bool,
             new_report: bool) -> tuple[float, int]:
        return feedforward_volts(target_gps, self.params), SEGMENT_NONE
