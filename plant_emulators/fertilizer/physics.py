"""Fertilizer planter physics: servo motor → reducer → fluted rollers → tubes.

The plant of paper [F], as papers.md corrects it: the Dunkermotoren BG45X30SI has an integrated
speed controller, so a 0-10 V command sets a *speed* and the plant is command → speed → flow
(type 0). One step of :class:`FertilizerPlant` does, in order:

1. **Drive.** The command (clipped to 0-10 V, dead band) sets a speed reference, rate-limited
   by the drive's ramp. A PI speed loop asks for a current, limited by the drive's current
   limit (derated to the continuous current by an I²t budget) and by the supply voltage minus
   the back-EMF. The shaft obeys ``J dω/dt = Kt·i - b·ω - T_c·sign(ω)``, integrated with a
   linearly implicit Euler step (stable with the ~1 ms electromechanical time constant at any
   step up to 5 ms) and the friction-type load ``T_c`` (meter rollers, chain, bearings,
   reflected through the reducer) applied as an impulse that can stop the shaft but not
   reverse it, so the shaft sticks at standstill instead of chattering. ``stalled`` jams
   the shaft: ω = 0, and the current climbs to the limit.
2. **Reducer and meter.** 50:1 to the meter shaft. Each row's mean flow is the
   :class:`~plant_emulators.fertilizer.flow_map.FlowMap` value times the row's spread, the
   fertilizer's bulk-density factor and the hopper-level factor (falling as the square root
   of what is left once the box is nearly empty); the flutes make it pulse at
   ``flutes x shaft speed`` (two harmonics) and each flute's charge varies a little.
3. **Transport.** A first-order dispersion, then a delay line tapped at the flow sensor and at
   the tube exit. Delivered grams (the truth a scale would weigh) accumulate at the exit.

The hot loop exists twice (see :mod:`plant_emulators.engine`): the Python loop below, the
reference, and its C twin (``native/plant_core.c``), which runs the same operations in the same
order and gives the same floats bit for bit, several times faster. ``AGRIHIL_PHYSICS`` or the
``engine`` argument picks one. The Python loop is plain floats: numpy per step would cost more
than the whole step.
It runs the drive and the meter step by step (they feed back through the hopper level); the
transport, which feeds nothing back, then runs row by row over the whole call. Constants of a
step size are computed once, when the step size is bound.
Every random value comes from the generator given at construction (per-run values drawn then,
per-step noise in pre-drawn blocks), so a run is reproducible from its seed and
``advance(n, dt)`` equals ``n`` calls of ``advance(1, dt)`` bit for bit.

Example
-------
>>> import numpy as np
>>> from plant_emulators.fertilizer.config import load_rig_config
>>> plant = FertilizerPlant(load_rig_config(), np.random.default_rng(7))
>>> plant.command_v = 2.0                     # 600 rpm motor, 12 r/min shaft
>>> plant.advance(3000, 0.001)
>>> round(plant.shaft_speed_rpm, 2)
12.0
"""

from __future__ import annotations

import math
from functools import partial
from typing import NamedTuple

import numpy as np

from plant_emulators.engine import Engine, load_native, resolve_engine
from plant_emulators.fertilizer.config import RPM_PER_RAD_S, FertilizerRigConfig
from plant_emulators.fertilizer.flow_map import FlowMap
from plant_emulators.fertilizer.noise import NormalStream, ou_coefficients, spawn

__all__ = ["MAX_STEP_S", "FertilizerPlant"]

MAX_STEP_S = 0.005
"""Largest physics step (s) for which the speed loop's discrete integrator stays accurate."""

_SLOW_UPDATE_S = 0.01
"""Period (s) of the slow random processes (bulk-density wander)."""

_FLUTE_GUARD = 1e-12
"""Safety margin (flute pitches, per unit of flute index) of the window in which no roller can
have moved to a new flute (see :func:`_flute_window`): thousands of times the rounding error
of ``fpos + offset`` (a few 1e-16 per unit)."""

_LINE_TRIM = 256
"""The transport delay lines grow by one value per step; the values already consumed are
dropped once there are this many (one ``del`` per line every 256 steps keeps the lines short
and cache-friendly)."""


class _DriveConstants(NamedTuple):
    """Drive constants for one step size (computed once, when the step size is bound).

    The three ``den``/``dwf`` pairs are the linearly implicit Euler denominator and the
    friction impulse for each value the current's derivative with respect to the speed can
    take: ``-Ke/Ra`` on the voltage limit, 0 on the current limit, ``-Kp`` in the PI range.
    Precomputing them with the same expressions gives the same floats as computing them per
    step.
    """

    ke: float
    kt: float
    ra: float
    inv_j: float
    kp: float
    ki_dt: float
    vs: float
    i_peak: float
    i_cont: float
    i_cont2: float
    budget: float
    ramp: float
    bl: float
    den_emf: float
    dwf_emf: float
    den_lim: float
    dwf_lim: float
    den_pi: float
    dwf_pi: float


class _MeterConstants(NamedTuple):
    """Meter, fertilizer and transport constants for one step size."""

    shaft_rpm_per_w: float
    rev_per_w_step: float
    coeff: float
    expo: float
    knee: float
    lin_slope: float
    flutes: float
    two_pi_flutes: float
    a1: float
    a2: float
    inv_cap: float
    lsens: float
    starve: float
    starve_level: float
    inv_starve: float
    slow_steps: int
    ou_a: float
    ou_b: float


def _implicit_step(dt: float, kt: float, di: float, bl: float, inv_j: float,
                   t0: float) -> tuple[float, float]:
    """Denominator of the linearly implicit Euler step and the friction impulse divided by it.

    Parameters
    ----------
    dt : float
        Step (s).
    kt, di, bl, inv_j, t0 : float
        Torque constant (N·m/A), d(current)/d(speed) (A·s/rad), viscous load (N·m·s/rad),
        1/J (1/(kg·m²)), friction-type load torque (N·m).

    Returns
    -------
    tuple of float
        ``(den, dw_friction)``.
    """
    den = 1.0 - dt * (kt * di - bl) * inv_j
    return den, dt * t0 * inv_j / den


def _flute_window(offsets: list[float], indices: list[int]) -> tuple[float, float]:
    """Open interval of ``flutes x revolutions`` in which no row changes flute.

    Row ``r`` is on flute ``int(fpos + offsets[r])``. While ``fpos`` stays strictly inside the
    returned interval, that value equals ``indices[r]`` for every row, so the per-row check
    (an ``int()`` per row and step) can be skipped: one comparison per step instead. The
    interval is shrunk by a margin far above the rounding of ``fpos + offset``; near its ends
    the exact per-row check runs, so the result never differs from checking every step.
    """
    lo, hi = -math.inf, math.inf
    for off, k in zip(offsets, indices, strict=True):
        # int() truncates toward zero: int(x) == k on [k, k+1) for k >= 1, on (-1, 1) for
        # k == 0 and on (k-1, k] for k <= -1.
        if k >= 1:
            a, b = k, k + 1
        elif k == 0:
            a, b = -1, 1
        else:
            a, b = k - 1, k
        margin = _FLUTE_GUARD * (abs(k) + 2)
        lo = max(lo, a - off + margin)
        hi = min(hi, b - off - margin)
    return lo, hi


class FertilizerPlant:
    """Servo motor, reducer, four fluted-roller meters and their tubes.

    Parameters
    ----------
    config : FertilizerRigConfig
        The rig configuration (sections motor, drive, meter, fertilizer, transport are used).
    rng : numpy.random.Generator
        The run's generator; the plant spawns its own child stream from it at construction.
    engine : {"native", "python"}, optional
        Which step loop runs (the same floats either way); None: ``AGRIHIL_PHYSICS``.

    Attributes
    ----------
    command_v : float
        Input: voltage at the drive's analog speed input (V), set by the rig from the analog
        output module.
    stalled : bool
        Input (fault): the meter shaft is jammed.
    row_engaged : tuple of bool
        Input: each row's clutch (:meth:`engage_rows`); a disengaged roller stands and meters
        nothing (its drag on the drive is kept: the clutch sits at the roller).
    time_s : float
        Simulated time (s).
    motor_speed_rpm, shaft_speed_rpm : float
        Motor and meter-shaft speed (rpm, r/min).
    motor_current_a : float
        Motor current (A).
    flow_at_meter_gps, flow_at_sensor_gps : tuple of float
        Per row: flow leaving the roller and flow passing the flow sensor (g/s), at the last
        step.
    delivered_g : tuple of float
        Per row: grams that have left the tube exit (the truth).
    in_transit_g : tuple of float
        Per row: grams metered but not yet delivered.
    sensor_passed_g : tuple of float
        Per row: grams that have passed the flow sensor. The mean flow at the sensor over an
        interval is the difference of two readings divided by the interval.
    """

    def __init__(self, config: FertilizerRigConfig, rng: np.random.Generator, *,
                 engine: str | None = None) -> None:
        self.config = config
        self.engine: Engine = resolve_engine(engine)
        motor = config.motor
        drive = config.drive
        meter = config.meter
        fert = config.fertilizer
        rows = meter.rows
        self._rows = rows
        self._flow_map = FlowMap.from_config(meter)

        own = spawn(rng)
        z_rng = spawn(own)
        # Per-run draws, in a fixed order.
        # The rollers differ from each other, not from the meter's calibration: the operator's
        # rotation test (scripts/calibrate_meter.py) weighs all rows of *this* meter together,
        # so their mean is what the calibration absorbs. A draw with its own mean would be a
        # new, uncalibrated meter on every run (issue #16): the spread is drawn about its mean.
        spread = own.standard_normal(rows)
        if rows > 1:
            spread = (spread - spread.mean()) * math.sqrt(rows / (rows - 1))
        self.row_gain: tuple[float, ...] = tuple(
            max(0.5, 1.0 + meter.row_spread_sd_frac * float(v)) for v in spread)
        """Per-row delivery factor of each roller relative to the calibrated meter (mean 1)."""
        flute_offsets = own.uniform(0.0, 1.0, rows).tolist()
        self.density_offset_frac: float = (fert.density_offset_mean_frac
                                           + fert.density_offset_sd_frac
                                           * float(own.standard_normal()))
        """This run's fertilizer delivery offset relative to the calibration (fraction)."""
        self._density_wander = fert.density_drift_sd_frac * float(own.standard_normal())
        cos_off = [math.cos(2.0 * math.pi * f) for f in flute_offsets]
        sin_off = [math.sin(2.0 * math.pi * f) for f in flute_offsets]
        self._core = None
        if self.engine == "native":
            native = load_native("plant_emulators.fertilizer._plant_native")
            # The twin draws its noise from the same generator in the same blocks as the
            # Python loop's NormalStream, starting with each row's first flute charge.
            self._core = native.PlantCore(
                rows, meter.flute_charge_sd_frac, 1.0 + self.density_offset_frac,
                self.row_gain, flute_offsets, cos_off, sin_off,
                fert.hopper_initial_kg * 1000.0, self._density_wander,
                partial(z_rng.standard_normal, native.NORMAL_BLOCK))
        else:
            self._z = NormalStream(z_rng)
            self._charge = [self._draw_charge() for _ in range(rows)]

        # Inputs.
        self.command_v = 0.0
        self.stalled = False
        self.row_engaged: tuple[bool, ...] = (True,) * rows
        #: the gain each row meters with now: its roller's, or 0 with the clutch out
        self._gain_now: list[float] = list(self.row_gain)

        # Drive constants (SI).
        self._ke = motor.ke_v_s_per_rad
        self._kt = motor.kt_nm_per_a
        self._ra = motor.armature_resistance_ohm
        self._inv_j = 1.0 / motor.inertia_kg_m2
        wn = 2.0 * math.pi * motor.speed_loop_bandwidth_hz
        self._kp = 2.0 * motor.speed_loop_damping * wn * motor.inertia_kg_m2 / self._kt
        self._ki = wn * wn * motor.inertia_kg_m2 / self._kt
        self._w_per_v = motor.rpm_per_command_v / RPM_PER_RAD_S
        self._ratio = drive.total_ratio
        shaft_rpm_per_rad_s = RPM_PER_RAD_S / self._ratio
        to_motor = 1.0 / (self._ratio * drive.reducer_efficiency)
        self._load_t0 = ((rows * meter.roller_torque_nm + drive.shaft_friction_nm) * to_motor
                         + motor.coulomb_friction_nm)
        self._load_b = (rows * meter.roller_torque_per_rpm_nm * shaft_rpm_per_rad_s * to_motor
                        + motor.viscous_friction_nm_per_krpm / 1000.0 * RPM_PER_RAD_S)
        self._i2t_budget = ((motor.current_limit_a ** 2 - motor.continuous_current_a ** 2)
                            * motor.peak_current_time_s)

        # Meter state of the Python loop (the twin keeps its own, charges included).
        if self._core is None:
            self._flute_offsets = flute_offsets
            self._cos_off = cos_off
            self._sin_off = sin_off
            self._flute_index = [int(f) for f in flute_offsets]
            # Per-row values the inner loop reads, packed so that one tuple unpacking replaces
            # four list subscripts per row and step; rebuilt when a row's flute charge changes.
            self._row_params = [(g, ch, co, so) for g, ch, co, so in zip(
                self._gain_now, self._charge, self._cos_off, self._sin_off, strict=True)]
            self._flute_lo, self._flute_hi = _flute_window(flute_offsets, self._flute_index)
            self._q_map = 0.0      # flow map value at ``_n_map`` (cache of the power law)
            self._n_map = 0.0

        # State.
        self._w = 0.0              # motor speed (rad/s)
        self._w_ref = 0.0          # ramped speed reference (rad/s)
        self._xi = 0.0             # speed-loop integrator (A)
        self._i = 0.0              # motor current (A)
        self._i2t = 0.0            # used I²t budget (A²·s)
        self._derated = False      # drive limited to continuous current
        self._rev = 0.0            # meter-shaft revolutions
        self._hopper_g = fert.hopper_initial_kg * 1000.0
        # Per row: (Σ meter flow, dispersion filter output, Σ flow at the sensor, Σ flow at
        # the exit), flows in g/s and sums over steps (x dt = grams).
        self._row_state: list[tuple[float, float, float, float]] = [(0.0, 0.0, 0.0, 0.0)] * rows
        self.flow_at_meter_gps: tuple[float, ...] = (0.0,) * rows
        self.flow_at_sensor_gps: tuple[float, ...] = (0.0,) * rows
        self._steps = 0
        self._slow_countdown = 0
        self._dt: float | None = None
        self._drive: _DriveConstants          # both set when the step size is bound
        self._meter: _MeterConstants
        # Transport delay line per row: the dispersion output of every step, oldest first,
        # from index ``_line_base`` on (see :meth:`_transport`).
        self._lines: list[list[float]] = []
        self._line_base = 0
        self._to_exit = 0
        self._to_sensor = 0
        self._alpha = 1.0
        self._update_outputs()

    # ------------------------------------------------------------------ helpers
    def engage_rows(self, engaged: tuple[bool, ...]) -> None:
        """Set the row clutches (one flag per row, row 1 first) from the next step on.

        Raises
        ------
        ValueError
            Not one flag per row.
        """
        engaged = tuple(bool(e) for e in engaged)
        if len(engaged) != self._rows:
            raise ValueError(f"{len(engaged)} clutch states for {self._rows} rows")
        if engaged == self.row_engaged:
            return
        self.row_engaged = engaged
        self._gain_now = [g if e else 0.0 for g, e in zip(self.row_gain, engaged, strict=True)]
        if self._core is not None:
            self._core.set_gains(self._gain_now)
        else:
            self._row_params = [(g, *rest[1:]) for g, rest in
                                zip(self._gain_now, self._row_params, strict=True)]

    def _draw_charge(self) -> float:
        return max(0.0, 1.0 + self.config.meter.flute_charge_sd_frac * self._z.next())

    def _bind_dt(self, dt: float) -> None:
        if self._dt is not None:
            if dt != self._dt:
                raise ValueError(
                    f"dt changed from {self._dt} s to {dt} s; a plant runs at one step size")
            return
        if not 0.0 < dt <= MAX_STEP_S:
            raise ValueError(f"dt must be in (0, {MAX_STEP_S}] s, got {dt!r}")
        tr = self.config.transport
        to_sensor = max(1, round(tr.meter_to_sensor_delay_s / dt))
        to_exit = max(1, round(tr.sensor_to_exit_delay_s / dt))
        if self._core is None:
            self._lines = [[0.0] * (to_sensor + to_exit) for _ in range(self._rows)]
        self._line_base = 0
        self._to_exit = to_exit
        self._to_sensor = to_sensor
        self._drive = self._drive_constants(dt)
        self._meter = self._meter_constants(dt)
        tau_d = tr.dispersion_time_s
        self._alpha = 1.0 - math.exp(-dt / tau_d) if tau_d > 0.0 else 1.0
        if self._core is not None:
            self._core.bind(dt, self._drive, self._meter, self._alpha, to_sensor, to_exit)
        self._dt = dt

    def _drive_constants(self, dt: float) -> _DriveConstants:
        motor = self.config.motor
        ke, kt, ra, inv_j = self._ke, self._kt, self._ra, self._inv_j
        kp = self._kp
        i_cont = motor.continuous_current_a
        t0, bl = self._load_t0, self._load_b
        ke_ra = ke / ra
        return _DriveConstants(
            ke, kt, ra, inv_j, kp, self._ki * dt, motor.supply_v, motor.current_limit_a,
            i_cont, i_cont * i_cont, self._i2t_budget,
            motor.setpoint_ramp_rpm_per_s / RPM_PER_RAD_S * dt, bl,
            *_implicit_step(dt, kt, -ke_ra, bl, inv_j, t0),
            *_implicit_step(dt, kt, 0.0, bl, inv_j, t0),
            *_implicit_step(dt, kt, -kp, bl, inv_j, t0))

    def _meter_constants(self, dt: float) -> _MeterConstants:
        meter = self.config.meter
        fert = self.config.fertilizer
        fm = self._flow_map
        flutes = float(meter.flutes)
        lsens = fert.level_sensitivity_frac
        starve = fert.starvation_fill_frac
        slow_steps = max(1, round(_SLOW_UPDATE_S / dt))
        return _MeterConstants(
            RPM_PER_RAD_S / self._ratio, dt / (2.0 * math.pi * self._ratio),
            fm.coeff_gps, fm.exponent, fm.linear_below_rpm, fm.linear_slope_gps_per_rpm,
            flutes, 2.0 * math.pi * flutes,
            meter.pulsation_first_harmonic_frac, meter.pulsation_second_harmonic_frac,
            1.0 / (fert.hopper_capacity_kg * 1000.0), lsens, starve,
            1.0 - lsens * (1.0 - starve), 1.0 / starve if starve > 0.0 else 0.0,
            slow_steps,
            *ou_coefficients(slow_steps * dt, fert.density_drift_time_s,
                             fert.density_drift_sd_frac))

    # ------------------------------------------------------------------ stepping
    def advance(self, n: int, dt: float) -> None:
        """Advance the plant by ``n`` steps of ``dt`` seconds.

        Parameters
        ----------
        n : int
            Number of steps (>= 0).
        dt : float
            Step (s), in (0, :data:`MAX_STEP_S`]; fixed by the first call.

        Raises
        ------
        ValueError
            On a negative ``n``, a step outside the range, or a step that differs from the
            first call's.
        """
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        if dt != self._dt:          # first call (binds the step) or a changed step (raises)
            self._bind_dt(dt)
        if n == 0:
            return
        motor = self.config.motor

        # Inputs, held for the whole call.
        v_cmd = min(max(self.command_v, 0.0), motor.command_full_scale_v)
        w_target = v_cmd * self._w_per_v if v_cmd > motor.command_deadband_v else 0.0
        stalled = bool(self.stalled)
        if self._core is not None:
            self._core.advance(n, w_target, stalled, 1.0 + self.density_offset_frac)
            self._steps += n
            self._update_outputs()
            return

        # Constants of this step size: one tuple unpacking each (fields in declared order)
        # instead of rebuilding them from the configuration on every call.
        (ke, kt, ra, inv_j, kp, ki_dt, vs, i_peak, i_cont, i_cont2, budget, ramp, bl,
         den_emf, dwf_emf, den_lim, dwf_lim, den_pi, dwf_pi) = self._drive
        (shaft_rpm_per_w, rev_per_w_step, coeff, expo, knee, lin_slope, flutes, two_pi_flutes,
         a1, a2, inv_cap, lsens, starve, starve_level, inv_starve, slow_steps, ou_a,
         ou_b) = self._meter
        znext = self._z.next
        cos, sin = math.cos, math.sin
        dens_base = 1.0 + self.density_offset_frac
        row_params = self._row_params
        # Per-step meter flows of every row, step-major; the transport runs on them after the
        # loop (it does not feed back into the drive or the meter).
        flows: list[float] = []
        put = flows.append

        # State to locals.
        w, w_ref, xi, cur = self._w, self._w_ref, self._xi, self._i
        i2t, derated = self._i2t, self._derated
        i_lim = i_cont if derated else i_peak     # current limit, updated with ``derated``
        rev, hopper = self._rev, self._hopper_g
        wander = self._density_wander
        density = dens_base + wander
        countdown = self._slow_countdown
        flute_lo, flute_hi = self._flute_lo, self._flute_hi
        n_map, q_map = self._n_map, self._q_map

        for _ in range(n):
            # ---- slow processes
            if countdown <= 0:
                countdown = slow_steps
                wander = ou_a * wander + ou_b * znext()
                density = dens_base + wander
            countdown -= 1

            # ---- speed reference ramp
            if w_ref < w_target:
                w_ref += ramp
                if w_ref > w_target:
                    w_ref = w_target
            elif w_ref > w_target:
                w_ref -= ramp
                if w_ref < w_target:
                    w_ref = w_target
            if stalled:
                w = 0.0

            # ---- current: PI, current limit, voltage limit. The upper limit is the lower of
            # the current limit and what the supply can drive against the back-EMF (the
            # lower limit likewise); each branch also picks the implicit-Euler denominator
            # and friction impulse of its d(current)/d(speed): -Ke/Ra on the voltage limit,
            # 0 on the current limit, -Kp in the PI range.
            err = w_ref - w
            i_cmd = kp * err + xi
            back_emf = ke * w
            i_hi = (vs - back_emf) / ra
            if i_cmd > i_hi or i_cmd > i_lim:
                if i_hi < i_lim:
                    cur, den, dwf = i_hi, den_emf, dwf_emf
                else:
                    cur, den, dwf = i_lim, den_lim, dwf_lim
                if err < 0.0:
                    xi += ki_dt * err
            else:
                # The lower limit only matters below the upper one: computed only then.
                i_lo = (-vs - back_emf) / ra
                if i_cmd < i_lo or i_cmd < -i_lim:
                    if i_lo > -i_lim:
                        cur, den, dwf = i_lo, den_emf, dwf_emf
                    else:
                        cur, den, dwf = -i_lim, den_lim, dwf_lim
                    if err > 0.0:
                        xi += ki_dt * err
                else:
                    cur, den, dwf = i_cmd, den_pi, dwf_pi
                    xi += ki_dt * err

            # ---- mechanics: linearly implicit Euler on the smooth torques, then the
            # friction-type load (meter, chain, bearings) as a velocity impulse that can stop
            # the shaft but never reverse it (stick-slip without chatter).
            if not stalled:
                w_free = w + dt * (kt * cur - bl * w) * inv_j / den
                if w_free > dwf:
                    w = w_free - dwf
                elif w_free < -dwf:
                    w = w_free + dwf
                else:
                    w = 0.0

            # ---- I²t protection
            i2t += (cur * cur - i_cont2) * dt
            if i2t <= 0.0:
                i2t = 0.0
                derated = False
                i_lim = i_peak
            elif i2t >= budget:
                derated = True
                i_lim = i_cont

            # ---- meter
            n_shaft = w * shaft_rpm_per_w
            rev += w * rev_per_w_step
            if n_shaft != n_map:
                # At steady speed the shaft speed repeats exactly: the power law (the
                # costliest operation of the drive and meter) is evaluated only on change.
                n_map = n_shaft
                if n_shaft >= knee:
                    q_map = coeff * n_shaft ** expo
                elif n_shaft > 0.0:
                    q_map = lin_slope * n_shaft
                else:
                    q_map = 0.0
            fill = hopper * inv_cap
            if fill >= starve:
                level = 1.0 - lsens * (1.0 - fill)
            elif fill > 0.0:
                level = math.sqrt(fill * inv_starve) * starve_level
            else:
                level = 0.0
            q0 = q_map * (density * level)
            fpos = flutes * rev
            if not flute_lo < fpos < flute_hi:
                flute_lo, flute_hi = self._next_flutes(fpos)
            theta = two_pi_flutes * rev
            c1 = cos(theta)
            s1 = sin(theta)
            q_total = 0.0
            for gain, charge, cos_off, sin_off in row_params:
                c = c1 * cos_off - s1 * sin_off
                q = q0 * gain * charge * (1.0 + a1 * c + a2 * (2.0 * c * c - 1.0))
                q_total += q
                put(q)
            hopper -= q_total * dt

        # State back.
        self._w, self._w_ref, self._xi, self._i = w, w_ref, xi, cur
        self._i2t, self._derated = i2t, derated
        self._rev, self._hopper_g = rev, hopper
        self._density_wander = wander
        self._slow_countdown = countdown
        self._flute_lo, self._flute_hi = flute_lo, flute_hi
        self._n_map, self._q_map = n_map, q_map
        self.flow_at_meter_gps = tuple(flows[-len(row_params):])
        self._transport(flows, n)
        self._steps += n
        self._update_outputs()

    def _next_flutes(self, fpos: float) -> tuple[float, float]:
        """Redraw the charge of each row whose roller reached a new flute; the new window.

        Called when ``fpos`` (flutes x revolutions) leaves the window in which no row can
        change flute. Rows are checked in order, so the random draws come in the same order
        as a per-row, per-step check would make them.
        """
        sd = self.config.meter.flute_charge_sd_frac
        znext = self._z.next
        offsets, indices, charges = self._flute_offsets, self._flute_index, self._charge
        for r, off in enumerate(offsets):
            k = int(fpos + off)
            if k != indices[r]:
                indices[r] = k
                ch = 1.0 + sd * znext()
                charges[r] = ch if ch > 0.0 else 0.0
                self._row_params[r] = (self._gain_now[r], charges[r], self._cos_off[r],
                                       self._sin_off[r])
        return _flute_window(offsets, indices)

    def _transport(self, flows: list[float], n: int) -> None:
        """Dispersion, delay line and accumulators of every row, over a whole call.

        ``flows`` holds the meter flow of every row at each of the ``n`` steps, step-major.
        A row's transport depends neither on the other rows nor on the drive, so it runs row
        by row with its state in locals (no list subscripts per step); every accumulation is
        still a sequential ``+=`` per step, so the results are the same floats.
        """
        rows, alpha = self._rows, self._alpha
        base, to_exit, to_sensor = self._line_base, self._to_exit, self._to_sensor
        lines, state = self._lines, self._row_state
        # ``line[base:]`` holds a row's line oldest first: at step j of the call, the value
        # written ``length`` steps earlier leaves the tube (``line[base + j]``) and the one
        # written ``to_sensor = length - to_exit`` steps earlier passes the sensor
        # (``line[base + to_exit + j]``). Chunks of at most ``to_sensor`` steps (one chunk
        # for the rig's 10-step calls) read only values written before the chunk.
        for start in range(0, n, to_sensor):
            stop = min(n, start + to_sensor)
            exit_lo, exit_hi = base + start, base + stop
            sens_lo, sens_hi = exit_lo + to_exit, exit_hi + to_exit
            for r in range(rows):
                line = lines[r]
                put = line.append
                m, y, p, d = state[r]
                for q, q_exit, q_sens in zip(flows[start * rows + r:stop * rows:rows],
                                             line[exit_lo:exit_hi], line[sens_lo:sens_hi],
                                             strict=True):
                    m += q
                    y += alpha * (q - y)
                    put(y)
                    p += q_sens
                    d += q_exit
                state[r] = (m, y, p, d)
        base += n
        self.flow_at_sensor_gps = tuple([line[base + to_exit - 1] for line in lines])
        if base >= _LINE_TRIM:
            for line in lines:
                del line[:base]
            base = 0
        self._line_base = base

    # ------------------------------------------------------------------ outputs
    def _update_outputs(self) -> None:
        dt = self._dt or 0.0
        core = self._core
        if core is not None:
            (self._w, self._w_ref, self._xi, self._i, self._i2t, self._derated, self._rev,
             self._hopper_g, self._density_wander) = core.state()
            if self._dt is not None:
                (self.sensor_passed_g, self.delivered_g, self.flow_at_meter_gps,
                 self.flow_at_sensor_gps) = core.rows_out()
            else:
                self.sensor_passed_g = self.delivered_g = (0.0,) * self._rows
        else:
            state = self._row_state
            self.sensor_passed_g = tuple([row[2] * dt for row in state])
            self.delivered_g = tuple([row[3] * dt for row in state])
        self.time_s = self._steps * dt
        self.motor_speed_rpm = self._w * RPM_PER_RAD_S
        self.shaft_speed_rpm = self.motor_speed_rpm / self.config.drive.total_ratio
        self.speed_reference_rpm = self._w_ref * RPM_PER_RAD_S
        self.motor_current_a = self._i
        self.motor_voltage_v = self._i * self._ra + self._ke * self._w
        self.drive_derated = self._derated
        self.shaft_revolutions = self._rev
        self.hopper_kg = self._hopper_g / 1000.0
        self.density_factor = 1.0 + self.density_offset_frac + self._density_wander

    @property
    def metered_g(self) -> tuple[float, ...]:
        """Per row: grams that have left the roller (computed on access: rarely read)."""
        if self._core is not None:
            return tuple(self._core.metered())
        dt = self._dt or 0.0
        return tuple([row[0] * dt for row in self._row_state])

    @property
    def in_transit_g(self) -> tuple[float, ...]:
        """Per row: grams metered but not yet delivered (computed on access)."""
        return tuple([m - d for m, d in zip(self.metered_g, self.delivered_g, strict=True)])

    @property
    def flow_map(self) -> FlowMap:
        """The calibrated map of the nominal row (no drift, spread or pulsation)."""
        return self._flow_map

    def signals(self) -> dict[str, tuple[float, str]]:
        """Every output with its unit, for trace recording.

        Returns
        -------
        dict
            ``name → (value, unit)``; per-row values are named ``row<k>_<output>`` with
            ``k`` from 1.
        """
        out: dict[str, tuple[float, str]] = {
            "time_s": (self.time_s, "s"),
            "command_v": (float(min(max(self.command_v, 0.0),
                                    self.config.motor.command_full_scale_v)), "V"),
            "stalled": (float(bool(self.stalled)), "1"),
            "speed_reference_rpm": (self.speed_reference_rpm, "rpm"),
            "motor_speed_rpm": (self.motor_speed_rpm, "rpm"),
            "shaft_speed_rpm": (self.shaft_speed_rpm, "r/min"),
            "motor_current_a": (self.motor_current_a, "A"),
            "motor_voltage_v": (self.motor_voltage_v, "V"),
            "drive_derated": (float(self.drive_derated), "1"),
            "hopper_kg": (self.hopper_kg, "kg"),
            "density_factor": (self.density_factor, "1"),
        }
        for r in range(self._rows):
            k = r + 1
            out[f"row{k}_flow_at_meter_gps"] = (self.flow_at_meter_gps[r], "g/s")
            out[f"row{k}_flow_at_sensor_gps"] = (self.flow_at_sensor_gps[r], "g/s")
            out[f"row{k}_metered_g"] = (self.metered_g[r], "g")
            out[f"row{k}_sensor_passed_g"] = (self.sensor_passed_g[r], "g")
            out[f"row{k}_delivered_g"] = (self.delivered_g[r], "g")
            out[f"row{k}_in_transit_g"] = (self.in_transit_g[r], "g")
        return out
