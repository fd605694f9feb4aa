"""The CAN adapters: frame-level behaviour from the contract, then short lockstep rig runs on
the inline bus."""

from __future__ import annotations

from pathlib import Path

import can
import numpy as np
import pytest

from hil.dut import InProcessDut
from hil.record import load_traces
from hil.rig import Event, RunOptions, Scenario, run_scenario
from plant_emulators.fertilizer.frames import FertilizerDatabase
from plant_emulators.fertilizer.rig import FertilizerRig
from plant_emulators.sowing_depth.frames import DepthSetpoint, FrameCodec, InclinometerFrame
from plant_emulators.sowing_depth.rig import SowingDepthRig
from plant_emulators.sowing_depth.sensors import calibration_signal_mv
from reference_controllers.fertilizer.adapter import FlowController, OpenLoopFlowController
from reference_controllers.fertilizer.piecewise_pid import PiecewisePidParams, feedforward_volts
from reference_controllers.params import ParamError
from reference_controllers.sowing_depth.adapter import DepthController
from reference_controllers.sowing_depth.ground_speed import nmea_speed

SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
DB = FertilizerDatabase()
PHYS = PiecewisePidParams.physical()


def flow(row: int, gps: float, *, ready: int = 1, overrange: int = 0) -> can.Message:
    return DB.encode(f"FlowModule{row}", {
        "Flow": gps, "WindowMass": gps, "Counter": 1, "BaselineReady": ready,
        "SlidingWindow": 0, "AdcOverrange": overrange, "InterceptApplied": 0,
        "WindowLength": 1000})


def setpoint(target: float = 23.0, *, mode: int = 1, enable: bool = True) -> can.Message:
    return DB.setpoint(mode=mode, enable=enable, target_flow_gps=target)


def decoded(frames: list[can.Message]) -> dict[str, dict[str, float]]:
    out = {}
    for msg in frames:
        name, signals = DB.decode(msg)
        out[name] = {k: float(v) for k, v in signals.items()}
    return out


# ------------------------------------------------------------------ fertilizer, frame level
def test_flow_controller_writes_command_status_and_heartbeat_each_step() -> None:
    ctl = FlowController("physical")
    assert [bytes(m.data) for m in ctl.on_start()] == [b"\x00"]       # boot-up 0x710
    ctl.on_frame(setpoint(23.0))
    first = decoded(ctl.on_frame(SYNC))
    assert set(first) == {"AnalogOutputCommand", "ControllerStatus", "ControllerHeartbeat"}
    assert first["AnalogOutputCommand"]["Ch1Output"] == round(feedforward_volts(23, PHYS) * 1000)
    assert first["ControllerHeartbeat"]["NmtState"] == 5
    status = first["ControllerStatus"]
    assert (status["TargetFlow"], status["Enabled"], status["SensorFault"]) == (23.0, 1, 1)
    names = [set(decoded(ctl.on_frame(SYNC))) for _ in range(10)]
    assert ["ControllerStatus" in n for n in names] == [False] * 9 + [True]   # every 10th
    # the command closes every step: the rig's lockstep barrier waits for it, so nothing of
    # the step may follow it (#22.7: frames after it landed in the next 10 ms slot at random)
    for _ in range(20):
        assert ctl.on_frame(SYNC)[-1].arbitration_id == DB.frame_id("AnalogOutputCommand")


def test_rows_valid_only_when_ready_fresh_plausible_and_in_range() -> None:
    ctl = FlowController("physical", {"stale_after_s": 0.5})
    ctl.on_frame(setpoint(20.0))
    for row, msg in enumerate([flow(1, 19.0), flow(2, 21.0, ready=0),
                               flow(3, 21.0, overrange=1), flow(4, 66.0)], start=1):
        assert ctl.on_frame(msg) == [], row
    m = ctl.rows.measure(20.0, ctl.steps)              # 66 > 3·20 + 5: implausible
    assert (m.measured_gps, m.has_measurement, m.new_report, m.valid_rows) == (19.0, True,
                                                                              True, 1)
    ctl.on_frame(flow(2, 21.0))
    ctl.on_frame(SYNC)                                 # the update uses rows 1 and 2
    assert ctl.closed_loop is not None and ctl.closed_loop.e_prev == pytest.approx(0.0)
    for _ in range(6):                                 # 0.6 s later both are stale
        ctl.on_frame(SYNC)
    held = ctl.volts
    assert not ctl.rows.measure(20.0, ctl.steps).has_measurement
    status = decoded(ctl.on_frame(SYNC) + [m for _ in range(3) for m in ctl.on_frame(SYNC)])
    assert ctl.volts == held and status["ControllerStatus"]["SensorFault"] == 1


def test_constant_speed_mode_runs_open_loop_and_field_mode_follows_the_speed() -> None:
    ctl = FlowController("physical")
    ctl.on_frame(flow(1, 10.0))
    ctl.on_frame(setpoint(30.0, mode=2))
    assert ctl.on_frame(SYNC) and ctl.volts == feedforward_volts(30.0, PHYS)
    # field: Q = 0.1·M·D·v / rows, v from the Hall wheel (source 0)
    ctl.on_frame(DB.encode("GroundWheelSpeed", {"WheelSpeed": 1.5, "PulseCount": 0,
                                                "PulsePeriod": 0.01, "Counter": 0,
                                                "Moving": 1}))
    ctl.on_frame(DB.setpoint(mode=0, enable=True, target_rate_kg_per_hm2=200.0,
                             working_width_m=3.0, speed_source=0, active_rows=4))
    assert ctl.target_gps() == pytest.approx(0.1 * 200 * 3 * 1.5 / 4)
    ctl.on_frame(DB.setpoint(mode=0, enable=False))
    ctl.on_frame(SYNC)
    assert ctl.volts == 0.0


def test_open_loop_controller_and_parameter_errors() -> None:
    ctl = OpenLoopFlowController()
    ctl.on_frame(setpoint(34.0))
    ctl.on_frame(flow(1, 100.0))
    ctl.on_frame(SYNC)
    assert (ctl.volts, ctl.segment) == (feedforward_volts(34.0, PHYS), 0)
    assert FlowController(mode="paper-literal").law == "paper-literal"      # profile keyword
    assert FlowController(ki1="0.3").core_params.ki1 == 0.3
    with pytest.raises(ParamError, match="'kj1'"):
        FlowController(kj1=1.0)
    with pytest.raises(ParamError, match="'ki1'"):
        OpenLoopFlowController(ki1=1.0)
    with pytest.raises(ParamError, match="contradicts"):
        FlowController("physical", mode="paper-literal")


# ------------------------------------------------------------------ depth, frame level
def test_depth_controller_masters_the_drive() -> None:
    ctl = DepthController()
    codec = FrameCodec()
    boot = ctl.on_frame(can.Message(arbitration_id=0x702, is_extended_id=False, data=b"\x00"))
    assert [(m.arbitration_id, bytes(m.data)) for m in boot] == [(0x000, b"\x01\x02")]
    assert ctl.on_frame(can.Message(arbitration_id=0x702, is_extended_id=False,
                                    data=b"\x05")) == []
    out = ctl.on_frame(SYNC)
    ids = [m.arbitration_id for m in out]
    # the mode first, the command last (it closes a lockstep step), status and heartbeat between
    assert ids == [0x402, 0x18FF3080, 0x701, 0x302]
    assert out[0].data[0] == 3                                  # profile velocity
    assert [m.arbitration_id for m in ctl.on_frame(SYNC)] == [0x302]    # mode written once

    def controlword(statusword: int) -> int:
        ctl.on_frame(can.Message(arbitration_id=0x182, is_extended_id=False,
                                 data=statusword.to_bytes(2, "little") + bytes(4)))
        rpdo2 = next(m for m in ctl.on_frame(SYNC) if m.arbitration_id == 0x302)
        return int.from_bytes(rpdo2.data[:2], "little")

    assert [controlword(s) for s in (0x0040, 0x0021, 0x0023, 0x0027, 0x0008, 0x0008, 0x0040)] \
        == [0x06, 0x07, 0x0F, 0x0F, 0x80, 0x00, 0x06]
    # depth: eq. 13 and the 0.2 filter; enabled needs a ground speed
    controlword(0x0027)
    x = round(calibration_signal_mv(25.0))
    ctl.on_frame(codec.encode(InclinometerFrame(x_mv=x, y_mv=2500)))
    assert ctl.depth_mm == pytest.approx(-0.065 * x + 270.35)
    ctl.on_frame(codec.encode(InclinometerFrame(x_mv=x - 100, y_mv=2500)))
    assert ctl.depth_mm == pytest.approx(-0.065 * x + 270.35 + 0.2 * 6.5)
    ctl.on_frame(codec.encode(DepthSetpoint(target_depth_mm=30.0)))
    controlword(0x0027)
    assert ctl.speed_mm_s == 0.0                                # no ground speed yet
    ctl.on_frame(can.Message(arbitration_id=0x0CFE49F0, is_extended_id=True,
                             data=codec.encode_signals("GBSD", {
                                 "GBSD_GroundSpeed": 1.1, "GBSD_GroundDistance": 0.0,
                                 "GBSD_Direction": "forward"}).data))
    controlword(0x0027)
    assert ctl.speed_mm_s > 0.0                                 # deeper: push the roller down


def _controlling_depth_controller(**params: float) -> tuple[DepthController, FrameCodec]:
    """A depth controller with its drive Operation enabled, a 30 mm set-point and 1.1 m/s."""
    ctl, codec = DepthController(params), FrameCodec()
    ctl.on_frame(can.Message(arbitration_id=0x702, is_extended_id=False, data=b"\x05"))
    ctl.on_frame(can.Message(arbitration_id=0x182, is_extended_id=False,
                             data=(0x0027).to_bytes(2, "little") + bytes(4)))
    ctl.on_frame(codec.encode(DepthSetpoint(target_depth_mm=30.0)))
    return ctl, codec


def _depth_step(ctl: DepthController, codec: FrameCodec, x_mv: int | None,
                status: str | int = "ok") -> tuple[float, int | None]:
    """Feed one inclinometer frame (None: none) and a GBSD, then SYNC: (speed, SensorFault)."""
    if x_mv is not None:
        ctl.on_frame(codec.encode(InclinometerFrame(x_mv=x_mv, y_mv=2500, x_status=status)))
    ctl.on_frame(can.Message(arbitration_id=0x0CFE49F0, is_extended_id=True,
                             data=codec.encode_signals("GBSD", {
                                 "GBSD_GroundSpeed": 1.1, "GBSD_GroundDistance": 0.0,
                                 "GBSD_Direction": "forward"}).data))
    out = ctl.on_frame(SYNC)
    fault = None
    for msg in out:
        if msg.arbitration_id == 0x18FF3080:
            fault = int(codec.decode(msg).sensor_fault)
    return ctl.speed_mm_s, fault


def test_depth_controller_holds_the_roller_on_a_frozen_inclinometer() -> None:
    ctl, codec = _controlling_depth_controller()
    shallow = round(calibration_signal_mv(25.0))        # 5 mm too shallow: push down
    for i in range(100):                                 # 1 s of a live sensor
        speed, fault = _depth_step(ctl, codec, shallow + (i % 3))
        assert speed > 0.0 and fault in (None, 0), i
    frozen = shallow + 99 % 3
    steps = [_depth_step(ctl, codec, frozen) for _ in range(100)]   # the output freezes
    # the last change came with the frame of step 99 (t = 0.99 s): the step at 1.19 s still
    # controls (0.2 s unchanged is not "more than" 0.2 s), the one at 1.20 s holds
    assert all(speed > 0.0 for speed, _ in steps[:20])
    assert all(speed == 0.0 for speed, _ in steps[20:])
    assert {fault for _, fault in steps[:20]} == {None, 0}
    assert {fault for _, fault in steps[20:]} == {None, 1}
    # a frame with a bad status is no sign of life, even with another voltage: still dead
    # when the good frames come back with the frozen voltage
    assert _depth_step(ctl, codec, frozen + 7, status=1)[0] == 0.0
    assert _depth_step(ctl, codec, frozen)[0] == 0.0
    assert _depth_step(ctl, codec, frozen + 1)[0] > 0.0          # alive again
    for _ in range(51):                                  # stops sending: dead as well
        _depth_step(ctl, codec, None)
    assert _depth_step(ctl, codec, None)[0] == 0.0


def test_depth_controller_frozen_check_off_and_bad_status() -> None:
    ctl, codec = _controlling_depth_controller(frozen_after_s=0.0)
    x = round(calibration_signal_mv(25.0))
    assert all(_depth_step(ctl, codec, x)[0] > 0.0 for _ in range(300))
    ctl, codec = _controlling_depth_controller()
    _depth_step(ctl, codec, x)
    for status in (1, 2):                                # a bad status holds the roller
        speeds = [_depth_step(ctl, codec, x + i, status=status) for i in range(10)]
        assert all(speed == 0.0 for speed, _ in speeds)
        assert 1 in {fault for _, fault in speeds}
    assert _depth_step(ctl, codec, x + 20)[0] > 0.0


def test_nmea_speed_sentences() -> None:
    from plant_emulators.sowing_depth.nmea import build_sentence

    rmc = build_sentence("GN", "RMC", ["120000.00", "A", "", "", "", "", "2.160", "90.0",
                                       "010123", "", "", "A"])
    assert nmea_speed(rmc.encode()) == (True, pytest.approx(2.160 * 1852 / 3600))
    vtg = build_sentence("GN", "VTG", ["", "", "", "", "", "", "", "", "N"])
    assert nmea_speed(vtg.encode()) == (True, None)
    assert nmea_speed(b"$GNVTG,,,,,,,,,N*00") == (False, None)    # bad checksum


# ------------------------------------------------------------------ rig runs, lockstep, inline
def test_flow_controller_reaches_a_bench_target(tmp_path: Path) -> None:
    scenario = Scenario(name="refctl-bench-23", description="", rig="fertilizer",
                        duration_s=20.0, seed=23,
                        initial={"terminal_mode": 1.0, "enable": 0.0, "target_flow_gps": 23.0},
                        events=(Event(at_s=3.0, set={"enable": 1.0}),))
    run = run_scenario(FertilizerRig, scenario, InProcessDut(FlowController("physical")),
                       RunOptions(out_dir=tmp_path, bus="inline", clock="lockstep"))
    assert run.record.get("error") is None
    tr = load_traces(tmp_path / "traces.npz")[0]
    t = tr["time_s"]
    # judged as the step suite judges a steady state: over the last 10 s, once the learnt meter
    # factor has settled (5 s after the enable it still carried the first report's noise)
    late = t > 10.0
    sensed = np.mean([tr[f"sensed_flow_{r}_gps"][late] for r in range(1, 5)])
    true = np.mean([tr[f"flow_at_sensor_{r}_gps"][late] for r in range(1, 5)])
    assert sensed == pytest.approx(23.0, rel=0.03)
    assert true == pytest.approx(23.0, rel=0.04)
    assert tr["command_v"][t < 2.9].max() == 0.0


def test_depth_controller_enables_the_drive_and_moves_towards_target(tmp_path: Path) -> None:
    scenario = Scenario(name="refctl-depth", description="", rig="sowing_depth",
                        duration_s=4.0, seed=1,
                        initial={"target_depth_mm": 30.0, "ground_speed_mps": 1.1111})
    ctl = DepthController()
    try:
        run = run_scenario(SowingDepthRig, scenario, InProcessDut(ctl),
                           RunOptions(out_dir=tmp_path, bus="inline", clock="lockstep"))
    finally:
        ctl.close()
    assert run.record.get("error") is None
    tr = load_traces(tmp_path / "traces.npz")[0]
    t = tr["time_s"]
    assert int(tr["drive_statusword"][-1]) & 0x6F == 0x27        # Operation enabled
    start = float(np.nanmean(tr["sensed_depth_mm"][(t > 0.05) & (t < 0.2)]))
    end = float(np.mean(tr["sensed_depth_mm"][t > 3.0]))
    assert abs(end - 30.0) < 3.0 < abs(start - 30.0)
    assert "gnss" in ctl.speeds.latest                           # read from the rig's pty
