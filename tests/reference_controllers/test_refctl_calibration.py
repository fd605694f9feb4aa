"""The reference hears the operator's calibration test (MeterCalibration) and fits its map."""

from __future__ import annotations

import dataclasses
import math

import can
import pytest

from plant_emulators.fertilizer.frames import FertilizerDatabase
from reference_controllers.fertilizer.adapter import FlowController
from reference_controllers.fertilizer.calibration import ff_coeff_from_test
from reference_controllers.fertilizer.isobus_mode import IsobusFlowController
from reference_controllers.fertilizer.piecewise_pid import PiecewisePidParams, feedforward_volts
from reference_controllers.params import ParamError

SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
DB = FertilizerDatabase()
PHYS = PiecewisePidParams.physical()


def calibration(grams_per_rev: float, shaft_rpm: float = 20.0) -> can.Message:
    return DB.encode("MeterCalibration", {"GramsPerRev": grams_per_rev,
                                          "TestShaftSpeed": shaft_rpm, "Revolutions": 50})


def command_mv(ctl: FlowController) -> int:
    out = ctl.on_frame(SYNC)
    return int(DB.decode(out[-1])[1]["Ch1Output"])


@pytest.mark.parametrize("rpm", [3.0, 5.0, 12.0, 20.0, 32.0])
def test_the_test_of_the_nominal_map_gives_its_coefficient_back(rpm: float) -> None:
    """The map's own grams per revolution at any test speed (the knee's below it) give the
    coefficient the map was made with."""
    c, p, knee = 4.586, PHYS.ff_exponent, PHYS.ff_linear_below_rpm
    g_rev = 60.0 * c * max(rpm, knee) ** p / max(rpm, knee)
    assert ff_coeff_from_test(g_rev, rpm, p, knee) == pytest.approx(c, rel=1e-12)
    assert ff_coeff_from_test(1.05 * g_rev, rpm, p, knee) == pytest.approx(1.05 * c, rel=1e-12)


def test_no_test_or_an_impossible_one_is_ignored() -> None:
    p, knee = PHYS.ff_exponent, PHYS.ff_linear_below_rpm
    assert ff_coeff_from_test(0.0, 20.0, p, knee) is None
    assert ff_coeff_from_test(95.0, 0.0, p, knee) is None
    assert ff_coeff_from_test(655.35, 100.0, 0.0, knee) is None      # 1092 g/s at 1 r/min


def test_the_controller_meters_the_tested_lot() -> None:
    """Heard at any time, the test replaces ff_coeff for the feedforward; a frame without a
    test keeps the last one."""
    ctl = FlowController("physical", {"ff_coeff": 4.390})
    ctl.on_frame(DB.setpoint(mode=1, enable=True, target_flow_gps=23.0))
    before = command_mv(ctl)
    assert before == round(feedforward_volts(23.0, dataclasses.replace(PHYS, ff_coeff=4.39))
                           * 1000)
    ctl.on_frame(calibration(93.5))
    coeff = 93.5 / 60.0 * math.pow(20.0, 1.0 - PHYS.ff_exponent)
    assert ctl.core_params.ff_coeff == coeff
    assert ctl.closed_loop is not None and ctl.closed_loop.params.ff_coeff == coeff
    assert ctl.open_loop.params.ff_coeff == coeff
    after = command_mv(ctl)
    assert after == round(feedforward_volts(23.0, dataclasses.replace(PHYS, ff_coeff=coeff))
                          * 1000)
    assert after < before          # 93.5 g/rev is a denser lot than 4.390's: a slower shaft
    ctl.on_frame(calibration(0.0))
    assert ctl.core_params.ff_coeff == coeff


def test_use_calibration_0_ignores_the_test() -> None:
    ctl = FlowController("physical", {"ff_coeff": 4.390, "use_calibration": 0})
    ctl.on_frame(calibration(93.5))
    assert ctl.core_params.ff_coeff == 4.390
    with pytest.raises(ParamError, match="use_calibration"):
        FlowController("physical", {"use_calibration": 0.5})


def test_the_isobus_mode_refuses_the_terminal_modes_parameter() -> None:
    """As the C build: use_calibration is the terminal mode's (fert_param_refs), not the
    implement's (fert_common_param_refs)."""
    with pytest.raises(ParamError, match="use_calibration"):
        IsobusFlowController(use_calibration=0)
