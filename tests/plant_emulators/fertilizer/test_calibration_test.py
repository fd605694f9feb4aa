"""The operator's calibration test of a lot: its physics, and when the terminal sends it."""

from __future__ import annotations

import dataclasses
import math
import statistics

import numpy as np
import pytest

from hil.errors import ConfigError
from hil.rig import RigContext
from hil.rig.scenario import Scenario
from plant_emulators.fertilizer.calibration_test import lot_seed_words, run_calibration_test
from plant_emulators.fertilizer.config import FertilizerRigConfig
from plant_emulators.fertilizer.flow_map import FlowMap
from plant_emulators.fertilizer.rig import FertilizerRig


def _errors(config: FertilizerRigConfig, n: int = 3000) -> list[float]:
    return [run_calibration_test(config, -0.035, seed_words=(i,)).error_frac for i in range(n)]


def test_the_test_weighs_the_lot_with_the_error_its_parts_give(rig_config) -> None:
    """Unbiased, and its spread is that of its parts: the day's offset, the wander, the flutes'
    fill over N revolutions and the scale (uniform +-e, read to the resolution)."""
    test_cfg = rig_config.calibration_test
    meter, fert = rig_config.meter, rig_config.fertilizer
    errors = _errors(rig_config)
    t = run_calibration_test(rig_config, -0.035, seed_words=(0,))
    mass_kg = t.lot_grams_per_rev_row * test_cfg.revolutions * meter.rows / 1000.0
    scale_sd = math.sqrt(test_cfg.scale_error_kg ** 2 / 3.0
                         + test_cfg.scale_resolution_kg ** 2 / 12.0) / mass_kg
    flute_sd = meter.flute_charge_sd_frac / math.sqrt(
        test_cfg.revolutions * meter.flutes * meter.rows)
    expected = math.sqrt(fert.density_offset_sd_frac ** 2 + fert.density_drift_sd_frac ** 2
                         + flute_sd ** 2 + scale_sd ** 2)
    assert abs(statistics.fmean(errors)) < 3 * expected / math.sqrt(len(errors))
    assert statistics.pstdev(errors) == pytest.approx(expected, rel=0.06)


def test_the_lot_and_the_map_set_what_the_test_reads(rig_config) -> None:
    """Without the test's own errors it reads the map's grams per revolution at its speed,
    times the lot and the box's level; a denser lot reads denser."""
    fert = rig_config.fertilizer
    quiet = dataclasses.replace(
        rig_config,
        fertilizer=dataclasses.replace(fert, density_offset_sd_frac=0.0,
                                       density_drift_sd_frac=0.0),
        meter=dataclasses.replace(rig_config.meter, flute_charge_sd_frac=0.0),
        calibration_test=dataclasses.replace(rig_config.calibration_test,
                                             scale_error_kg=0.0, scale_resolution_kg=1e-6))
    n = quiet.calibration_test.shaft_speed_rpm
    level = 1.0 - fert.level_sensitivity_frac * (1.0 - fert.hopper_initial_kg
                                                  / fert.hopper_capacity_kg)
    map_g_rev = 60.0 * FlowMap.from_config(quiet.meter).flow_gps(n) / n
    for lot in (-0.07, -0.035, 0.0, 0.045):
        t = run_calibration_test(quiet, lot, seed_words=(1,))
        assert t.grams_per_rev_row == pytest.approx(map_g_rev * (1 + lot) * level, rel=1e-6)
    coarse = run_calibration_test(rig_config, -0.035, seed_words=(5,))
    assert round(coarse.weighed_kg / 0.1, 6) == round(coarse.weighed_kg / 0.1)


def test_one_lot_one_test() -> None:
    """The test of a sample's lot is seeded by the lot: every run of the sample gets it."""
    assert lot_seed_words(-0.0312) == lot_seed_words(-0.0312)
    assert lot_seed_words(-0.0312) != lot_seed_words(-0.0313)


def _rig(config: FertilizerRigConfig, initial: dict[str, float] | None = None,
         seed: int = 3) -> FertilizerRig:
    scenario = Scenario(name="cal", description="", rig="fertilizer", duration_s=1.0,
                        initial={"terminal_mode": 1.0, **(initial or {})})
    rig = FertilizerRig(RigContext(seed=seed, rng=np.random.default_rng(seed),
                                   scenario=scenario), config)
    for name, value in (initial or {}).items():
        rig.set_input(name, value, 0.0)
    return rig


def _calibration_frames(rig: FertilizerRig) -> list:
    return rig.calibration.emit(0.0)


def test_the_terminal_sends_the_test_only_for_another_lot(rig_config) -> None:
    """The nominal lot is the one the controllers' own calibration was made on: no test, no
    frame (the nominal rig's bus is as before). A dispersed lot is tested, in every run alike;
    the frame carries the test as the DBC says."""
    nominal = _rig(rig_config)
    assert nominal.calibration_test() is None and _calibration_frames(nominal) == []
    assert nominal.truth()["calibration_test"] is None
    lot = dataclasses.replace(rig_config, fertilizer=dataclasses.replace(
        rig_config.fertilizer, density_offset_mean_frac=-0.0213))
    runs = [_rig(lot, seed=s) for s in (1, 2)]
    tests = [r.calibration_test() for r in runs]
    assert tests[0] is not None and tests[0] == tests[1]
    [frame] = _calibration_frames(runs[0])
    assert frame.arbitration_id == 0x310 and not frame.is_extended_id
    values = runs[0].codec.db.decode(frame)[1]
    assert values["GramsPerRev"] == pytest.approx(tests[0].grams_per_rev_row, abs=0.005)
    assert values["TestShaftSpeed"] == pytest.approx(20.0)
    assert values["Revolutions"] == 50
    assert runs[0].truth()["calibration_test"]["grams_per_rev_row"] == \
        tests[0].grams_per_rev_row


def test_a_scenario_sets_the_lot_and_whether_it_was_tested(rig_config) -> None:
    untested = _rig(rig_config, {"lot_offset_frac": 0.04, "calibration_test": 0.0})
    assert untested.calibration_test() is None
    assert untested.lot_frac == pytest.approx(rig_config.calibration_test.calibrated_lot_frac
                                              + 0.04)
    base = _rig(rig_config)
    assert untested.plant.density_offset_frac - base.plant.density_offset_frac == \
        pytest.approx(0.04)
    tested = _rig(rig_config, {"lot_offset_frac": 0.08, "calibration_test": 1.0})
    assert tested.calibration_test() is not None
    assert tested.calibration_test().lot_frac == pytest.approx(tested.lot_frac)
    with pytest.raises(ConfigError, match=r"lot_offset_frac.*0 s"):
        base.set_input("lot_offset_frac", 0.02, 1.0)
    with pytest.raises(ConfigError, match="calibration_test must be 0 or 1"):
        base.set_input("calibration_test", 0.5, 0.0)
