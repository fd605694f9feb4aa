"""Each TP/ETP timeout (ISO 11783-3: T1-T4, the BAM receiver's T1), against a scripted peer."""

from __future__ import annotations

import can
import pytest

from hil.isobus.can_id import decode_id, make_frame
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.tp_messages import (
    PGN_ETP_CM,
    PGN_TP_CM,
    PGN_TP_DT,
    AbortReason,
    CmFrame,
    Control,
    decode_cm,
    encode_cm,
)
from hil.isobus.wire import ScriptedNode, VirtualWire
from tests.hil.isobus.peers import claims

PGN = 0xEF00
RIG = IsobusName(identity_number=1, function=134)
PEER = 0x90


def frame(pgn: int, data: bytes, source: int = PEER, destination: int = 0x80) -> can.Message:
    return make_frame(7, pgn, source, destination, data)


def cm(control: Control, **kw: int) -> bytes:
    return encode_cm(CmFrame(control, PGN, **kw))


def start() -> tuple[IsobusNetwork, ScriptedNode, VirtualWire]:
    rig = IsobusNetwork()
    rig.add(RIG, 0x80)
    peer = ScriptedNode(claims(PEER))   # a transfer needs a claimed address
    wire = VirtualWire([rig, peer])
    wire.run_until(0.5)
    return rig, peer, wire


def aborts(peer: ScriptedNode) -> list[tuple[float, int]]:
    """(time, reason) of every abort the rig sent."""
    out = []
    for t, m in peer.heard:
        pgn = decode_id(m.arbitration_id).pgn
        if pgn in (PGN_TP_CM, PGN_ETP_CM) and m.data[0] == Control.ABORT:
            out.append((round(t, 6), m.data[1]))
    return out


def test_t3_sender_gets_no_cts_after_its_rts() -> None:
    rig, peer, wire = start()
    rig.functions[0].send(PGN, bytes(20), destination=PEER)
    wire.run_until(3.0)
    assert aborts(peer) == [(0.5 + 1.25, AbortReason.TIMEOUT)]
    assert rig.transport.events[-1].kind == "timeout"


def test_t3_sender_gets_no_end_of_message_ack() -> None:
    rig, peer, wire = start()
    rig.functions[0].send(PGN, bytes(20), destination=PEER)
    peer.at(0.6, frame(PGN_TP_CM, cm(Control.CTS, packets=3, next_packet=1)))
    wire.run_until(3.0)
    assert aborts(peer) == [(0.6 + 1.25, AbortReason.TIMEOUT)]


def test_t4_sender_held_by_cts_for_zero_packets() -> None:
    rig, peer, wire = start()
    rig.functions[0].send(PGN, bytes(20), destination=PEER)
    peer.at(0.7, frame(PGN_TP_CM, cm(Control.CTS, packets=0, next_packet=1)))
    wire.run_until(3.0)
    assert aborts(peer) == [(0.7 + 1.05, AbortReason.TIMEOUT)]


def test_a_hold_repeated_within_th_keeps_the_sender_waiting() -> None:
    rig, peer, wire = start()
    rig.functions[0].send(PGN, bytes(20), destination=PEER)
    for t in (0.6, 1.1, 1.6, 2.1):                         # every 0.5 s (Th)
        peer.at(t, frame(PGN_TP_CM, cm(Control.CTS, packets=0, next_packet=1)))
    peer.at(2.5, frame(PGN_TP_CM, cm(Control.CTS, packets=3, next_packet=1)))
    peer.at(2.6, frame(PGN_TP_CM, cm(Control.EOMA, size=20, packets=3)))
    wire.run_until(5.0)
    assert aborts(peer) == []
    assert rig.transport.events[-1].kind == "complete"


@pytest.mark.parametrize("etp", [False, True])
def test_t2_receiver_gets_no_data_after_its_cts(etp: bool) -> None:
    _rig, peer, wire = start()
    rts = (frame(PGN_ETP_CM, cm(Control.ETP_RTS, size=2000)) if etp
           else frame(PGN_TP_CM, cm(Control.RTS, size=20, packets=3, max_per_cts=255)))
    peer.at(0.6, rts)
    wire.run_until(3.0)
    assert aborts(peer) == [(0.6 + 1.25, AbortReason.TIMEOUT)]


def test_t1_receiver_waits_for_the_next_packet() -> None:
    _rig, peer, wire = start()
    peer.at(0.6, frame(PGN_TP_CM, cm(Control.RTS, size=20, packets=3, max_per_cts=255)))
    peer.at(0.7, frame(PGN_TP_DT, bytes([1]) + bytes(7)))
    wire.run_until(3.0)
    assert aborts(peer) == [(0.7 + 0.75, AbortReason.TIMEOUT)]


def test_t1_just_in_time_completes() -> None:
    rig, peer, wire = start()
    peer.at(0.6, frame(PGN_TP_CM, cm(Control.RTS, size=20, packets=3, max_per_cts=255)))
    peer.at(0.7, frame(PGN_TP_DT, bytes([1]) + bytes(7)))
    peer.at(1.44, frame(PGN_TP_DT, bytes([2]) + bytes(7)))   # 0.74 s later
    peer.at(2.18, frame(PGN_TP_DT, bytes([3]) + bytes(7)))
    wire.run_until(3.0)
    assert aborts(peer) == []
    assert rig.transport.events[-1].kind == "complete"


def test_bam_receiver_drops_silently_after_t1() -> None:
    rig, peer, wire = start()
    bam = encode_cm(CmFrame(Control.BAM, 0xFF10, size=20, packets=3))
    peer.at(0.6, frame(PGN_TP_CM, bam, destination=0xFF))
    peer.at(0.65, frame(PGN_TP_DT, bytes([1]) + bytes(7), destination=0xFF))
    wire.run_until(3.0)
    assert [m for _, m in peer.heard if decode_id(m.arbitration_id).pgn == PGN_TP_CM] == []
    event = rig.transport.events[-1]
    assert (event.kind, event.protocol, round(event.time_s, 6)) == ("dropped", "BAM", 1.4)


def test_the_cts_the_receiver_sends_is_decodable() -> None:
    _rig, peer, wire = start()
    peer.at(0.6, frame(PGN_TP_CM, cm(Control.RTS, size=200, packets=29, max_per_cts=5)))
    wire.run_until(0.7)
    cts = decode_cm(bytes(peer.heard[-1][1].data), extended=False)
    assert (cts.control, cts.packets, cts.next_packet, cts.pgn) == (Control.CTS, 5, 1, PGN)
