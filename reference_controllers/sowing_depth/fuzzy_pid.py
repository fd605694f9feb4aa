"""[D]'s fuzzy self-tuning PID (eq. 10, Table 2) as a pure core: depth in, rod speed out.

Section 2 of ``docs/reference-controllers.md``. Each step (T = 0.01 s, the drive's SYNC)::

    e  = target - depth;  ec = (e - e_prev) / T            (0 on the first step after a reset)
    E  = clamp(ke·e, -6, 6);  EC = clamp(kec·ec, -6, 6)     (Table 2's quantization factors)
    Kp = max(0, Kp0 + 0.30·Up); Ki = max(0, Ki0 + 0.02·Ui); Kd = max(0, Kd0 + 0.50·Ud)   (10)
    u  = Kp·e + Ki·I + Kd·ec;  speed = clamp(u, -v_max, v_max)
    I += e·T unless the output saturates in the direction of the error (conditional integration)

A positive speed pushes the pre-sowing roller down: more covering soil, more depth.

>>> pid = FuzzyPid(FuzzyPidParams(kp0=1.0, ki0=0.5, kd0=1.0))
>>> speed, kp, ki, kd = pid.step(30.0, 30.0, True, True)   # no error: ΔKp = ΔKi = 0, ΔKd NS
>>> speed, round(kp, 12), round(ki, 12), round(kd, 12)
(0.0, 1.0, 0.5, 0.5)
>>> pid.step(30.0, 20.0, True, False)           # not enabled: reset, speed 0, presets
(0.0, 1.0, 0.5, 1.0)
"""

from __future__ import annotations

from dataclasses import dataclass

from reference_controllers.sowing_depth.fuzzy import fuzzy_gains


def _clamp(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


def _sign(x: float) -> int:
    return (x > 0.0) - (x < 0.0)


@dataclass(frozen=True)
class FuzzyPidParams:
    """Preset gains and Table 2's factors.

    ``kp0`` (mm/s per mm), ``ki0`` (mm/s per mm·s), ``kd0`` (mm/s per mm/s): not published in
    [D], tuned on the emulator (see the contract's "Tuning results"). ``ke``, ``kec``: input
    quantization factors; ``kp_scale``, ``ki_scale``, ``kd_scale``: output scale factors;
    ``v_max``: the cylinder's rod speed (mm/s); ``period_s``: the control period T.
    """

    kp0: float = 3.0
    ki0: float = 0.1
    kd0: float = 0.0
    ke: float = 0.03
    kec: float = 0.12
    kp_scale: float = 0.30
    ki_scale: float = 0.02
    kd_scale: float = 0.50
    v_max: float = 50.0
    period_s: float = 0.01

    def __post_init__(self) -> None:
        if not self.period_s > 0.0:
            raise ValueError(f"period_s must be > 0, got {self.period_s}")
        if not self.v_max > 0.0:
            raise ValueError(f"v_max must be > 0, got {self.v_max}")


class FuzzyPid:
    """The fuzzy self-tuning PID. :meth:`step` returns ``(speed_mm_s, kp, ki, kd)``."""

    def __init__(self, params: FuzzyPidParams) -> None:
        self.params = params
        self.integral = 0.0
        self.e_prev: float | None = None

    def reset(self) -> None:
        """I = 0, no previous error."""
        self.integral = 0.0
        self.e_prev = None

    def step(self, target_mm: float, depth_mm: float, valid: bool,
             enabled: bool) -> tuple[float, float, float, float]:
        """One control period (section 2 of the contract)."""
        p = self.params
        if not (valid and enabled):
            self.reset()
            return 0.0, p.kp0, p.ki0, p.kd0
        e = target_mm - depth_mm
        ec = 0.0 if self.e_prev is None else (e - self.e_prev) / p.period_s
        up, ui, ud = fuzzy_gains(_clamp(p.ke * e, -6.0, 6.0), _clamp(p.kec * ec, -6.0, 6.0))
        kp = max(0.0, p.kp0 + p.kp_scale * up)
        ki = max(0.0, p.ki0 + p.ki_scale * ui)
        kd = max(0.0, p.kd0 + p.kd_scale * ud)
        u = kp * e + ki * self.integral + kd * ec
        speed = _clamp(u, -p.v_max, p.v_max)
        if not (u != speed and _sign(e) == _sign(u)):
            self.integral += e * p.period_s
        self.e_prev = e
        return speed, kp, ki, kd
