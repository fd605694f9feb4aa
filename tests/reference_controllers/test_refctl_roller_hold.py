"""Where the depth controller holds the roller while its inclinometer is dead (issue #16).

The adapter tracks the mean rod position (TPDO1's Position actual value) while it regulates,
and drives the rod back to it when the depth turns invalid on a running machine; the C build's
``firmware/tests/test_depth_adapter.c`` checks the same steps, and
``tests/firmware/test_firmware_depth.py`` that both builds hold at the same position bit for bit.
"""

from __future__ import annotations

import can
import pytest

from plant_emulators.sowing_depth.frames import DepthSetpoint, FrameCodec, InclinometerFrame
from reference_controllers.params import ParamError
from reference_controllers.sowing_depth.adapter import DepthController
from reference_controllers.sowing_depth.roller_hold import RollerHold, RollerHoldParams

SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
CODEC = FrameCodec()


def _tpdo1(statusword: int, position_inc: int) -> can.Message:
    return can.Message(arbitration_id=0x182, is_extended_id=False,
                       data=statusword.to_bytes(2, "little")
                       + position_inc.to_bytes(4, "little", signed=True))


def _controller(**params: float) -> DepthController:
    ctl = DepthController(params)
    ctl.on_frame(can.Message(arbitration_id=0x702, is_extended_id=False, data=b"\x05"))
    ctl.on_frame(CODEC.encode(DepthSetpoint(target_depth_mm=30.0)))
    return ctl


def _step(ctl: DepthController, i: int, position_inc: int, *, x_status: str | int = "ok",
          statusword: int = 0x0237, speed_mps: float = 1.0) -> tuple[int, float | None]:
    """One step with the rod at ``position_inc`` (0.01 mm), a live inclinometer frame (status
    ``x_status``) and a ground speed: (RPDO2 target velocity, RollerPositionCommand or None)."""
    ctl.on_frame(_tpdo1(statusword, position_inc))
    ctl.on_frame(CODEC.encode(InclinometerFrame(x_mv=3700 + i % 2, y_mv=2500,
                                                x_status=x_status)))
    ctl.on_frame(can.Message(arbitration_id=0x0CFE49F0, is_extended_id=True,
                             data=CODEC.encode_signals("GBSD", {
                                 "GBSD_GroundSpeed": speed_mps, "GBSD_GroundDistance": 0.0,
                                 "GBSD_Direction": "forward"}).data))
    out = ctl.on_frame(SYNC)
    rpdo2 = next(m for m in out if m.arbitration_id == 0x302)
    command = None
    for msg in out:
        if msg.arbitration_id == 0x18FF3080:
            status = CODEC.decode(msg)
            command = float(status.roller_position_command_mm)
            assert status.sensor_fault == int(x_status != "ok")
    return int.from_bytes(rpdo2.data[2:6], "little", signed=True), command


def test_holds_the_rod_at_its_mean_position_while_the_depth_is_invalid() -> None:
    ctl = _controller()
    # 10 s of valid control with the rod swinging 40.00 / 42.00 mm: the mean settles at 41 mm
    for i in range(1000):
        _, command = _step(ctl, i, 4200 if i % 2 else 4000)
        assert not ctl.holding and command in (None, 0.0)
    assert ctl.hold.mean_mm == pytest.approx(41.0, abs=0.01)
    # the target: the mean when the last new X voltage came (before step 999's tracking)
    mean, last_mean = ctl.hold.target_mm, ctl.hold.mean_mm
    assert mean == pytest.approx(41.0, abs=0.01)
    # the sensor fails with the rod at 39.00 mm: back at 5/s·(h - p), and the status frame
    # carries the hold target
    velocity, command = _step(ctl, 1000, 3900, x_status=1)
    assert ctl.holding and velocity == round(5.0 * (mean - 39.0) * 100.0)
    assert command == pytest.approx(round(mean * 100.0) / 100.0, abs=1e-9)
    assert ctl.hold.mean_mm == last_mean                # no tracking while invalid
    assert ctl.hold.target_mm == mean
    assert _step(ctl, 1001, 4150, x_status=1)[0] == round(5.0 * (mean - 41.5) * 100.0)
    assert _step(ctl, 1002, 2000, x_status=1)[0] == 1000        # bounded at 10 mm/s
    assert _step(ctl, 1003, 9000, x_status=1)[0] == -1000
    # the drive not in Operation enabled: nothing to drive
    assert _step(ctl, 1004, 3900, x_status=1, statusword=0x0233)[0] == 0
    assert not ctl.holding
    # standstill: 0 as before and the mean is forgotten, so a machine that drives off with
    # the sensor still dead holds the roller where it is
    assert _step(ctl, 1005, 3900, x_status=1, speed_mps=0.0)[0] == 0
    assert ctl.hold.mean_mm is None and ctl.hold.target_mm is None
    assert _step(ctl, 1006, 3900, x_status=1)[0] == 0
    # valid again: the mean starts afresh at the rod's position
    _step(ctl, 1007, 4321)
    assert ctl.hold.mean_mm == 43.21


def test_a_frozen_inclinometer_is_held_at_the_mean_of_its_last_sign_of_life() -> None:
    """The loop steers on the frozen reading for 0.2 s and the mean follows the rod it
    moves; the hold target is the mean at the last new X voltage, before any of that."""
    ctl = _controller()
    for i in range(300):
        _step(ctl, i, 4000)
    assert ctl.hold.mean_mm == 40.0
    for _ in range(22):                                 # X frozen from 3.00 s: dead at 3.21 s
        ctl.on_frame(_tpdo1(0x0237, 3800))
        ctl.on_frame(CODEC.encode(InclinometerFrame(x_mv=3700, y_mv=2500)))
        ctl.on_frame(SYNC)
    assert ctl.frozen() and ctl.holding
    assert ctl.hold.mean_mm is not None and ctl.hold.mean_mm < 39.99
    assert ctl.hold.target_mm == 40.0
    assert ctl.speed_mm_s == 10.0                       # 5/s · (40 - 38)


def test_gain_zero_holds_in_place_and_bad_parameters_are_named() -> None:
    ctl = _controller(hold_gain_per_s=0.0)
    for i in range(100):
        _step(ctl, i, 4000)
    assert _step(ctl, 100, 3000, x_status=1)[0] == 0 and ctl.holding
    for key, value in (("hold_time_constant_s", 0.0), ("hold_gain_per_s", -1.0),
                       ("hold_speed_mm_s", -1.0), ("hold_speed_mm_s", 60.0)):
        with pytest.raises(ParamError, match=key):
            DepthController({key: value})


def test_the_hold_loop_does_not_overshoot() -> None:
    """Against a rod that follows its speed command, seen one SYNC late (TPDO1 of the last
    step), the loop returns from 2 mm off without overshoot, within 0.05 mm in under 1 s."""
    hold = RollerHold(RollerHoldParams())
    hold.track(41.0, 0.01)
    hold.mark()
    x = seen = 39.0
    trace = []
    for _ in range(300):
        v = hold.speed(seen)
        assert abs(v) <= 10.0
        seen = x
        x += v * 0.01
        trace.append(x)
    assert max(trace) <= 41.0
    assert next(k for k, p in enumerate(trace) if abs(p - 41.0) <= 0.05) < 100
