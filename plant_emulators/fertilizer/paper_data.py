"""Published figures of paper [F] that the emulator is checked against.

Wang Hui et al., "Design and Test of Fertilizer Flow Piecewise PID Control System of Fertilizer
Planter", Trans. CSAM 54(2):32-40, 2023, doi:10.6041/j.issn.1000-1298.2023.02.003, as
transcribed in docs/reference/sources.md (Tables 1 and 2, the step and field results). Values
only: no model code lives here.
"""

from __future__ import annotations

BENCH_SHAFT_RPM: tuple[float, ...] = (12.0, 21.0, 32.0)
"""Steady meter-shaft speeds of the bench step tests (r/min)."""

BENCH_TARGET_GPS: tuple[float, ...] = (23.0, 34.0, 44.0)
"""Bench step-test target flows (g/s) reached at :data:`BENCH_SHAFT_RPM`; one row's flow."""

TABLE1_SHAFT_RPM: tuple[float, ...] = (5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0)
"""Table 1: shaft speeds of the sensor verification (r/min)."""

TABLE1_MEASURED_G: tuple[float, ...] = (
    136.651, 211.655, 264.162, 339.290, 395.375, 411.906, 443.421, 550.455)
"""Table 1: mass reported by the flow detection module (g)."""

TABLE1_WEIGHED_G: tuple[float, ...] = (
    137.90, 213.76, 267.37, 341.40, 399.27, 411.26, 445.49, 546.95)
"""Table 1: mass weighed on a scale (g)."""

TABLE1_ERROR_PCT: tuple[float, ...] = (0.91, 0.98, 1.20, 0.62, 0.98, 0.16, 0.46, 0.64)
"""Table 1: relative error of the module (%), as published (absolute values)."""

CALIBRATION_K_G_PER_PF: float = 18.655
"""Eq. (14) slope: grams per unit of the window sum Σ(C_k - C_initial)."""

CALIBRATION_B_G: float = 0.4053
"""Eq. (14) intercept (g)."""

CONSTANT_SPEED_DEFICIT_PCT: float = 3.80
"""Mean steady-state error of the constant-speed (open-loop) runs (%): the fertilizer drift."""

FIELD_RATE_KG_PER_HM2: float = 200.0
"""Field target rate M (kg/hm²)."""

FIELD_WIDTH_M: float = 3.0
"""Field working width D (m)."""

FIELD_SPEEDS_KMH: tuple[float, ...] = (4.0, 6.0, 8.0)
"""Field run speeds (km/h)."""
