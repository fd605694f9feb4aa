"""Reproducibility: advance(n) equals n x advance(1) bit for bit, seeds fix every run.

Every test runs on both physics engines (``plant_emulators.engine``): the runner relies on
these properties whichever engine runs the models."""

from __future__ import annotations

import numpy as np
import pytest

from plant_emulators.engine import ENV_VAR
from plant_emulators.fertilizer.flow_sensor import FlowSensor
from plant_emulators.fertilizer.ground_speed import GroundSpeedModel
from plant_emulators.fertilizer.physics import FertilizerPlant

DT = 0.001


@pytest.fixture(autouse=True, params=["native", "python"])
def engine(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """The engine every model of the test is built with (through AGRIHIL_PHYSICS)."""
    monkeypatch.setenv(ENV_VAR, request.param)
    return str(request.param)

# (steps, command V, stalled) segments that visit ramps, steady running, a stall and a stop.
PLANT_SCRIPT = [(700, 2.0, False), (1300, 5.3, False), (400, 5.3, True), (900, 7.0, False),
                (600, 0.0, False), (300, 12.0, False)]


def _run_plant(seed: int, chunk: int | None, config) -> FertilizerPlant:
    plant = FertilizerPlant(config, np.random.default_rng(seed))
    for steps, command, stalled in PLANT_SCRIPT:
        plant.command_v = command
        plant.stalled = stalled
        if chunk is None:
            plant.advance(steps, DT)
        else:
            done = 0
            while done < steps:
                k = min(chunk, steps - done)
                plant.advance(k, DT)
                done += k
    return plant


@pytest.mark.parametrize("chunk", [1, 7, 250])
def test_plant_advance_n_equals_n_single_steps(rig_config, chunk):
    whole = _run_plant(42, None, rig_config)
    pieces = _run_plant(42, chunk, rig_config)
    assert whole.signals() == pieces.signals()
    assert whole.flow_at_meter_gps == pieces.flow_at_meter_gps
    assert whole.shaft_revolutions == pieces.shaft_revolutions


def test_plant_same_seed_same_run_different_seed_different_run(rig_config):
    a = _run_plant(1, None, rig_config).signals()
    b = _run_plant(1, None, rig_config).signals()
    c = _run_plant(2, None, rig_config).signals()
    assert a == b
    assert a["row1_delivered_g"] != c["row1_delivered_g"]
    assert a["density_factor"] != c["density_factor"]


def test_sensor_advance_n_equals_n_single_steps(rig_config):
    def run(chunk: int) -> list:
        sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(9), mode="sliding")
        reports = []
        for steps, flow in ((2500, 0.0), (3000, 31.0), (1700, 12.5)):
            done = 0
            while done < steps:
                k = min(chunk, steps - done)
                sensor.advance(k, DT, flow)
                done += k
                reports += sensor.take_reports()
        return reports

    single, whole = run(1), run(10_000)
    assert single == whole
    assert len(single) > 50


def test_ground_speed_advance_n_equals_n_single_steps(rig_config):
    def run(chunk: int) -> tuple:
        model = GroundSpeedModel(rig_config.ground_speed, np.random.default_rng(4))
        model.target_speed_mps = 2.0
        done = 0
        while done < 4000:
            k = min(chunk, 4000 - done)
            model.advance(k, DT)
            done += k
        return model.signals(), model.hall_report()

    assert run(1) == run(4000)


def test_models_draw_from_their_own_streams(rig_config):
    """Advancing the sensors or not never changes the plant: each model owns a child stream."""
    def plant_after(advance_sensors: bool) -> dict:
        rng = np.random.default_rng(77)
        plant = FertilizerPlant(rig_config, rng)
        sensors = [FlowSensor(rig_config.flow_sensor, rng) for _ in range(4)]
        plant.command_v = 4.0
        for _ in range(300):
            plant.advance(10, DT)
            if advance_sensors:
                for r, sensor in enumerate(sensors):
                    sensor.advance(10, DT, plant.flow_at_sensor_gps[r])
        return plant.signals()

    assert plant_after(True) == plant_after(False)
