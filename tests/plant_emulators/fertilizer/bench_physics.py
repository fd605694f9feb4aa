"""Benchmarks: physics steps per second of the fertilizer rig's models.

Run explicitly (the project's pytest options skip benchmarks by default)::

    python -m pytest tests/plant_emulators/fertilizer/bench_physics.py --benchmark-enable -q

``extra_info`` of each benchmark carries ``us_per_step``. The rig calls every model with
``advance(10)`` per 10 ms period, interleaved (ground speed, plant, four flow modules): the
last benchmark replays that pattern, which is what a field run costs (it is slower per step
than a model run alone: per-call overhead and the models evicting each other from the caches).
Each benchmark runs on both physics engines (``plant_emulators.engine``): the C twins and the
Python models, which give the same floats.
"""

from __future__ import annotations

import numpy as np
import pytest

from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fertilizer.flow_sensor import FlowSensor
from plant_emulators.fertilizer.ground_speed import GroundSpeedModel
from plant_emulators.fertilizer.physics import FertilizerPlant

DT = 0.001
STEPS_PER_ROUND = 10_000
"""Ten seconds of 1 kHz physics per benchmark round."""
TARGET_STEPS_PER_S = 100_000
"""Requirement: a 60 s run at 1 kHz must take well under one second."""
RIG_STEPS_PER_S = 50_000
"""Requirement for all models together in the rig's pattern (60 s of physics in 1.2 s)."""


@pytest.fixture(params=["native", "python"])
def engine(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture
def running_plant(engine: str) -> FertilizerPlant:
    plant = FertilizerPlant(load_rig_config(), np.random.default_rng(1), engine=engine)
    plant.command_v = 3.5                 # 21 r/min, 4 rows delivering and pulsing
    plant.advance(2000, DT)
    return plant


@pytest.fixture
def running_sensor(engine: str) -> FlowSensor:
    sensor = FlowSensor(load_rig_config().flow_sensor, np.random.default_rng(2), engine=engine)
    sensor.advance(3000, DT, 0.0)          # baseline acquired
    sensor.vibration_rms_mps2 = 2.5        # field: 6 km/h
    return sensor


@pytest.fixture
def running_ground(engine: str) -> GroundSpeedModel:
    ground = GroundSpeedModel(load_rig_config().ground_speed, np.random.default_rng(3),
                              engine=engine)
    ground.target_speed_mps = 6 / 3.6
    ground.advance(5000, DT)
    return ground


def _report(benchmark, steps: int) -> float:
    steps_per_s = steps / benchmark.stats.stats.mean
    benchmark.extra_info["steps_per_s"] = round(steps_per_s)
    benchmark.extra_info["us_per_step"] = round(1e6 / steps_per_s, 3)
    return steps_per_s


def test_physics_steps_per_second(benchmark, running_plant):
    benchmark.pedantic(running_plant.advance, args=(STEPS_PER_ROUND, DT), rounds=20,
                       warmup_rounds=2)
    benchmark.extra_info["rows"] = running_plant.config.meter.rows
    assert _report(benchmark, STEPS_PER_ROUND) >= TARGET_STEPS_PER_S


def test_control_period_call_overhead(benchmark, running_plant):
    """The rig calls advance(10) per 10 ms period: per-call overhead included."""
    def one_second() -> None:
        for _ in range(100):
            running_plant.advance(10, DT)

    benchmark.pedantic(one_second, rounds=20, warmup_rounds=2)
    assert _report(benchmark, 1000) >= TARGET_STEPS_PER_S


def test_flow_sensor_steps_per_second(benchmark, running_sensor):
    def one_second() -> None:
        for _ in range(100):
            running_sensor.advance(10, DT, 25.0)
            running_sensor.take_reports()

    benchmark.pedantic(one_second, rounds=20, warmup_rounds=2)
    assert _report(benchmark, 1000) >= 4 * TARGET_STEPS_PER_S


def test_ground_speed_steps_per_second(benchmark, running_ground):
    def one_second() -> None:
        for _ in range(100):
            running_ground.advance(10, DT)

    benchmark.pedantic(one_second, rounds=20, warmup_rounds=2)
    assert _report(benchmark, 1000) >= 4 * TARGET_STEPS_PER_S


def test_rig_call_pattern(benchmark, engine: str):
    """Every model as the rig drives it: ground speed, plant, four modules, 10 steps a call."""
    cfg = load_rig_config()
    rng = np.random.default_rng(6)
    plant = FertilizerPlant(cfg, rng, engine=engine)
    sensors = [FlowSensor(cfg.flow_sensor, rng, engine=engine) for _ in range(cfg.meter.rows)]
    ground = GroundSpeedModel(cfg.ground_speed, rng, engine=engine)
    ground.target_speed_mps = 6 / 3.6
    plant.command_v = 2.4                  # ~14 r/min: 25 g/s per row
    state = {"before": list(plant.sensor_passed_g)}

    def one_second() -> None:
        for _ in range(100):
            ground.advance(10, DT)
            plant.advance(10, DT)
            passed = plant.sensor_passed_g
            before = state["before"]
            for row, sensor in enumerate(sensors):
                sensor.vibration_rms_mps2 = ground.vibration_rms_mps2
                sensor.advance(10, DT, (passed[row] - before[row]) / (10 * DT))
                sensor.take_reports()
            state["before"] = list(passed)

    benchmark.pedantic(one_second, rounds=20, warmup_rounds=3)
    assert _report(benchmark, 1000) >= RIG_STEPS_PER_S
