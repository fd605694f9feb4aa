"""The servo electric cylinder: integrated servo motor, belt, 10:1 reducer, lead screw, rod.

Model (rod frame, SI except positions in mm)
-------------------------------------------
The integrated servo motor runs its own current and velocity loops; the CiA 402 drive logic
(:mod:`.cia402`) hands it a rod velocity command ``v_cmd`` each step. The velocity loop is a
first-order lag of time constant ``τ_v`` with ideal load feed-forward, limited by the torque the
motor may give::

    k_F   = 2π · i_belt · i_red · η / lead              rod force per motor torque [N/(N·m)]
    m_eff = (J_a + J_tr) · (2π · i_belt · i_red / lead)² + m_rod      reflected mass [kg]
    a_des = (v_cmd - v) · (1 - exp(-dt/τ_v)) / dt
    F_req = m_eff · a_des + F_load
    T     = clamp(F_req / k_F, ±T_lim),   T_lim = min(F_max / k_F, Kt · (U - Ke·|ω|) / R_a)
    a     = (k_F · T - F_load) / m_eff,   v ← clamp(v + a·dt, ±v_max),   x ← x + (v + v')/2 · dt

``T_lim`` is the push-force rating (9,806.65 N) and, when the motor is driving, the voltage limit
of the DC bus. When ``T`` is clipped the cylinder is *at its force limit* (the drive's overload
monitor integrates that). The soil reaction on the pre-sowing press roller is a one-sided spring
set by the plant, with viscous soil damping while in contact:
``F_load = k · max(0, x - x_contact) + c · v · [x > x_contact] - W`` (``W`` the roller's weight).
Hard end stops at 0 and the stroke stop the rod. With the power stage off the holding brake
holds the rod. ``jammed`` (a fault hook) holds the rod as if blocked by a stone.

The 0.39 Ω, 2.78 kg·cm², 6.1 Vrms/krpm of [D] are used in the DC-equivalent form of [D]'s
eq. (4), where Kt = Ke in SI (0.0583 N·m/A); the published Kt = 0.3 N·m/A is not consistent with
Ke (see the README).
"""

from __future__ import annotations

import math

from plant_emulators.sowing_depth.config import CylinderConfig, MotorConfig

__all__ = ["ServoCylinder"]


class ServoCylinder:
    """State and step of the servo electric cylinder.

    Parameters
    ----------
    motor : MotorConfig
        The integrated servo motor.
    cylinder : CylinderConfig
        Transmission, stroke and limits.

    Attributes
    ----------
    position_mm : float
        Rod extension from fully retracted.
    velocity_mm_s : float
        Rod velocity, positive extending.
    force_n : float
        Force the rod exerts on the roller linkage (push positive).
    torque_n_m, current_a : float
        Motor torque and the DC-equivalent torque-producing current.
    at_force_limit : bool
        True when the last step's torque was clipped to its limit.
    load_stiffness_n_per_mm, load_damping_n_s_per_mm, load_contact_mm, load_preload_n : float
        The soil reaction (spring, damper, contact point, weight), set by the plant.
    jammed : bool
        Fault hook: the rod cannot move.
    """

    __slots__ = (
        "_dt_cached", "_k_vel", "at_force_limit", "current_a", "dc_bus_voltage_v", "force_n",
        "jammed", "k_force_n_per_n_m", "ke_v_s_per_rad", "kt_n_m_per_a",
        "load_contact_mm", "load_damping_n_s_per_mm", "load_preload_n",
        "load_stiffness_n_per_mm", "m_eff_kg",
        "position_mm", "ra_ohm", "rad_per_mm", "rated_speed_rpm", "rated_torque_n_m",
        "rod_speed_max_mm_per_s", "stroke_mm", "tau_v_s", "torque_limit_n_m", "torque_max_n_m",
        "torque_n_m", "velocity_mm_s",
    )

    def __init__(self, motor: MotorConfig, cylinder: CylinderConfig) -> None:
        ratio = cylinder.belt_ratio * cylinder.reducer_ratio
        lead_m = cylinder.screw_lead_mm * 1e-3
        self.k_force_n_per_n_m = 2.0 * math.pi * ratio * cylinder.transmission_efficiency / lead_m
        gear_rad_per_m = 2.0 * math.pi * ratio / lead_m
        inertia = motor.ja_kg_m2 + cylinder.transmission_inertia_kg_cm2 * 1e-4
        self.m_eff_kg = inertia * gear_rad_per_m**2 + cylinder.moving_mass_kg
        self.rad_per_mm = gear_rad_per_m * 1e-3
        self.torque_max_n_m = cylinder.push_force_max_n / self.k_force_n_per_n_m
        self.torque_limit_n_m = self.torque_max_n_m
        self.kt_n_m_per_a = motor.kt_n_m_per_a
        self.ke_v_s_per_rad = motor.ke_v_s_per_rad
        self.ra_ohm = motor.ra_ohm
        self.dc_bus_voltage_v = motor.dc_bus_voltage_v
        self.rated_torque_n_m = motor.rated_torque_n_m
        self.rated_speed_rpm = motor.rated_speed_rpm
        self.tau_v_s = motor.velocity_loop_time_constant_ms * 1e-3
        self.stroke_mm = cylinder.stroke_mm
        self.rod_speed_max_mm_per_s = cylinder.rod_speed_max_mm_per_s
        self.position_mm = cylinder.initial_rod_position_mm
        self.velocity_mm_s = 0.0
        self.force_n = 0.0
        self.torque_n_m = 0.0
        self.current_a = 0.0
        self.at_force_limit = False
        self.load_stiffness_n_per_mm = 0.0
        self.load_damping_n_s_per_mm = 0.0
        self.load_contact_mm = 0.0
        self.load_preload_n = 0.0
        self.jammed = False
        self._dt_cached = -1.0
        self._k_vel = 0.0

    @property
    def load_force_n(self) -> float:
        """Soil reaction on the rod at the present position (positive resists extension)."""
        return self._load(self.position_mm, self.velocity_mm_s)

    @property
    def rated_current_a(self) -> float:
        """Current at rated torque."""
        return self.rated_torque_n_m / self.kt_n_m_per_a

    def _load(self, position_mm: float, velocity_mm_s: float) -> float:
        pen = position_mm - self.load_contact_mm
        if pen > 0.0:
            return (self.load_stiffness_n_per_mm * pen
                    + self.load_damping_n_s_per_mm * velocity_mm_s - self.load_preload_n)
        return -self.load_preload_n

    def hold(self) -> None:
        """One step with the power stage off: the brake holds the rod."""
        self.velocity_mm_s = 0.0
        self.torque_n_m = 0.0
        self.current_a = 0.0
        self.at_force_limit = False
        self.force_n = self._load(self.position_mm, 0.0)

    def velocity_gain(self, dt: float) -> float:
        """``(1 - exp(-dt/τ_v)) / dt`` of the velocity loop, computed once per step size."""
        if dt != self._dt_cached:
            self._dt_cached = dt
            self._k_vel = -math.expm1(-dt / self.tau_v_s) / dt
        return self._k_vel

    def step(self, dt: float, v_cmd_mm_s: float) -> None:
        """Advance ``dt`` seconds with the power stage on, tracking ``v_cmd_mm_s``.

        (The C twin of the drive's profile-velocity loop, ``native/drive_cycle_core.c``, has
        this step expression for expression: change both.)
        """
        k_vel = self.velocity_gain(dt)
        v = self.velocity_mm_s
        x = self.position_mm
        pen = x - self.load_contact_mm
        if pen > 0.0:
            f_load = (self.load_stiffness_n_per_mm * pen + self.load_damping_n_s_per_mm * v
                      - self.load_preload_n)
        else:
            f_load = -self.load_preload_n
        m_eff = self.m_eff_kg
        k_f = self.k_force_n_per_n_m
        # m_eff [kg] · a [mm/s²] · 1e-3 = N
        torque = (m_eff * (v_cmd_mm_s - v) * k_vel * 1e-3 + f_load) / k_f
        limit = self.torque_limit_n_m
        if torque * v > 0.0:
            volt_limit = self.kt_n_m_per_a * (
                self.dc_bus_voltage_v - self.ke_v_s_per_rad * abs(v) * self.rad_per_mm
            ) / self.ra_ohm
            if volt_limit < limit:
                limit = volt_limit if volt_limit > 0.0 else 0.0
        saturated = False
        if torque > limit:
            torque = limit
            saturated = True
        elif torque < -limit:
            torque = -limit
            saturated = True
        if self.jammed:
            # The velocity loop's integral action winds up against the blocked rod.
            v_new = 0.0
            x_new = x
            if abs(v_cmd_mm_s) > 0.01 * self.rod_speed_max_mm_per_s:
                torque = limit if v_cmd_mm_s > 0.0 else -limit
                saturated = True
            else:
                torque = f_load / k_f
                saturated = False
            force = torque * k_f
        else:
            force = torque * k_f
            v_new = v + (force - f_load) / m_eff * 1e3 * dt
            vmax = self.rod_speed_max_mm_per_s
            if v_new > vmax:
                v_new = vmax
            elif v_new < -vmax:
                v_new = -vmax
            x_new = x + 0.5 * (v + v_new) * dt
            if x_new <= 0.0:
                x_new = 0.0
                v_new = 0.0
            elif x_new >= self.stroke_mm:
                x_new = self.stroke_mm
                v_new = 0.0
        self.position_mm = x_new
        self.velocity_mm_s = v_new
        self.torque_n_m = torque
        self.current_a = torque / self.kt_n_m_per_a
        self.force_n = force
        self.at_force_limit = saturated
