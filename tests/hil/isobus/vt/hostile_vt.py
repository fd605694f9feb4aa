"""A bench for the VT under a hostile or broken peer, in virtual time: the rig's tractor with
the VT beside its TC and the VT's screens drawn (as ``hil isobus serve --vt`` has them), a
well-behaved implement (the project's VT client) on a network of its own, and a peer with two
hands: raw frames from any address (a :class:`~hil.isobus.wire.ScriptedNode`) and whole VT
messages from two claimed control functions at 0x92 and 0x93 (the network layer carries them by
TP or ETP, so the VT's parser and checks see them). :func:`check_vt` says what must hold
whatever the peer sends."""

from __future__ import annotations

import itertools
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import can

from hil.isobus.can_id import decode_id, make_frame
from hil.isobus.field import load_field
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.port import GLOBAL_ADDRESS
from hil.isobus.tecu import PGN_WHEEL_BASED_SPEED
from hil.isobus.tp_messages import PGN_ADDRESS_CLAIMED
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.vt import server as vt_server
from hil.isobus.vt.attach import attach_vt
from hil.isobus.vt.bench import IMPLEMENT_ADDRESS, IMPLEMENT_NAME
from hil.isobus.vt.client import VtClient
from hil.isobus.vt.messages import (
    ECU_TO_VT_PGN,
    VT_TO_ECU_PGN,
    WORKING_SET_MASTER_PGN,
    Function,
    pad,
    u16,
    u32,
)
from hil.isobus.vt.screens import ScreenRecorder
from hil.isobus.vt.server import VT_ADDRESS, VirtualTerminalServer, VtOptions
from hil.isobus.vt.store import VersionStore
from hil.isobus.wire import ScriptedNode, VirtualWire
from tests.fuzz.isobus_peer import Sender
from tests.hil.isobus.hostile import FIELD
from tests.hil.isobus.peers import claim

from .pools import implement_pool, split

PEER_NAMES = {0x92: IsobusName(identity_number=0x92, manufacturer_code=77, function=130,
                               device_class=5),
              0x93: IsobusName(identity_number=0x93, manufacturer_code=77, function=130,
                               device_class=5)}
GOOD_LABEL = b"GOOD"


@dataclass
class VtPeerBench:
    tractor: Tractor
    vt: VirtualTerminalServer
    recorder: ScreenRecorder
    wire: VirtualWire
    raw: ScriptedNode
    senders: dict[int, Sender]
    client: VtClient | None
    store: VersionStore

    def vt_frames(self, function: int, destination: int | None = None) -> list[tuple[float,
                                                                                      bytes]]:
        """(time, data) of the VT's single frames of ``function`` (to ``destination``)."""
        out = []
        for f in self.wire.frames:
            fid = decode_id(f.frame.arbitration_id)
            if f.sender == 0 and fid.pgn == VT_TO_ECU_PGN and fid.source == VT_ADDRESS and \
                    f.frame.data[0] == function and \
                    (destination is None or fid.destination == destination):
                out.append((f.time_s, bytes(f.frame.data)))
        return out


def build(raw: list[tuple[float, can.Message]] = (),
          groups: list[tuple[float, int, int, bytes, int]] = (), *,
          options: VtOptions | None = None, store: VersionStore | None = None,
          good: bool = True, log_frames: int | None = None) -> VtPeerBench:
    """The tractor and its VT, the good implement (``good``), the raw hand's script and the
    group hand's plan ``(time, from, pgn, data, to)``; ``log_frames``: the rig network's log
    of the last frames shorter than its 10,000 (a memory test fills it sooner)."""
    tractor = Tractor(TractorSetup(load_field(FIELD), drive_after_s=100.0))
    if log_frames is not None:
        tractor.network.log = deque(maxlen=log_frames)
    store = store if store is not None else VersionStore()
    attached = attach_vt(tractor.network, options=options, store=store, console=None)
    nodes: list = [tractor.network]
    client = None
    if good:
        implement = IsobusNetwork(name="implement", log_frames=100)
        cf = implement.add(IMPLEMENT_NAME, IMPLEMENT_ADDRESS, "implement")
        client = VtClient(cf, split(implement_pool(), 2), GOOD_LABEL)
        cf.run(client)
        nodes.append(implement)
    net = IsobusNetwork(name="peer", log_frames=100)   # the peer's memory is not the rig's
    senders = {}
    for address, name in PEER_NAMES.items():
        port = net.add(name, address, f"peer 0x{address:02X}")
        senders[address] = Sender(port)
        port.run(senders[address])
    for t, source, pgn, data, destination in sorted(groups, key=lambda g: g[0]):
        senders[source].plan.append((t, pgn, data, destination))
    node = ScriptedNode(list(raw))
    nodes += [net, node]
    return VtPeerBench(tractor, attached.vt, attached.recorder, VirtualWire(nodes), node,
                       senders, client, store)


# --- VT messages a working set sends --------------------------------------------------------------

def maintenance(init: bool = False, version: int = 4) -> bytes:
    return pad([Function.WORKING_SET_MAINTENANCE, int(init), version])


def get_memory(size: int) -> bytes:
    return bytes([Function.GET_MEMORY, 0xFF]) + u32(size) + b"\xff\xff"


def transfer(pool: bytes) -> bytes:
    return bytes([Function.OBJECT_POOL_TRANSFER]) + pool


END_OF_POOL = pad([Function.END_OF_OBJECT_POOL])
WORKING_SET_MASTER = pad([1])


def store_version(label: bytes, extended: bool = False) -> bytes:
    size = 32 if extended else 7
    code = Function.EXTENDED_STORE_VERSION if extended else Function.STORE_VERSION
    return bytes([code]) + (label + b" " * size)[:size]


def load_version(label: bytes, extended: bool = False) -> bytes:
    size = 32 if extended else 7
    code = Function.EXTENDED_LOAD_VERSION if extended else Function.LOAD_VERSION
    return bytes([code]) + (label + b" " * size)[:size]


def delete_version(label: bytes, extended: bool = False) -> bytes:
    size = 32 if extended else 7
    code = Function.EXTENDED_DELETE_VERSION if extended else Function.DELETE_VERSION
    return bytes([code]) + (label + b" " * size)[:size]


def change_numeric(object_id: int, value: int) -> bytes:
    return bytes([Function.CHANGE_NUMERIC_VALUE]) + u16(object_id) + b"\xff" + u32(value)


def connection(source: int, t0: float, pool: bytes, label: bytes | None = None,
               ) -> list[tuple[float, int, int, bytes, int]]:
    """A working set's whole connection from ``t0``: working set master, maintenance, get
    memory, the pool, end of object pool (1.5 s later: the transfer takes a while over TP/ETP)
    and, with ``label``, store version."""
    steps = [(t0, WORKING_SET_MASTER_PGN, WORKING_SET_MASTER, GLOBAL_ADDRESS),
             (t0, ECU_TO_VT_PGN, maintenance(True), VT_ADDRESS),
             (t0 + 0.05, ECU_TO_VT_PGN, get_memory(len(pool)), VT_ADDRESS),
             (t0 + 0.1, ECU_TO_VT_PGN, transfer(pool), VT_ADDRESS),
             (t0 + 1.6, ECU_TO_VT_PGN, END_OF_POOL, VT_ADDRESS)]
    if label is not None:
        steps.append((t0 + 1.7, ECU_TO_VT_PGN, store_version(label), VT_ADDRESS))
    return [(t, source, pgn, data, to) for t, pgn, data, to in steps]


def keep_alive(source: int, t0: float, until_s: float) -> list[tuple[float, int, int, bytes,
                                                                       int]]:
    """Maintenance messages every second from ``t0``."""
    n = int((until_s - t0) // 1.0) + 1
    return [(t0 + k, source, ECU_TO_VT_PGN, maintenance(), VT_ADDRESS) for k in range(n)]


def raw_vt(source: int, data: bytes, destination: int = VT_ADDRESS) -> can.Message:
    """A single-frame ECU to VT message from any address."""
    return make_frame(5, ECU_TO_VT_PGN, source, destination, pad(data)[:8])


# --- what must hold ---------------------------------------------------------------------------

def took_over(raw: list[tuple[float, can.Message]], *addresses: int) -> bool:
    """Whether the raw script claims one of ``addresses`` (it may take it from its owner)."""
    for _, frame in raw:
        fid = decode_id(frame.arbitration_id)
        if fid.pgn == PGN_ADDRESS_CLAIMED and fid.source in addresses:
            return True
    return False


def check_vt(bench: VtPeerBench, until_s: float, *, good_connects: bool = True) -> None:
    """What the VT (and the tractor beside it) keeps whatever the peer sent."""
    vt, wire = bench.vt, bench.wire
    # nothing a working set sent raised inside the VT (it would have ended that working set)
    assert vt.counts["event client error"] == 0, [e for e in vt.events
                                                  if e.kind == "client error"]
    assert vt.counts["event error"] == 0, [e for e in vt.events if e.kind == "error"]
    # never a working set for 0xFE or 0xFF; each one the NAME's that holds its address
    for address, ws in vt.sessions.items():
        assert address not in (0xFE, 0xFF)
        assert ws.name is not None and ws.key == ws.name
        assert vt.port.name_of(address) == ws.name, (address, ws.name)
    # the VT status every second while the VT holds its address
    lost = [e.time_s for e in vt.port.claimer.events if e.kind == "lost"]
    end = min([until_s, *lost])
    status = [t for t, _ in bench.vt_frames(Function.VT_STATUS, GLOBAL_ADDRESS) if t <= end]
    assert status and status[0] <= 0.25 + 1e-6, status[:2]
    gaps = [b - a for a, b in itertools.pairwise(status)]
    assert not gaps or max(gaps) <= vt_server.STATUS_PERIOD_S + 1e-6, max(gaps)
    assert end - status[-1] <= vt_server.STATUS_PERIOD_S + 1e-6
    # the TECU's speeds every 100 ms of run time while it holds its address
    tecu_lost = [e.time_s for e in bench.tractor.tecu.port.claimer.events if e.kind == "lost"]
    tecu_end = min([until_s, *tecu_lost])
    times = [f.time_s for f in wire.frames if f.sender == 0 and f.time_s <= tecu_end
             and decode_id(f.frame.arbitration_id).pgn == PGN_WHEEL_BASED_SPEED]
    tecu_gaps = [b - a for a, b in itertools.pairwise(times)]
    assert times and (not tecu_gaps or max(tecu_gaps) <= 0.1 + 1e-6)
    # memory: the VT's records, pools and transfers, and the store, within their bounds
    assert len(vt.events) <= vt_server.EVENTS_KEPT
    assert len(vt.commands) <= vt_server.COMMANDS_KEPT
    assert len(vt.responses) <= vt_server.RESPONSES_KEPT
    assert len(vt.activations) <= vt_server.ACTIVATIONS_KEPT
    used = sum((ws.pool.size if ws.pool is not None else 0) + sum(map(len, ws.transfers))
               for ws in vt.sessions.values())
    assert used <= vt.options.memory_bytes, used
    limits = vt.options.store_limits
    assert bench.store.bytes <= limits.max_bytes and bench.store.count <= limits.max_versions
    if bench.store.directory is not None and bench.store.directory.exists():
        files = list(bench.store.directory.iterdir())
        assert len(files) == bench.store.count, files
        assert all(f.suffix == ".vtp" and f.parent == bench.store.directory for f in files)
    # the good implement connected and its pool is active, whatever else happened
    if bench.client is not None and good_connects:
        assert bench.client.state == "connected", bench.client.state
        ws = vt.sessions.get(IMPLEMENT_ADDRESS)
        assert ws is not None and ws.pool is not None


def files_under(root: Path) -> list[Path]:
    """Every file below ``root`` (to see nothing was written outside the store)."""
    return sorted(p for p in root.rglob("*") if p.is_file())


__all__ = ["GOOD_LABEL", "PEER_NAMES", "VtPeerBench", "build", "check_vt", "claim",
           "connection", "keep_alive", "raw_vt"]
