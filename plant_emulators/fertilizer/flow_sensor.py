"""Capacitive flow detection module of paper [F] (STM32 + AD7746), one per row.

Physics. Granules falling through the sensor's electrodes raise its capacitance in proportion
to the mass held between them, ``ΔC = s·H``. The holdup ``H`` follows the flow with the
granules' transit time ``τ``: ``dH/dt = q - H/τ``, so in steady flow ``H = q·τ`` and the sum of
``ΔC`` over a window of conversions is proportional to the grams that passed. The transit time
jitters (granule velocity), the empty-pipe capacitance wanders (temperature, dust), the AD7746
adds noise and quantizes, and field vibration adds noise; each module's true sensitivity
differs a little from the one its calibration assumes.

Firmware, as [F] describes it. At start-up the module averages ``baseline_samples`` (200)
conversions as the empty-pipe capacitance ``C_initial``; then each window it sums
``C_k - C_initial`` and converts with eq. (10)/(14): ``m = k·ΣΔC (+ b)``. Two modes:

``block``
    [F]'s module: one report per second, the grams of the last 1 s window.
``sliding``
    A 1 s window sliding in 0.1 s steps, reported at 10 Hz (papers.md: this is what [F]'s
    0.98 s mean response time needs). Until a full window has been seen the flow is the
    grams over the part seen so far divided by its length.

The intercept ``b`` of eq. (14) is a regression intercept over the calibration runs; adding it
to every 1 s window would bias the flow by +0.4 g/s (papers.md), and Table 1's errors are
mostly negative, which it would not explain. It is therefore not applied by default
(``intercept = "never"``); ``"per_window"`` reproduces eq. (10) literally.

Conversions and windows run on the module's own crystal (a few tens of ppm off the rig's
clock) and are resolved to the physics step; a 1 s window holds 90 or 91 conversions of
11 ms, as the real firmware's would.

The per-step loop (holdup, conversions, baseline, window sums) exists twice (see
:mod:`plant_emulators.engine`): the Python loop below, the reference, and its C twin
(``native/flow_sensor_core.c``), which runs the same operations in the same order and gives
the same floats bit for bit. ``AGRIHIL_PHYSICS`` or the ``engine`` argument picks one. What
runs once per window or less (reports, faults, the vibration noise level) is Python in both.

Example
-------
>>> import numpy as np
>>> from plant_emulators.fertilizer.config import load_rig_config
>>> sensor = FlowSensor(load_rig_config().flow_sensor, np.random.default_rng(3))
>>> sensor.advance(3000, 0.001, 0.0)          # empty pipe: baseline acquisition
>>> sensor.baseline_ready
True
>>> sensor.advance(10000, 0.001, 25.0)
>>> reports = sensor.take_reports()
>>> abs(reports[-1].flow_gps - 25.0) < 1.0      # ~1-2 % scatter per 1 s window
True
"""

from __future__ import annotations

import enum
import math
from bisect import bisect_left
from collections import deque
from functools import partial
from itertools import accumulate, repeat
from typing import Literal, NamedTuple

import numpy as np

from plant_emulators.engine import Engine, load_native, resolve_engine
from plant_emulators.fertilizer.config import FlowSensorConfig
from plant_emulators.fertilizer.noise import NormalStream, ou_coefficients, spawn

__all__ = ["FlowReport", "FlowSensor", "SensorStatus"]

_EMPTY_PIPE_PF = 1.0
"""Empty-pipe capacitance left after the AD7746's CAPDAC offset (pF); it cancels in ΔC."""

_COUNTER_MODULO = 256
"""The rolling counter is one byte."""

_RAW_MAX = 655.35
"""Largest value the 16-bit, 0.01-resolution flow and mass signals can carry."""


_ACCEPTANCE_SIGMAS = 2.0
"""Modules whose calibration error exceeds this many standard deviations fail their
verification (Table 1's worst is 1.20 %) and are recalibrated: the mismatch is drawn from a
normal truncated here."""


def _accepted_normal(rng: np.random.Generator) -> float:
    """A standard normal variate redrawn until within ±:data:`_ACCEPTANCE_SIGMAS`."""
    while True:
        z = float(rng.standard_normal())
        if abs(z) <= _ACCEPTANCE_SIGMAS:
            return z


def _crossing(t0: float, step: float, due: float) -> tuple[int, float]:
    """When a clock that adds ``step`` once per step, starting at ``t0``, first reaches ``due``.

    The additions are the very float operations of ``t += step`` done once per step, in the
    same order (``itertools.accumulate`` runs them in C), so the result is the step at which
    the per-step comparison ``t >= due`` would first be true.

    Parameters
    ----------
    t0 : float
        Clock value before the first step.
    step : float
        Clock increment per step (> 0).
    due : float
        Threshold.

    Returns
    -------
    tuple
        ``(k, t)``: the number of steps (>= 1) and the clock value after them.

    Examples
    --------
    >>> _crossing(0.0, 0.001, 0.011)     # 11 steps of 1 ms, with the rounding they carry
    (11, 0.011000000000000003)
    """
    done = 0
    while True:
        # Enough steps to cross (plus rounding), in bounded pieces.
        chunk = min(4096, max(2, int((due - t0) / step) + 2))
        clock = list(accumulate(repeat(step, chunk), initial=t0))
        k = bisect_left(clock, due, 1)        # clock is increasing: first value >= due
        if k < len(clock):
            return done + k, clock[k]
        done += chunk
        t0 = clock[-1]


_hypot = math.hypot


class SensorStatus(enum.IntFlag):
    """Status bits of a flow report (the DBC's FlowModule status byte)."""

    BASELINE_READY = 1
    """The empty-pipe capacitance has been acquired; values are valid."""
    SLIDING_WINDOW = 2
    """The report is a sliding 1 s window (else a 1 s block)."""
    ADC_OVERRANGE = 4
    """A conversion in the window was outside the AD7746's input range."""
    INTERCEPT_APPLIED = 8
    """The calibration intercept b was added to the window."""


_BASELINE_READY = SensorStatus.BASELINE_READY.value
_SLIDING_WINDOW = SensorStatus.SLIDING_WINDOW.value
_ADC_OVERRANGE = SensorStatus.ADC_OVERRANGE.value
_INTERCEPT_APPLIED = SensorStatus.INTERCEPT_APPLIED.value
_STATUS: tuple[SensorStatus, ...] = tuple(SensorStatus(bits) for bits in range(16))
"""Every status, indexed by its bits."""


#: Report faults: the module reports on time and its number is wrong but looks plausible.
#: Those marked (flag) say so in their status bits, as a real module does; the others do not.
REPORT_FAULTS: dict[str, str] = {
    "baseline_lost": "(flag) a supply dip reset the module with fertilizer in the pipe: it "
                     "clears BaselineReady and, until it can measure the empty pipe again, "
                     "reports against the default baseline: ~65 % of the true flow",
    "overrange": "(flag) dust caked on the electrodes pushes the capacitance past the "
                 "AD7746's input range: conversions clip, AdcOverrange is set, and the flow "
                 "reported is the clipped one, ~60 % of the true flow",
    "implausible": "the calibration constant k of eq. 10 is corrupted (an EEPROM write cut "
                   "short): every report reads 4x the true flow, more than the meter can "
                   "deliver at the target, with good status bits",
    "gain_step": "the sensitivity steps up 30 % (a wet layer on the electrodes): good status "
                 "bits, a plausible number",
    "drift": "the sensitivity drifts up 2 %/s (condensation building up): good status bits",
    "stuck_mid": "the reading freezes at a mid-range number (60 % of the flow when the fault "
                 "began; the ADC's last good conversion repeated): good status bits, the "
                 "counter keeps counting",
}
BASELINE_LOST_GAIN = 0.65
OVERRANGE_GAIN = 0.7
IMPLAUSIBLE_GAIN = 4.0
GAIN_STEP = 1.3
DRIFT_PER_S = 0.02
STUCK_MID_FRACTION = 0.6


class FlowReport(NamedTuple):
    """One report of a flow detection module."""

    time_s: float
    """Rig time at which the report was produced (s)."""
    grams_in_window: float
    """Mass that passed during the window (g)."""
    flow_gps: float
    """Mean flow over the window (g/s)."""
    counter: int
    """Rolling counter, 0..255, incremented per report (frozen when the module is stuck)."""
    status: SensorStatus
    """Status bits."""
    window_s: float
    """Length of the window the values cover, on the rig's clock (s)."""


class FlowSensor:
    """One row's capacitive flow detection module.

    Parameters
    ----------
    config : FlowSensorConfig
        The ``[flow_sensor]`` section.
    rng : numpy.random.Generator
        The run's generator; the module spawns its own child stream at construction.
    mode : {"block", "sliding"}, optional
        Overrides ``config.mode``.
    engine : {"native", "python"}, optional
        Which step loop runs (the same floats either way); None: ``AGRIHIL_PHYSICS``.

    Attributes
    ----------
    stuck : bool
        Fault: the module repeats its last report (same values, same counter).
    silent : bool
        Fault: the module's transmitter is dead. The model keeps running and producing
        reports; the device that sends frames must not send them while this is set.
    garbage : bool
        Fault: reported flow and mass are out of the valid range (above
        ``flow_valid_max_gps``, up to the signal's raw maximum); the counter keeps counting.
    report_fault : str or None
        Fault: the module keeps reporting on time, with a number that looks plausible and is
        wrong (one of :data:`REPORT_FAULTS`; see there what each does). ``None``: healthy.
    vibration_rms_mps2 : float
        Input: RMS vibration of the frame at the module (m/s²); adds capacitance noise.
    """

    def __init__(self, config: FlowSensorConfig, rng: np.random.Generator, *,
                 mode: Literal["block", "sliding"] | None = None,
                 engine: str | None = None) -> None:
        self.config = config
        self.mode: Literal["block", "sliding"] = mode if mode is not None else config.mode
        if self.mode not in ("block", "sliding"):
            raise ValueError(f"mode must be 'block' or 'sliding', got {self.mode!r}")
        self.engine: Engine = resolve_engine(engine)
        own = spawn(rng)
        z_rng = spawn(own)
        self._fault_rng = spawn(own)
        self.calibration_error_frac = config.calibration_mismatch_sd_frac * _accepted_normal(own)
        """This module's true sensitivity relative to what its calibration assumes."""
        self.clock_error_ppm = config.clock_error_sd_ppm * float(own.standard_normal())
        """This module's crystal error (ppm, positive = fast)."""
        self._sensitivity = config.sensitivity_pf_per_g * (1.0 + self.calibration_error_frac)
        self._jitter = config.transit_jitter_sd_frac * float(own.standard_normal())
        self._drift_pf = config.baseline_drift_sd_ff * 1e-3 * float(own.standard_normal())

        self.stuck = False
        self.silent = False
        self.garbage = False
        self.report_fault: str | None = None
        self._fault_since_s = 0.0
        self._stuck_at_gps: float | None = None
        self.vibration_rms_mps2 = 0.0

        conv_s = config.conversion_time_ms / 1000.0
        self._conv_s = conv_s
        self._jit_a, self._jit_b = ou_coefficients(conv_s, config.transit_jitter_time_s,
                                                   config.transit_jitter_sd_frac)
        self._drift_a, self._drift_b = ou_coefficients(
            conv_s, config.baseline_drift_time_s, config.baseline_drift_sd_ff * 1e-3)
        sub_s = config.window_s if self.mode == "block" else config.sliding_report_period_s
        self._sub_s = sub_s
        self._subs_per_window = round(config.window_s / sub_s)
        # Conversion constants, hoisted out of the per-conversion path.
        self._transit_s = config.sensing_transit_s
        self._adc_noise_pf = config.adc_noise_rms_af * 1e-6
        self._vib_pf_per_mps2 = config.vibration_noise_ff_per_mps2 * 1e-3
        self._noise_vib = 0.0                          # vibration of the cached noise level
        self._noise_pf = self._noise_level(0.0)
        self._range_pf = config.adc_range_pf
        self._lsb_pf = config.adc_lsb_af * 1e-6

        # State.
        self._dt: float | None = None
        inv_tau = 1.0 / (config.sensing_transit_s * (1.0 + self._jitter))
        self._core = None
        if self.engine == "native":
            # The twin owns the per-step state (holdup, conversion, baseline, window sums, the
            # window ends; read through the properties) and draws its noise from the same
            # generator in the same blocks as the Python loop's NormalStream.
            native = load_native("plant_emulators.fertilizer._flow_sensor_native")
            self._core = native.FlowSensorCore(
                conv_s, self._jit_a, self._jit_b, self._drift_a, self._drift_b,
                self._transit_s, self._sensitivity, self._range_pf, self._lsb_pf,
                config.baseline_samples, self._jitter, self._drift_pf, inv_tau,
                partial(z_rng.standard_normal, native.NORMAL_BLOCK))
        else:
            self._z = NormalStream(z_rng)
            # The end of the running block (or sliding sub-) window: step count at which it
            # falls due and the module clock then (s); scheduled when dt is bound.
            self._sub_at = 0
            self._sub_clock = 0.0
            self._steps = 0
            self._holdup_g = 0.0
            self._inv_tau = inv_tau
            self._h_acc = 0.0         # Σ holdup over the steps of the running conversion
            self._conv_start = 0      # step count at the start of the running conversion
            self._t_conv = 0.0        # module clock since the last conversion (s)
            self._baseline_acc = 0.0
            self._baseline_n = 0
            self._baseline_pf: float | None = None
            self._sub_sum_pf = 0.0
            self._sub_overrange = False
        self._window: deque[tuple[float, bool]] = deque(maxlen=self._subs_per_window)
        self._counter = 0
        self._last: FlowReport | None = None
        self._pending: list[FlowReport] = []

    # ------------------------------------------------------------------ properties
    @property
    def time_s(self) -> float:
        """Rig time the module has been advanced to (s)."""
        core = self._core
        steps = self._steps if core is None else core.steps
        return steps * (self._dt or 0.0)

    @property
    def baseline_ready(self) -> bool:
        """True once the empty-pipe capacitance has been acquired."""
        return self.baseline_pf is not None

    @property
    def baseline_pf(self) -> float | None:
        """The empty-pipe capacitance the module subtracts (pF), once acquired."""
        core = self._core
        return self._baseline_pf if core is None else core.baseline_pf

    @property
    def holdup_g(self) -> float:
        """Grams currently between the electrodes."""
        core = self._core
        return self._holdup_g if core is None else core.holdup_g

    @property
    def report_period_s(self) -> float:
        """Time between reports on the module's clock (s)."""
        return self._sub_s

    @property
    def step_s(self) -> float | None:
        """The step the module is advanced by (bound by the first :meth:`advance`)."""
        return self._dt

    @property
    def reports_pending(self) -> int:
        """Reports produced and not yet taken (:meth:`take_reports`)."""
        return len(self._pending)

    def next_report_time_s(self) -> float | None:
        """Rig time of the step at whose end the next report will be produced (the end of the
        running window, scheduled in advance on the module's own clock); ``None`` until the
        step size is bound by the first :meth:`advance`. No report can appear before then."""
        if self._dt is None:
            return None
        core = self._core
        return (self._sub_at if core is None else core.sub_at) * self._dt

    # ------------------------------------------------------------------ stepping
    def _bind_dt(self, dt: float) -> None:
        if self._dt is not None:
            if dt != self._dt:
                raise ValueError(
                    f"dt changed from {self._dt} s to {dt} s; a sensor runs at one step size")
            return
        if not 0.0 < dt <= min(self._conv_s, self.config.sensing_transit_s):
            raise ValueError(
                f"dt must be in (0, {min(self._conv_s, self.config.sensing_transit_s)}] s "
                f"(conversion time and transit time), got {dt!r}")
        self._step_rig = dt * (1.0 + self.clock_error_ppm * 1e-6)
        # A small tolerance so that 11 steps of 1 ms make an 11 ms conversion despite rounding.
        tol = dt * 1e-6
        self._conv_due, self._sub_due = self._conv_s - tol, self._sub_s - tol
        if self._core is None:
            self._sub_at, self._sub_clock = _crossing(0.0, self._step_rig, self._sub_due)
        else:                       # the twin schedules the window ends (the same _crossing)
            self._core.bind(dt, self._step_rig, self._conv_due, self._sub_s, self._sub_due)
        self._dt = dt

    def advance(self, n: int, dt: float, flow_gps: float) -> None:
        """Advance ``n`` steps of ``dt`` with ``flow_gps`` passing the module.

        Parameters
        ----------
        n : int
            Number of steps (>= 0).
        dt : float
            Step (s); fixed by the first call.
        flow_gps : float
            Flow through the module during these steps (g/s). Pass the plant's mean flow at
            the sensor over the interval (difference of ``sensor_passed_g`` over ``n·dt``) to
            conserve mass whatever the rig's step partition.
        """
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        if dt != self._dt:          # first call (binds the step) or a changed step (raises)
            self._bind_dt(dt)
        vibration = self.vibration_rms_mps2
        if vibration != self._noise_vib:
            # The vibration is an input held for the whole call: the noise level is
            # recomputed only when it changes, not at every conversion (what _noise_level
            # computes, inlined: this runs on every call of a moving rig).
            self._noise_vib = vibration
            self._noise_pf = _hypot(self._adc_noise_pf, self._vib_pf_per_mps2 * vibration)
        core = self._core
        if core is not None:
            # The twin runs the loop below (q included) up to the end of the call or of the
            # window; at a window's end it schedules the next one (the _crossing below) and
            # returns the steps left, and the window is closed here, as below.
            rest = core.advance(n, flow_gps, self._noise_pf)
            while rest is not None:
                self._close_sub_window(core.steps * dt)
                rest = core.advance(rest, flow_gps, self._noise_pf)
            return
        q = flow_gps if flow_gps > 0.0 else 0.0
        step, conv_due, conv_s = self._step_rig, self._conv_due, self._conv_s
        h, inv_tau = self._holdup_g, self._inv_tau
        h_acc, conv_start = self._h_acc, self._conv_start
        t_conv = self._t_conv
        steps = self._steps
        end = steps + n
        sub_at = self._sub_at
        while True:
            # Run up to the end of the call or of the window, whichever comes first: the
            # window's end is scheduled in advance (``_crossing``), which saves the per-step
            # clock update and test of the window (1 s or 0.1 s away) in this hot loop.
            stop = end if end < sub_at else sub_at
            # The loop variable is the step count after the step (no separate counter).
            for count in range(steps + 1, stop + 1):
                h += dt * (q - h * inv_tau)
                h_acc += h
                t_conv += step
                if t_conv >= conv_due:
                    t_conv -= conv_s
                    inv_tau = self._convert(h_acc / (count - conv_start))
                    h_acc = 0.0
                    conv_start = count
            steps = stop
            if steps != sub_at:
                break
            self._close_sub_window(steps * dt)
            k, self._sub_clock = _crossing(self._sub_clock - self._sub_s, step,
                                           self._sub_due)
            sub_at += k
        self._holdup_g = h
        self._h_acc, self._conv_start = h_acc, conv_start
        self._t_conv, self._sub_at = t_conv, sub_at
        self._steps = steps

    def _noise_level(self, vibration_rms_mps2: float) -> float:
        """RMS capacitance noise of one conversion (pF): ADC noise and vibration combined."""
        return _hypot(self._adc_noise_pf, self._vib_pf_per_mps2 * vibration_rms_mps2)

    def _convert(self, holdup_g: float) -> float:
        """One AD7746 conversion of the mean holdup over the conversion time.

        Returns
        -------
        float
            ``1/τ`` of the transit time for the next conversion (it jitters per conversion).
        """
        z = self._z.next
        jitter = self._jit_a * self._jitter + self._jit_b * z()
        self._jitter = jitter
        inv_tau = 1.0 / (self._transit_s * (1.0 + jitter))
        self._inv_tau = inv_tau
        drift = self._drift_pf = self._drift_a * self._drift_pf + self._drift_b * z()
        c = _EMPTY_PIPE_PF + drift + self._sensitivity * holdup_g + self._noise_pf * z()
        range_pf = self._range_pf
        overrange = abs(c) > range_pf
        if overrange:
            c = math.copysign(range_pf, c)
        lsb = self._lsb_pf
        c = round(c / lsb) * lsb
        baseline = self._baseline_pf
        if baseline is None:
            self._acquire_baseline(c)
        else:
            self._sub_sum_pf += c - baseline
            if overrange:
                self._sub_overrange = True
        return inv_tau

    def _acquire_baseline(self, c: float) -> None:
        """Start-up: average the first conversions as the empty-pipe capacitance."""
        self._baseline_acc += c
        self._baseline_n += 1
        if self._baseline_n >= self.config.baseline_samples:
            self._baseline_pf = self._baseline_acc / self._baseline_n

    def _close_sub_window(self, now_s: float) -> None:
        """End of a block window or of a sliding sub-window: produce a report."""
        cfg = self.config
        # The status bits as a plain int, made a SensorStatus by one table look-up at the end:
        # IntFlag arithmetic costs ~0.8 us an operation, more than the rest of this method.
        status = _SLIDING_WINDOW if self.mode == "sliding" else 0
        grams = flow = 0.0
        span_rig_s = self._sub_s / (1.0 + self.clock_error_ppm * 1e-6)
        if self.baseline_pf is not None:
            core = self._core
            if core is None:
                self._window.append((self._sub_sum_pf, self._sub_overrange))
                self._sub_sum_pf = 0.0
                self._sub_overrange = False
            else:
                self._window.append(core.take_window())
            status |= _BASELINE_READY
            sum_pf = sum([s for s, _ in self._window])          # oldest first, as appended
            if any([o for _, o in self._window]):
                status |= _ADC_OVERRANGE
            grams = cfg.calibration_k_g_per_pf * sum_pf
            if cfg.intercept == "per_window":
                grams += cfg.calibration_b_g
                status |= _INTERCEPT_APPLIED
            span_s = len(self._window) * self._sub_s
            flow = grams / span_s
            span_rig_s = span_s / (1.0 + self.clock_error_ppm * 1e-6)
        if self.stuck and self._last is not None:
            report = self._last._replace(time_s=now_s)
        else:
            if self.garbage:
                lo = cfg.flow_valid_max_gps
                grams = float(self._fault_rng.uniform(lo, _RAW_MAX))
                flow = float(self._fault_rng.uniform(lo, _RAW_MAX))
            elif self.report_fault is not None and status & _BASELINE_READY:
                grams, flow, status = self._faulty_report(grams, flow, status, now_s)
            report = FlowReport(now_s, grams, flow, self._counter, _STATUS[status], span_rig_s)
            self._counter = (self._counter + 1) % _COUNTER_MODULO
            self._last = report
        self._pending.append(report)

    def set_report_fault(self, kind: str | None, time_s: float) -> None:
        """Start the report fault ``kind`` (one of :data:`REPORT_FAULTS`) at ``time_s``, or
        end it (``None``)."""
        if kind is not None and kind not in REPORT_FAULTS:
            raise ValueError(f"unknown report fault {kind!r} ({', '.join(REPORT_FAULTS)})")
        self.report_fault = kind
        self._fault_since_s = time_s
        self._stuck_at_gps = None

    def _faulty_report(self, grams: float, flow: float, status: int,
                       now_s: float) -> tuple[float, float, int]:
        """This report's mass, flow and status bits under ``report_fault``."""
        kind = self.report_fault
        if kind == "stuck_mid":
            # the reading freezes at a mid-range number; the counter keeps counting
            if self._stuck_at_gps is None:
                self._stuck_at_gps = STUCK_MID_FRACTION * flow
            ratio = grams / flow if flow else 0.0          # the window's length, s
            return self._stuck_at_gps * ratio, self._stuck_at_gps, status
        if kind == "baseline_lost":
            gain, status = BASELINE_LOST_GAIN, status & ~_BASELINE_READY
        elif kind == "overrange":
            gain, status = OVERRANGE_GAIN, status | _ADC_OVERRANGE
        elif kind == "implausible":
            gain = IMPLAUSIBLE_GAIN
        elif kind == "gain_step":
            gain = GAIN_STEP
        else:       # drift
            gain = 1.0 + DRIFT_PER_S * max(0.0, now_s - self._fault_since_s)
        return grams * gain, flow * gain, status

    def take_reports(self) -> list[FlowReport]:
        """Return the reports produced since the last call, oldest first, and forget them."""
        out, self._pending = self._pending, []
        return out

    def signals(self) -> dict[str, tuple[float, str]]:
        """Internal state with units, for trace recording."""
        last = self._last
        return {
            "holdup_g": (self.holdup_g, "g"),
            "baseline_ready": (float(self.baseline_ready), "1"),
            "last_flow_gps": (last.flow_gps if last else 0.0, "g/s"),
            "last_grams_in_window": (last.grams_in_window if last else 0.0, "g"),
            "stuck": (float(self.stuck), "1"),
            "silent": (float(self.silent), "1"),
            "garbage": (float(self.garbage), "1"),
        }
