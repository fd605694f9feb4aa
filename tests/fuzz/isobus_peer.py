"""A hostile or broken ISOBUS peer against the rig's tractor (TECU and TC), in virtual time:
what it may send, and what must hold whatever it sends (issue 43's "the project's own tests must
find this class of fault").

The peer has two hands: a :class:`~hil.isobus.wire.ScriptedNode` for raw frames (claims,
TP/ETP connection management and data, process data, from any address including 0xFE and 0xFF)
and a network of its own whose control functions at 0x92 and 0x93 claim their addresses and
send whole parameter groups (a DDOP of any bytes goes over TP or ETP properly, so the TC's
parser and checks see it). :func:`check_invariants` says what the tractor must keep.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import can
from hypothesis import strategies as st

from hil.isobus import ddi
from hil.isobus import process_data as pd
from hil.isobus.can_id import decode_id, make_frame
from hil.isobus.ddop.samples import parent_chain_pool, section_control_pool
from hil.isobus.field import load_field
from hil.isobus.name import IsobusName
from hil.isobus.network import InternalControlFunction, IsobusNetwork
from hil.isobus.port import GLOBAL_ADDRESS
from hil.isobus.process_data import AckError, Command, ElementCommand
from hil.isobus.tc import EventKind
from hil.isobus.tecu import PGN_WHEEL_BASED_SPEED
from hil.isobus.tp_messages import (
    PGN_ADDRESS_CLAIMED,
    PGN_ETP_CM,
    PGN_ETP_DT,
    PGN_REQUEST,
    PGN_TP_CM,
    PGN_TP_DT,
    Control,
)
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.wire import ScriptedNode, VirtualWire
from tests.hil.isobus.hostile import FIELD

PEER_NAMES = {0x92: IsobusName(identity_number=0x92, manufacturer_code=77, function=130,
                               device_class=5),
              0x93: IsobusName(identity_number=0x93, manufacturer_code=77, function=130,
                               device_class=5)}
SAMPLE_POOL = section_control_pool(sections=3, name=PEER_NAMES[0x92].value).to_bytes()
SOURCES = [0x80, 0x90, 0x91, 0x92, 0x93, 0xF7, 0xFE, 0xFF]
DESTINATIONS = [0x80, 0xF7, 0xFF, 0x92]
CONTROLS = [int(c) for c in Control]


@dataclass
class Sender:
    """An application on a peer control function: sends given groups at given times."""

    port: InternalControlFunction
    plan: list[tuple[float, int, bytes, int]] = field(default_factory=list)

    def next_due(self, now_s: float) -> float:
        return self.plan[0][0] if self.plan else math.inf

    def tick(self, now_s: float) -> None:
        while self.plan and self.plan[0][0] <= now_s + 1e-9:
            _, pgn, data, destination = self.plan.pop(0)
            self.port.send(pgn, data, destination, 5)


@dataclass
class Peer:
    tractor: Tractor
    wire: VirtualWire
    raw: ScriptedNode
    senders: dict[int, Sender]


def build(raw: list[tuple[float, can.Message]], groups: list[tuple[float, int, int, bytes, int]],
          ) -> Peer:
    """The tractor, the raw hand's script and the group hand's plan (time, from, pgn, data,
    to)."""
    tractor = Tractor(TractorSetup(load_field(FIELD), drive_after_s=100.0))
    net = IsobusNetwork(name="peer", log_frames=100)   # the peer's memory is not the rig's
    senders = {}
    for address, name in PEER_NAMES.items():
        port = net.add(name, address, f"peer 0x{address:02X}")
        senders[address] = Sender(port)
        port.run(senders[address])
    for t, source, pgn, data, destination in sorted(groups, key=lambda g: g[0]):
        senders[source].plan.append((t, pgn, data, destination))
    node = ScriptedNode(raw)
    return Peer(tractor, VirtualWire([tractor.network, net, node]), node, senders)


# --- what the peer sends ------------------------------------------------------------------------

def _mutated(data: bytes, draw: st.DrawFn) -> bytes:
    out = bytearray(data)
    for _ in range(draw(st.integers(0, 4))):
        kind = draw(st.sampled_from(["flip", "cut", "insert", "delete"]))
        pos = draw(st.integers(0, max(len(out) - 1, 0)))
        if kind == "flip" and out:
            out[pos] = draw(st.integers(0, 255))
        elif kind == "cut":
            del out[max(pos, 1):]
        elif kind == "insert":
            out[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        elif out:
            del out[pos:pos + draw(st.integers(1, 8))]
    return bytes(out)


@st.composite
def ddop_bytes(draw: st.DrawFn) -> bytes:
    """A pool's bytes: the sample mutated, one the tractor cannot use, a long chain, noise."""
    kind = draw(st.integers(0, 3))
    if kind == 0:
        return _mutated(SAMPLE_POOL, draw)
    if kind == 1:
        return section_control_pool(sections=draw(st.integers(1, 3)), section_width_mm=0,
                                    name=PEER_NAMES[0x92].value).to_bytes()
    if kind == 2:
        return parent_chain_pool(draw(st.integers(1, 600)), name=PEER_NAMES[0x92].value)
    return draw(st.binary(min_size=1, max_size=300))


@st.composite
def process_data(draw: st.DrawFn) -> bytes:
    """A process data message a client could send, right or wrong."""
    kind = draw(st.integers(0, 9))
    element = draw(st.integers(0, 12))
    ddi_ = draw(st.sampled_from([ddi.ACTUAL_MASS_PER_AREA_RATE, 161, ddi.ACTUAL_WORK_STATE,
                                 ddi.SETPOINT_MASS_PER_AREA_RATE, 0xFFFF, 0]))
    value = draw(st.integers(-2**31, 2**31 - 1))
    messages = [pd.RequestVersion(), pd.Version(draw(st.integers(0, 255))),
                pd.RequestStructureLabel(), pd.RequestLocalizationLabel(),
                pd.RequestObjectPoolTransfer(draw(st.integers(0, 2**32 - 1))),
                pd.ObjectPoolActivate(draw(st.booleans())), pd.DeleteObjectPool(),
                ElementCommand(Command.VALUE, element, ddi_, value),
                pd.ClientTask(draw(st.booleans())),
                pd.ProcessDataAcknowledge(element, ddi_, AckError.NONE, 3)]
    if kind == 9 and draw(st.booleans()):
        return draw(st.binary(max_size=12))
    return pd.encode(messages[kind])


@st.composite
def raw_frame(draw: st.DrawFn) -> can.Message:
    """One frame from any address: a claim, TP/ETP connection management or data, process
    data, a request, or noise."""
    source = draw(st.sampled_from(SOURCES) | st.integers(0, 255))
    destination = draw(st.sampled_from(DESTINATIONS))
    kind = draw(st.integers(0, 5))
    if kind == 0:
        name = draw(st.sampled_from([0, 1, PEER_NAMES[0x92].value]) | st.integers(0, 2**64 - 1))
        return make_frame(6, PGN_ADDRESS_CLAIMED, source, GLOBAL_ADDRESS,
                          name.to_bytes(8, "little"))
    if kind == 1:
        data = bytes([draw(st.sampled_from(CONTROLS))]) + draw(st.binary(min_size=7,
                                                                         max_size=7))
        pgn = draw(st.sampled_from([PGN_TP_CM, PGN_ETP_CM]))
        return make_frame(7, pgn, source, destination, data)
    if kind == 2:
        pgn = draw(st.sampled_from([PGN_TP_DT, PGN_ETP_DT]))
        return make_frame(7, pgn, source, destination, draw(st.binary(min_size=1, max_size=8)))
    if kind == 3:
        data = draw(process_data())[:8].ljust(8, b"\xff")
        return make_frame(5, pd.PROCESS_DATA_PGN, source, destination, data)
    if kind == 4:
        pgn = draw(st.sampled_from([PGN_ADDRESS_CLAIMED, pd.WORKING_SET_MASTER_PGN, 0xFE0F]))
        return make_frame(6, PGN_REQUEST, source, destination, pgn.to_bytes(3, "little"))
    pgn = draw(st.sampled_from([pd.WORKING_SET_MASTER_PGN, 0xFE48, 0xEF00]))
    return make_frame(6, pgn, source, GLOBAL_ADDRESS if pgn >= 0xF000 else destination,
                      draw(st.binary(max_size=8)))


@st.composite
def group(draw: st.DrawFn) -> tuple[int, int, bytes, int]:
    """A whole parameter group from a claimed peer: a connection step, a DDOP of any bytes,
    values."""
    source = draw(st.sampled_from(sorted(PEER_NAMES)))
    kind = draw(st.integers(0, 3))
    if kind == 0:
        return source, pd.WORKING_SET_MASTER_PGN, pd.encode_working_set_master(
            pd.WorkingSetMaster(1)), GLOBAL_ADDRESS
    if kind == 1:
        return source, pd.PROCESS_DATA_PGN, pd.encode(pd.ObjectPoolTransfer(draw(ddop_bytes()))), \
            0xF7
    return source, pd.PROCESS_DATA_PGN, draw(process_data()), 0xF7


def connection(source: int, t0: float, pool: bytes) -> list[tuple[float, int, int, bytes, int]]:
    """A client's whole connection from ``t0``: working-set master, version, transfer,
    activate (each 50 ms after the last)."""
    steps = [(pd.WORKING_SET_MASTER_PGN, pd.encode_working_set_master(pd.WorkingSetMaster(1)),
              GLOBAL_ADDRESS),
             (pd.PROCESS_DATA_PGN, pd.encode(pd.RequestVersion()), 0xF7),
             (pd.PROCESS_DATA_PGN, pd.encode(pd.Version(4)), 0xF7),
             (pd.PROCESS_DATA_PGN, pd.encode(pd.RequestObjectPoolTransfer(len(pool))), 0xF7),
             (pd.PROCESS_DATA_PGN, pd.encode(pd.ObjectPoolTransfer(pool)), 0xF7),
             (pd.PROCESS_DATA_PGN, pd.encode(pd.ObjectPoolActivate(True)), 0xF7)]
    # the transfer takes a while over TP/ETP: the activation 1.5 s after it
    times = [t0 + 0.05 * i for i in range(5)] + [t0 + 1.7]
    return [(t, source, pgn, data, to) for t, (pgn, data, to) in zip(times, steps, strict=True)]


# --- what must hold -------------------------------------------------------------------------------

def check_invariants(peer: Peer, until_s: float) -> None:
    """What the tractor keeps whatever the peer sent."""
    tractor, wire = peer.tractor, peer.wire
    tc = tractor.tc
    # no client's input raised inside the TC or the tractor
    errors = [e for e in tc.events if e.kind == EventKind.CLIENT_ERROR]
    assert not errors, errors
    # never a session for 0xFE or 0xFF, each one the NAME's that holds its address
    for address, session in tc.sessions.items():
        assert address not in (0xFE, 0xFF)
        assert session.name is not None
        assert tractor.network.table.name_of(address) == session.name, (address, session)
    # transport sessions within their bounds
    timing = tractor.network.transport.timing
    receiving = [s for s in tractor.network.transport.sessions()
                 if s.role == "receiver" and s.protocol != "BAM"]
    assert len(receiving) <= timing.max_sessions
    for source, sessions in itertools.groupby(sorted(s.source for s in receiving)):
        assert len(list(sessions)) <= timing.max_sessions_per_source, source
    # the TECU's speeds every 100 ms of run time while it holds its address
    lost = [e.time_s for e in tractor.tecu.port.claimer.events if e.kind == "lost"]
    end = min([until_s, *lost])
    times = [f.time_s for f in wire.frames if f.sender == 0 and f.time_s <= end
             and decode_id(f.frame.arbitration_id).pgn == PGN_WHEEL_BASED_SPEED]
    assert times and times[0] <= 0.25 + 1e-6
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert not gaps or max(gaps) <= 0.1 + 1e-6, max(gaps)
    assert end - times[-1] <= 0.1 + 1e-6
    # the TC's status at least every 2 s while it holds an address (a move restarts it)
    if tractor.tc_function.address is not None:
        status = [f.time_s for f in wire.frames if f.sender == 0
                  and decode_id(f.frame.arbitration_id).pgn == pd.PROCESS_DATA_PGN
                  and f.frame.data[0] == 0xFE
                  and decode_id(f.frame.arbitration_id).source == tractor.tc_function.address]
        assert status and until_s - status[-1] <= 2.0 + 1e-6
    # what the TC and the network keep is bounded
    assert len(tc.events) <= 5_000 and len(tractor.network.transport.events) <= 1000
