"""TP and ETP (ISO 11783-3): round trips at the boundary lengths, both directions, BAM."""

from __future__ import annotations

import itertools

import pytest

from hil.errors import FrameError
from hil.isobus.can_id import decode_id
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.port import Received
from hil.isobus.tp_messages import (
    ETP_MAX_BYTES,
    PGN_ETP_CM,
    PGN_ETP_DT,
    PGN_TP_CM,
    PGN_TP_DT,
    AbortReason,
    CmFrame,
    Control,
    decode_cm,
    encode_cm,
)
from hil.isobus.transport import TransportTiming
from hil.isobus.wire import VirtualWire

RIG = IsobusName(identity_number=1, function=134, device_class=1)
DUT = IsobusName(identity_number=2, function=130, device_class=6)
PGN = 0xEF00          # proprietary A, destination-specific
PGN_BROADCAST = 0xFF10


def payload(n: int, seed: int = 0) -> bytes:
    return bytes((i * 31 + seed) & 0xFF for i in range(n))


def setup(timing: TransportTiming | None = None):
    rig, dut = IsobusNetwork(name="rig", timing=timing), IsobusNetwork(name="dut")
    a = rig.add(RIG, 0x80)
    b = dut.add(DUT, 0x90)
    wire = VirtualWire([rig, dut])
    wire.run_until(0.5)
    got_a: list[Received] = []
    got_b: list[Received] = []
    for pgn in (PGN, PGN_BROADCAST):
        a.subscribe(pgn, got_a.append)
        b.subscribe(pgn, got_b.append)
    return rig, dut, a, b, wire, got_a, got_b


def pgns(wire: VirtualWire, since: float = 0.0) -> list[int]:
    return [decode_id(f.frame.arbitration_id).pgn for f in wire.frames if f.time_s >= since]


@pytest.mark.parametrize(("size", "protocol"), [(8, None), (9, PGN_TP_CM), (1785, PGN_TP_CM),
                                                (1786, PGN_ETP_CM), (20_000, PGN_ETP_CM)])
@pytest.mark.parametrize("direction", ["rig->dut", "dut->rig"])
def test_peer_to_peer_round_trip(size: int, protocol: int | None, direction: str) -> None:
    rig, dut, a, b, wire, got_a, got_b = setup()
    sender, receiver, got = (a, b, got_b) if direction == "rig->dut" else (b, a, got_a)
    data = payload(size, seed=size)
    sender.send(PGN, data, destination=receiver.address)
    wire.run_until(3.0)
    assert len(got) == 1
    msg = got[0]
    assert (msg.pgn, msg.data, msg.source, msg.destination) == (PGN, data, sender.address,
                                                               receiver.address)
    seen = set(pgns(wire, since=0.5))
    if protocol is None:
        assert seen == {PGN}
    else:
        assert protocol in seen and PGN not in seen
        other = PGN_ETP_CM if protocol == PGN_TP_CM else PGN_TP_CM
        assert other not in seen
    events = rig.transport.events + dut.transport.events
    assert all(e.kind == "complete" for e in events)
    assert not rig.transport.busy() and not dut.transport.busy()


def test_tp_frames_are_the_standards() -> None:
    _rig, _dut, a, _b, wire, _got_a, _got_b = setup()
    a.send(PGN, payload(20), destination=0x90)
    wire.run_until(1.0)
    frames = [(f.frame.arbitration_id, bytes(f.frame.data)) for f in wire.frames
              if f.time_s >= 0.5]
    assert frames[0] == (0x1CEC9080, bytes([16, 20, 0, 3, 0xFF, 0x00, 0xEF, 0x00]))   # RTS
    assert frames[1] == (0x1CEC8090, bytes([17, 3, 1, 0xFF, 0xFF, 0x00, 0xEF, 0x00]))  # CTS
    assert frames[2][0] == 0x1CEB9080 and frames[2][1] == bytes([1]) + payload(20)[:7]
    assert frames[4][1] == bytes([3]) + payload(20)[14:] + b"\xff"      # last packet padded
    assert frames[5] == (0x1CEC8090, bytes([19, 20, 0, 3, 0xFF, 0x00, 0xEF, 0x00]))  # EOMA


def test_etp_windows_use_dpo_offsets() -> None:
    _rig, _dut, a, _b, wire, _got_a, got_b = setup()
    a.send(PGN, payload(3000), destination=0x90)        # 429 packets: windows 255 + 174
    wire.run_until(2.0)
    cms = [decode_cm(bytes(f.frame.data), extended=True) for f in wire.frames
           if decode_id(f.frame.arbitration_id).pgn == PGN_ETP_CM]
    assert [(c.control, c.size, c.packets, c.next_packet, c.offset) for c in cms] == [
        (Control.ETP_RTS, 3000, 0, 0, 0),
        (Control.ETP_CTS, 0, 255, 1, 0), (Control.ETP_DPO, 0, 255, 0, 0),
        (Control.ETP_CTS, 0, 174, 256, 0), (Control.ETP_DPO, 0, 174, 0, 255),
        (Control.ETP_EOMA, 3000, 0, 0, 0)]
    seqs = [f.frame.data[0] for f in wire.frames
            if decode_id(f.frame.arbitration_id).pgn == PGN_ETP_DT]
    assert seqs == list(range(1, 256)) + list(range(1, 175))
    assert got_b[0].data == payload(3000)


@pytest.mark.parametrize("size", [9, 1785])
def test_bam_round_trip_paced_50_ms(size: int) -> None:
    _rig, _dut, a, _b, wire, _got_a, got_b = setup()
    data = payload(size, seed=3)
    a.send(PGN_BROADCAST, data)
    wire.run_until(0.5 + 0.05 * (size // 7 + 2) + 0.1)
    assert [(m.data, m.destination) for m in got_b] == [(data, 0xFF)]
    times = [f.time_s for f in wire.frames if decode_id(f.frame.arbitration_id).pgn == PGN_TP_DT]
    gaps = {round(t2 - t1, 9) for t1, t2 in itertools.pairwise(times)}
    assert gaps == {0.05}
    assert not [f for f in wire.frames if f.sender == 1 and f.time_s > 0.5]   # no handshake


def test_sizes_beyond_the_protocols_are_refused() -> None:
    rig, _dut, a, _b, _wire, _got_a, _got_b = setup()
    with pytest.raises(FrameError, match="broadcast"):
        a.send(PGN_BROADCAST, bytes(1786))
    with pytest.raises(FrameError, match="117440505"):
        rig.transport.send(PGN, b"\0" * (ETP_MAX_BYTES + 1), 0x80, 0x90, 7, 1.0)
    with pytest.raises(FrameError, match="PDU2"):
        a.send(PGN_BROADCAST, bytes(3), destination=0x90)


def test_the_largest_etp_announcement_is_accepted_and_one_more_byte_refused() -> None:
    # a receiver that takes the protocol's largest message (the default takes 2 MiB)
    _rig, _dut, _a, _b, wire, _got_a, _got_b = setup(
        TransportTiming(max_receive_bytes=ETP_MAX_BYTES))
    for size, expected in ((ETP_MAX_BYTES, Control.ETP_CTS), (ETP_MAX_BYTES + 1, Control.ABORT)):
        rts = CmFrame(Control.ETP_RTS, PGN, size=size)
        start = len(wire.frames)
        wire.inject(_frame(PGN_ETP_CM, 0x90, 0x80, encode_cm(rts)), sender=1)
        answer = decode_cm(bytes(wire.frames[start + 1].frame.data), extended=True)
        assert answer.control == expected
        if expected == Control.ETP_CTS:
            assert (answer.packets, answer.next_packet) == (255, 1)
            wire.inject(_frame(PGN_ETP_CM, 0x90, 0x80, encode_cm(
                CmFrame(Control.ABORT, PGN, reason=250))), sender=1)


def test_a_message_larger_than_the_receiver_takes_is_refused_at_its_rts() -> None:
    rig, _dut, _a, _b, wire, _got_a, _got_b = setup(TransportTiming(max_receive_bytes=4000))
    for size, expected in ((4000, Control.ETP_CTS), (4001, Control.ABORT)):
        start = len(wire.frames)
        wire.inject(_frame(PGN_ETP_CM, 0x90, 0x80, encode_cm(
            CmFrame(Control.ETP_RTS, PGN, size=size))), sender=1)
        answer = decode_cm(bytes(wire.frames[start + 1].frame.data), extended=True)
        assert answer.control == expected
        if expected == Control.ABORT:
            assert answer.reason == AbortReason.RESOURCES_NEEDED
            assert "at most 4000" in rig.transport.events[-1].detail
        else:
            wire.inject(_frame(PGN_ETP_CM, 0x90, 0x80, encode_cm(
                CmFrame(Control.ABORT, PGN, reason=250))), sender=1)


def test_several_sessions_at_once_both_ways_and_queued_per_pair() -> None:
    rig, dut = IsobusNetwork(name="rig"), IsobusNetwork(name="dut")
    r1 = rig.add(RIG, 0x80)
    r2 = rig.add(IsobusName(identity_number=3, function=130), 0xF7)
    d1 = dut.add(DUT, 0x90)
    d2 = dut.add(IsobusName(identity_number=4, function=131), 0x91)
    wire = VirtualWire([rig, dut])
    wire.run_until(0.5)
    got: dict[str, list[bytes]] = {"r1": [], "r2": [], "d1": [], "d2": []}
    for key, cf in (("r1", r1), ("r2", r2), ("d1", d1), ("d2", d2)):
        cf.subscribe(PGN, lambda m, k=key: got[k].append(m.data))
        cf.subscribe(PGN_BROADCAST, lambda m, k=key: got[k].append(m.data))
    r1.send(PGN, payload(100, 1), destination=0x90)
    r1.send(PGN, payload(200, 2), destination=0x90)     # same pair: waits for the first
    r1.send(PGN, payload(2000, 3), destination=0x91)     # ETP beside it
    r2.send(PGN_BROADCAST, payload(50, 4))               # BAM beside both
    d1.send(PGN, payload(300, 5), destination=0x80)      # the other way at the same time
    d2.send(PGN, payload(40, 6), destination=0xF7)
    wire.run_until(3.0)
    assert got["d1"] == [payload(100, 1), payload(200, 2), payload(50, 4)]
    assert got["d2"] == [payload(2000, 3), payload(50, 4)]
    assert got["r1"] == [payload(300, 5), payload(50, 4)]    # internal BAM heard by r1
    assert got["r2"] == [payload(40, 6)]
    ends = [e.kind for e in rig.transport.events + dut.transport.events if e.protocol != "BAM"]
    assert ends and set(ends) == {"complete"}


def _frame(pgn: int, source: int, destination: int, data: bytes, priority: int = 7):
    from hil.isobus.can_id import make_frame

    return make_frame(priority, pgn, source, destination, data)
