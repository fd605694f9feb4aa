"""agrihil-depth-fw, the C build of [D]'s depth controller, as a process on the software bus.

It is the CANopen master of the servo drive (node 2): NMT start on the drive's heartbeat,
Modes of operation through RPDO3 once, RPDO2 (controlword, target velocity) on every SYNC;
ground speed from GBSD or from the GNSS receiver's NMEA on a pty (docs/reference-controllers.md
section 2, "CAN adapter").
"""

from __future__ import annotations

import os
import signal
import struct
import time
import tty
from collections.abc import Iterator
from pathlib import Path

import cantools
import numpy as np
import pytest

from hil.dut import InProcessDut
from hil.record.traces import load_traces
from hil.rig import Event, RunOptions, Scenario, run_scenario
from hil.softbus import SoftwareBus
from plant_emulators.sowing_depth.rig import SowingDepthRig
from reference_controllers.sowing_depth.adapter import DepthController

ROOT = Path(__file__).resolve().parents[2]
DB = cantools.database.load_file(ROOT / "plant_emulators/sowing_depth/db/sowing_depth.dbc")
APP = "agrihil-depth-fw"
HEARTBEAT = 0x701
DRIVE_HEARTBEAT, TPDO1, RPDO2, RPDO3 = 0x702, 0x182, 0x302, 0x402
STATUS = 0x18FF3080


def encode(name: str, **signals: float) -> bytes:
    return DB.get_message_by_name(name).encode(signals)


def inclinometer(x_mv: int) -> bytes:
    return encode("Inclinometer", INC_X_Voltage=x_mv, INC_Y_Voltage=2500, INC_X_Status=0,
                  INC_Y_Status=0, INC_Counter=0)


def depth_setpoint(target_mm: float, enable: int = 1, mode: int = 1) -> bytes:
    return encode("DepthSetpoint", DS_TargetDepth=target_mm, DS_ManualRollerPosition=0,
                  DS_Enable=enable, DS_Mode=mode, DS_Counter=0)


def rpdo2(frames: dict) -> tuple[int, int]:
    """(controlword, target velocity in 0.01 mm/s) of the drive's RPDO2."""
    controlword, velocity = struct.unpack("<Hi", bytes(frames[RPDO2].data))
    return controlword, velocity


def nmea(body: str) -> bytes:
    checksum = 0
    for ch in body:
        checksum ^= ord(ch)
    return f"${body}*{checksum:02X}\r\n".encode()


@pytest.fixture
def gnss_pty() -> Iterator[tuple[int, str]]:
    """A raw pty: (master fd to write NMEA into, slave path the app opens)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    yield master, os.ttyname(slave)
    os.close(master)
    os.close(slave)


def test_drive_master_nmt_mode_and_rpdo2_on_sync(start_app) -> None:
    with SoftwareBus(port=0) as sb:
        app = start_app(APP, sb.spec(), "--sync", bootup_id=HEARTBEAT)
        app.send(DRIVE_HEARTBEAT, b"\x00")                    # the drive boots
        nmt = app.collect({0x000})[0x000]
        assert bytes(nmt.data) == b"\x01\x02"                 # NMT start node 2
        app.send(DRIVE_HEARTBEAT, b"\x05")                    # now Operational
        app.send(TPDO1, struct.pack("<Hi", 0x0250, 0))        # Switch on disabled
        time.sleep(0.05)
        frames = app.sync({RPDO3, RPDO2, STATUS, HEARTBEAT})
        assert bytes(frames[RPDO3].data) == b"\x03"           # profile velocity
        assert rpdo2(frames) == (0x06, 0)                     # shutdown
        assert bytes(frames[HEARTBEAT].data) == b"\x05"
        status = DB.decode_message(STATUS, frames[STATUS].data, decode_choices=False)
        assert status["DC_SensorFault"] == 1 and status["DC_SpeedLost"] == 1
        app.drain()
        app.send(TPDO1, struct.pack("<Hi", 0x0231, 0))        # Ready to switch on
        time.sleep(0.05)
        frames = app.sync({RPDO2})
        assert RPDO3 not in frames                            # the mode is written once
        assert rpdo2(frames) == (0x07, 0)
        app.send(TPDO1, struct.pack("<Hi", 0x0218, 0))        # Fault: reset as an edge
        time.sleep(0.05)
        assert rpdo2(app.sync({RPDO2}))[0] == 0x80
        assert rpdo2(app.sync({RPDO2}))[0] == 0x00
        code, took = app.terminate()
        assert code == 0 and took < 1.0


def test_gnss_speed_on_a_pty_enables_depth_control(start_app, gnss_pty) -> None:
    master, path = gnss_pty
    with SoftwareBus(port=0) as sb:
        # fuzzy layer held at E = EC = 0 (ke = kec = 0): Kp = kp0, Ki = ki0, Kd = kd0 - 0.5
        app = start_app(APP, sb.spec(), "--sync", "--param", "kp0=2", "--param", "ki0=1",
                        "--param", "kd0=0", "--param", "ke=0", "--param", "kec=0",
                        env={"AGRIHIL_GNSS_PORT": path}, bootup_id=HEARTBEAT)
        app.send(DRIVE_HEARTBEAT, b"\x05")
        app.send(TPDO1, struct.pack("<Hi", 0x0237, 0))        # Operation enabled
        app.send(0x0CFF11A1, inclinometer(3700))              # eq. 13: 29.85 mm
        app.send(0x18FF2026, depth_setpoint(30.0))            # on, automatic
        time.sleep(0.05)
        frames = app.sync({RPDO2, STATUS})
        assert rpdo2(frames) == (0x0F, 0)                     # no ground speed yet
        status = DB.decode_message(STATUS, frames[STATUS].data, decode_choices=False)
        assert status["DC_SpeedLost"] == 1
        assert status["DC_MeasuredDepth"] == pytest.approx(29.9, abs=0.051)
        os.write(master, nmea("GNVTG,90.00,T,,M,2.160,N,4.000,K,A"))   # 4 km/h
        time.sleep(0.05)
        # e = 0.15 mm, first step after the reset: u = Kp·e = 0.3 mm/s -> 30 x 0.01 mm/s
        assert rpdo2(app.sync({RPDO2})) == (0x0F, 30)
        # I = 0.0015 mm·s now: u = 0.3 + 0.0015
        assert rpdo2(app.sync({RPDO2})) == (0x0F, 30)
        os.write(master, nmea("GNVTG,,,,,,,,,N"))             # the receiver lost its fix
        time.sleep(0.05)
        assert rpdo2(app.sync({RPDO2})) == (0x0F, 0)
        assert "GNSS on" in app.stderr()
        code, _ = app.terminate()
        assert code == 0


def test_gbsd_speed_enables_depth_control(start_app) -> None:
    with SoftwareBus(port=0) as sb:
        app = start_app(APP, sb.spec(), "--sync", "--param", "kp0=2", "--param", "ke=0",
                        "--param", "kec=0", "--param", "min_speed_mps=0.5",
                        bootup_id=HEARTBEAT)
        app.send(DRIVE_HEARTBEAT, b"\x05")
        app.send(TPDO1, struct.pack("<Hi", 0x0237, 0))
        app.send(0x0CFF11A1, inclinometer(3700))              # 29.85 mm
        app.send(0x18FF2026, depth_setpoint(30.0))
        app.send(0x0CFE49F0, encode("GBSD", GBSD_GroundSpeed=0.4, GBSD_GroundDistance=0,
                                    GBSD_Direction=1))        # below min_speed_mps
        time.sleep(0.05)
        assert rpdo2(app.sync({RPDO2})) == (0x0F, 0)
        app.send(0x0CFE49F0, encode("GBSD", GBSD_GroundSpeed=1.1, GBSD_GroundDistance=0,
                                    GBSD_Direction=1))
        time.sleep(0.05)
        assert rpdo2(app.sync({RPDO2})) == (0x0F, 30)         # Kp·e = 2 x 0.15 mm/s
        app.terminate()


def test_free_running_steps_on_its_own_timer(start_app) -> None:
    with SoftwareBus(port=0) as sb:
        app = start_app(APP, sb.spec(), "--period-ms", "10", bootup_id=HEARTBEAT)
        app.send(DRIVE_HEARTBEAT, b"\x05")
        stamps = []
        t_end = time.monotonic() + 0.3
        while time.monotonic() < t_end:
            msg = app.bus.recv(0.05)
            if msg is not None and msg.arbitration_id == RPDO2:
                stamps.append(time.monotonic())
        code, _ = app.terminate(signal.SIGINT)
        assert code == 0
    assert 20 <= len(stamps) <= 40, len(stamps)


def test_bad_arguments_exit_2(run_fw, tmp_path: Path) -> None:
    done = run_fw(APP, "--bus", "socketcand:127.0.0.1:9", "--param", "kp1=1")
    assert done.returncode == 2 and "unknown parameter 'kp1'" in done.stderr
    done = run_fw(APP, "--bus", "socketcand:127.0.0.1:9", "--bogus")
    assert done.returncode == 2 and "--bogus" in done.stderr
    done = run_fw(APP, "--bus", "socketcand:127.0.0.1:9", "--sync",
                  env={"AGRIHIL_GNSS_PORT": str(tmp_path / "no-such-tty")})
    assert done.returncode == 1 and "no-such-tty" in done.stderr


def test_short_lockstep_run_of_the_depth_rig(firmware_bin: Path, firmware_dut,
                                             tmp_path: Path) -> None:
    """The firmware holds the depth through the drive and follows a step (GNSS on a pty)."""
    scenario = Scenario(name="fw-depth-short", description="", rig="sowing_depth",
                        duration_s=7.0,
                        initial={"target_depth_mm": 30.0, "ground_speed_mps": 1.1111},
                        events=(Event(at_s=3.0, set={"target_depth_mm": 38.0}),))
    dut = firmware_dut([str(firmware_bin / APP), "--sync"], bootup_id=HEARTBEAT)
    run = run_scenario(SowingDepthRig, scenario, dut,
                       RunOptions(out_dir=tmp_path, bus="softbus", clock="lockstep", seed=3))
    assert run.record["dut"]["exit_code"] == 0, run.record["dut"]
    assert run.record["error"] is None
    assert "GNSS on /dev/" in run.record["dut"]["stderr"]
    tr = load_traces(tmp_path / "traces.npz")[0]
    t = tr["time_s"]
    assert int(tr["drive_statusword"][-1]) & 0x6F == 0x27     # enabled by the firmware
    before = tr["mean_true_depth_mm"][(t > 1.5) & (t < 3)].mean()
    after = tr["mean_true_depth_mm"][(t > 5.5) & (t < 7)].mean()
    print(f"depth {before:.2f} mm before, {after:.2f} mm after the step to 38 mm")
    assert before == pytest.approx(30.0, abs=2.5)
    assert after == pytest.approx(38.0, abs=2.5)


def _hold_commands(bus_log: Path) -> list[tuple[float, float]]:
    """(time, DC_RollerPositionCommand) of the status frames that said SensorFault."""
    message = DB.get_message_by_frame_id(STATUS)
    out = []
    for line in bus_log.read_text().splitlines():
        stamp, _, frame = line.split()[:3]
        can_id, _, data = frame.partition("#")
        if int(can_id, 16) == STATUS:
            sig = message.decode(bytes.fromhex(data), decode_choices=False)
            if sig["DC_SensorFault"]:
                out.append((float(stamp.strip("()")), float(sig["DC_RollerPositionCommand"])))
    return out


def test_both_builds_hold_the_roller_at_the_same_mean_position(firmware_bin: Path,
                                                               firmware_dut,
                                                               tmp_path: Path) -> None:
    """The inclinometer dies (open circuit) at 6 s: the firmware and the Python build drive
    the rod to the same hold target (the mean rod position of valid control), bit for bit,
    and the status frame carries that target (issue #16)."""
    scenario = Scenario(name="fw-depth-hold", description="", rig="sowing_depth",
                        duration_s=8.0,
                        initial={"target_depth_mm": 30.0, "ground_speed_mps": 1.1111},
                        events=(Event(at_s=6.0, fault="inclinometer_open_circuit"),))
    fw = run_scenario(SowingDepthRig, scenario,
                      firmware_dut([str(firmware_bin / APP), "--sync"], bootup_id=HEARTBEAT),
                      RunOptions(out_dir=tmp_path / "fw", bus="softbus", clock="lockstep",
                                 seed=8))
    ctl = DepthController()
    try:
        py = run_scenario(SowingDepthRig, scenario, InProcessDut(ctl),
                          RunOptions(out_dir=tmp_path / "py", bus="inline", clock="lockstep",
                                     seed=8))
    finally:
        ctl.close()
    assert fw.record["error"] is None and py.record["error"] is None
    tr_fw = load_traces(tmp_path / "fw" / "traces.npz")[0]
    tr_py = load_traces(tmp_path / "py" / "traces.npz")[0]
    assert (tr_fw["rod_position_mm"] == tr_py["rod_position_mm"]).all()
    holds_fw = _hold_commands(tmp_path / "fw" / "bus.log")
    assert holds_fw == _hold_commands(tmp_path / "py" / "bus.log")
    assert len(holds_fw) >= 15                      # 6.1 ... 7.9 s (at least)
    target = holds_fw[-1][1]
    assert {value for _, value in holds_fw} == {target}     # the mean is frozen while holding
    # the target is the rod's 2 s low-pass mean up to the fault (recomputed here from the
    # rig's rod trace, which the controller sees one SYNC late through TPDO1)
    t, rod = tr_fw["time_s"], tr_fw["rod_position_mm"]
    valid = np.flatnonzero((t > 0.1) & (t < 6.0))
    mean = float(rod[valid[0]])
    for k in valid[1:]:
        mean += 0.01 / 2.0 * (float(rod[k]) - mean)
    print(f"hold target {target:.2f} mm, 2 s mean {mean:.3f} mm, rod {rod[t < 6.0][-1]:.2f} mm "
          f"at the fault, {rod[-1]:.2f} mm at the end")
    assert target == pytest.approx(mean, abs=0.05)
    assert abs(target - rod[t < 6.0][-1]) > 0.1     # not where the fault left the rod ...
    assert rod[-1] == pytest.approx(target, abs=0.05)     # ... but back at the mean
