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

The hot loop is plain Python floats: numpy per step would cost more than the whole step.
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

import numpy as np

from plant_emulators.fertilizer.config import RPM_PER_RAD_S, FertilizerRigConfig
from plant_emulators.fertilizer.flow_map import FlowMap
from plant_emulators.fertilizer.noise import NormalStream, ou_coefficients, spawn

__all__ = ["MAX_STEP_S", "FertilizerPlant"]

MAX_STEP_S = 0.005
"""Largest physics step (s) for which the speed loop's discrete integrator stays accurate."""

_SLOW_UPDATE_S = 0.01
"""Period (s) of the slow random processes (bulk-density wander)."""



class FertilizerPlant:
    """Servo motor, reducer, four fluted-roller meters and their tubes.

    Parameters
    ----------
    config : FertilizerRigConfig
        The rig configuration (sections motor, drive, meter, fertilizer, transport are used).
    rng : numpy.random.Generator
        The run's generator; the plant spawns its own child stream from it at construction.

    Attributes
    ----------
    command_v : float
        Input: voltage at the drive's analog speed input (V), set by the rig from the analog
        output module.
    stalled : bool
        Input (fault): the meter shaft is jammed.
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

    def __init__(self, config: FertilizerRigConfig, rng: np.random.Generator) -> None:
        self.config = config
        motor = config.motor
        drive = config.drive
        meter = config.meter
        fert = config.fertilizer
        rows = meter.rows
        self._rows = rows
        self._flow_map = FlowMap.from_config(meter)

        own = spawn(rng)
        self._z = NormalStream(spawn(own))
        # Per-run draws, in a fixed order.
        self.row_gain: tuple[float, ...] = tuple(
            max(0.5, 1.0 + meter.row_spread_sd_frac * float(v))
            for v in own.standard_normal(rows))
        """Per-row delivery factor of each roller relative to the nominal map."""
        flute_offsets = own.uniform(0.0, 1.0, rows).tolist()
        self.density_offset_frac: float = (fert.density_offset_mean_frac
                                           + fert.density_offset_sd_frac
                                           * float(own.standard_normal()))
        """This run's fertilizer delivery offset relative to the calibration (fraction)."""
        self._density_wander = fert.density_drift_sd_frac * float(own.standard_normal())
        self._charge = [self._draw_charge() for _ in range(rows)]

        # Inputs.
        self.command_v = 0.0
        self.stalled = False

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

        # Meter constants.
        self._flute_offsets = flute_offsets
        self._cos_off = [math.cos(2.0 * math.pi * f) for f in flute_offsets]
        self._sin_off = [math.sin(2.0 * math.pi * f) for f in flute_offsets]
        self._flute_index = [int(f) for f in flute_offsets]

        # State.
        self._w = 0.0              # motor speed (rad/s)
        self._w_ref = 0.0          # ramped speed reference (rad/s)
        self._xi = 0.0             # speed-loop integrator (A)
        self._i = 0.0              # motor current (A)
        self._i2t = 0.0            # used I²t budget (A²·s)
        self._derated = False      # drive limited to continuous current
        self._rev = 0.0            # meter-shaft revolutions
        self._hopper_g = fert.hopper_initial_kg * 1000.0
        self._disp = [0.0] * rows  # dispersion filter state per row (g/s)
        self._flow_meter = [0.0] * rows
        self._flow_sensor = [0.0] * rows
        self._metered_sum = [0.0] * rows   # Σ flow over steps (g/s·step); x dt = grams
        self._passed_sum = [0.0] * rows
        self._delivered_sum = [0.0] * rows
        self._steps = 0
        self._slow_countdown = 0
        self._dt: float | None = None
        self._delay: list[list[float]] = []
        self._write = 0
        self._tap = 0
        self._update_outputs()

    # ------------------------------------------------------------------ helpers
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
        length = to_sensor + to_exit
        self._delay = [[0.0] * length for _ in range(self._rows)]
        self._write = 0
        self._tap = to_exit % length    # reads the value written ``to_sensor`` steps ago
        self._dt = dt

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
        self._bind_dt(dt)
        if n == 0:
            return
        cfg = self.config
        motor = cfg.motor
        meter = cfg.meter
        fert = cfg.fertilizer

        # Inputs, held for the whole call.
        v_cmd = min(max(self.command_v, 0.0), motor.command_full_scale_v)
        w_target = v_cmd * self._w_per_v if v_cmd > motor.command_deadband_v else 0.0
        stalled = bool(self.stalled)

        # Drive constants.
        ke, kt, ra, inv_j = self._ke, self._kt, self._ra, self._inv_j
        kp, ki_dt = self._kp, self._ki * dt
        vs = motor.supply_v
        i_peak, i_cont = motor.current_limit_a, motor.continuous_current_a
        i_cont2 = i_cont * i_cont
        budget = self._i2t_budget
        ramp = motor.setpoint_ramp_rpm_per_s / RPM_PER_RAD_S * dt
        t0, bl = self._load_t0, self._load_b
        ke_ra = ke / ra
        # Meter constants.
        shaft_rpm_per_w = RPM_PER_RAD_S / self._ratio
        rev_per_w_step = dt / (2.0 * math.pi * self._ratio)
        fm = self._flow_map
        coeff, expo, knee = fm.coeff_gps, fm.exponent, fm.linear_below_rpm
        lin_slope = fm.linear_slope_gps_per_rpm
        flutes = float(meter.flutes)
        two_pi_flutes = 2.0 * math.pi * flutes
        a1 = meter.pulsation_first_harmonic_frac
        a2 = meter.pulsation_second_harmonic_frac
        charge_sd = meter.flute_charge_sd_frac
        gains = self.row_gain
        cos_off, sin_off = self._cos_off, self._sin_off
        foff = self._flute_offsets
        kidx, charge = self._flute_index, self._charge
        znext = self._z.next
        cap_g = fert.hopper_capacity_kg * 1000.0
        inv_cap = 1.0 / cap_g
        lsens = fert.level_sensitivity_frac
        starve = fert.starvation_fill_frac
        starve_level = 1.0 - lsens * (1.0 - starve)
        inv_starve = 1.0 / starve if starve > 0.0 else 0.0
        slow_steps = max(1, round(_SLOW_UPDATE_S / dt))
        ou_a, ou_b = ou_coefficients(slow_steps * dt, fert.density_drift_time_s,
                                     fert.density_drift_sd_frac)
        dens_base = 1.0 + self.density_offset_frac
        tau_d = cfg.transport.dispersion_time_s
        alpha = 1.0 - math.exp(-dt / tau_d) if tau_d > 0.0 else 1.0
        rows = range(self._rows)
        delay = self._delay
        length = len(delay[0])
        disp = self._disp
        flow_meter, flow_sensor = self._flow_meter, self._flow_sensor
        metered, passed, delivered = self._metered_sum, self._passed_sum, self._delivered_sum

        # State to locals.
        w, w_ref, xi, cur = self._w, self._w_ref, self._xi, self._i
        i2t, derated = self._i2t, self._derated
        rev, hopper = self._rev, self._hopper_g
        wander = self._density_wander
        countdown = self._slow_countdown
        wi, ti = self._write, self._tap

        for _ in range(n):
            # ---- slow processes
            if countdown <= 0:
                countdown = slow_steps
                wander = ou_a * wander + ou_b * znext()
            countdown -= 1
            density = dens_base + wander

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

            # ---- current: PI, current limit, voltage limit
            i_lim = i_cont if derated else i_peak
            err = w_ref - w
            i_cmd = kp * err + xi
            i_hi = (vs - ke * w) / ra
            if i_hi < i_lim:
                d_hi = -ke_ra
            else:
                i_hi = i_lim
                d_hi = 0.0
            i_lo = (-vs - ke * w) / ra
            if i_lo > -i_lim:
                d_lo = -ke_ra
            else:
                i_lo = -i_lim
                d_lo = 0.0
            if i_cmd > i_hi:
                cur = i_hi
                di = d_hi
                if err < 0.0:
                    xi += ki_dt * err
            elif i_cmd < i_lo:
                cur = i_lo
                di = d_lo
                if err > 0.0:
                    xi += ki_dt * err
            else:
                cur = i_cmd
                di = -kp
                xi += ki_dt * err

            # ---- mechanics: linearly implicit Euler on the smooth torques, then the
            # friction-type load (meter, chain, bearings) as a velocity impulse that can stop
            # the shaft but never reverse it (stick-slip without chatter).
            if not stalled:
                den = 1.0 - dt * (kt * di - bl) * inv_j
                w_free = w + dt * (kt * cur - bl * w) * inv_j / den
                dw_friction = dt * t0 * inv_j / den
                if w_free > dw_friction:
                    w = w_free - dw_friction
                elif w_free < -dw_friction:
                    w = w_free + dw_friction
                else:
                    w = 0.0

            # ---- I²t protection
            i2t += (cur * cur - i_cont2) * dt
            if i2t <= 0.0:
                i2t = 0.0
                derated = False
            elif i2t >= budget:
                derated = True

            # ---- meter
            n_shaft = w * shaft_rpm_per_w
            rev += w * rev_per_w_step
            if n_shaft >= knee:
                q0 = coeff * n_shaft ** expo
            elif n_shaft > 0.0:
                q0 = lin_slope * n_shaft
            else:
                q0 = 0.0
            fill = hopper * inv_cap
            if fill >= starve:
                level = 1.0 - lsens * (1.0 - fill)
            elif fill > 0.0:
                level = math.sqrt(fill * inv_starve) * starve_level
            else:
                level = 0.0
            q0 *= density * level
            fpos = flutes * rev
            theta = two_pi_flutes * rev
            c1 = math.cos(theta)
            s1 = math.sin(theta)
            q_total = 0.0
            for r in rows:
                k = int(fpos + foff[r])
                if k != kidx[r]:
                    kidx[r] = k
                    ch = 1.0 + charge_sd * znext()
                    charge[r] = ch if ch > 0.0 else 0.0
                c = c1 * cos_off[r] - s1 * sin_off[r]
                q = q0 * gains[r] * charge[r] * (1.0 + a1 * c + a2 * (2.0 * c * c - 1.0))
                flow_meter[r] = q
                metered[r] += q
                q_total += q
                y = disp[r]
                y += alpha * (q - y)
                disp[r] = y
                line = delay[r]
                q_exit = line[wi]
                q_sens = line[ti]
                line[wi] = y
                flow_sensor[r] = q_sens
                passed[r] += q_sens
                delivered[r] += q_exit
            hopper -= q_total * dt
            wi += 1
            if wi == length:
                wi = 0
            ti += 1
            if ti == length:
                ti = 0

        # State back.
        self._w, self._w_ref, self._xi, self._i = w, w_ref, xi, cur
        self._i2t, self._derated = i2t, derated
        self._rev, self._hopper_g = rev, hopper
        self._density_wander = wander
        self._slow_countdown = countdown
        self._write, self._tap = wi, ti
        self._steps += n
        self._update_outputs()

    # ------------------------------------------------------------------ outputs
    def _update_outputs(self) -> None:
        dt = self._dt or 0.0
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
        self.flow_at_meter_gps = tuple(self._flow_meter)
        self.flow_at_sensor_gps = tuple(self._flow_sensor)
        metered = tuple(s * dt for s in self._metered_sum)
        self.metered_g = metered
        self.sensor_passed_g = tuple(s * dt for s in self._passed_sum)
        self.delivered_g = tuple(s * dt for s in self._delivered_sum)
        self.in_transit_g = tuple(m - d for m, d in zip(metered, self.delivered_g, strict=True))

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
