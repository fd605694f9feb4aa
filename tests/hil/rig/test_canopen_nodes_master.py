"""The emulated CANopen nodes against canopen's own master classes on python-can's virtual bus.

The servo drive (CiA 402) faults, recovers after its fault reset, and a ``BaseNode402`` master's
``emcy.active`` is empty again (#20.1); 0x1001 and 0x1003 read by SDO; the analog output
module (CiA 401) reports a heartbeat consumer timeout by EMCY 0x8130 and its end by the
error-reset EMCY; a stopped node answers no SDO.

The device runs on the wall clock in a thread, so on a loaded machine anything may take a while:
every wait here ends on the event it waits for (a frame the master heard, a condition met), and
its time limit is only a watchdog against a device that never gets there (``WATCHDOG_S``).
``canopen``'s ``wait_for_bootup`` is not used for the first boot-up: it waits for a boot-up
*after* the call and misses one the device already sent (as it does when the test's thread is
slow to get there), then times out on the heartbeats that follow.
"""

from __future__ import annotations

import math
import threading
from pathlib import Path

import can
import canopen
import numpy as np
import pytest

from hil.dut import InProcessDut
from hil.rig import RunOptions, load_scenario, run_scenario
from plant_emulators.fertilizer.analog_output import AnalogOutputChannel
from plant_emulators.fertilizer.config import load_rig_config as load_fertilizer_config
from plant_emulators.fertilizer.devices import AnalogOutputModule
from plant_emulators.sowing_depth.cia402_objects import ErrorCode
from plant_emulators.sowing_depth.config import load_rig_config as load_sowing_config
from plant_emulators.sowing_depth.controllers import PiDepthController
from plant_emulators.sowing_depth.devices import ServoDriveDevice
from plant_emulators.sowing_depth.frames import EDS_PATH
from plant_emulators.sowing_depth.physics import SowingDepthPlant
from plant_emulators.sowing_depth.rig import SowingDepthRig

from .canopen_bench import master_and_device, wait_for

#: the longest any wait here may take: a device that is not there, not a slow machine
WATCHDOG_S = 120.0


def _heard_the_device(master: canopen.RemoteNode) -> None:
    """Until the master has heard the device: its boot-up (or, if that was before the master
    listened, a heartbeat after it) takes the master's view off INITIALISING."""
    wait_for(lambda: master.nmt.state != "INITIALISING", timeout_s=WATCHDOG_S)


def _until(condition) -> None:  # type: ignore[no-untyped-def]
    wait_for(condition, timeout_s=WATCHDOG_S)


def _drive_device() -> tuple[ServoDriveDevice, SowingDepthPlant]:
    cfg = load_sowing_config()
    plant = SowingDepthPlant(cfg, np.random.default_rng(0))
    return ServoDriveDevice(plant, cfg.wiring.drive_node_id, str(EDS_PATH)), plant


def _plant_advance(plant: SowingDepthPlant):
    def advance(t: float) -> None:
        steps = int((t - plant.time_s) / 0.001)
        if steps > 0:
            plant.advance(steps, 0.001)
    return advance


def test_drive_fault_and_recovery_leave_no_active_emcy() -> None:
    device, plant = _drive_device()
    with master_and_device(device, str(EDS_PATH), canopen.BaseNode402,
                           _plant_advance(plant)) as (master, bench):
        _heard_the_device(master)
        master.nmt.state = "PRE-OPERATIONAL"
        master.setup_402_state_machine(read_pdos=True)
        master.nmt.state = "OPERATIONAL"
        master.network.sync.start(0.005)
        master.rpdo[1].start(0.005)
        master.state = "OPERATION ENABLED"
        assert master.sdo[0x1001].raw == 0 and master.sdo[0x1003][0].raw == 0
        with bench.lock:
            plant.drive.inject_fault(ErrorCode.CONTINUOUS_OVER_CURRENT)
        _until(lambda: [e.code for e in master.emcy.active] == [0x2310])
        assert master.emcy.active[0].register == 0x03          # generic + current
        assert master.sdo[0x1001].raw == 0x03
        assert master.sdo[0x1003][0].raw == 1
        assert master.sdo[0x1003][1].raw == 0x2310
        with bench.lock:
            plant.drive.clear_injected_fault(ErrorCode.CONTINUOUS_OVER_CURRENT)
        master.state = "SWITCH ON DISABLED"                     # BaseNode402's fault reset
        _until(lambda: master.emcy.log[-1].code == 0x0000)
        assert master.emcy.active == []
        assert master.emcy.log[-1].register == 0
        assert master.sdo[0x1001].raw == 0
        assert master.sdo[0x1003][0].raw == 1                    # the history stays
        master.sdo[0x1003][0].raw = 0                            # until the master clears it
        assert master.sdo[0x1003][0].raw == 0
        master.state = "OPERATION ENABLED"
        assert master.state == "OPERATION ENABLED"


def test_stopped_drive_answers_no_sdo_but_its_heartbeat_says_stopped() -> None:
    device, plant = _drive_device()
    with master_and_device(device, str(EDS_PATH), canopen.RemoteNode,
                           _plant_advance(plant)) as (master, _):
        _heard_the_device(master)
        master.sdo.RESPONSE_TIMEOUT = WATCHDOG_S / 4             # answered: however slowly
        assert master.sdo[0x1000].raw == 0x00020192
        stopped = threading.Event()
        master.nmt.add_heartbeat_callback(lambda state: state == 4 and stopped.set())
        master.nmt.state = "STOPPED"
        assert stopped.wait(WATCHDOG_S), "no heartbeat saying STOPPED"
        master.sdo.RESPONSE_TIMEOUT = 0.3                       # not answered: fail fast
        master.sdo.MAX_RETRIES = 1
        with pytest.raises(canopen.SdoCommunicationError):
            _ = master.sdo[0x1000].raw
        master.sdo.RESPONSE_TIMEOUT = WATCHDOG_S / 4
        master.nmt.state = "PRE-OPERATIONAL"
        assert master.sdo[0x1000].raw == 0x00020192
        booted = threading.Event()
        master.nmt.add_heartbeat_callback(lambda state: state == 0 and booted.set())
        master.nmt.send_command(0x82)                           # reset communication
        assert booted.wait(WATCHDOG_S), "no boot-up after the reset"
        _until(lambda: master.nmt.state == "PRE-OPERATIONAL")


def test_analog_output_module_reports_the_heartbeat_timeout_and_its_end() -> None:
    cfg = load_fertilizer_config()
    wiring = cfg.wiring
    module = AnalogOutputModule(wiring.analog_output_node_id, wiring.analog_output_eds_file,
                                AnalogOutputChannel(cfg.analog_output,
                                                    np.random.default_rng(0)),
                                wiring.analog_output_channel)
    assert module.consumer_time_s > 0
    with master_and_device(module, wiring.analog_output_eds_file,
                           advance=module.update) as (master, _):
        _heard_the_device(master)
        network = master.network
        beat = network.send_periodic(0x700 + module.watched_node, [0x05], 0.05)
        _until(lambda: module.heartbeat_seen)
        assert master.sdo[0x1001].raw == 0
        beat.stop()                                             # the controller goes silent
        _until(lambda: [e.code for e in master.emcy.active] == [0x8130])
        assert master.emcy.active[0].register == 0x11          # generic + communication
        assert master.sdo[0x1001].raw == 0x11
        assert master.sdo[0x1003][1].raw == 0x8130
        beat = network.send_periodic(0x700 + module.watched_node, [0x05], 0.05)
        _until(lambda: master.emcy.log[-1].code == 0x0000)
        assert master.emcy.active == [] and master.sdo[0x1001].raw == 0
        beat.stop()


def test_fault_drive_overcurrent_run_ends_with_no_active_emcy(tmp_path: Path) -> None:
    scenario = load_scenario(SowingDepthRig.scenario_dir() / "fault-drive-overcurrent.toml")
    run_scenario(SowingDepthRig, scenario, InProcessDut(PiDepthController()),
                 RunOptions(out_dir=tmp_path, bus="virtual", clock="lockstep"))
    node_id = load_sowing_config().wiring.drive_node_id
    master = canopen.RemoteNode(node_id, str(EDS_PATH))
    network = canopen.Network()
    network.add_node(master)
    codes = []
    for frame in can.LogReader(tmp_path / "bus.log"):
        if frame.arbitration_id == 0x80 + node_id:
            network.notify(frame.arbitration_id, bytes(frame.data), frame.timestamp)
            codes.append((round(frame.timestamp), master.emcy.log[-1].code))
    assert codes[0][1] == 0x2310 and math.isclose(codes[0][0], 20, abs_tol=1)
    assert codes[-1][1] == 0x0000 and codes[-1][0] >= 25
    assert master.emcy.active == []


def test_a_boot_up_before_the_master_waits_is_not_missed() -> None:
    """A test thread that gets to its wait late (a loaded machine) still sees the device: with
    ``master.nmt.wait_for_bootup`` this waited for a second boot-up that never comes."""
    import time

    device, plant = _drive_device()
    with master_and_device(device, str(EDS_PATH), canopen.RemoteNode,
                           _plant_advance(plant)) as (master, _):
        _until(lambda: master.nmt._state_received not in (None, 0))   # a heartbeat after it
        time.sleep(0.2)
        _heard_the_device(master)
        assert master.nmt.state == "PRE-OPERATIONAL"
        with pytest.raises(canopen.nmt.NmtError):
            master.nmt.wait_for_bootup(0.5)     # canopen's own wait misses the boot-up
