"""What a hostile or broken peer cannot take from the transport layer: transfers from addresses
that never claimed are not answered, sessions are bounded per source and in all, and 64
unclaimed addresses holding sessions open do not starve a good client's pool transfer
(issue 43, item 6). Frames from 0xFF, and from 0xFE but for claims, are dropped (item 3)."""

from __future__ import annotations

import can

from hil.isobus.can_id import decode_id, make_frame
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.port import Received
from hil.isobus.tp_messages import PGN_TP_CM, AbortReason, CmFrame, Control, encode_cm
from hil.isobus.transport import TransportTiming
from hil.isobus.wire import ScriptedNode, VirtualWire
from tests.hil.isobus.peers import claims

PGN = 0xEF00
RIG = IsobusName(identity_number=1, function=134)
TC = IsobusName(identity_number=2, function=130)
GOOD = IsobusName(identity_number=7, manufacturer_code=200, function=130, device_class=5)


def rts(source: int, destination: int = 0x80, size: int = 20) -> can.Message:
    packets = (size + 6) // 7
    return make_frame(7, PGN_TP_CM, source, destination,
                      encode_cm(CmFrame(Control.RTS, PGN, size=size, packets=packets,
                                        max_per_cts=255)))


def answers(peer: ScriptedNode, to: int | None = None) -> list[tuple[int, int, int]]:
    """(destination, control byte, reason byte) of every TP CM frame the rig (0x80, 0xF7)
    sent."""
    out = []
    for _, m in peer.heard:
        fid = decode_id(m.arbitration_id)
        if fid.pgn == PGN_TP_CM and fid.source in (0x80, 0xF7) and (
                to is None or fid.destination == to):
            out.append((fid.destination, m.data[0], m.data[1]))
    return out


def bench(script: list[tuple[float, can.Message]],
          timing: TransportTiming | None = None) -> tuple[IsobusNetwork, ScriptedNode,
                                                           VirtualWire, list[Received]]:
    rig = IsobusNetwork(timing=timing)
    got: list[Received] = []
    rig.add(RIG, 0x80).subscribe(PGN, got.append)
    rig.add(TC, 0xF7).subscribe(PGN, got.append)
    peer = ScriptedNode(script)
    wire = VirtualWire([rig, peer])
    return rig, peer, wire, got


def test_a_transfer_from_an_address_that_never_claimed_is_not_answered() -> None:
    rig, peer, wire, _ = bench([(0.6, rts(0x90))])
    wire.run_until(3.0)
    assert answers(peer) == []
    assert rig.transport.counts["unclaimed"] == 1
    assert not rig.transport.sessions()
    # claimed, the same RTS is answered with a CTS
    rig, peer, wire, _ = bench([*claims(0x90), (0.6, rts(0x90))])
    wire.run_until(0.7)
    assert answers(peer) == [(0x90, Control.CTS, 3)]


def test_sessions_per_source_are_bounded() -> None:
    timing = TransportTiming(max_sessions_per_source=1)
    rig, peer, wire, _ = bench([*claims(0x90), (0.6, rts(0x90, 0x80)), (0.6, rts(0x90, 0xF7))],
                               timing)
    wire.run_until(0.7)
    assert answers(peer) == [(0x90, Control.CTS, 3),
                             (0x90, Control.ABORT, AbortReason.ALREADY_IN_SESSION)]
    assert "from 0x90" in rig.transport.events[-1].detail


def test_sixty_four_unclaimed_addresses_do_not_starve_a_good_clients_transfer() -> None:
    # 64 addresses that never claimed open a TP session each and keep it open, every 0.5 s
    # (within T2), for the whole run; a good client then sends its 1,500 bytes
    flood = [(0.6 + 0.5 * k, rts(0x90 + i)) for i in range(64) for k in range(7)]
    rig, peer, wire, got = bench(flood)
    dut = IsobusNetwork(name="dut")
    good = dut.add(GOOD, 0x85)
    wire = VirtualWire([rig, peer, dut])
    wire.run_until(1.0)
    payload = bytes(range(250)) * 6
    good.send(PGN, payload, destination=0xF7)
    wire.run_until(4.0)
    assert [m.data for m in got] == [payload]
    assert rig.transport.counts["unclaimed"] == 64 * 7
    assert [a for a in answers(peer) if a[0] != 0x85] == []


def test_sixty_four_claimed_addresses_are_refused_beyond_the_session_bound() -> None:
    # claimed, each gets a session until the bound; the rest are aborted with reason 1
    rig, peer, wire, _ = bench([*claims(*range(0x90, 0xD0)),
                                *[(0.6, rts(0x90 + i)) for i in range(64)]])
    wire.run_until(0.7)
    sent = answers(peer)
    assert sum(1 for a in sent if a[1] == Control.CTS) == 16
    assert sum(1 for a in sent if a[1:] == (Control.ABORT,
                                            AbortReason.ALREADY_IN_SESSION)) == 48
    assert len(rig.transport.sessions()) == 16


def test_frames_from_the_global_and_null_addresses_are_dropped() -> None:
    rig, peer, wire, got = bench([
        (0.6, make_frame(6, PGN, 0xFF, 0x80, b"12345678")),
        (0.6, make_frame(6, PGN, 0xFE, 0x80, b"12345678")),
        (0.6, rts(0xFF)),
        (0.6, make_frame(6, PGN, 0x90, 0x80, b"12345678"))])
    wire.run_until(1.0)
    assert [m.source for m in got] == [0x90]
    assert rig.dropped == {"source 0xFF": 2, "source 0xFE": 1}
    assert answers(peer) == []
