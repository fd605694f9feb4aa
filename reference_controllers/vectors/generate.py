"""Input sequences for the shared test vectors, and the expected outputs from the Python cores.

The inputs do not depend on the controller's outputs (a replay feeds them as they are), but
they look like what the adapters feed the cores on the rigs, from seeded numpy generators:

* fertilizer (320 steps of 0.1 s): target 0 → 23 → 44 → 34 g/s, a reset to 0, then
  23 → 44 → 34 again, 8 g/s (below the map's knee: the linear part of the feedforward) and a
  target above the meter's range (80 g/s: the feedforward clamps);
  the measured flow lags the target (first order, τ = 0.8 s) times a slowly varying delivery
  gain (±3 %) with sensor noise; a block sensor (a new report every 10th step) for the first
  half, a sliding one (every step) for the second; the measurement drops for a few steps
  twice; two reports land exactly on the paper-literal thresholds (|e| = e1 and |e| = e2);
* depth (500 steps of 0.01 s): target 30 then 40 mm; the depth lags the target with noise
  (which alone drives EC over its whole universe); a sensor glitch sweeps the error from
  -210 to +210 mm (E over [-6, 6], saturation, conditional integration); ``valid`` and
  ``enabled`` drop for a few steps each (resets).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from reference_controllers.fertilizer.piecewise_pid import PiecewisePidParams
from reference_controllers.params import field_names
from reference_controllers.sowing_depth.fuzzy_pid import FuzzyPidParams
from reference_controllers.vectors import (
    DEPTH_COLUMNS,
    FERTILIZER_COLUMNS,
    VECTOR_DIR,
    Vector,
    fertilizer_core,
    write_vector,
)

FERTILIZER_SEED = 20230202     # [F]: Trans. CSAM 54(2)
DEPTH_SEED = 20230111          # [D]: Trans. CSAM 54(S1)
FEEDFORWARD_KEYS = ("ff_coeff", "ff_exponent", "shaft_rpm_per_v", "v_max", "ff_linear_below_rpm")


@dataclass(frozen=True)
class FertilizerStep:
    target_gps: float
    measured_gps: float
    has_measurement: int
    new_report: int


def fertilizer_target(k: int) -> float:
    for end, target in ((10, 0.0), (70, 23.0), (120, 44.0), (160, 34.0), (170, 0.0),
                        (220, 23.0), (260, 44.0), (300, 34.0), (310, 8.0)):
        if k < end:
            return target
    return 80.0


def fertilizer_inputs(n: int = 320, seed: int = FERTILIZER_SEED) -> list[FertilizerStep]:
    rng = np.random.default_rng(seed)
    alpha = 1.0 - math.exp(-0.1 / 0.8)
    flow = 0.0
    steps = []
    for k in range(n):
        target = fertilizer_target(k)
        gain = 1.0 + 0.03 * math.sin(2.0 * math.pi * k / 90.0)
        flow += alpha * (target * gain - flow)
        measured = max(0.0, flow + float(rng.normal(0.0, 0.25)))
        new_report = int(k % 10 == 0) if k < 160 else 1
        has = int(not (60 <= k < 75 or 230 <= k < 234))
        if k == 40:
            measured = target - 1.0         # |e| = e1 (paper-literal): medium band
        elif k == 50:
            measured = target - 5.0         # |e| = e2 (paper-literal): coarse band
        steps.append(FertilizerStep(target, measured, has, new_report))
    return steps


def fertilizer_vector(mode: str, inputs: list[FertilizerStep]) -> Vector:
    if mode == "open-loop":
        base = PiecewisePidParams.physical()
        params: dict[str, str | float] = {"mode": "open-loop",
                                          **{k: getattr(base, k) for k in FEEDFORWARD_KEYS}}
    else:
        p = PiecewisePidParams.default(mode)
        params = {k: getattr(p, k) for k in field_names(p)}
    text = {k: v if isinstance(v, str) else repr(v) for k, v in params.items()}
    core = fertilizer_core(text)
    rows = []
    for s in inputs:
        volts, segment = core.step(s.target_gps, s.measured_gps, bool(s.has_measurement),
                                   bool(s.new_report))
        rows.append((s.target_gps, s.measured_gps, s.has_measurement, s.new_report, volts,
                     segment))
    return Vector({k: str(v) for k, v in params.items()}, FERTILIZER_COLUMNS, rows)


@dataclass(frozen=True)
class DepthStep:
    target_mm: float
    depth_mm: float
    valid: int
    enabled: int


def depth_inputs(n: int = 500, seed: int = DEPTH_SEED) -> list[DepthStep]:
    rng = np.random.default_rng(seed)
    alpha = 1.0 - math.exp(-0.01 / 0.3)
    depth = 12.0
    steps = []
    for k in range(n):
        target = 30.0 if k < 250 else 40.0
        depth += alpha * (target - depth)
        sensed = depth + float(rng.normal(0.0, 0.3))
        if 330 <= k < 400:                  # glitch: error sweeps -210 … +210 mm
            sensed = target + 210.0 - 420.0 * (k - 330) / 69.0
        valid = int(not 150 <= k < 158)
        enabled = int(not 200 <= k < 206)
        steps.append(DepthStep(target, sensed, valid, enabled))
    return steps


def depth_vector(params: FuzzyPidParams, inputs: list[DepthStep]) -> Vector:
    from reference_controllers.sowing_depth.fuzzy_pid import FuzzyPid

    core = FuzzyPid(params)
    rows = []
    for s in inputs:
        out = core.step(s.target_mm, s.depth_mm, bool(s.valid), bool(s.enabled))
        rows.append((s.target_mm, s.depth_mm, s.valid, s.enabled, *out))
    text = {k: repr(getattr(params, k)) for k in field_names(params)}
    return Vector(text, DEPTH_COLUMNS, rows)


def all_vectors() -> dict[str, Vector]:
    """Every vector file by name."""
    fert = fertilizer_inputs()
    depth = depth_inputs()
    return {
        "fertilizer-physical": fertilizer_vector("physical", fert),
        "fertilizer-paper-literal": fertilizer_vector("paper-literal", fert),
        "fertilizer-open-loop": fertilizer_vector("open-loop", fert),
        "depth-fuzzy-pid": depth_vector(FuzzyPidParams(), depth),
        # low presets: the max(0, ·) floors of eq. 10 bite (Kp, Kd reach 0)
        "depth-fuzzy-pid-low-presets": depth_vector(
            FuzzyPidParams(kp0=0.5, ki0=0.04, kd0=0.3), depth),
    }


def write_all(directory: Path = VECTOR_DIR) -> list[Path]:
    paths = []
    for name, vector in all_vectors().items():
        path = directory / f"{name}.csv"
        write_vector(path, dict(vector.params), vector.columns, vector.rows)
        paths.append(path)
    return paths
