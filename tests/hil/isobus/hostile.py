"""A bench for the TC under a hostile or broken peer: the rig's tractor, a well-behaved
implement (the project's TC client) on a network of its own, and a scripted peer that sends
whatever a test wants, all in virtual time."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import can

from hil.isobus import process_data as pd
from hil.isobus.can_id import decode_id, make_frame
from hil.isobus.ddop import ObjectPool
from hil.isobus.ddop.samples import section_control_pool
from hil.isobus.field import load_field
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.process_data import AckError
from hil.isobus.tc_client import TaskControllerClient
from hil.isobus.tecu import PGN_WHEEL_BASED_SPEED
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.wire import ScriptedNode, VirtualWire

FIELD = (Path(__file__).resolve().parents[3] / "plant_emulators" / "fertilizer" / "fields"
         / "field-rect.geojson")
IMPLEMENT = IsobusName(identity_number=9, manufacturer_code=300, function=130, device_class=5)
IMPLEMENT_ADDRESS = 0x85
WSM = pd.encode_working_set_master(pd.WorkingSetMaster(1))


@dataclass
class Implement:
    """A TC client that applies what it is told and reports a rate."""

    pool: ObjectPool
    setpoints: list[tuple[float, int, int, int]] = field(default_factory=list)

    def on_setpoint(self, element: int, ddi_: int, value: int, t: float) -> AckError | None:
        self.setpoints.append((t, element, ddi_, value))
        return None

    def read_value(self, element: int, ddi_: int, t: float) -> int | None:
        return 0


@dataclass
class Bench:
    tractor: Tractor
    wire: VirtualWire
    peer: ScriptedNode
    clients: list[TaskControllerClient]

    def tecu_times(self) -> list[float]:
        """When the TECU's wheel-based speed went out."""
        return [f.time_s for f in self.wire.frames
                if decode_id(f.frame.arbitration_id).pgn == PGN_WHEEL_BASED_SPEED]

    def to(self, address: int, since_s: float = 0.0) -> list[tuple[float, pd.ProcessDataMessage]]:
        """Process data the TC sent to ``address`` from ``since_s`` on."""
        tc = self.tractor.tc_function
        out = []
        for f in self.wire.frames:
            fid = decode_id(f.frame.arbitration_id)
            if (fid.pgn == pd.PROCESS_DATA_PGN and fid.destination == address
                    and f.time_s >= since_s and fid.source == tc.address
                    and len(f.frame.data) == 8):
                out.append((f.time_s, pd.decode(bytes(f.frame.data))))
        return out


def bench(*pools: tuple[ObjectPool, IsobusName, int], script=(), drive_after_s: float = 100.0,
          ) -> Bench:
    """The tractor, one client per ``(pool, NAME, address)``, and a scripted peer."""
    tractor = Tractor(TractorSetup(load_field(FIELD), drive_after_s=drive_after_s))
    nodes: list = [tractor.network]
    clients = []
    for pool, name, address in pools:
        net = IsobusNetwork(name=f"implement 0x{address:02X}")
        port = net.add(name, address, "implement")
        implement = Implement(pool)
        client = TaskControllerClient(port, pool, on_setpoint=implement.on_setpoint,
                                      read_value=implement.read_value)
        port.run(client)
        nodes.append(net)
        clients.append(client)
    peer = ScriptedNode(list(script))
    nodes.append(peer)
    return Bench(tractor, VirtualWire(nodes), peer, clients)


def good_pool(name: IsobusName = IMPLEMENT) -> ObjectPool:
    return section_control_pool(sections=4, name=name.value)


def frame(pgn: int, data: bytes, source: int, destination: int = 0xF7,
          priority: int = 5) -> can.Message:
    return make_frame(priority, pgn, source, destination, data)
