"""The depth reference as an ISOBUS implement: its DDOP, the TC's depth, the fallback."""

from __future__ import annotations

import pytest

from hil.isobus import ddi as dd
from hil.isobus.field.prescription import RATE_UNITS
from hil.isobus.process_data import AckError
from hil.isobus.tc_client import ClientState
from reference_controllers.params import ParamError
from reference_controllers.sowing_depth.isobus_mode import IsobusDepthController


def _controller(**params) -> IsobusDepthController:
    return IsobusDepthController({"kp0": 3.0, "ki0": 0.1, "kd0": 0.0, **params})


def test_a_depth_map_is_sent_as_ddi_56_in_whole_mm() -> None:
    unit = RATE_UNITS["mm"]
    assert (unit.ddi, unit.ddi_per_unit) == (dd.SETPOINT_SEEDING_DEPTH, 1.0)


def test_the_ddop_declares_the_depth_process_data_and_its_range() -> None:
    ctl = _controller()
    pool, line = ctl.pool, ctl.elements.seed_line
    assert pool.settable() == ((line, dd.SETPOINT_SEEDING_DEPTH),)
    assert pool.property_value(line, dd.DEFAULT_SEEDING_DEPTH) == 30
    assert pool.property_value(line, dd.MINIMUM_SEEDING_DEPTH) == 10
    assert pool.property_value(line, dd.MAXIMUM_SEEDING_DEPTH) == 60
    assert pool.property_value(line, dd.DEVICE_ELEMENT_OFFSET_X) == -1900   # the seed tubes
    assert pool.property_value(line, dd.ACTUAL_WORKING_WIDTH) == 2400       # 12 x 200 mm


def test_the_tc_sets_the_depth_and_losing_it_falls_back_to_the_default() -> None:
    ctl = _controller()
    line = ctl.elements.seed_line
    assert ctl._on_setpoint(line, dd.SETPOINT_SEEDING_DEPTH, 40, 1.0) is None
    assert ctl._on_setpoint(line, dd.SETPOINT_SEEDING_DEPTH, 70, 1.1) == \
        AckError.VALUE_OUT_OF_OPERATIONAL_RANGE
    assert ctl._on_setpoint(line, dd.ACTUAL_SEEDING_DEPTH, 40, 1.1) == \
        AckError.DDI_NOT_SUPPORTED_BY_ELEMENT
    ctl.client.state = ClientState.CONNECTED                # the TC's pool active
    assert ctl.current_target_mm() == 40.0
    ctl.client.state = ClientState.WAIT_STATUS
    ctl._on_connection(False, 9.0)
    assert ctl.current_target_mm() == 30.0                  # DDI 58, as the DDOP declares


def test_the_must_fail_defects_are_parameters() -> None:
    fixed = _controller(fixed_depth_mm=35)
    line = fixed.elements.seed_line
    fixed._on_setpoint(line, dd.SETPOINT_SEEDING_DEPTH, 40, 1.0)
    assert fixed.current_target_mm() == 35.0
    hold = _controller(fallback="hold")
    hold._on_setpoint(line, dd.SETPOINT_SEEDING_DEPTH, 40, 1.0)
    hold._on_connection(False, 9.0)
    assert hold.current_target_mm() == 40.0
    with pytest.raises(ParamError, match="fixed_depth_mm"):
        _controller(fixed_depth_mm=5)
    with pytest.raises(ParamError, match="fallback"):
        _controller(fallback="never")
