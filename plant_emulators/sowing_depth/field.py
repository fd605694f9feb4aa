"""The field as seeded random processes along distance, pre-drawn in blocks on the truth grid.

Everything random about the field lives here, drawn with numpy in blocks of cells (one cell is
``machine.truth_cell_length_mm`` of travel) and handed to the plant as plain Python lists so the
hot loop never calls numpy. Draws happen in cell order, so a run's randomness depends only on the
seed and the distance travelled, never on how the caller slices time.

Processes (Δ = cell length, ``a = exp(-Δ/lc)`` for a correlation length ``lc``)
------------------------------------------------------------------------------
* **Terrain** ``z(x)`` [mm]: the field's gradient ``tan(slope) · x`` plus a long and a short
  band, each white noise through two identical AR(1) stages (a smooth, twice-filtered profile)
  scaled to its SD.
* **Machine pose.** The frame rides with the tractor (hitch in position control), so its height
  follows the line through the tractor's rear and front wheel contacts at ``x_r`` and
  ``x_r + wheelbase`` ahead of the seed point::

      slope_k    = (z(x_k + x_r + wb) - z(x_k + x_r)) / wb           [mm/m]
      line_k(u)  = z(x_k + x_r) + slope_k · (u - x_r)                   frame line, u ahead of seed
      e_k        = z(x_k) - line_k(0)        ground above the frame line at the seed point [mm]
      pitch_k    = atan(slope_k / 1000)      nose up positive

* **Lateral ground tilt** relative to the machine (rad), AR(1): row ``r`` at lateral offset
  ``y_r`` sees the seedbed ``y_r · tilt`` deeper.
* **Tractor roll** [deg], smooth AR: what the inclinometer's second axis reads.
* **Soil**: moisture [%], compaction [N/cm²], relative stubble density, each AR(1) around its mean.
* **Per-row throw noise**: AR(1) of unit SD per row (scaled by the plant with the speed).
* **Outlier draws**: one uniform per row and cell, compared with the local event probability;
  event lengths and sizes come from a separate pool consumed in event order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from plant_emulators.sowing_depth.config import SowingDepthRigConfig

__all__ = ["FieldBlock", "FieldGenerator", "UniformPool"]


@dataclass(frozen=True)
class FieldBlock:
    """One block of cells; every attribute is a list with one entry per cell, except the
    per-row draws: arrays of shape (cells, rows), read one cell at a time (``tolist`` of the
    whole block was ~70 % of drawing a block, 6 ms in one go, a stall in a real-time run)."""

    ground_mm: list[float]
    line_seed_mm: list[float]
    line_pivot_mm: list[float]
    pitch_deg: list[float]
    roll_deg: list[float]
    tilt_rad: list[float]
    moisture_percent: list[float]
    compaction_n_per_cm2: list[float]
    soil_gain: list[float]
    stiffness_factor: list[float]
    clod_factor: list[float]
    stubble_factor: list[float]
    row_noise: np.ndarray
    row_uniform: np.ndarray

    def __len__(self) -> int:
        return len(self.ground_mm)


class _Ar1:
    """AR(1) processes of standard deviation ``sd`` (one per column), continuous over blocks."""

    def __init__(self, rng: np.random.Generator, length_cells: float, sd: float,
                 width: int = 1, stages: int = 1) -> None:
        self._rng = rng
        self._a = math.exp(-1.0 / length_cells)
        self._width = width
        self._stages = stages
        a2 = self._a * self._a
        # Gain of `stages` cascaded AR(1) filters y[n] = a·y[n-1] + w[n] on unit white noise.
        var = 1.0 / (1.0 - a2) if stages == 1 else (1.0 + a2) / (1.0 - a2) ** 3
        self._scale = sd / math.sqrt(var)
        self._sd = sd
        # Start in the stationary distribution (one burn-in of ~6 correlation lengths).
        self._zi = [np.zeros((width, 1)) for _ in range(stages)]
        burn = int(min(6.0 * length_cells * stages, 200_000)) + 1
        if sd > 0.0:
            self.draw(burn)

    def draw(self, n: int) -> np.ndarray:
        """Next ``n`` values, shape (width, n)."""
        w = self._rng.standard_normal((self._width, n))
        if self._sd == 0.0:
            return np.zeros((self._width, n))
        y = w
        for i in range(self._stages):
            y, self._zi[i] = lfilter([1.0], [1.0, -self._a], y, axis=1, zi=self._zi[i])
        return y * self._scale


class UniformPool:
    """Uniform [0, 1) numbers consumed one by one, refilled from the generator in chunks."""

    def __init__(self, rng: np.random.Generator, chunk: int = 1024) -> None:
        self._rng = rng
        self._chunk = chunk
        self._values: list[float] = []
        self._i = 0

    def next(self) -> float:
        """The next uniform number."""
        if self._i >= len(self._values):
            self._values = self._rng.random(self._chunk).tolist()
            self._i = 0
        value = self._values[self._i]
        self._i += 1
        return value


class FieldGenerator:
    """Draws the field's random processes block by block.

    Parameters
    ----------
    config : SowingDepthRigConfig
        Terrain, soil, throw and machine geometry.
    rng : numpy.random.Generator
        The only source of randomness.
    block_cells : int, default 4096
        Cells per block.
    """

    def __init__(self, config: SowingDepthRigConfig, rng: np.random.Generator,
                 block_cells: int = 4096) -> None:
        self._cfg = config
        self._rng = rng
        self._block = block_cells
        m = config.machine
        cell_m = m.truth_cell_length_mm * 1e-3
        self.cell_m = cell_m
        self._x_r = m.tractor_rear_axle_ahead_of_seed_m
        self._wb = m.tractor_wheelbase_m
        self._n_r = round(self._x_r / cell_m)
        self._n_f = round((self._x_r + self._wb) / cell_m)
        arm = config.arm
        phi0 = math.asin(min(1.0, max(-1.0, (arm.pivot_height_above_seedbed_mm
                                               - arm.roller_radius_mm - 30.0)
                                              / arm.arm_length_mm)))
        #: Where the arm pivot is, ahead of the seed point [m] (negative: behind).
        self.pivot_ahead_of_seed_m = (-m.post_press_roller_behind_seed_m
                                      + arm.arm_length_mm * 1e-3 * math.cos(phi0))
        t, s, th = config.terrain, config.soil, config.throw

        def cells(length_m: float) -> float:
            return max(length_m / cell_m, 1e-9)

        self._z_long = _Ar1(rng, cells(t.long_wave_correlation_length_m), t.long_wave_sd_mm,
                            stages=2)
        self._z_short = _Ar1(rng, cells(t.short_wave_correlation_length_m), t.short_wave_sd_mm,
                             stages=2)
        self._roll = _Ar1(rng, cells(t.roll_correlation_length_m), t.roll_sd_deg, stages=2)
        self._tilt = _Ar1(rng, cells(th.lateral_tilt_correlation_length_m),
                          math.radians(th.lateral_tilt_sd_deg))
        self._moisture = _Ar1(rng, cells(s.moisture_correlation_length_m), s.moisture_sd_percent)
        self._compaction = _Ar1(rng, cells(s.compaction_correlation_length_m),
                                s.compaction_sd_n_per_cm2)
        self._stubble = _Ar1(rng, cells(s.stubble_correlation_length_m), s.stubble_sd_relative)
        self._noise = _Ar1(rng, cells(th.noise_correlation_length_m), 1.0, width=m.rows)
        self._slope_mm_per_cell = math.tan(math.radians(t.field_slope_deg)) * m.truth_cell_length_mm
        self._z_cells = 0
        self._z_tail = self._terrain(self._n_f)

    def _terrain(self, n: int) -> np.ndarray:
        ramp = (self._z_cells + np.arange(n)) * self._slope_mm_per_cell
        self._z_cells += n
        return ramp + self._z_long.draw(n)[0] + self._z_short.draw(n)[0]

    def next_block(self) -> FieldBlock:
        """Draw the next block of cells."""
        n = self._block
        cfg = self._cfg
        z_new = self._terrain(n)
        z = np.concatenate([self._z_tail, z_new])
        self._z_tail = z[n:]
        k = np.arange(n)
        z_r = z[k + self._n_r]
        z_f = z[k + self._n_f]
        slope = (z_f - z_r) / self._wb
        line_seed = z_r - slope * self._x_r
        line_pivot = z_r + slope * (self.pivot_ahead_of_seed_m - self._x_r)
        ground = z[:n] - line_seed
        pitch = np.degrees(np.arctan(slope * 1e-3))
        roll = self._roll.draw(n)[0]
        tilt = self._tilt.draw(n)[0]
        soil, th, out = cfg.soil, cfg.throw, cfg.outliers
        dm = self._moisture.draw(n)[0]
        dc = self._compaction.draw(n)[0]
        stubble = np.maximum(0.0, 1.0 + self._stubble.draw(n)[0])
        soil_gain = 1.0 + th.moisture_gain_per_percent * dm + th.compaction_gain_per_n_per_cm2 * dc
        stiffness = (soil.compaction_mean_n_per_cm2 + dc) / soil.compaction_mean_n_per_cm2
        clod = np.maximum(0.0, 1.0 + out.clod_compaction_gain_per_n_per_cm2 * dc
                          + out.clod_moisture_gain_per_percent * dm)
        noise = self._noise.draw(n).T
        uniform = self._rng.random((n, cfg.machine.rows))
        return FieldBlock(
            ground_mm=ground.tolist(),
            line_seed_mm=line_seed.tolist(),
            line_pivot_mm=line_pivot.tolist(),
            pitch_deg=pitch.tolist(),
            roll_deg=roll.tolist(),
            tilt_rad=tilt.tolist(),
            moisture_percent=(soil.moisture_mean_percent + dm).tolist(),
            compaction_n_per_cm2=(soil.compaction_mean_n_per_cm2 + dc).tolist(),
            soil_gain=soil_gain.tolist(),
            stiffness_factor=np.maximum(stiffness, 0.0).tolist(),
            clod_factor=clod.tolist(),
            stubble_factor=stubble.tolist(),
            row_noise=noise,
            row_uniform=uniform,
        )
