"""Physics throughput: 12-row sowing-depth plant steps per second at 1 kHz.

Run with ``python -m pytest tests/plant_emulators/sowing_depth/bench_physics.py
--benchmark-enable -q``. The target is ≥ 50,000 steps/s (50x real time at 1 kHz).
"""

from __future__ import annotations

import numpy as np
import pytest

from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.physics import SowingDepthPlant

STEPS = 20_000
DT = 0.001


def moving_plant(mode: int, speed_kmh: float) -> SowingDepthPlant:
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(0))
    plant.advance(30, DT)
    drive = plant.drive
    drive.write(0x6060, 0, mode)
    for word in (0x06, 0x07, 0x0F):
        drive.write(0x6040, 0, word)
    if mode == 3:
        drive.write(0x60FF, 0, 200)           # 2 mm/s: the rod creeps the whole run
    else:
        drive.write(0x607A, 0, 9000)
        drive.write(0x6040, 0, 0x1F)
    plant.ground_speed_mps = speed_kmh / 3.6
    return plant


@pytest.mark.parametrize(("mode", "speed_kmh"), [(1, 7.0), (3, 7.0), (3, 2.0)],
                         ids=["pp-7kmh", "pv-7kmh", "pv-2kmh"])
def test_physics_steps_per_second(benchmark: object, mode: int, speed_kmh: float) -> None:
    plant = moving_plant(mode, speed_kmh)
    benchmark.pedantic(plant.advance, args=(STEPS, DT), rounds=5, iterations=1)  # type: ignore[attr-defined]
    stats = benchmark.stats.stats  # type: ignore[attr-defined]
    steps_per_s = STEPS / stats.mean
    benchmark.extra_info["steps_per_s"] = round(steps_per_s)  # type: ignore[attr-defined]
    benchmark.extra_info["rows"] = plant.config.machine.rows  # type: ignore[attr-defined]
    assert steps_per_s >= 50_000
