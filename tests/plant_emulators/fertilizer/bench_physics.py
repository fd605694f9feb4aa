"""Benchmark: physics steps per second of the 4-row fertilizer plant.

Run explicitly (the project's pytest options skip benchmarks by default)::

    python -m pytest tests/plant_emulators/fertilizer/bench_physics.py --benchmark-enable -q
"""

from __future__ import annotations

import numpy as np
import pytest

from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fertilizer.physics import FertilizerPlant

DT = 0.001
STEPS_PER_ROUND = 10_000
"""Ten seconds of 1 kHz physics per benchmark round."""
TARGET_STEPS_PER_S = 100_000
"""Requirement: a 60 s run at 1 kHz must take well under one second."""


@pytest.fixture
def running_plant() -> FertilizerPlant:
    plant = FertilizerPlant(load_rig_config(), np.random.default_rng(1))
    plant.command_v = 3.5                 # 21 r/min, 4 rows delivering and pulsing
    plant.advance(2000, DT)
    return plant


def test_physics_steps_per_second(benchmark, running_plant):
    benchmark.pedantic(running_plant.advance, args=(STEPS_PER_ROUND, DT), rounds=20,
                       warmup_rounds=2)
    steps_per_s = STEPS_PER_ROUND / benchmark.stats.stats.mean
    benchmark.extra_info["steps_per_s"] = round(steps_per_s)
    benchmark.extra_info["rows"] = running_plant.config.meter.rows
    assert steps_per_s >= TARGET_STEPS_PER_S


def test_control_period_call_overhead(benchmark, running_plant):
    """The rig calls advance(10) per 10 ms control period: per-call overhead included."""
    def one_second() -> None:
        for _ in range(100):
            running_plant.advance(10, DT)

    benchmark.pedantic(one_second, rounds=20, warmup_rounds=2)
    steps_per_s = 1000 / benchmark.stats.stats.mean
    benchmark.extra_info["steps_per_s"] = round(steps_per_s)
    assert steps_per_s >= TARGET_STEPS_PER_S
