"""The sowing-depth rig end to end: CiA 402 drive, sensors, GNSS pty and scenarios."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import can
import canopen
import numpy as np
import pytest
import serial

from hil.dut import Controller, InProcessDut
from hil.record import load_traces
from hil.rig import Event, RunOptions, Scenario, run_scenario
from hil.softbus import SoftwareBus
from plant_emulators.sowing_depth.controllers import PiDepthController, next_controlword
from plant_emulators.sowing_depth.frames import FrameCodec
from plant_emulators.sowing_depth.nmea import parse_sentence
from plant_emulators.sowing_depth.rig import EDS, SowingDepthRig

DRIVE = 2


def _scenario(duration: float = 12.0, events: tuple = (), target: float = 30.0) -> Scenario:
    return Scenario(name="short", description="", rig="sowing_depth", duration_s=duration,
                    initial={"target_depth_mm": target, "ground_speed_mps": 1.1111},
                    events=events)


def _run(tmp: Path, scenario: Scenario, *, controller: Controller | None = None,
         seed: int | None = None, bus: str = "virtual", clock: str = "lockstep"):
    return run_scenario(SowingDepthRig, scenario, InProcessDut(controller or PiDepthController()),
                        RunOptions(out_dir=tmp, bus=bus, clock=clock, seed=seed))


def test_packaged_scenarios_load() -> None:
    names = {name for name, _ in SowingDepthRig.scenario_names()}
    assert {"depth-step", "depth-square", "field-1-3kmh", "field-3-5kmh", "field-5-7kmh",
            "fault-drive-jammed", "fault-gnss-fix-lost", "fault-controller-silent"} <= names


def test_controller_follows_a_depth_step_through_the_drive(tmp_path: Path) -> None:
    run = _run(tmp_path, _scenario(20.0, (Event(at_s=8.0, set={"target_depth_mm": 38.0}),)))
    tr = load_traces(tmp_path / "traces.npz")[0]
    t = tr["time_s"]
    before = tr["mean_true_depth_mm"][(t > 5) & (t < 8)].mean()
    after = tr["mean_true_depth_mm"][(t > 15) & (t < 20)].mean()
    assert before == pytest.approx(30.0, abs=2.5)
    assert after == pytest.approx(38.0, abs=2.5)
    assert np.abs(tr["rod_velocity_mm_s"]).max() <= 50.0 + 1e-6
    truth = np.load(tmp_path / "truth.npz")
    assert truth["depth_mm"].shape[1] == 12
    assert truth["distance_m"][-1] == pytest.approx(20 * 1.1111, rel=0.02)
    assert run.record["truth"]["rows"] == 12


def test_same_seed_identical_traces(tmp_path: Path) -> None:
    a = _run(tmp_path / "a", _scenario(6.0), seed=3)
    b = _run(tmp_path / "b", _scenario(6.0), seed=3)
    c = _run(tmp_path / "c", _scenario(6.0), seed=4)
    ta, tb, tc = (load_traces(r.out_dir / "traces.npz")[0] for r in (a, b, c))
    for name in ta:
        np.testing.assert_array_equal(ta[name], tb[name], err_msg=name)
    assert not np.array_equal(ta["mean_true_depth_mm"], tc["mean_true_depth_mm"])


def test_jammed_rod_trips_the_drive_and_the_controller_resets_it(tmp_path: Path) -> None:
    run = _run(tmp_path, _scenario(16.0, (Event(at_s=4.0, fault="drive_jammed"),
                                          Event(at_s=9.0, clear="drive_jammed"),
                                          Event(at_s=4.0, set={"target_depth_mm": 40.0}))))
    frames = list(can.LogReader(tmp_path / "bus.log"))
    emcy = [m for m in frames if m.arbitration_id == 0x80 + DRIVE and not m.is_rx]
    assert emcy, "the drive sends EMCY when it trips"
    # a blocked rod drives the current to its limit: the drive trips on continuous
    # overcurrent (0x2310) or following error (0x8611), whichever monitor fires first
    assert int.from_bytes(bytes(emcy[0].data[:2]), "little") in (0x2310, 0x8611)
    tr = load_traces(tmp_path / "traces.npz")[0]
    t = tr["time_s"]
    assert np.isin(tr["drive_error_code"][(t > 4) & (t < 9)], (0x2310, 0x8611)).any()
    # after the stone is gone the controller's fault reset brings the drive back
    assert int(tr["drive_statusword"][-1]) & 0x6F == 0x27
    assert run.record["error"] is None


def test_cut_wire_leaves_the_drive_on_its_last_command(tmp_path: Path) -> None:
    """The drive has no communication watchdog (CiA 402 0x6007 is not modelled): with the
    controller's wire cut it keeps executing the last target velocity. The rig shows that
    hazard as it is; a suite must catch it from the truth."""
    run = _run(tmp_path, _scenario(10.0, (Event(at_s=5.0, fault="controller_silent"),)))
    tr = load_traces(tmp_path / "traces.npz")[0]
    t = tr["time_s"]
    assert run.record["error"] is None     # frames still cross the bus: the steps complete
    after = tr["rod_velocity_mm_s"][t > 5.2]
    assert np.ptp(after) < 0.05            # one constant velocity: the last command
    assert np.ptp(tr["rod_velocity_mm_s"][(t > 2) & (t < 5)]) > 0.5   # it was regulating


def test_draw_wire_lost_stops_its_frames(tmp_path: Path) -> None:
    _run(tmp_path, _scenario(6.0, (Event(at_s=3.0, fault="draw_wire_lost"),)))
    stamps = [m.timestamp for m in can.LogReader(tmp_path / "bus.log")
              if m.arbitration_id == 0x0CFF10A0 and not m.is_rx]
    assert max(stamps) < 3.0 and len(stamps) > 250


def test_inclinometer_lost_stops_its_frames(tmp_path: Path) -> None:
    _run(tmp_path, _scenario(6.0, (Event(at_s=3.0, fault="inclinometer_lost"),)))
    stamps = [m.timestamp for m in can.LogReader(tmp_path / "bus.log")
              if m.arbitration_id == 0x0CFF11A1 and not m.is_rx]
    assert max(stamps) < 3.0 and len(stamps) > 250


def test_inclinometer_open_circuit_reads_0_mv_below_range(tmp_path: Path) -> None:
    _run(tmp_path, _scenario(6.0, (Event(at_s=3.0, fault="inclinometer_open_circuit"),)))
    codec = FrameCodec()
    frames = [(m.timestamp, codec.decode(m)) for m in can.LogReader(tmp_path / "bus.log")
              if m.arbitration_id == 0x0CFF11A1 and not m.is_rx]
    before = [f for t, f in frames if t < 2.99]
    after = [f for t, f in frames if t > 3.01]
    assert len(after) > 250 and all(f.x_mv == 0 and f.x_status == "below range" for f in after)
    assert all(f.x_status == "ok" and f.x_mv > 1000 for f in before)
    assert all(f.y_status == "ok" for f in after)            # only the X wire broke


def test_gnss_sentences_reach_a_serial_reader_during_a_run(tmp_path: Path) -> None:
    seen: list[str] = []

    class Reader(PiDepthController):
        def configure(self, env: dict[str, str]) -> None:
            self.port = serial.Serial(env["AGRIHIL_GNSS_PORT"], 115200, timeout=0)

        def on_sync(self) -> list[can.Message]:
            data = self.port.read(4096)
            if data:
                seen.extend(data.decode("ascii").splitlines())
            return super().on_sync()

    run = _run(tmp_path, _scenario(3.0, (Event(at_s=1.0, fault="gnss_fix_lost"),)),
               controller=Reader())
    assert run.record["dut_environment"]["AGRIHIL_GNSS_PORT"].startswith("/dev/pts/")
    sentences = [parse_sentence(line) for line in seen if line.startswith("$")]
    kinds = {s.kind for s in sentences}
    assert {"RMC", "VTG", "GGA"} <= kinds
    rmc = [s for s in sentences if s.kind == "RMC"]
    assert rmc[0].fields[1] == "A" and rmc[-1].fields[1] == "V"   # fix, then fix lost


def test_controlword_sequence() -> None:
    assert next_controlword(0x0250) == 0x06      # switch on disabled -> shutdown
    assert next_controlword(0x0231) == 0x07      # ready to switch on -> switch on
    assert next_controlword(0x0233) == 0x0F      # switched on -> enable operation
    assert next_controlword(0x0237) == 0x0F
    assert next_controlword(0x0218) == 0x80      # fault -> fault reset


class _Idle(Controller):
    def on_frame(self, msg: can.Message) -> list[can.Message]:
        return []


@pytest.mark.realtime
def test_canopen_cia402_master_drives_the_emulated_cylinder_over_the_bus(tmp_path) -> None:
    with SoftwareBus(port=0) as softbus:
        runner = threading.Thread(target=lambda: _run(
            tmp_path, _scenario(6.0), bus=softbus.spec(), clock="realtime",
            controller=_Idle()))
        network = canopen.Network()
        network.connect(interface="socketcand", host=softbus.host, port=softbus.port,
                        channel="can0", tcp_tune=True)
        try:
            runner.start()
            node = canopen.BaseNode402(DRIVE, str(EDS))
            network.add_node(node)
            time.sleep(0.3)
            node.nmt.state = "OPERATIONAL"
            time.sleep(0.2)
            assert node.sdo[0x1000].raw == 0x00020192
            node.sdo[0x6060].raw = 1                          # profile position
            node.sdo[0x6081].raw = 2000                       # 20 mm/s
            for cw in (0x06, 0x07, 0x0F):
                node.sdo[0x6040].raw = cw
                time.sleep(0.05)
            assert node.sdo[0x6041].raw & 0x6F == 0x27       # operation enabled
            start = node.sdo[0x6064].raw
            node.sdo[0x607A].raw = start + 1000               # +10 mm
            node.sdo[0x6040].raw = 0x1F                       # new set-point
            time.sleep(1.2)
            moved = node.sdo[0x6064].raw - start
            assert moved == pytest.approx(1000, abs=20)
            assert node.sdo[0x6041].raw & 0x0400              # target reached
            with pytest.raises(canopen.SdoAbortedError):
                node.sdo[0x6060].raw = 6                      # homing: not supported
        finally:
            runner.join(15)
            network.disconnect()


def test_packaged_overcurrent_fault_trips_and_recovers(tmp_path: Path) -> None:
    _run(tmp_path, SowingDepthRig.load_scenario("fault-drive-overcurrent"))
    tr = load_traces(tmp_path / "traces.npz")[0]
    t = tr["time_s"]
    assert (tr["drive_error_code"][(t > 20) & (t < 25)] == 0x2310).any()
    assert int(tr["drive_statusword"][-1]) & 0x6F == 0x27     # reset once the cause cleared


def test_packaged_stuck_inclinometer_freezes_the_sensed_depth(tmp_path: Path) -> None:
    _run(tmp_path, SowingDepthRig.load_scenario("fault-inclinometer-stuck"))
    tr = load_traces(tmp_path / "traces.npz")[0]
    t = tr["time_s"]
    assert np.ptp(tr["sensed_depth_mm"][t > 20.05]) == 0.0
    assert np.ptp(tr["sensed_depth_mm"][(t > 10) & (t < 20)]) > 1.0
    assert np.ptp(tr["mean_true_depth_mm"][t > 20.05]) > 1.0   # the truth keeps moving
