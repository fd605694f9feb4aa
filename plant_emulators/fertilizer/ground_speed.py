"""Ground speed: the tractor's true travel, the planter's ground wheel and the ISOBUS speeds.

The scenario sets :attr:`GroundSpeedModel.target_speed_mps`. The tractor follows it with a
first-order response and an acceleration limit, around a smooth random variation (engine droop,
changing draft: an Ornstein-Uhlenbeck factor filtered by the tractor's response). Asked to stop
(target 0), it brakes at the acceleration limit to a standstill, where every speed it reports
is 0 (the Hall node's after its ``hall_timeout_s``). Three
speeds are derived from the true one:

* the planter's **ground wheel**, which skids and sinks on loose soil and so travels a few
  percent less than the ground (slip ``s_w``: ``v_wheel = v·(1 - s_w)``); a Hall sensor
  reads ``pulses_per_rev`` pulses per wheel revolution, with small per-magnet spacing errors,
  and its node reports the speed from the pulse periods of the last ``hall_average_window_s``;
* the tractor's **wheel-based** speed (ISO 11783-7 PGN 65096), from its driven wheels, which
  slip forward under draft (``v_wb = v/(1 - s_t)``);
* the tractor's **ground-based** speed (PGN 65097), from a radar: a cosine bias and correlated
  noise.

A vertical vibration of the frame (a resonant random process whose RMS grows with speed) is
exposed for the sensor models ([F]: field accuracy is below the bench "because of sensor noise
and vibration").

Same contract as the plant: randomness drawn from the generator given at construction, noise
in pre-drawn blocks, and ``advance(n, dt)`` equal to ``n`` x ``advance(1, dt)`` exactly.

The step loop exists twice (see :mod:`plant_emulators.engine`): the Python loop below, the
reference, and its C twin (``native/ground_speed_core.c``), which runs the same operations in
the same order and gives the same floats bit for bit. ``AGRIHIL_PHYSICS`` or the ``engine``
argument picks one. With the twin, the state, the outputs and the Hall edges live in the C
object: :meth:`GroundSpeedModel.advance` gets the outputs back in one tuple and
:meth:`GroundSpeedModel.hall_report` is computed there too.

Example
-------
>>> import numpy as np
>>> from plant_emulators.fertilizer.config import load_rig_config
>>> gs = GroundSpeedModel(load_rig_config().ground_speed, np.random.default_rng(5))
>>> gs.target_speed_mps = 4.0 / 3.6
>>> gs.advance(20000, 0.001)
>>> abs(gs.true_speed_mps - 4.0 / 3.6) < 0.1
True
>>> gs.hall_pulses > 0
True
"""

from __future__ import annotations

import enum
import math
from collections import deque
from functools import partial
from typing import NamedTuple

import numpy as np

from plant_emulators.engine import Engine, load_native, resolve_engine
from plant_emulators.fertilizer.config import GroundSpeedConfig
from plant_emulators.fertilizer.noise import NormalStream, ou_coefficients, spawn

__all__ = ["GroundSpeedModel", "HallReport", "MachineDirection", "TractorSpeedReport"]

_SLOW_UPDATE_S = 0.005
"""Update period (s) of the random processes (variation, slips, radar noise, vibration)."""

_EDGE_HISTORY = 512
"""Hall edge times kept for the speed estimate (the C twin keeps as many: EDGE_HISTORY)."""

_NATIVE_MODULE = "plant_emulators.fertilizer._ground_speed_native"


class MachineDirection(enum.IntEnum):
    """ISO 11783-7 / SAE J1939-71 machine direction (2 bits)."""

    REVERSE = 0
    FORWARD = 1
    ERROR = 2
    NOT_AVAILABLE = 3


class HallReport(NamedTuple):
    """What the Hall ground-speed node reports."""

    wheel_speed_mps: float
    """Ground-wheel surface speed from the recent pulse periods (m/s)."""
    pulse_count: int
    """Pulses counted since power-up (not wrapped; the frame carries it modulo 65536)."""
    last_period_s: float
    """Time between the last two pulses (s); 0 when fewer than two pulses were seen."""
    moving: bool
    """False when no pulse came within ``hall_timeout_s``."""


class TractorSpeedReport(NamedTuple):
    """Speed and distance as the tractor ECU broadcasts them (PGN 65096 or 65097)."""

    speed_mps: float
    distance_m: float
    direction: MachineDirection


class _StepConstants(NamedTuple):
    """What :meth:`GroundSpeedModel.advance` needs that depends only on the config and dt.

    Computed once when the step size is bound, instead of on every call (the OU
    coefficients alone cost four ``exp`` and four ``sqrt`` per call).
    """

    slow: int
    """Steps per update of the slow processes."""
    var_a: float
    var_b: float
    ws_a: float
    ws_b: float
    ts_a: float
    ts_b: float
    rn_a: float
    rn_b: float
    """OU coefficients of the speed variation, wheel slip, tractor slip, radar noise."""
    ws_mean: float
    ts_mean: float
    """Mean wheel and tractor slip."""
    k_tau: float
    """dt / speed time constant."""
    dv_max: float
    """Largest speed change per step (m/s)."""
    inv_pitch: float
    """Hall pulses per metre of ground-wheel travel."""
    radar_gain: float
    """1 + radar bias."""

    @classmethod
    def for_step(cls, cfg: GroundSpeedConfig, dt: float) -> _StepConstants:
        """The constants for steps of ``dt`` seconds."""
        slow = max(1, round(_SLOW_UPDATE_S / dt))
        h = slow * dt
        return cls(slow,
                   *ou_coefficients(h, cfg.speed_variation_time_s, cfg.speed_variation_sd_frac),
                   *ou_coefficients(h, cfg.wheel_slip_time_s, cfg.wheel_slip_sd_frac),
                   *ou_coefficients(h, cfg.tractor_slip_time_s, cfg.tractor_slip_sd_frac),
                   *ou_coefficients(h, cfg.radar_noise_time_s, cfg.radar_noise_sd_frac),
                   cfg.wheel_slip_mean_frac, cfg.tractor_slip_mean_frac,
                   dt / cfg.speed_time_constant_s, cfg.max_accel_mps2 * dt,
                   1.0 / cfg.metres_per_pulse, 1.0 + cfg.radar_bias_frac)


def _slow_factors(target: float, variation: float, wheel_slip: float, tractor_slip: float,
                  radar_noise: float, radar_gain: float) -> tuple[float, float, float, float]:
    """Per-step factors that change only when the slow processes update.

    Returns
    -------
    tuple of float
        ``(v_goal, 1 - s_w, 1 - s_t, radar gain + noise)``: the speed the tractor heads for
        and the factors of the ground-wheel, wheel-based and ground-based speeds (slips below
        zero count as zero).
    """
    return (target * (1.0 + variation),
            1.0 - (wheel_slip if wheel_slip > 0.0 else 0.0),
            1.0 - (tractor_slip if tractor_slip > 0.0 else 0.0),
            radar_gain + radar_noise)


class GroundSpeedModel:
    """True ground speed, ground-wheel slip and Hall pulses, tractor wheel and radar speed.

    Parameters
    ----------
    config : GroundSpeedConfig
        The ``[ground_speed]`` section.
    rng : numpy.random.Generator
        The run's generator; the model spawns its own child stream at construction.
    engine : {"native", "python"}, optional
        Which step loop runs (the same floats either way); None: ``AGRIHIL_PHYSICS``.

    Attributes
    ----------
    target_speed_mps : float
        Input: the travel speed the scenario asks of the tractor (m/s, >= 0).
    """

    def __init__(self, config: GroundSpeedConfig, rng: np.random.Generator, *,
                 engine: str | None = None) -> None:
        self.config = config
        self.engine: Engine = resolve_engine(engine)
        own = spawn(rng)
        z_rng = spawn(own)
        n_mag = config.pulses_per_rev
        self._pulse_spacing_errors: tuple[float, ...] = tuple(
            float(v) for v in config.pulse_spacing_error_sd_frac * own.standard_normal(n_mag))
        variation = config.speed_variation_sd_frac * float(own.standard_normal())
        wheel_slip = config.wheel_slip_mean_frac + config.wheel_slip_sd_frac * float(
            own.standard_normal())
        tractor_slip = (config.tractor_slip_mean_frac
                        + config.tractor_slip_sd_frac * float(own.standard_normal()))
        radar_noise = config.radar_noise_sd_frac * float(own.standard_normal())

        # Vibration: AR(2) resonator at vibration_freq_hz, unit variance.
        h = _SLOW_UPDATE_S
        omega = 2.0 * math.pi * config.vibration_freq_hz
        r = math.exp(-config.vibration_damping * omega * h)
        c = math.cos(omega * h * math.sqrt(max(1e-12, 1.0 - config.vibration_damping ** 2)))
        self._ar1 = 2.0 * r * c
        self._ar2 = -r * r
        var = (1.0 + r * r) / ((1.0 - r * r) * ((1.0 + r * r) ** 2 - 4.0 * r * r * c * c))
        self._ar_gain = 1.0 / math.sqrt(var)
        self._radar_gain = 1.0 + config.radar_bias_frac
        self._vib_rms_per_mps = config.vibration_rms_mps2_per_mps

        self.target_speed_mps = 0.0
        self._dt: float | None = None
        self._k: _StepConstants               # set when the step size is bound
        self._core = None
        if self.engine == "native":
            native = load_native(_NATIVE_MODULE)
            # The twin owns the state from here on (no Python copy of it to go stale). It
            # draws its noise from the same generator in the same blocks as the Python loop's
            # NormalStream, so the sequence is the same.
            self._core = native.GroundSpeedCore(
                self.pulse_spacing_errors, variation, wheel_slip, tractor_slip, radar_noise,
                self._ar1, self._ar2, self._ar_gain, self._radar_gain, self._vib_rms_per_mps,
                config.hall_timeout_s, config.hall_average_window_s,
                config.reported_metres_per_pulse, HallReport,
                partial(z_rng.standard_normal, native.NORMAL_BLOCK))
            self._set_outputs(self._core.outputs())
            return

        self._z = NormalStream(z_rng)
        self._variation = variation
        self._wheel_slip = wheel_slip
        self._tractor_slip = tractor_slip
        self._radar_noise = radar_noise
        self._vib = [0.0, 0.0]
        self._steps = 0
        self._countdown = 0
        self._v = 0.0
        self._dist = 0.0
        self._wheel_dist = 0.0
        self._wb_dist = 0.0
        self._gb_dist = 0.0
        self._pulse_pos = 0.0          # ground-wheel travel in pulse pitches
        self._pulses = 0
        self._next_edge = 1.0 + self.pulse_spacing_errors[1 % n_mag]
        self._edges: deque[float] = deque(maxlen=_EDGE_HISTORY)
        self._update_outputs()

    @property
    def pulse_spacing_errors(self) -> tuple[float, ...]:
        """Per-magnet edge position error (fraction of a pulse pitch), drawn per run.

        Read-only: the C twin takes it (like the frozen config) when it is built."""
        return self._pulse_spacing_errors

    # ------------------------------------------------------------------ stepping
    def _bind_dt(self, dt: float) -> None:
        if self._dt is not None:
            if dt != self._dt:
                raise ValueError(f"dt changed from {self._dt} s to {dt} s")
            return
        if not 0.0 < dt <= _SLOW_UPDATE_S:
            raise ValueError(f"dt must be in (0, {_SLOW_UPDATE_S}] s, got {dt!r}")
        self._k = _StepConstants.for_step(self.config, dt)
        if self._core is not None:
            self._core.bind(dt, self._k)
        self._dt = dt

    def advance(self, n: int, dt: float) -> None:
        """Advance ``n`` steps of ``dt`` seconds (``dt`` fixed by the first call)."""
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        if dt != self._dt:          # first call (binds the step) or a changed step (raises)
            self._bind_dt(dt)
        target = max(0.0, float(self.target_speed_mps))
        if self._core is not None:
            self._set_outputs(self._core.advance(n, target))
            return
        # One tuple unpacking instead of ~20 attribute lookups per call (order as declared).
        (slow, var_a, var_b, ws_a, ws_b, ts_a, ts_b, rn_a, rn_b, ws_mean, ts_mean,
         k_tau, dv_max, inv_pitch, radar_gain) = self._k
        ar1, ar2, ar_gain = self._ar1, self._ar2, self._ar_gain
        znext = self._z.next
        errors = self.pulse_spacing_errors
        n_mag = len(errors)
        add_edge = self._edges.append

        v, dist = self._v, self._dist
        wheel_dist, wb_dist, gb_dist = self._wheel_dist, self._wb_dist, self._gb_dist
        variation, wslip, tslip, rnoise = (self._variation, self._wheel_slip,
                                           self._tractor_slip, self._radar_noise)
        vib0, vib1 = self._vib
        pos, pulses, next_edge = self._pulse_pos, self._pulses, self._next_edge
        countdown = self._countdown
        steps = self._steps
        # Factors that change only with the slow processes, hoisted out of the per-step
        # arithmetic (recomputed below whenever those processes update; same expressions,
        # so the same floats).
        v_goal, f_wheel, f_wb, f_gb = _slow_factors(target, variation, wslip, tslip, rnoise,
                                                    radar_gain)

        for k in range(steps, steps + n):
            if countdown <= 0:
                countdown = slow
                variation = var_a * variation + var_b * znext()
                wslip = ws_mean + ws_a * (wslip - ws_mean) + ws_b * znext()
                tslip = ts_mean + ts_a * (tslip - ts_mean) + ts_b * znext()
                rnoise = rn_a * rnoise + rn_b * znext()
                vib0, vib1 = ar1 * vib0 + ar2 * vib1 + znext() * ar_gain, vib0
                v_goal, f_wheel, f_wb, f_gb = _slow_factors(target, variation, wslip, tslip,
                                                            rnoise, radar_gain)
            countdown -= 1
            dv = (v_goal - v) * k_tau
            if v_goal <= 0.0:
                # asked to stop: the driver brakes at the field deceleration to a standstill
                # (a first-order approach would crawl at a few cm/s for ever)
                dv = -dv_max
            elif dv > dv_max:
                dv = dv_max
            elif dv < -dv_max:
                dv = -dv_max
            v += dv
            if v < 0.0:
                v = 0.0
            dist += v * dt
            wheel_step = v * f_wheel * dt              # ground-wheel travel this step (m)
            wheel_dist += wheel_step
            wb_dist += v / f_wb * dt
            gb_dist += v * f_gb * dt
            step_pitches = wheel_step * inv_pitch
            new_pos = pos + step_pitches
            while new_pos >= next_edge:
                add_edge((k + (next_edge - pos) / step_pitches) * dt)
                pulses += 1
                next_edge = pulses + 1 + errors[(pulses + 1) % n_mag]
            pos = new_pos
        steps += n

        self._v, self._dist = v, dist
        self._wheel_dist, self._wb_dist, self._gb_dist = wheel_dist, wb_dist, gb_dist
        self._variation, self._wheel_slip = variation, wslip
        self._tractor_slip, self._radar_noise = tslip, rnoise
        self._vib = [vib0, vib1]
        self._pulse_pos, self._pulses, self._next_edge = pos, pulses, next_edge
        self._countdown = countdown
        self._steps = steps
        self._update_outputs()

    # ------------------------------------------------------------------ outputs
    def _update_outputs(self) -> None:
        if self._core is not None:
            self._set_outputs(self._core.outputs())
            return
        v = self._v
        self.time_s = self._steps * (self._dt or 0.0)
        self.true_speed_mps = v
        self.true_distance_m = self._dist
        wheel_slip, tractor_slip = self._wheel_slip, self._tractor_slip
        self.wheel_slip_frac = wheel_slip if wheel_slip > 0.0 else 0.0
        self.tractor_slip_frac = tractor_slip if tractor_slip > 0.0 else 0.0
        self.ground_wheel_speed_mps = v * (1.0 - self.wheel_slip_frac)
        self.ground_wheel_distance_m = self._wheel_dist
        self.hall_pulses = self._pulses
        self.wheel_based_speed_mps = v / (1.0 - self.tractor_slip_frac)
        self.wheel_based_distance_m = self._wb_dist
        self.ground_based_speed_mps = v * (self._radar_gain + self._radar_noise)
        self.ground_based_distance_m = self._gb_dist
        self.vibration_rms_mps2 = self._vib_rms_per_mps * v
        self.vibration_mps2 = self.vibration_rms_mps2 * self._vib[0]

    def _set_outputs(self, outputs: tuple) -> None:
        """The twin's outputs, in the order :meth:`_update_outputs` sets them."""
        (self.time_s, self.true_speed_mps, self.true_distance_m, self.wheel_slip_frac,
         self.tractor_slip_frac, self.ground_wheel_speed_mps, self.ground_wheel_distance_m,
         self.hall_pulses, self.wheel_based_speed_mps, self.wheel_based_distance_m,
         self.ground_based_speed_mps, self.ground_based_distance_m, self.vibration_rms_mps2,
         self.vibration_mps2) = outputs

    def hall_report(self) -> HallReport:
        """What the Hall node would report now, from its recorded pulse edges."""
        if self._core is not None:
            return self._core.hall_report()       # the same computation, in the twin
        cfg = self.config
        now = self.time_s
        edges = self._edges
        if not edges:
            return HallReport(0.0, self._pulses, 0.0, False)
        last = edges[-1]
        last_period = last - edges[-2] if len(edges) >= 2 else 0.0
        if now - last > cfg.hall_timeout_s or len(edges) < 2:
            return HallReport(0.0, self._pulses, last_period, False)
        horizon = now - cfg.hall_average_window_s
        first_i = len(edges) - 2
        while first_i > 0 and edges[first_i - 1] >= horizon:
            first_i -= 1
        span = last - edges[first_i]
        count = len(edges) - 1 - first_i
        period = span / count
        # A wheel that is slowing down: the time since the last pulse bounds the speed.
        period = max(period, now - last)
        return HallReport(cfg.reported_metres_per_pulse / period, self._pulses, last_period, True)

    def wheel_based_report(self) -> TractorSpeedReport:
        """PGN 65096 content: wheel-based machine speed and distance."""
        return TractorSpeedReport(self.wheel_based_speed_mps, self.wheel_based_distance_m,
                                  MachineDirection.FORWARD)

    def ground_based_report(self) -> TractorSpeedReport:
        """PGN 65097 content: ground-based (radar) machine speed and distance."""
        return TractorSpeedReport(self.ground_based_speed_mps, self.ground_based_distance_m,
                                  MachineDirection.FORWARD)

    def signals(self) -> dict[str, tuple[float, str]]:
        """Every output with its unit, for trace recording."""
        return {
            "time_s": (self.time_s, "s"),
            "target_speed_mps": (max(0.0, float(self.target_speed_mps)), "m/s"),
            "true_speed_mps": (self.true_speed_mps, "m/s"),
            "true_distance_m": (self.true_distance_m, "m"),
            "ground_wheel_speed_mps": (self.ground_wheel_speed_mps, "m/s"),
            "ground_wheel_distance_m": (self.ground_wheel_distance_m, "m"),
            "hall_pulses": (float(self.hall_pulses), "1"),
            "wheel_slip_frac": (self.wheel_slip_frac, "1"),
            "tractor_slip_frac": (self.tractor_slip_frac, "1"),
            "wheel_based_speed_mps": (self.wheel_based_speed_mps, "m/s"),
            "wheel_based_distance_m": (self.wheel_based_distance_m, "m"),
            "ground_based_speed_mps": (self.ground_based_speed_mps, "m/s"),
            "ground_based_distance_m": (self.ground_based_distance_m, "m"),
            "vibration_mps2": (self.vibration_mps2, "m/s^2"),
            "vibration_rms_mps2": (self.vibration_rms_mps2, "m/s^2"),
        }
