"""canopen's CiA 402 master remaps the rig's servo drive at boot and drives it over the bus.

``canopen.BaseNode402`` on python-can's virtual bus, in real time, against the drive as the rig
runs it (:mod:`.canopen_bench`): the master rewrites every PDO by SDO (CiA 301 sequence, through
``PdoMap.save``), reads the layout back, then moves the cylinder in profile position and profile
velocity modes through the new PDOs. Exact TPDO timing is checked in lockstep in
``test_canopen_master_config.py``.
"""

from __future__ import annotations

import canopen
import numpy as np
import pytest

from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.devices import ServoDriveDevice
from plant_emulators.sowing_depth.frames import EDS_PATH
from plant_emulators.sowing_depth.physics import SowingDepthPlant

from .canopen_bench import master_and_device, wait_for

SW_TARGET_REACHED = 0x0400
SW_SET_POINT_ACK = 0x1000
RPDO1_ID, RPDO2_ID, TPDO1_ID, TPDO2_ID = 0x212, 0x312, 0x192, 0x292


def remap(master: canopen.BaseNode402) -> None:
    """RPDO1: controlword + target position, at once (255); RPDO2: target velocity (255);
    RPDO3 off (modes of operation by SDO); TPDO1: statusword + position actual every 2nd SYNC;
    TPDO2: mode display + velocity actual on a 20 ms event timer; TPDO3 off. New COB-IDs."""
    master.rpdo.read()
    master.tpdo.read()
    layout = {
        master.rpdo[1]: (RPDO1_ID, 255, (0x6040, 0x607A)),
        master.rpdo[2]: (RPDO2_ID, 255, (0x60FF,)),
        master.tpdo[1]: (TPDO1_ID, 2, (0x6041, 0x6064)),
        master.tpdo[2]: (TPDO2_ID, 255, (0x6061, 0x606C)),
    }
    for pdo, (cob_id, trans_type, objects) in layout.items():
        pdo.clear()
        for index in objects:
            pdo.add_variable(index)
        pdo.cob_id, pdo.trans_type, pdo.enabled = cob_id, trans_type, True
    master.tpdo[2].event_timer = 20
    master.rpdo[3].enabled = False
    master.tpdo[3].enabled = False
    master.pdo.save()


def test_a_remapped_drive_runs_profile_position_and_profile_velocity() -> None:
    cfg = load_rig_config()
    plant = SowingDepthPlant(cfg, np.random.default_rng(0))
    device = ServoDriveDevice(plant, cfg.wiring.drive_node_id, str(EDS_PATH))

    def advance(t: float) -> None:
        steps = int((t - plant.time_s) / 0.001)
        if steps > 0:
            plant.advance(steps, 0.001)

    with master_and_device(device, str(EDS_PATH), canopen.BaseNode402,
                           advance) as (master, _):
        seen: dict[int, int] = {}
        for cob_id in (0x182, 0x282, 0x382, TPDO1_ID, TPDO2_ID):
            master.network.subscribe(
                cob_id, lambda can_id, data, ts: seen.__setitem__(can_id,
                                                                  seen.get(can_id, 0) + 1))
        # its boot-up may come before the master waits for it: wait for any heartbeat
        master.nmt.wait_for_heartbeat(5)
        assert device.rpdo_ids_mapping((0x607A, 0x60FF)) == {0x202, 0x302}   # the EDS's
        remap(master)
        assert device.refused == []
        # the rig's lockstep step waits for the RPDOs that carry a target, where they now are
        assert device.rpdo_ids_mapping((0x607A, 0x60FF)) == {RPDO1_ID, RPDO2_ID}
        master.setup_402_state_machine(read_pdos=True)      # reads the new layout back by SDO
        assert [v.index for v in master.rpdo[1]] == [0x6040, 0x607A]
        assert master.tpdo[1].cob_id == TPDO1_ID and master.tpdo[1].trans_type == 2
        assert not master.rpdo[3].enabled and not master.tpdo[3].enabled
        master.nmt.state = "OPERATIONAL"
        master.network.sync.start(0.005)
        master.state = "OPERATION ENABLED"
        assert master.state == "OPERATION ENABLED"

        master.op_mode = "PROFILED POSITION"                  # by SDO: RPDO3 is off
        assert master.op_mode == "PROFILED POSITION"          # from TPDO2
        master.rpdo[1]["Target position"].raw = 6000          # 60 mm
        master.controlword = 0x1F                              # new set-point, RPDO1 at once
        wait_for(lambda: master.statusword & SW_SET_POINT_ACK)
        master.controlword = 0x0F
        wait_for(lambda: master.statusword & SW_TARGET_REACHED
                 and not master.statusword & SW_SET_POINT_ACK)
        wait_for(lambda: abs(master.tpdo_values[0x6064] - 6000) <= 10)
        assert plant.rod_position_mm == pytest.approx(60.0, abs=0.1)

        master.op_mode = "PROFILED VELOCITY"
        assert master.op_mode == "PROFILED VELOCITY"
        master.rpdo[2]["Target velocity"].raw = -2000         # retract at 20 mm/s
        master.rpdo[2].transmit()
        wait_for(lambda: abs(master.tpdo_values[0x606C] + 2000) <= 50)
        master.rpdo[2]["Target velocity"].raw = 0
        master.rpdo[2].transmit()
        wait_for(lambda: abs(master.tpdo_values[0x606C]) <= 5)
        assert plant.rod_position_mm < 59.0
        assert master.tpdo_values[0x6064] == pytest.approx(plant.rod_position_mm * 100, abs=20)
        master.state = "SWITCH ON DISABLED"
    assert seen.get(0x182, 0) == seen.get(0x382, 0) == 0     # the old TPDOs are gone
    assert seen[TPDO1_ID] > 0 and seen[TPDO2_ID] > 0
