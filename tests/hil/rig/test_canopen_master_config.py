"""A CANopen master configures the rig's nodes at boot (CiA 301), in lockstep: timing is exact.

canopen's own master classes (``RemoteNode``: ``pdo.read``/``save``, SDO, NMT, SYNC) talk to a
rig :class:`~hil.rig.canopen_device.CanopenDevice` through :class:`Loopback`, which carries
each frame between them at once on a simulated clock, the way the rig's lockstep runner does:
the device is due at ``next_due`` and sends what ``emit`` returns, before the master's SYNC of
the same instant; the master's SYNC, RPDOs, SDO and NMT frames reach ``on_frame``. Unlike the
runner today, the loop asks the device's ``next_due`` again after each frame it hands it, so a
TPDO or heartbeat the master just configured is due at once (the runner reaches the device at
its previously announced time, at most one heartbeat period later: reported to the lead). Every
frame is logged with its time, so the tests count TPDOs per SYNC and measure event timers to
the microsecond. The same master over python-can's
virtual bus, in real time, drives the remapped drive in ``test_canopen_master_config_drive.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import can
import canopen
import numpy as np
import pytest

from hil.rig.canopen_device import CanopenDevice
from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.devices import ServoDriveDevice
from plant_emulators.sowing_depth.frames import EDS_PATH
from plant_emulators.sowing_depth.physics import SowingDepthPlant

DRIVE_EDS = str(EDS_PATH)
PLANT_STEP_S = 0.001


class _LoopNetwork(canopen.Network):
    """The master's side: what canopen sends goes to the device at once."""

    def __init__(self, loop: Loopback) -> None:
        super().__init__(bus=None)
        self.loop = loop

    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
        self.loop.to_device(can.Message(arbitration_id=can_id, data=bytes(data),
                                        is_extended_id=can_id > 0x7FF))


class Loopback:
    """A canopen master and a rig CANopen device on one simulated wire, in one thread.

    Parameters
    ----------
    device
        The rig's node.
    eds
        The EDS the master loads.
    advance
        ``advance(t)``: move the device's physics to ``t`` before it acts (optional).
    node_cls
        The master's node class (``canopen.RemoteNode`` or ``canopen.BaseNode402``).
    """

    def __init__(self, device: CanopenDevice, eds: str,
                 advance: Callable[[float], None] | None = None,
                 node_cls: type = canopen.RemoteNode) -> None:
        self.device = device
        self.advance = advance
        self.t = 0.0
        #: every frame on the wire: (time, sender "master"/"device", frame)
        self.wire: list[tuple[float, str, can.Message]] = []
        self.network = _LoopNetwork(self)
        self.master = node_cls(device.node_id, eds)
        self.network.add_node(self.master)
        self.master.sdo.MAX_RETRIES = 0
        self.master.sdo.RESPONSE_TIMEOUT = 0.2
        self._due = device.next_due(-1.0)
        self._next_sync = math.inf
        self.sync_period_s = 0.0
        self.run_until(0.0)

    def to_device(self, msg: can.Message) -> None:
        self.wire.append((self.t, "master", msg))
        if self.device.accepts(msg):
            for reply in self.device.on_frame(msg, self.t):
                self.to_master(reply)
            self._due = min(self._due, self.device.next_due(self.t))

    def to_master(self, msg: can.Message) -> None:
        self.wire.append((self.t, "device", msg))
        self.network.notify(msg.arbitration_id, bytes(msg.data), self.t)

    def start_sync(self, period_s: float) -> None:
        """The master sends SYNC every ``period_s`` from now (0x1005 COB-ID of the master)."""
        self.sync_period_s = period_s
        self._next_sync = self.t + period_s

    def run_until(self, t_end: float) -> None:
        """Advance the clock to ``t_end``: SYNCs and the device's own frames, in time order."""
        while True:
            t = min(self._due, self._next_sync)
            if t > t_end + 1e-12:
                break
            self.t = t
            if self.advance is not None:
                self.advance(t)
            if self._due <= t + 1e-12:
                for frame in self.device.emit(t):
                    self.to_master(frame)
                self._due = self.device.next_due(t)
            if t == self._next_sync:
                self._next_sync = t + self.sync_period_s
                self.network.sync.transmit()
        self.t = t_end
        if self.advance is not None:
            self.advance(t_end)

    def sent(self, can_id: int, by: str = "device") -> list[tuple[float, can.Message]]:
        """The frames with ``can_id`` the given side sent, with their times."""
        return [(t, m) for t, who, m in self.wire if m.arbitration_id == can_id and who == by]


def drive_loop(node_cls: type = canopen.RemoteNode) -> tuple[Loopback, SowingDepthPlant]:
    """The sowing-depth rig's drive (node 2) with its plant, booted, facing a master."""
    cfg = load_rig_config()
    plant = SowingDepthPlant(cfg, np.random.default_rng(0))
    device = ServoDriveDevice(plant, cfg.wiring.drive_node_id, DRIVE_EDS)

    def advance(t: float) -> None:
        steps = round((t - plant.time_s) / PLANT_STEP_S)
        if steps > 0:
            plant.advance(steps, PLANT_STEP_S)

    return Loopback(device, DRIVE_EDS, advance, node_cls), plant


# ------------------------------------------------------------------------ the tests
def remap_tpdos(master: canopen.RemoteNode) -> None:
    """TPDO1: statusword + position actual on every 2nd SYNC, COB-ID 0x1A2; TPDO2: velocity
    actual + mode display on a 25 ms event timer with a 10 ms inhibit time; TPDO3 off."""
    master.tpdo.read()
    tpdo1, tpdo2, tpdo3 = master.tpdo[1], master.tpdo[2], master.tpdo[3]
    tpdo1.clear()
    tpdo1.add_variable(0x6041)
    tpdo1.add_variable(0x6064)
    tpdo1.cob_id, tpdo1.trans_type, tpdo1.enabled = 0x1A2, 2, True
    tpdo2.clear()
    tpdo2.add_variable(0x606C)
    tpdo2.add_variable(0x6061)
    tpdo2.trans_type, tpdo2.event_timer, tpdo2.inhibit_time = 255, 25, 100
    tpdo3.enabled = False
    master.tpdo.save()


def test_remapped_tpdos_go_out_with_their_new_ids_layouts_and_timing() -> None:
    loop, plant = drive_loop()
    master = loop.master
    remap_tpdos(master)
    master.tpdo.read()                          # read back over SDO: what the drive stored
    assert [(v.index, v.subindex) for v in master.tpdo[1]] == [(0x6041, 0), (0x6064, 0)]
    assert (master.tpdo[1].cob_id, master.tpdo[1].trans_type) == (0x1A2, 2)
    assert (master.tpdo[2].trans_type, master.tpdo[2].event_timer) == (255, 25)
    assert not master.tpdo[3].enabled
    master.nmt.state = "OPERATIONAL"
    loop.start_sync(0.005)
    start = loop.t
    loop.run_until(start + 0.5)
    syncs = loop.sent(0x080, by="master")
    tpdo1 = loop.sent(0x1A2)
    assert len(syncs) == 100 and len(tpdo1) == 50          # every 2nd SYNC
    assert [t for t, _ in tpdo1] == [t for t, _ in syncs[1::2]]
    assert loop.sent(0x182) == [] and loop.sent(0x382) == []  # old id, disabled TPDO3
    tpdo2 = [t for t, _ in loop.sent(0x282)]
    gaps = np.diff(tpdo2)
    assert len(tpdo2) >= 19 and np.allclose(gaps, 0.025, atol=1e-9)
    status, position = master.tpdo[1]["Statusword"].raw, master.tpdo[1][1].raw
    assert status == plant.drive.statusword
    assert position == round(plant.drive.read(0x6064, 0))
    assert len(tpdo1[-1][1].data) == 6 and len(loop.sent(0x282)[-1][1].data) == 5


def test_inhibit_time_spaces_event_tpdos() -> None:
    loop, _ = drive_loop()
    master = loop.master
    master.tpdo.read()
    tpdo = master.tpdo[2]
    tpdo.trans_type, tpdo.event_timer, tpdo.inhibit_time = 254, 1, 40    # 1 ms timer, 4 ms
    tpdo.save()
    master.nmt.state = "OPERATIONAL"
    loop.run_until(loop.t + 0.2)
    gaps = np.diff([t for t, _ in loop.sent(0x282)])
    assert len(gaps) > 10 and gaps.min() >= 0.004 - 1e-9


def test_synchronous_acyclic_tpdo_goes_at_the_sync_after_its_data_changed() -> None:
    loop, plant = drive_loop()
    master = loop.master
    master.tpdo.read()
    master.tpdo[3].trans_type = 0
    master.tpdo[3].save()
    master.nmt.state = "OPERATIONAL"
    loop.start_sync(0.01)
    loop.run_until(loop.t + 0.2)                   # boot of the drive: statusword settles
    before = len(loop.sent(0x382))
    loop.run_until(loop.t + 0.2)
    assert len(loop.sent(0x382)) == before          # nothing changed: nothing sent
    master.sdo[0x6040].raw = 0x06                  # shutdown: the statusword changes
    loop.run_until(loop.t + 0.2)
    assert len(loop.sent(0x382)) == before + 1
    assert master.tpdo[3]["Statusword"].raw == plant.drive.statusword


def test_heartbeat_period_and_sync_cob_id_take_effect_and_a_reset_restores_the_eds() -> None:
    loop, _ = drive_loop()
    master = loop.master
    master.sdo[0x1017].raw = 20
    t0 = loop.t
    loop.run_until(t0 + 0.1)
    beats = [t for t, _ in loop.sent(0x702) if t > t0]
    assert np.allclose(np.diff(beats), 0.020) and beats[0] == pytest.approx(t0 + 0.020)
    master.nmt.state = "OPERATIONAL"
    master.sdo[0x1005].raw = 0x0F0
    master.network.sync.cob_id = 0x0F0
    loop.start_sync(0.01)
    loop.run_until(loop.t + 0.1)
    assert len(loop.sent(0x182)) == 10               # TPDOs follow SYNC on 0x0F0
    master.nmt.send_command(0x82)                     # reset communication
    assert master.sdo[0x1017].raw == 100 and master.sdo[0x1005].raw == 0x80
    master.nmt.state = "OPERATIONAL"
    n = len(loop.sent(0x182))
    loop.run_until(loop.t + 0.1)
    assert len(loop.sent(0x182)) == n               # SYNC on 0x0F0 is no SYNC any more


def test_the_default_configuration_is_what_the_eds_declares() -> None:
    loop, _ = drive_loop()
    master = loop.master
    master.pdo.read()
    reference = canopen.RemoteNode(loop.device.node_id, DRIVE_EDS)
    canopen.Network().add_node(reference)
    reference.pdo.read(from_od=True)
    for mine, eds in zip(list(master.rpdo.values()) + list(master.tpdo.values()),
                         list(reference.rpdo.values()) + list(reference.tpdo.values()),
                         strict=True):
        assert (mine.cob_id, mine.trans_type, mine.enabled) == (eds.cob_id, eds.trans_type,
                                                                eds.enabled)
        assert [(v.index, v.subindex, v.length) for v in mine] == [
            (v.index, v.subindex, v.length) for v in eds]


def _eds_variables(od: canopen.ObjectDictionary) -> list[canopen.objectdictionary.ODVariable]:
    out = []
    for obj in od.values():
        if isinstance(obj, canopen.objectdictionary.ODVariable):
            out.append(obj)
        else:
            out.extend(obj.subindices.values())
    return out


def _download(master: canopen.RemoteNode, index: int, sub: int, raw: int) -> None:
    master.sdo.download(index, sub, master.object_dictionary[index][sub].encode_raw(raw))


def check_access_and_mapping(loop: Loopback, rpdo: int, tpdo: int | None) -> dict[str, int]:
    """Try AccessType and PDOMapping of every object of the device's EDS, as a master would.

    A writable object takes its own value back by SDO, a read-only one refuses (0x06010002); a
    mappable writable object goes alone into RPDO ``rpdo`` and a new value sent in it reaches the
    device; a mappable readable one goes alone into TPDO ``tpdo`` (if any) and comes out at the
    next SYNC as the device reads it. Mapping parameters and the controlword are left out (the
    re-mapping tests; the drive's state machine). Returns how many objects each check saw.
    """
    master, device = loop.master, loop.device
    od = device.node.object_dictionary
    checked = {"rw": 0, "ro": 0, "rpdo": 0, "tpdo": 0}
    for var in _eds_variables(od):
        index, sub = var.index, var.subindex
        if 0x1600 <= index <= 0x17FF or 0x1A00 <= index <= 0x1BFF or index == 0x6040:
            continue
        if var.writable:
            master.sdo.download(index, sub, master.sdo.upload(index, sub))
            checked["rw"] += 1
        else:
            data = b"\x00" * max(1, len(var) // 8)     # 0x1003 entries hold no data yet
            with pytest.raises(canopen.SdoAbortedError) as info:
                master.sdo.download(index, sub, data)
            assert info.value.code == 0x06010002, var.name
            checked["ro"] += 1
    rx_com, tx_com = 0x1400 + rpdo - 1, 0x1800 + (tpdo or 1) - 1
    rx_id = int(master.sdo[rx_com][1].raw) & 0x7FF
    tx_id = int(master.sdo[tx_com][1].raw) & 0x7FF if tpdo else 0
    for var in _eds_variables(od):
        if not var.pdo_mappable:
            continue
        entry = var.index << 16 | var.subindex << 8 | len(var)
        if var.writable:
            old = device.read(var.index, var.subindex)
            new = old + 1 if var.max is None or old < var.max else old - 1
            for index, sub, raw in ((rx_com, 1, 0x80000000 | rx_id), (rx_com + 0x200, 0, 0),
                                    (rx_com + 0x200, 1, entry), (rx_com + 0x200, 0, 1),
                                    (rx_com, 2, 255), (rx_com, 1, rx_id)):
                _download(master, index, sub, raw)
            master.rpdo.read()
            master.rpdo[rpdo][0].raw = new
            master.rpdo[rpdo].transmit()
            assert device.rejected == [], var.name
            assert device.read(var.index, var.subindex) == new, var.name
            checked["rpdo"] += 1
        if var.readable and tpdo:
            for index, sub, raw in ((tx_com, 1, 0x80000000 | tx_id), (tx_com + 0x200, 0, 0),
                                    (tx_com + 0x200, 1, entry), (tx_com + 0x200, 0, 1),
                                    (tx_com, 1, tx_id)):
                _download(master, index, sub, raw)
            master.tpdo.read()
            loop.run_until(loop.t + loop.sync_period_s)
            assert master.tpdo[tpdo][0].raw == device.read(var.index, var.subindex), var.name
            checked["tpdo"] += 1
    assert device.refused == []
    return checked


def test_every_drive_object_is_writable_and_mappable_as_its_eds_says() -> None:
    loop, _ = drive_loop()
    loop.master.nmt.state = "OPERATIONAL"
    loop.start_sync(0.01)
    loop.run_until(0.1)
    # counted by hand from the EDS: 45 rw and 43 ro objects (without the mapping parameters
    # and the controlword); 8 writable and 21 readable ones with PDOMapping=1
    assert check_access_and_mapping(loop, rpdo=2, tpdo=3) == {
        "rw": 45, "ro": 43, "rpdo": 8, "tpdo": 21}


def test_an_rpdo_of_the_wrong_length_for_its_mapping_gives_an_emcy() -> None:
    """The master remapped RPDO2 to the target velocity alone (4 bytes); a frame of the old
    layout (6 bytes) is used by its first 4 bytes with EMCY 0x8220, a short one is dropped with
    EMCY 0x8210, and a right one ends the error."""
    loop, plant = drive_loop()
    master = loop.master
    master.rpdo.read()
    rpdo = master.rpdo[2]
    rpdo.clear()
    rpdo.add_variable(0x60FF)
    rpdo.trans_type = 255
    rpdo.save()
    master.nmt.state = "OPERATIONAL"
    loop.start_sync(0.01)

    def send(data: bytes) -> None:
        loop.to_device(can.Message(arbitration_id=0x302, data=data, is_extended_id=False))
        loop.run_until(loop.t + 0.02)

    send((1500).to_bytes(4, "little", signed=True) + b"\x0f\x00")
    assert plant.drive.read(0x60FF, 0) == 1500
    assert [(e.code, e.register) for e in master.emcy.active] == [(0x8220, 0x11)]
    send(b"\x10\x00")
    assert plant.drive.read(0x60FF, 0) == 1500                  # not processed
    assert [e.code for e in master.emcy.active] == [0x8220, 0x8210]
    assert master.sdo[0x1001].raw == 0x11
    send((-700).to_bytes(4, "little", signed=True))
    assert plant.drive.read(0x60FF, 0) == -700
    assert master.emcy.active == [] and master.sdo[0x1001].raw == 0
