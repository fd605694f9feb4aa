"""Each abort reason the layer sends (ISO 11783-3, table 5), and an abort from the peer."""

from __future__ import annotations

import can
import pytest

from hil.isobus.can_id import decode_id, encode_id, make_frame
from hil.isobus.faults import IsobusFaults, LatePacket
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.tp_messages import (
    PGN_ETP_CM,
    PGN_ETP_DT,
    PGN_TP_CM,
    PGN_TP_DT,
    AbortReason,
    CmFrame,
    Control,
    encode_cm,
)
from hil.isobus.transport import TransportTiming
from hil.isobus.wire import ScriptedNode, VirtualWire
from tests.hil.isobus.peers import claims

PGN = 0xEF00
RIG = IsobusName(identity_number=1, function=134)
PEER = 0x90


def frame(pgn: int, data: bytes, source: int = PEER, destination: int = 0x80) -> can.Message:
    return make_frame(7, pgn, source, destination, data)


def cm(control: Control, pgn: int = PGN, **kw: int) -> bytes:
    return encode_cm(CmFrame(control, pgn, **kw))


def dt(seq: int) -> bytes:
    return bytes([seq]) + bytes(7)


def run(script: list[tuple[float, can.Message]], *, send: int | None = None,
        timing: TransportTiming | None = None, faults: IsobusFaults | None = None,
        until: float = 3.0) -> tuple[IsobusNetwork, ScriptedNode]:
    rig = IsobusNetwork(timing=timing, faults=faults)
    cf = rig.add(RIG, 0x80)
    # the peers claim their addresses first: a transfer from an address that never claimed
    # is not answered (test_transport_guard.py)
    peer = ScriptedNode([*claims(PEER, 0x91), *script])
    wire = VirtualWire([rig, peer])
    wire.run_until(0.5)
    if send is not None:
        cf.send(PGN, bytes(send), destination=PEER)
    wire.run_until(until)
    return rig, peer


def aborts(peer: ScriptedNode) -> list[tuple[int, int]]:
    """(destination, reason) of every abort the rig sent."""
    out = []
    for _, m in peer.heard:
        fid = decode_id(m.arbitration_id)
        if fid.pgn in (PGN_TP_CM, PGN_ETP_CM) and m.data[0] == Control.ABORT:
            out.append((fid.destination, m.data[1]))
    return out


TP_RTS = frame(PGN_TP_CM, cm(Control.RTS, size=20, packets=3, max_per_cts=255))
ETP_RTS = frame(PGN_ETP_CM, cm(Control.ETP_RTS, size=2000))


@pytest.mark.parametrize(("name", "script", "reason"), [
    ("bad sequence", [(0.6, TP_RTS), (0.7, frame(PGN_TP_DT, dt(2)))], AbortReason.BAD_SEQUENCE),
    ("duplicate", [(0.6, TP_RTS), (0.7, frame(PGN_TP_DT, dt(1))),
                   (0.8, frame(PGN_TP_DT, dt(1)))], AbortReason.DUPLICATE_SEQUENCE),
    ("ETP data before DPO", [(0.6, ETP_RTS), (0.7, frame(PGN_ETP_DT, dt(1)))],
     AbortReason.UNEXPECTED_DATA),
    ("second DPO", [(0.6, ETP_RTS),
                    (0.7, frame(PGN_ETP_CM, cm(Control.ETP_DPO, packets=10, offset=0))),
                    (0.8, frame(PGN_ETP_CM, cm(Control.ETP_DPO, packets=10, offset=0)))],
     AbortReason.UNEXPECTED_DPO),
    ("DPO for another PGN", [(0.6, ETP_RTS), (0.7, frame(PGN_ETP_CM, cm(
        Control.ETP_DPO, pgn=0xEE00, packets=10, offset=0)))], AbortReason.DPO_PGN),
    ("DPO with a bad offset", [(0.6, ETP_RTS), (0.7, frame(PGN_ETP_CM, cm(
        Control.ETP_DPO, packets=10, offset=3)))], AbortReason.BAD_DPO_OFFSET),
    ("TP RTS beyond 1785 bytes", [(0.6, frame(PGN_TP_CM, cm(
        Control.RTS, size=1786, packets=255, max_per_cts=255)))], AbortReason.OTHER),
    ("TP RTS whose packets do not match its size", [(0.6, frame(PGN_TP_CM, cm(
        Control.RTS, size=20, packets=4, max_per_cts=255)))], AbortReason.OTHER),
    ("ETP RTS small enough for TP", [(0.6, frame(PGN_ETP_CM, cm(Control.ETP_RTS, size=1785)))],
     AbortReason.OTHER),
])
def test_receiver_aborts(name: str, script: list, reason: int) -> None:
    rig, peer = run(script)
    assert aborts(peer) == [(PEER, reason)], name
    assert rig.transport.events[-1].reason == reason


def test_a_dpo_announcing_more_than_the_cts_allowed_is_reason_11() -> None:
    # 2000 bytes = 286 packets; this receiver's CTS allows 10, the DPO announces 11
    script = [(0.6, ETP_RTS), (0.7, frame(PGN_ETP_CM, cm(Control.ETP_DPO, packets=11,
                                                         offset=0)))]
    _rig, peer = run(script, timing=TransportTiming(etp_cts_packets=10))
    assert aborts(peer) == [(PEER, AbortReason.DPO_PACKETS_EXCEED_CTS)]


def test_one_session_too_many_is_refused_with_reason_1() -> None:
    other = can.Message(arbitration_id=encode_id(7, PGN_TP_CM, 0x91, 0x80),
                        data=cm(Control.RTS, size=20, packets=3, max_per_cts=255),
                        is_extended_id=True)
    _rig, peer = run([(0.6, TP_RTS), (0.6, other)], timing=TransportTiming(max_sessions=1),
                    until=1.0)
    assert aborts(peer) == [(0x91, AbortReason.ALREADY_IN_SESSION)]


@pytest.mark.parametrize(("name", "script", "send", "reason"), [
    ("retransmit asked a third time",
     [(0.6 + 0.1 * i, frame(PGN_TP_CM, cm(Control.CTS, packets=1, next_packet=1)))
      for i in range(4)], 20, AbortReason.MAX_RETRANSMIT),
    ("TP CTS beyond the message", [(0.6, frame(PGN_TP_CM, cm(Control.CTS, packets=4,
                                                              next_packet=1)))],
     20, AbortReason.OTHER),
    ("ETP CTS beyond the message", [(0.6, frame(PGN_ETP_CM, cm(Control.ETP_CTS, packets=10,
                                                                next_packet=280)))],
     2000, AbortReason.CTS_EXCEEDS_SIZE),
    ("ETP CTS for another PGN", [(0.6, frame(PGN_ETP_CM, cm(
        Control.ETP_CTS, pgn=0xEE00, packets=10, next_packet=1)))], 2000, AbortReason.CTS_PGN),
])
def test_sender_aborts(name: str, script: list, send: int, reason: int) -> None:
    _rig, peer = run(script, send=send)
    assert aborts(peer) == [(PEER, reason)], name


def test_cts_while_packets_are_still_going_out_is_reason_4() -> None:
    # packet 2 held back 0.5 s (a fault); a CTS in between finds the transfer in progress
    faults = IsobusFaults(late_packets=[LatePacket(packet=2, delay_s=0.5)])
    script = [(0.6, frame(PGN_TP_CM, cm(Control.CTS, packets=3, next_packet=1))),
              (0.8, frame(PGN_TP_CM, cm(Control.CTS, packets=1, next_packet=3)))]
    _rig, peer = run(script, send=20, faults=faults)
    assert aborts(peer) == [(PEER, AbortReason.CTS_DURING_TRANSFER)]
    sent = [m.data[0] for _, m in peer.heard if decode_id(m.arbitration_id).pgn == PGN_TP_DT]
    assert sent == [1]


@pytest.mark.parametrize("etp", [False, True])
def test_an_abort_from_the_peer_ends_the_transfer_silently(etp: bool) -> None:
    pgn = PGN_ETP_CM if etp else PGN_TP_CM
    script = [(0.7, frame(pgn, cm(Control.ABORT, reason=AbortReason.RESOURCES_NEEDED)))]
    rig, peer = run(script, send=2000 if etp else 20)
    assert aborts(peer) == []
    event = rig.transport.events[-1]
    assert (event.kind, event.reason, event.role) == ("peer-aborted", 2, "sender")
    assert not rig.transport.busy()
