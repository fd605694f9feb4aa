"""A bus log is what the rig received (issue 43): the DUT's frames that a fault keeps from the
rig (a cut wire, ``controller_silent`` on both rigs) are in neither bus log. They were logged as
received ("R") while the drive never got them (0x302 commanding -43 mm/s while 0x282 showed the
rod at +2.44 mm/s); they now go to ``bus-unheard.log`` as the DUT's frames nobody heard, and
the record counts them."""

from __future__ import annotations

from pathlib import Path

import can
import numpy as np
import pytest

from hil.conformance.framelog import read_bus_log
from hil.dut import InProcessDut
from hil.rig import Event, RunOptions, Scenario, run_scenario
from plant_emulators.fertilizer.controllers import PiFlowController
from plant_emulators.fertilizer.rig import FertilizerRig
from plant_emulators.sowing_depth.controllers import PiDepthController
from plant_emulators.sowing_depth.rig import SowingDepthRig

CUT = (3.0, 5.0)
CUT_EVENTS = (Event(at_s=CUT[0], fault="controller_silent"),
              Event(at_s=CUT[1], clear="controller_silent"))
#: per rig: the class, its controller, its scenario's start and the DUT's command frame
RIGS = {
    "sowing_depth": (SowingDepthRig, PiDepthController, {
        "target_depth_mm": 30.0, "ground_speed_mps": 1.1111}, (), 0x302),
    "fertilizer": (FertilizerRig, PiFlowController, {
        "terminal_mode": 1.0, "enable": 0.0, "target_flow_gps": 34.0},
        (Event(at_s=1.0, set={"enable": 1.0}),), None),
}


def _cut_wire_run(rig: str, out: Path):
    cls, controller, initial, events, _ = RIGS[rig]
    scenario = Scenario(name="cut", description="", rig=rig, duration_s=7.0, initial=initial,
                        events=(*events, *CUT_EVENTS))
    return run_scenario(cls, scenario, InProcessDut(controller()),
                        RunOptions(out_dir=out, bus="virtual", clock="lockstep"))


def _in_cut(time_s: np.ndarray) -> np.ndarray:
    return (time_s >= CUT[0]) & (time_s < CUT[1])


@pytest.mark.parametrize("rig", sorted(RIGS))
def test_frames_lost_to_a_cut_wire_are_not_logged_as_received(rig: str, tmp_path: Path) -> None:
    run = _cut_wire_run(rig, tmp_path)
    log = read_bus_log(tmp_path / "bus.log")
    # nothing of the DUT's reached the rig during the cut; before and after it did
    assert not np.any(log.rx & _in_cut(log.time_s))
    assert np.any(log.rx & (log.time_s < CUT[0])) and np.any(log.rx & (log.time_s > CUT[1]))
    # the rig's own frames went on
    assert np.count_nonzero(~log.rx & _in_cut(log.time_s)) > 100
    # the ASC log says the same: as many received frames as the candump log
    asc_rx = sum(1 for m in can.LogReader(tmp_path / "bus.asc") if m.is_rx)
    assert asc_rx == int(np.count_nonzero(log.rx))
    # what the DUT sent during the cut is still there to read, as its frames nobody heard
    unheard = read_bus_log(tmp_path / "bus-unheard.log")
    assert len(unheard) > 20 and not np.any(unheard.rx)
    assert np.all(_in_cut(unheard.time_s))
    command = RIGS[rig][4]
    if command is not None:     # one command per SYNC, as before the cut
        assert np.count_nonzero(unheard.can_id == command) == pytest.approx(200, abs=2)
    said = run.record["unheard"]
    assert said["frames"] == len(unheard) and said["file"] == "bus-unheard.log"
    assert CUT[0] <= said["first_s"] <= said["last_s"] < CUT[1]
    assert "bus-unheard.log" in run.record["artifacts"]
    assert run.record["frames"]["rx"] == int(np.count_nonzero(log.rx))


def test_a_run_without_a_cut_writes_no_unheard_log(tmp_path: Path) -> None:
    cls, controller, initial, _, _ = RIGS["sowing_depth"]
    scenario = Scenario(name="plain", description="", rig="sowing_depth", duration_s=2.0,
                        initial=initial)
    run = run_scenario(cls, scenario, InProcessDut(controller()),
                       RunOptions(out_dir=tmp_path, bus="virtual", clock="lockstep"))
    assert not (tmp_path / "bus-unheard.log").exists()
    assert "unheard" not in run.record and "bus-unheard.log" not in run.record["artifacts"]


def test_the_recorder_keeps_unheard_frames_apart(tmp_path: Path) -> None:
    """The recorder's half on its own: a frame logged as unheard is in neither bus log, in
    ``bus-unheard.log`` as sent (``T``), counted in the record, listed among the artifacts."""
    from hil.record import Recorder

    heard = can.Message(arbitration_id=0x302, is_extended_id=False, data=b"\x0f\x00\x01\x00")
    lost = can.Message(arbitration_id=0x302, is_extended_id=False, data=b"\x0f\x00\xd5\xff")
    status = can.Message(arbitration_id=0x18FF3080, data=bytes(8))
    with Recorder(tmp_path, run_id="r") as rec:
        rec.log_frame(heard, 1.0, rx=True)
        rec.log_unheard(lost, 1.01)
        rec.log_unheard(status, 1.01)
        rec.log_unheard(lost, 1.02)
        rec.log_frame(heard, 1.03, rx=True)
    record = rec.final_record
    logged = list(can.LogReader(tmp_path / "bus.log"))
    assert [m.timestamp for m in logged] == [1.0, 1.03] and all(m.is_rx for m in logged)
    assert sum(1 for m in can.LogReader(tmp_path / "bus.asc")) == 2
    unheard = list(can.LogReader(tmp_path / "bus-unheard.log"))
    assert [(m.timestamp, m.arbitration_id, m.is_rx) for m in unheard] == [
        (1.01, 0x302, False), (1.01, 0x18FF3080, False), (1.02, 0x302, False)]
    assert bytes(unheard[0].data) == b"\x0f\x00\xd5\xff"
    assert record["unheard"] == {"frames": 3, "first_s": 1.01, "last_s": 1.02,
                                 "ids": {"0x18FF3080": 1, "0x302": 2},
                                 "file": "bus-unheard.log"}
    assert record["artifacts"] == ["record.json", "bus.log", "bus.asc", "bus-unheard.log",
                                   "traces.npz"]
