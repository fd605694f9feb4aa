"""agrihil-fertilizer-fw, the C build of [F]'s flow controller, as a process on the software bus.

The apps are driven directly with python-can (docs/reference-controllers.md section 1,
"CAN adapter"), plus a short lockstep run of the fertilizer rig against the process.
"""

from __future__ import annotations

import signal
import socket
import time
from pathlib import Path

import cantools
import numpy as np
import pytest

from hil.record.traces import load_traces
from hil.rig import Event, RunOptions, Scenario, run_scenario
from hil.softbus import SoftwareBus
from plant_emulators.fertilizer.rig import FertilizerRig

ROOT = Path(__file__).resolve().parents[2]
DB = cantools.database.load_file(ROOT / "plant_emulators/fertilizer/db/fertilizer.dbc")
APP = "agrihil-fertilizer-fw"
HEARTBEAT = 0x710


def feedforward_v(q_gps: float, c: float = 4.586, p: float = 0.6537,
                  rpm_per_v: float = 6.0) -> float:
    """Section 1: ff(Q) = clamp((Q / c)^(1/p) / k_n, 0, v_max)."""
    return min(max((q_gps / c) ** (1.0 / p) / rpm_per_v, 0.0), 10.0)


def setpoint(*, mode: int = 1, enable: int = 1, target_flow: float = 23.0) -> bytes:
    return DB.get_message_by_name("FertSetpoint").encode({
        "TargetRate": 0, "WorkingWidth": 0, "TargetFlow": target_flow, "Mode": mode,
        "Enable": enable, "SpeedSource": 0, "ActiveRows": 4, "Counter": 0})


def flow_report(flow_gps: float) -> bytes:
    return DB.get_message_by_name("FlowModule1").encode({
        "Flow": flow_gps, "WindowMass": flow_gps, "Counter": 1, "BaselineReady": 1,
        "SlidingWindow": 0, "AdcOverrange": 0, "InterceptApplied": 0, "WindowLength": 1000})


def ch1_mv(frames: dict) -> int:
    return int(DB.decode_message(0x220, frames[0x220].data)["Ch1Output"])


def test_bench_setpoint_gives_the_feedforward_on_sync(start_app) -> None:
    with SoftwareBus(port=0) as sb:
        # no settle gate: the report of the next period counts at once
        app = start_app(APP, sb.spec(), "--sync", "--param", "settle_periods=0",
                        bootup_id=HEARTBEAT)
        app.send(0x210, setpoint(target_flow=23.0))
        time.sleep(0.05)                       # the setpoint is in before the SYNC
        frames = app.sync({0x220, 0x190, HEARTBEAT})
        assert ch1_mv(frames) == round(feedforward_v(23.0) * 1000.0) == 1964
        assert bytes(frames[HEARTBEAT].data) == b"\x05"
        status = DB.decode_message(0x190, frames[0x190].data, decode_choices=False)
        assert status["TargetFlow"] == pytest.approx(23.0)
        assert status["Enabled"] == 1 and status["ActiveMode"] == 1
        assert status["SensorFault"] == 1       # enabled and no flow module has reported
        # a report 5 % low (medium band): the first update learns I = ki_first·r and adds
        # Kp2·r (the defaults: ki_first = 0.8, Kp2 = 0.4)
        app.drain()
        app.send(0x181, flow_report(23.0 * 0.95))
        time.sleep(0.05)
        frames = app.sync({0x220, HEARTBEAT})
        assert ch1_mv(frames) == round(feedforward_v(23.0) * (1 + 0.4 * 0.05 + 0.8 * 0.05)
                                       * 1000.0)
        # disabled: 0 V
        app.send(0x210, setpoint(enable=0))
        time.sleep(0.05)
        assert ch1_mv(app.sync({0x220})) == 0
        code, took = app.terminate()
        assert code == 0 and took < 1.0, app.stderr()


def test_paper_literal_law_starts_from_zero(start_app) -> None:
    with SoftwareBus(port=0) as sb:
        app = start_app(APP, sb.spec(), "--sync", "--law", "paper-literal",
                        bootup_id=HEARTBEAT)
        app.send(0x210, setpoint(target_flow=23.0))
        time.sleep(0.05)
        assert ch1_mv(app.sync({0x220})) == 0      # no feedforward in [F]'s own law
        app.drain()
        app.send(0x181, flow_report(20.0))          # e = 3 g/s: medium, first update Ki2·e
        time.sleep(0.05)
        frames = app.sync({0x220, HEARTBEAT})     # (status only every 10th step)
        # volts = km·(Ki2·e) = 0.0045 V: 4.5 mV exactly, rounded half to even as Python's
        # round() does (the Python build's adapter sends the same 4 mV)
        assert ch1_mv(frames) == round(0.1 * (0.015 * 3.0) * 1000.0) == 4
        app.terminate()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_stops_the_app_promptly_with_status_0(start_app, sig: int) -> None:
    with SoftwareBus(port=0) as sb:
        app = start_app(APP, sb.spec(), "--sync", bootup_id=HEARTBEAT)
        time.sleep(0.1)                         # idle, blocked waiting for frames
        code, took = app.terminate(sig)
        assert code == 0
        assert took < 0.5
        assert "stopped after 0 steps" in app.stderr()


def test_free_running_steps_on_its_own_timer(start_app) -> None:
    with SoftwareBus(port=0) as sb:
        app = start_app(APP, sb.spec(), "--period-ms", "20", bootup_id=HEARTBEAT)
        stamps = []
        t_end = time.monotonic() + 0.6
        while time.monotonic() < t_end:
            msg = app.bus.recv(0.1)
            if msg is not None and msg.arbitration_id == 0x220:
                stamps.append(time.monotonic())
        app.terminate()
    assert 20 <= len(stamps) <= 40, len(stamps)
    assert np.median(np.diff(stamps)) == pytest.approx(0.020, abs=0.004)


def test_unknown_parameter_exits_2_naming_it(run_fw) -> None:
    done = run_fw(APP, "--bus", "socketcand:127.0.0.1:9", "--param", "kp9=1")
    assert done.returncode == 2
    assert "unknown parameter 'kp9'" in done.stderr
    done = run_fw(APP, "--bus", "socketcand:127.0.0.1:9", "--law", "open-loop",
                  "--param", "ki1=0.2")
    assert done.returncode == 2 and "'ki1'" in done.stderr
    done = run_fw(APP, "--bus", "socketcand:127.0.0.1:9", "--param", "kp1=fast")
    assert done.returncode == 2 and "kp1" in done.stderr


def test_bus_failures_exit_1_with_a_clear_message(run_fw) -> None:
    with socket.socket() as s:                  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    done = run_fw(APP, "--bus", f"socketcand:127.0.0.1:{port}", "--sync")
    assert done.returncode == 1
    assert f"127.0.0.1:{port}" in done.stderr and "refused" in done.stderr.lower()
    done = run_fw(APP, "--sync", env={"AGRIHIL_BUS": "socketcan:agrihil9"})
    assert done.returncode == 1 and "socketcan:agrihil9" in done.stderr
    done = run_fw(APP, "--sync", env={"AGRIHIL_BUS": ""})
    assert done.returncode == 2 and "AGRIHIL_BUS" in done.stderr


def test_short_lockstep_run_of_the_fertilizer_rig(firmware_bin: Path, firmware_dut,
                                                  tmp_path: Path) -> None:
    """The firmware closes the loop on the emulated rig: 23 g/s per row from 3 s on."""
    scenario = Scenario(name="fw-short", description="", rig="fertilizer", duration_s=9.0,
                        initial={"terminal_mode": 1.0, "enable": 0.0, "target_flow_gps": 23.0},
                        events=(Event(at_s=3.0, set={"enable": 1.0}),))
    dut = firmware_dut([str(firmware_bin / APP), "--sync"], bootup_id=HEARTBEAT)
    t0 = time.monotonic()
    run = run_scenario(FertilizerRig, scenario, dut,
                       RunOptions(out_dir=tmp_path, bus="softbus", clock="lockstep", seed=7))
    wall = time.monotonic() - t0
    assert run.record["dut"]["exit_code"] == 0, run.record["dut"]
    assert run.record.get("error") in (None, ""), run.record.get("error")
    tr = load_traces(run.out_dir / "traces.npz")[0]
    t = tr["time_s"]
    assert np.all(tr["command_v"][t < 2.9] == 0.0)
    enabled = tr["command_v"][(t > 3.5) & (t < 9.0)]
    ff = feedforward_v(23.0)
    assert enabled.min() > 0.9 * ff and enabled.max() < 1.5 * ff
    assert wall < 20.0


def test_both_builds_fit_their_map_to_the_calibration_test(firmware_bin: Path, firmware_dut,
                                                           tmp_path: Path) -> None:
    """A lot 8 points denser than ff_coeff's, tested by the operator (MeterCalibration): the
    firmware over the software bus and the Python controller in process command the same
    millivolts at every step, and less than they do when told to ignore the test."""
    from hil.dut import InProcessDut
    from reference_controllers.fertilizer.adapter import FlowController

    scenario = Scenario(name="fw-lot", description="", rig="fertilizer", duration_s=6.0,
                        initial={"terminal_mode": 1.0, "enable": 0.0, "target_flow_gps": 23.0,
                                 "lot_offset_frac": 0.08, "calibration_test": 1.0},
                        events=(Event(at_s=3.0, set={"enable": 1.0}),))

    def command(dut, name: str, bus: str) -> np.ndarray:
        run = run_scenario(FertilizerRig, scenario, dut,
                           RunOptions(out_dir=tmp_path / name, bus=bus, clock="lockstep",
                                      seed=11))
        assert run.record.get("error") in (None, ""), run.record.get("error")
        return load_traces(run.out_dir / "traces.npz")[0]["command_v"]

    firmware = command(firmware_dut([str(firmware_bin / APP), "--sync", "--param",
                                     "ff_coeff=4.390"], bootup_id=HEARTBEAT), "fw", "softbus")
    python = command(InProcessDut(FlowController("physical", {"ff_coeff": 4.390})), "py",
                     "inline")
    ignored = command(InProcessDut(FlowController("physical", {"ff_coeff": 4.390,
                                                               "use_calibration": 0})),
                      "ignored", "inline")
    assert np.array_equal(firmware, python)
    enabled = firmware > 0.0
    assert enabled.any() and np.all(firmware[enabled][:10] < ignored[enabled][:10])
