"""The sowing-depth plant: servo cylinder + press rollers + covering soil + field, 12 rows.

:class:`SowingDepthPlant` steps the CiA 402 drive (which moves the cylinder) at the physics rate
and, each time the seed point passes a truth cell (``machine.truth_cell_length_mm`` of travel),
computes how deep the seeds of every row lie.

Model equations (per truth cell k; the README explains each parameter)
----------------------------------------------------------------------
Seedbed. The cylinder (rod extension ``p``) moves the pre-sowing press roller and the seeding
carrier down ``i·p`` against the frame, which rides with the tractor; the roller presses the
seedbed ``s`` below the loose tilled surface::

    s_k = s_0 + i·p + e_k                                                    [mm]

``e_k`` is the ground above the frame line at the seed point (terrain, :mod:`.field`).

Cover. Soil thrown by the rotor covers the seed row. The share that lands on the row falls at
low speed ([D]: low speed throws soil worse) and varies with moisture and compaction::

    η(v)   = η_max · (1 - a_lo · exp(-v / v_lo))
    G_k    = 1 + g_m·(m_k - m̄) + g_c·(C_k - C̄)
    sd(v)  = sd_0 · (1 + b_lo · exp(-v / v_lo) + b_v · v)
    d_rk   = max(0, η(v)·G_k·(s_k + y_r·τ_k) + sd(v)·n_rk + o_r)             [mm]

with ``y_r`` the row's lateral offset, ``τ_k`` the lateral ground tilt, ``n_rk`` unit AR(1) noise
per row and ``o_r`` a fixed per-row offset (seed-tube and roller tolerances).

Outliers. Per row, an event starts in a free cell with probability ``Σ λ_j · Δ``:
clod (``λ_c · (1 - w + w·v/v_ref) · f_clod(soil)``, the seed lies ``A ∈ [A_min, A_max]`` deeper),
seed bounce (``λ_b · (v/v_ref)^β``), stubble hairpinning (``λ_s · f_stubble``) and poor throw at
low speed (``λ_p · exp(-v/v_p)``); the three shallow kinds leave the seed at a fraction
``[f_min, f_max]`` of its depth. An event lasts a length drawn from its range.

Press arm and inclinometer. The post-sowing roller, ``n_post`` cells behind the seed point,
rides on the mean surface of the rows (shallow outliers do not change the surface, clods do).
The arm's pivot sits on the carrier, so its height above the soil under the roller is::

    h = H - R + line_now(pivot) - i·p_now - (line_then(seed) - i·p_then + c_then)
    φ = asin(h / L)            (arm angle below horizontal, gravity referenced)

which contains machine pitch and rod motion since the soil was pressed: on a steady slope θ the
arm reads φ_0 + θ, as papers.md notes for a gravity-referenced sensor.

Cylinder load. The soil under the pre-sowing roller is a one-sided spring and damper:
``F_rod = i² · (k_soil · (C_k/C̄) · (p - p_contact) + c_soil · ṗ) - i·W`` while
``p > p_contact = -(s_0 + e_k)/i``, else ``-i·W``.

Determinism: all randomness is pre-drawn in cell order from the generator passed in, and
``advance(n, dt)`` runs exactly the operations of n calls of ``advance(1, dt)``.

Engines (see :mod:`plant_emulators.engine`): the drive's steady profile-velocity loop (the
drive's cycle, the cylinder and the drive's monitors, ten steps per control period, ~60 % of
the plant's time in a depth run) also exists as a C twin, ``native/drive_cycle_core.c``, that
gives the same floats; the ``engine`` argument picks it (``native``) or the Python models
alone (``python``). Everything else (truth cells, the other drive states) is Python in both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from plant_emulators.engine import Engine, load_native, resolve_engine
from plant_emulators.sowing_depth.arm import PressArm
from plant_emulators.sowing_depth.cia402 import Cia402Drive
from plant_emulators.sowing_depth.config import SowingDepthRigConfig
from plant_emulators.sowing_depth.cylinder import ServoCylinder
from plant_emulators.sowing_depth.field import FieldBlock, FieldGenerator, UniformPool

__all__ = ["OUTLIER_KINDS", "SowingDepthPlant", "TruthCells"]

#: Outlier kind codes in :attr:`SowingDepthPlant.outlier_kinds` and :class:`TruthCells`.
OUTLIER_KINDS = {0: "none", 1: "clod", 2: "bounce", 3: "stubble", 4: "poor throw"}
_CLOD, _BOUNCE, _STUBBLE, _POOR = 1, 2, 3, 4


@dataclass(frozen=True)
class TruthCells:
    """Ground truth per truth cell, as drained by :meth:`SowingDepthPlant.drain_truth`.

    Attributes
    ----------
    distance_m : numpy.ndarray, shape (n,)
        Distance of each cell along the rows.
    depth_mm : numpy.ndarray, shape (n, rows)
        True seed depth per row.
    outlier_kind : numpy.ndarray of int8, shape (n, rows)
        0 inlier, else the outlier kind (see :data:`OUTLIER_KINDS`).
    ground_speed_mps : numpy.ndarray, shape (n,)
        Ground speed when the seed point passed the cell.
    rod_position_mm : numpy.ndarray, shape (n,)
        Rod extension when the seed point passed the cell.
    """

    distance_m: np.ndarray
    depth_mm: np.ndarray
    outlier_kind: np.ndarray
    ground_speed_mps: np.ndarray
    rod_position_mm: np.ndarray


class SowingDepthPlant:
    """The wheat planter of paper [D] (2BFG-12) with its servo cylinder and CiA 402 drive.

    Parameters
    ----------
    config : SowingDepthRigConfig
        The rig configuration (:func:`~plant_emulators.sowing_depth.config.load_rig_config`).
    rng : numpy.random.Generator
        The plant's only source of randomness (give sensors their own generators).
    engine : {"native", "python"}, optional
        Which implementation runs the drive's steady loop (default: ``AGRIHIL_PHYSICS``, see
        :mod:`plant_emulators.engine`); both give the same floats.

    Attributes
    ----------
    drive : Cia402Drive
        The cylinder's drive; the rig's CANopen node reads and writes its objects.
    cylinder : ServoCylinder
        The cylinder mechanics (``jammed`` is a fault hook).
    time_s, distance_m : float
        Simulated time and distance travelled by the seed point.

    Examples
    --------
    >>> import numpy as np
    >>> from plant_emulators.sowing_depth.config import load_rig_config
    >>> plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(1))
    >>> plant.ground_speed_mps = 1.2
    >>> plant.advance(1000, 0.001)
    >>> round(plant.distance_m, 6), len(plant.true_depth_mm)
    (1.2, 12)
    """

    def __init__(self, config: SowingDepthRigConfig, rng: np.random.Generator,
                 engine: str | None = None) -> None:
        self.engine: Engine = resolve_engine(engine)
        self._native = (load_native("plant_emulators.sowing_depth._drive_cycle_native")
                        if self.engine == "native" else None)
        self.config = config
        m, th, out = config.machine, config.throw, config.outliers
        self.cylinder = ServoCylinder(config.motor, config.cylinder)
        self.drive = Cia402Drive(config.drive, self.cylinder)
        self.arm = PressArm(config.arm)
        self._field = FieldGenerator(config, rng)
        self._pool = UniformPool(rng)
        self._rows = m.rows
        self._cell_m = m.truth_cell_length_mm * 1e-3
        self._cell_mm = m.truth_cell_length_mm
        self._i = m.roller_travel_per_rod_mm
        self._s0 = m.seedbed_depth_at_rod_zero_mm
        self._k_rod = m.soil_stiffness_n_per_mm * self._i * self._i
        self.cylinder.load_preload_n = m.roller_weight_n * self._i
        self.cylinder.load_damping_n_s_per_mm = m.soil_damping_n_s_per_mm * self._i * self._i
        self._row_y_mm = [(r - 0.5 * (m.rows - 1)) * m.row_spacing_mm for r in range(m.rows)]
        self._row_offset_mm = rng.normal(0.0, th.row_offset_sd_mm, m.rows).tolist() \
            if th.row_offset_sd_mm > 0 else [0.0] * m.rows
        self._n_post = round(m.post_press_roller_behind_seed_m / self._cell_m)
        self._ring: list[tuple[float, float]] = [(0.0, 0.0)] * max(self._n_post, 1)
        self._ring_w = 0
        self._h0 = config.arm.pivot_height_above_seedbed_mm - config.arm.roller_radius_mm
        self._len_cells = {
            kind: (math.ceil(lo / self._cell_mm), math.ceil(hi / self._cell_mm))
            for kind, lo, hi in (
                (_CLOD, out.clod_length_min_mm, out.clod_length_max_mm),
                (_BOUNCE, out.bounce_length_min_mm, out.bounce_length_max_mm),
                (_STUBBLE, out.stubble_length_min_mm, out.stubble_length_max_mm),
                (_POOR, out.poor_throw_length_min_mm, out.poor_throw_length_max_mm),
            )
        }
        self._event_left = [0] * m.rows
        self._event_kind = [0] * m.rows
        self._event_value = [0.0] * m.rows
        self._speed = 0.0
        self._speed_cached = -1.0
        self._eta = self._sigma = 0.0
        self._p_clod = self._p_bounce = self._p_poor = 0.0
        self._p_stubble = out.stubble_rate_per_m * self._cell_m
        self._block: FieldBlock = self._field.next_block()
        self._j = 0
        # Outputs updated per cell.
        self.true_depth_mm: tuple[float, ...] = (0.0,) * m.rows
        self.outlier_kinds: tuple[int, ...] = (0,) * m.rows
        self.mean_true_depth_mm = 0.0
        self.seedbed_depth_mm = 0.0
        self.cover_soil_mm = 0.0
        self.machine_pitch_deg = 0.0
        self.machine_roll_deg = 0.0
        self.soil_moisture_percent = 0.0
        self.soil_compaction_n_per_cm2 = 0.0
        self._line_pivot_mm = 0.0
        self._q_post = 0.0
        self._truth_x: list[float] = []
        self._truth_d: list[tuple[float, ...]] = []
        self._truth_k: list[tuple[int, ...]] = []
        self._truth_v: list[float] = []
        self._truth_p: list[float] = []
        # Soil that passed before distance 0 (under and behind the rollers at start).
        self._cell_index = -self._n_post
        for _ in range(self._n_post):
            self._cell(record=False)
        self._cell(record=True)
        self.time_s = 0.0
        self.distance_m = 0.0
        self._next_cell_m = self._cell_index * self._cell_m

    # ------------------------------------------------------------------ inputs
    @property
    def ground_speed_mps(self) -> float:
        """Ground speed [m/s], set by the scenario (forward only)."""
        return self._speed

    @ground_speed_mps.setter
    def ground_speed_mps(self, value: float) -> None:
        value = float(value)
        if not (value >= 0.0 and math.isfinite(value)):
            raise ValueError(f"ground_speed_mps must be finite and >= 0, got {value!r}")
        self._speed = value

    # ------------------------------------------------------------------ stepping
    def advance(self, n: int, dt: float) -> None:
        """Advance ``n`` physics steps of ``dt`` seconds.

        ``advance(n, dt)`` performs exactly the operations of ``n`` calls of ``advance(1, dt)``.
        """
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        if not dt > 0.0:
            raise ValueError(f"dt must be > 0, got {dt!r}")
        drive = self.drive
        drive_step = drive.step
        native = self._native
        dx = self._speed * dt
        t = self.time_s
        x = self.distance_m
        nxt = self._next_cell_m
        left = n
        while left:
            if native is not None and drive.pv_steady():
                # the C twin runs the steps up to the next cell (or an overload fault)
                done, t, x = drive.run_pv_native(native, left, dt, dx, t, x, nxt)
                left -= done
            else:
                drive_step(dt)
                t += dt
                x += dx
                left -= 1
            if x >= nxt:
                while x >= nxt:
                    self._cell(record=True)
                    nxt = self._cell_index * self._cell_m
        self.time_s = t
        self.distance_m = x
        self._next_cell_m = nxt

    def _update_speed_terms(self, v: float) -> None:
        th, out = self.config.throw, self.config.outliers
        lo = math.exp(-v / th.low_speed_scale_m_per_s)
        self._eta = th.efficiency_max * (1.0 - th.low_speed_loss * lo)
        self._sigma = th.noise_sd_mm * (1.0 + th.noise_low_speed_gain * lo
                                        + th.noise_speed_gain_per_m_per_s * v)
        rel = v / out.reference_speed_m_per_s
        cell = self._cell_m
        self._p_clod = out.clod_rate_per_m * cell * (1.0 - out.clod_speed_weight
                                                     + out.clod_speed_weight * rel)
        self._p_bounce = out.bounce_rate_per_m * cell * rel ** out.bounce_speed_exponent
        self._p_poor = out.poor_throw_rate_per_m * cell * math.exp(
            -v / out.poor_throw_speed_scale_m_per_s)
        self._speed_cached = v

    def _start_event(self, r: int, u: float, p_clod: float, p_bounce: float,
                     p_stubble: float) -> None:
        if u < p_clod:
            kind = _CLOD
        elif u < p_clod + p_bounce:
            kind = _BOUNCE
        elif u < p_clod + p_bounce + p_stubble:
            kind = _STUBBLE
        else:
            kind = _POOR
        pool = self._pool
        out = self.config.outliers
        lo, hi = self._len_cells[kind]
        self._event_left[r] = lo + int((hi - lo + 1) * pool.next())
        self._event_kind[r] = kind
        if kind == _CLOD:
            self._event_value[r] = out.clod_extra_depth_min_mm + pool.next() * (
                out.clod_extra_depth_max_mm - out.clod_extra_depth_min_mm)
        else:
            self._event_value[r] = out.shallow_depth_factor_min + pool.next() * (
                out.shallow_depth_factor_max - out.shallow_depth_factor_min)

    def _cell(self, *, record: bool) -> None:
        blk = self._block
        j = self._j
        if j >= len(blk):
            blk = self._block = self._field.next_block()
            j = 0
        self._j = j + 1
        v = self._speed
        if v != self._speed_cached:
            self._update_speed_terms(v)
        cyl = self.cylinder
        p = cyl.position_mm
        i_link = self._i
        e = blk.ground_mm[j]
        s = self._s0 + i_link * p + e
        eta_g = self._eta * blk.soil_gain[j]
        tilt = blk.tilt_rad[j]
        sigma = self._sigma
        noise = blk.row_noise[j].tolist()
        uniform = blk.row_uniform[j].tolist()
        p_clod = self._p_clod * blk.clod_factor[j]
        p_bounce = self._p_bounce
        p_stubble = self._p_stubble * blk.stubble_factor[j]
        p_total = p_clod + p_bounce + p_stubble + self._p_poor
        left = self._event_left
        kinds = self._event_kind
        values = self._event_value
        offsets = self._row_offset_mm
        depths = []
        cell_kinds = []
        surface = 0.0
        for r, y in enumerate(self._row_y_mm):
            d = eta_g * (s + y * tilt) + sigma * noise[r] + offsets[r]
            if d < 0.0:
                d = 0.0
            if left[r] == 0 and uniform[r] < p_total:
                self._start_event(r, uniform[r], p_clod, p_bounce, p_stubble)
            if left[r]:
                left[r] -= 1
                kind = kinds[r]
                if kind == _CLOD:
                    d += values[r]
                    surface += d
                else:
                    surface += d
                    d *= values[r]
                cell_kinds.append(kind)
            else:
                surface += d
                cell_kinds.append(0)
            depths.append(d)
        surface /= self._rows
        # Press-arm geometry: soil pressed now, read n_post cells later.
        pressed = (blk.line_seed_mm[j] - i_link * p + surface, surface)
        if self._n_post:
            w = self._ring_w
            self._q_post, self.cover_soil_mm = self._ring[w]
            self._ring[w] = pressed
            self._ring_w = w + 1 if w + 1 < self._n_post else 0
        else:
            self._q_post, self.cover_soil_mm = pressed
        self._line_pivot_mm = blk.line_pivot_mm[j]
        # Soil spring under the pre-sowing roller.
        cyl.load_contact_mm = -(self._s0 + e) / i_link
        cyl.load_stiffness_n_per_mm = self._k_rod * blk.stiffness_factor[j]
        self.true_depth_mm = tuple(depths)
        self.outlier_kinds = tuple(cell_kinds)
        self.mean_true_depth_mm = sum(depths) / self._rows
        self.seedbed_depth_mm = s
        self.machine_pitch_deg = blk.pitch_deg[j]
        self.machine_roll_deg = blk.roll_deg[j]
        self.soil_moisture_percent = blk.moisture_percent[j]
        self.soil_compaction_n_per_cm2 = blk.compaction_n_per_cm2[j]
        if record:
            self._truth_x.append(self._cell_index * self._cell_m)
            self._truth_d.append(self.true_depth_mm)
            self._truth_k.append(self.outlier_kinds)
            self._truth_v.append(v)
            self._truth_p.append(p)
        self._cell_index += 1

    # ------------------------------------------------------------------ outputs
    @property
    def rod_position_mm(self) -> float:
        """Rod extension from fully retracted [mm]."""
        return self.cylinder.position_mm

    @property
    def rod_velocity_mm_s(self) -> float:
        """Rod velocity, extending positive [mm/s]."""
        return self.cylinder.velocity_mm_s

    @property
    def rod_force_n(self) -> float:
        """Force the rod exerts on the roller linkage, push positive [N]."""
        return self.cylinder.force_n

    @property
    def load_force_n(self) -> float:
        """Soil reaction on the rod, resisting extension positive [N]."""
        return self.cylinder.load_force_n

    @property
    def motor_current_a(self) -> float:
        """Torque-producing current of the DC-equivalent motor [A]."""
        return self.cylinder.current_a

    @property
    def motor_torque_n_m(self) -> float:
        """Motor torque [N·m]."""
        return self.cylinder.torque_n_m

    @property
    def roller_position_mm(self) -> float:
        """Pre-sowing press roller travel below its top position [mm] (draw-wire measurand)."""
        return self._i * self.cylinder.position_mm

    @property
    def arm_angle_deg(self) -> float:
        """Post-sowing press roller arm angle below horizontal, gravity referenced [deg]."""
        h = self._h0 + self._line_pivot_mm - self._i * self.cylinder.position_mm - self._q_post
        ratio = h / self.arm.arm_length_mm
        if ratio > 1.0:
            ratio = 1.0
        elif ratio < -1.0:
            ratio = -1.0
        return math.degrees(math.asin(ratio))

    def signals(self) -> dict[str, tuple[float, str]]:
        """Every output as ``name → (value, unit)`` for trace recording."""
        out: dict[str, tuple[float, str]] = {
            "time_s": (self.time_s, "s"),
            "distance_m": (self.distance_m, "m"),
            "ground_speed_mps": (self._speed, "m/s"),
            "rod_position_mm": (self.cylinder.position_mm, "mm"),
            "rod_velocity_mm_s": (self.cylinder.velocity_mm_s, "mm/s"),
            "rod_force_n": (self.cylinder.force_n, "N"),
            "load_force_n": (self.cylinder.load_force_n, "N"),
            "motor_torque_n_m": (self.cylinder.torque_n_m, "N*m"),
            "motor_current_a": (self.cylinder.current_a, "A"),
            "position_demand_mm": (self.drive.position_demand_mm, "mm"),
            "drive_statusword": (float(self.drive.statusword), "1"),
            "drive_error_code": (float(self.drive.error_code), "1"),
            "roller_position_mm": (self.roller_position_mm, "mm"),
            "seedbed_depth_mm": (self.seedbed_depth_mm, "mm"),
            "cover_soil_mm": (self.cover_soil_mm, "mm"),
            "arm_angle_deg": (self.arm_angle_deg, "deg"),
            "machine_pitch_deg": (self.machine_pitch_deg, "deg"),
            "machine_roll_deg": (self.machine_roll_deg, "deg"),
            "soil_moisture_percent": (self.soil_moisture_percent, "%"),
            "soil_compaction_n_per_cm2": (self.soil_compaction_n_per_cm2, "N/cm2"),
            "mean_true_depth_mm": (self.mean_true_depth_mm, "mm"),
        }
        for r, (d, kind) in enumerate(zip(self.true_depth_mm, self.outlier_kinds,
                                          strict=True), start=1):
            out[f"true_depth_row{r:02d}_mm"] = (d, "mm")
            out[f"outlier_row{r:02d}"] = (float(kind), "1")
        return out

    def drain_truth(self) -> TruthCells:
        """Truth cells recorded since the previous call (the first call includes distance 0)."""
        rows = self._rows
        n = len(self._truth_x)
        truth = TruthCells(
            distance_m=np.asarray(self._truth_x, dtype=float),
            depth_mm=np.asarray(self._truth_d, dtype=float).reshape(n, rows),
            outlier_kind=np.asarray(self._truth_k, dtype=np.int8).reshape(n, rows),
            ground_speed_mps=np.asarray(self._truth_v, dtype=float),
            rod_position_mm=np.asarray(self._truth_p, dtype=float),
        )
        self._truth_x, self._truth_d, self._truth_k = [], [], []
        self._truth_v, self._truth_p = [], []
        return truth
