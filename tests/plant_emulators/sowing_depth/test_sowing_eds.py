"""The drive's EDS: loads in canopen, matches the drive logic, and a standard master drives it."""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Iterator

import canopen
import numpy as np
import pytest
from canopen.objectdictionary import datatypes
from canopen.sdo import SdoAbortedError

from plant_emulators.sowing_depth.cia402 import OBJECTS, DriveObjectError
from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.frames import EDS_PATH
from plant_emulators.sowing_depth.physics import SowingDepthPlant

NODE_ID = load_rig_config().wiring.drive_node_id
DATA_TYPES = {"U8": datatypes.UNSIGNED8, "I8": datatypes.INTEGER8, "U16": datatypes.UNSIGNED16,
              "I16": datatypes.INTEGER16, "U32": datatypes.UNSIGNED32,
              "I32": datatypes.INTEGER32}


def od_entry(od: canopen.ObjectDictionary, index: int,
             subindex: int) -> canopen.objectdictionary.ODVariable:
    entry = od[index]
    return entry if isinstance(entry, canopen.objectdictionary.ODVariable) else entry[subindex]


def test_eds_loads_as_local_remote_and_402_node() -> None:
    local = canopen.LocalNode(NODE_ID, str(EDS_PATH))
    remote = canopen.RemoteNode(NODE_ID, str(EDS_PATH))
    master = canopen.BaseNode402(NODE_ID, str(EDS_PATH))
    for node in (local, remote, master):
        od = node.object_dictionary
        assert od[0x1000].default == 0x00020192          # CiA 402, servo drive
        assert od[0x1017].default == load_rig_config().wiring.drive_heartbeat_period_ms
        assert od[0x1018][1].default == 0 and od[0x1018][0].default == 4
        assert od[0x1400][1].default == 0x200 + NODE_ID
        assert od[0x1800][1].default == 0x180 + NODE_ID


def test_every_drive_object_is_in_the_eds_with_its_type_access_and_default() -> None:
    od = canopen.LocalNode(NODE_ID, str(EDS_PATH)).object_dictionary
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(0))
    drive = plant.drive
    computed = {0x1001, 0x2001, 0x603F, 0x6041, 0x6061, 0x6062, 0x6064, 0x606B, 0x606C,
                0x6077, 0x6078, 0x60F4}
    for (index, sub), spec in OBJECTS.items():
        var = od_entry(od, index, sub)
        assert var.data_type == DATA_TYPES[spec.data_type], spec.name
        assert var.access_type == spec.access, spec.name
        assert var.pdo_mappable == spec.pdo_mappable, spec.name
        if index not in computed:
            assert var.default == drive.read(index, sub), spec.name
    for index in (0x6040, 0x6041, 0x6060, 0x6061, 0x6064, 0x606C, 0x607A, 0x60FF, 0x6081,
                  0x6083, 0x6084, 0x6065, 0x603F, 0x607D):
        assert index in od


def test_pdo_mappings_and_transmission_types() -> None:
    node = canopen.RemoteNode(NODE_ID, str(EDS_PATH))
    canopen.Network().add_node(node)          # not connected: only to hold subscriptions
    node.pdo.read(from_od=True)
    expected_rx = {1: (0x200, 1, ["Controlword", "Target position"]),
                   2: (0x300, 1, ["Controlword", "Target velocity"]),
                   3: (0x400, 255, ["Modes of operation"])}
    expected_tx = {1: (0x180, 1, ["Statusword", "Position actual value"]),
                   2: (0x280, 1, ["Statusword", "Velocity actual value"]),
                   3: (0x380, 1, ["Statusword", "Modes of operation display", "Error code",
                                  "Torque actual value"])}
    for maps, expected in ((node.rpdo, expected_rx), (node.tpdo, expected_tx)):
        assert len(maps) == 3
        for number, (cob, trans, names) in expected.items():
            pdo = maps[number]
            assert pdo.enabled and pdo.cob_id == cob + NODE_ID and pdo.trans_type == trans
            assert [var.name for var in pdo] == names
            assert sum(var.length for var in pdo) <= 64


# ---------------------------------------------------------------------- a standard master
class DriveNode:
    """Test-only wiring of the drive into a canopen LocalNode: SDO callbacks, PDOs on SYNC.

    The rig's own device does this for real; here it proves the EDS and the drive logic work
    with an unmodified ``canopen.BaseNode402`` master.
    """

    def __init__(self, network: canopen.Network, plant: SowingDepthPlant, sync_s: float) -> None:
        self.plant = plant
        self.steps = round(sync_s / 0.001)
        self.lock = threading.Lock()
        self.node = canopen.LocalNode(NODE_ID, str(EDS_PATH))
        network.add_node(self.node)
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)
        self.node.rpdo.read(from_od=True)
        self.node.tpdo.read(from_od=True)
        for pdo in self.node.rpdo.values():
            if pdo.trans_type >= 254:
                pdo.add_callback(self._apply)
        network.subscribe(0x80, self._on_sync)

    def _on_read(self, index: int, subindex: int, od: object) -> int | None:
        if self.plant.drive.owns(index, subindex):
            with self.lock:
                return self.plant.drive.read(index, subindex)
        return None

    def _on_write(self, index: int, subindex: int, od: canopen.objectdictionary.ODVariable,
                  data: bytes) -> None:
        if self.plant.drive.owns(index, subindex):
            try:
                with self.lock:
                    self.plant.drive.write(index, subindex, od.decode_raw(data))
            except DriveObjectError as exc:
                raise SdoAbortedError(exc.abort_code) from exc

    def _apply(self, pdo: canopen.pdo.PdoMap) -> None:
        with self.lock:
            for var in pdo:
                self.plant.drive.write(var.index, var.subindex, var.raw)

    def _on_sync(self, can_id: int, data: bytes, timestamp: float) -> None:
        for pdo in self.node.rpdo.values():
            if pdo.trans_type <= 240 and pdo.timestamp is not None:
                self._apply(pdo)
        with self.lock:
            self.plant.advance(self.steps, 0.001)
            for pdo in self.node.tpdo.values():
                for var in pdo:
                    var.raw = self.plant.drive.read(var.index, var.subindex)
        for pdo in self.node.tpdo.values():
            pdo.transmit()


@pytest.fixture
def bench() -> Iterator[tuple[canopen.BaseNode402, SowingDepthPlant]]:
    channel = f"sd-{uuid.uuid4().hex}"
    slave_net, master_net = canopen.Network(), canopen.Network()
    slave_net.connect(interface="virtual", channel=channel)
    master_net.connect(interface="virtual", channel=channel)
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(0))
    DriveNode(slave_net, plant, sync_s=0.005)
    master = canopen.BaseNode402(NODE_ID, str(EDS_PATH))
    master_net.add_node(master)
    try:
        yield master, plant
    finally:
        master_net.sync.stop()
        for pdo in master.rpdo.values():
            pdo.stop()
        master_net.disconnect()
        slave_net.disconnect()


def wait_for(condition: object, timeout_s: float = 3.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():  # type: ignore[operator]
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.005)


def test_sdo_access_goes_to_the_drive(bench: tuple[canopen.BaseNode402, SowingDepthPlant]) -> None:
    master, plant = bench
    master_net = master.network
    master_net.sync.start(0.005)
    wait_for(lambda: plant.time_s > 0.05)
    assert master.sdo[0x6041].raw == plant.drive.statusword
    assert master.sdo[0x6064].raw == 4000
    with pytest.raises(SdoAbortedError) as info:
        master.sdo[0x6060].raw = 6
    assert info.value.code == 0x06090030
    with pytest.raises(SdoAbortedError) as info:
        master.sdo[0x6041].raw = 1
    assert info.value.code == 0x06010002


def test_base_node_402_enables_and_moves_the_cylinder(
        bench: tuple[canopen.BaseNode402, SowingDepthPlant]) -> None:
    master, plant = bench
    master.nmt.state = "PRE-OPERATIONAL"
    master.setup_402_state_machine(read_pdos=True)
    assert master.is_op_mode_supported("PROFILED POSITION")
    assert master.is_op_mode_supported("PROFILED VELOCITY")
    assert not master.is_op_mode_supported("HOMING")
    master.nmt.state = "OPERATIONAL"
    master.network.sync.start(0.005)
    master.rpdo[1].start(0.005)
    master.state = "OPERATION ENABLED"
    assert master.state == "OPERATION ENABLED"
    master.op_mode = "PROFILED POSITION"
    assert master.op_mode == "PROFILED POSITION"
    master.rpdo[1]["Target position"].raw = 6000
    master.controlword = 0x1F
    wait_for(lambda: master.statusword & 0x1000)
    master.controlword = 0x0F
    wait_for(lambda: master.statusword & 0x0400 and not master.statusword & 0x1000)
    assert master.tpdo_values[0x6064] == pytest.approx(6000, abs=10)
    assert plant.rod_position_mm == pytest.approx(60.0, abs=0.1)
    master.state = "SWITCH ON DISABLED"
    assert plant.drive.state.value == "SWITCH ON DISABLED"
