"""Fluted-roller flow map: meter-shaft speed → one row's mean flow.

Paper [F]'s bench reached 23 / 34 / 44 g/s at 12 / 21 / 32 r/min: 115 / 97 / 82.5 g per
revolution, falling with speed. A power law ``q = c·n^p`` (g/s per row, n in r/min) fits the
three points; below ``linear_below_rpm`` the grams per revolution are held constant so that the
map stays finite and linear near standstill (a flute cannot hold more than it holds).

Example
-------
>>> fm = FlowMap(coeff_gps=4.586, exponent=0.6537, linear_below_rpm=5.0)
>>> round(fm.flow_gps(12.0), 2), round(fm.grams_per_rev(12.0), 1)
(23.28, 116.4)
>>> round(fm.speed_for_flow(fm.flow_gps(21.0)), 6)
21.0
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from plant_emulators.fertilizer.config import MeterConfig

__all__ = ["FlowMap", "fit_power_law"]


@dataclass(frozen=True)
class FlowMap:
    """The calibrated mean flow of one nominal row, before drift, spread and pulsation.

    Parameters
    ----------
    coeff_gps : float
        ``c`` in ``q = c·n^p`` (g/s at 1 r/min).
    exponent : float
        ``p`` (dimensionless, 0 < p <= 1).
    linear_below_rpm : float
        Speed below which the grams per revolution stay constant (r/min).
    """

    coeff_gps: float
    exponent: float
    linear_below_rpm: float

    @classmethod
    def from_config(cls, meter: MeterConfig) -> FlowMap:
        """Build the map from the ``[meter]`` section."""
        return cls(meter.flow_coeff_gps, meter.flow_exponent, meter.linear_below_rpm)

    @property
    def linear_slope_gps_per_rpm(self) -> float:
        """Slope of the linear part below :attr:`linear_below_rpm` (g/s per r/min)."""
        return self.coeff_gps * self.linear_below_rpm ** (self.exponent - 1.0)

    def flow_gps(self, shaft_rpm: float) -> float:
        """Mean flow of one row (g/s) at ``shaft_rpm`` (r/min); 0 at or below standstill."""
        if shaft_rpm >= self.linear_below_rpm:
            return self.coeff_gps * shaft_rpm ** self.exponent
        if shaft_rpm > 0.0:
            return self.linear_slope_gps_per_rpm * shaft_rpm
        return 0.0

    def grams_per_rev(self, shaft_rpm: float) -> float:
        """Mass delivered per shaft revolution by one row (g) at ``shaft_rpm`` > 0."""
        if shaft_rpm <= 0.0:
            raise ValueError("grams per revolution is defined for a turning shaft only")
        return 60.0 * self.flow_gps(shaft_rpm) / shaft_rpm

    def speed_for_flow(self, flow_gps: float) -> float:
        """Inverse map: shaft speed (r/min) that delivers ``flow_gps`` per row."""
        if flow_gps <= 0.0:
            return 0.0
        knee_flow = self.coeff_gps * self.linear_below_rpm ** self.exponent
        if flow_gps >= knee_flow:
            return (flow_gps / self.coeff_gps) ** (1.0 / self.exponent)
        return flow_gps / self.linear_slope_gps_per_rpm


def fit_power_law(speeds_rpm: Sequence[float], flows_gps: Sequence[float]) -> tuple[float, float]:
    """Least-squares fit (in flow, not in log flow) of ``q = c·n^p``.

    Parameters
    ----------
    speeds_rpm, flows_gps : sequence of float
        Measured points, at least two.

    Returns
    -------
    tuple of float
        ``(c, p)``.

    Examples
    --------
    >>> c, p = fit_power_law([12, 21, 32], [23, 34, 44])
    >>> round(c, 3), round(p, 4)
    (4.586, 0.6537)
    """
    if len(speeds_rpm) != len(flows_gps) or len(speeds_rpm) < 2:
        raise ValueError("need at least two (speed, flow) points of equal count")
    n = [float(v) for v in speeds_rpm]
    q = [float(v) for v in flows_gps]
    # Start from the log-log regression, then Gauss-Newton on the flow residuals.
    ln_n = [math.log(v) for v in n]
    ln_q = [math.log(v) for v in q]
    mean_x = sum(ln_n) / len(n)
    mean_y = sum(ln_q) / len(n)
    sxx = sum((x - mean_x) ** 2 for x in ln_n)
    p = sum((x - mean_x) * (y - mean_y) for x, y in zip(ln_n, ln_q, strict=True)) / sxx
    c = math.exp(mean_y - p * mean_x)
    for _ in range(50):
        # J columns: dq/dc = n^p, dq/dp = c·n^p·ln n
        j1 = [v ** p for v in n]
        j2 = [c * a * x for a, x in zip(j1, ln_n, strict=True)]
        r = [qi - c * a for qi, a in zip(q, j1, strict=True)]
        a11 = sum(a * a for a in j1)
        a12 = sum(a * b for a, b in zip(j1, j2, strict=True))
        a22 = sum(b * b for b in j2)
        b1 = sum(a * e for a, e in zip(j1, r, strict=True))
        b2 = sum(b * e for b, e in zip(j2, r, strict=True))
        det = a11 * a22 - a12 * a12
        dc = (a22 * b1 - a12 * b2) / det
        dp = (a11 * b2 - a12 * b1) / det
        c += dc
        p += dp
        if abs(dc) < 1e-12 * abs(c) and abs(dp) < 1e-12:
            break
    return c, p
