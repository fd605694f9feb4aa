"""Sensors of the sowing-depth rig: the LVT525H inclinometer and the draw-wire sensor.

Each sensor turns a true quantity from the plant into what its electronics report, with seeded
noise, resolution, a per-unit error drawn once, and fault hooks. Devices (the rig's CAN nodes)
call ``sample`` at their frame period and encode the result through the DBC.

Inclinometer chain (per axis)
-----------------------------
``true angle → clip to ±range → + unit bias → first-order lag (response time) → + noise
(electronics + tiller vibration ∝ ground speed) → quantize to the 0.01° resolution → 0-5 V
output → ADC in whole mV``. The output is ``zero_mv + angle · mv_per_deg`` (±30°: 2500 mV at 0°,
83.33 mV/°). Paper [D]'s calibration (13) turns the X output back into depth:
:func:`calibration_depth_mm`.

Draw-wire chain
---------------
``roller travel → + smooth linearity error (a half sine of amplitude ≤ linearity_error_mm drawn
once) → + noise → quantize to the resolution → clip to [0, range]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from plant_emulators.sowing_depth.config import DrawWireConfig, InclinometerConfig

__all__ = [
    "CALIBRATION_INTERCEPT_MM",
    "CALIBRATION_RANGE_MV",
    "CALIBRATION_SLOPE_MM_PER_MV",
    "DrawWireSensor",
    "Inclinometer",
    "InclinometerReading",
    "calibration_depth_mm",
    "calibration_signal_mv",
]

#: Paper [D] eq. (13): y = -0.065·x + 270.35 mm for x = 2,628 … 4,356 mV (R² = 0.9962).
CALIBRATION_SLOPE_MM_PER_MV = -0.065
CALIBRATION_INTERCEPT_MM = 270.35
CALIBRATION_RANGE_MV = (2628.0, 4356.0)


def calibration_depth_mm(signal_mv: float) -> float:
    """Depth by [D]'s calibration (13) from the inclinometer's X output in mV.

    >>> round(calibration_depth_mm(3697.69), 2)
    30.0
    """
    return CALIBRATION_SLOPE_MM_PER_MV * signal_mv + CALIBRATION_INTERCEPT_MM


def calibration_signal_mv(depth_mm: float) -> float:
    """Inverse of :func:`calibration_depth_mm`."""
    return (depth_mm - CALIBRATION_INTERCEPT_MM) / CALIBRATION_SLOPE_MM_PER_MV


@dataclass(frozen=True)
class InclinometerReading:
    """One sample of both axes: ADC values in mV and the sensor's own angles in degrees."""

    x_mv: int
    y_mv: int
    x_deg: float
    y_deg: float


class _Axis:
    __slots__ = ("bias_deg", "filtered_deg", "held")

    def __init__(self, bias_deg: float) -> None:
        self.bias_deg = bias_deg
        self.filtered_deg: float | None = None
        self.held: tuple[int, float] | None = None


class Inclinometer:
    """LVT525H dual-axis inclinometer read by a 0-5 V analog input module.

    Parameters
    ----------
    config : InclinometerConfig
        Range, resolution, accuracy, noise, output scaling.
    rng : numpy.random.Generator
        This sensor's own generator (draws the unit's bias at construction, noise per sample).

    Attributes
    ----------
    stuck : bool
        Fault hook: both outputs freeze at their present value.
    noisy : bool
        Fault hook: noise multiplied by ``noisy_fault_gain``.
    """

    def __init__(self, config: InclinometerConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._rng = rng
        half = 0.5 * config.accuracy_deg
        self._x = _Axis(float(rng.uniform(-half, half)))
        self._y = _Axis(float(rng.uniform(-half, half)))
        self._last_time_s: float | None = None
        self.stuck = False
        self.noisy = False

    def angle_to_mv(self, angle_deg: float) -> float:
        """Output voltage in mV for a sensor angle (no noise, no quantization, clipped)."""
        c = self.config
        mv = c.zero_mv + angle_deg * c.mv_per_deg
        return min(max(mv, c.output_min_mv), c.output_max_mv)

    def mv_to_angle(self, mv: float) -> float:
        """Sensor angle in degrees for an output in mV."""
        c = self.config
        return (mv - c.zero_mv) / c.mv_per_deg

    def sample(self, time_s: float, x_angle_deg: float, y_angle_deg: float,
               ground_speed_mps: float = 0.0) -> InclinometerReading:
        """Sample both axes at ``time_s`` given the true angles of the sensor's axes.

        Parameters
        ----------
        time_s : float
            Simulated time of the sample (drives the response lag; never wall-clock time).
        x_angle_deg : float
            True angle of the X axis: the press arm's angle plus the mounting offset.
        y_angle_deg : float
            True angle of the Y axis: the machine's roll.
        ground_speed_mps : float, default 0
            Ground speed, for the tiller-vibration part of the noise.
        """
        c = self.config
        dt = 0.0 if self._last_time_s is None else max(0.0, time_s - self._last_time_s)
        self._last_time_s = time_s
        tau = c.response_time_constant_ms * 1e-3
        alpha = 1.0 if tau <= 0.0 else -math.expm1(-dt / tau)
        sd = c.noise_sd_deg + c.vibration_noise_sd_deg_per_m_per_s * abs(ground_speed_mps)
        if self.noisy:
            sd *= c.noisy_fault_gain
        x_mv, x_deg = self._axis(self._x, x_angle_deg, alpha, sd)
        y_mv, y_deg = self._axis(self._y, y_angle_deg, alpha, sd)
        return InclinometerReading(x_mv=x_mv, y_mv=y_mv, x_deg=x_deg, y_deg=y_deg)

    def _axis(self, axis: _Axis, angle_deg: float, alpha: float,
              sd: float) -> tuple[int, float]:
        c = self.config
        noise = float(self._rng.normal(0.0, sd)) if sd > 0.0 else 0.0
        if self.stuck and axis.held is not None:
            return axis.held
        clipped = min(max(angle_deg, -c.range_deg), c.range_deg) + axis.bias_deg
        if axis.filtered_deg is None:
            axis.filtered_deg = clipped
        else:
            axis.filtered_deg += alpha * (clipped - axis.filtered_deg)
        angle = axis.filtered_deg + noise
        angle = round(angle / c.resolution_deg) * c.resolution_deg
        angle = min(max(angle, -c.range_deg), c.range_deg)
        mv = int(round(self.angle_to_mv(angle) / c.adc_resolution_mv) * c.adc_resolution_mv)
        axis.held = (mv, round(angle, 6))
        return axis.held


class DrawWireSensor:
    """Draw-wire displacement sensor on the pre-sowing press roller carrier.

    Parameters
    ----------
    config : DrawWireConfig
        Range, resolution, linearity, noise.
    rng : numpy.random.Generator
        This sensor's own generator (draws the unit's linearity error, then noise).

    Attributes
    ----------
    lost : bool
        Fault hook: the sensor is lost (broken wire or node off the bus); :meth:`sample`
        returns None and the device should stop sending.
    """

    def __init__(self, config: DrawWireConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._rng = rng
        self._linearity_mm = float(rng.uniform(-config.linearity_error_mm,
                                               config.linearity_error_mm))
        self.lost = False

    def sample(self, position_mm: float) -> float | None:
        """Reported position in mm for a true roller travel of ``position_mm`` (None if lost)."""
        c = self.config
        noise = float(self._rng.normal(0.0, c.noise_sd_mm)) if c.noise_sd_mm > 0.0 else 0.0
        if self.lost:
            return None
        frac = min(max(position_mm / c.range_mm, 0.0), 1.0)
        value = position_mm + self._linearity_mm * math.sin(math.pi * frac) + noise
        value = round(value / c.resolution_mm) * c.resolution_mm
        return round(min(max(value, 0.0), c.range_mm), 6)
