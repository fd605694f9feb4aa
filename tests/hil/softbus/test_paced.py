"""The paced bus at 250 kbit/s (ISOBUS): no more frames than the bit rate allows, and
contended frames go out by identifier. Checked on the server's own delivery stamps, which are
the simulated wire times, not on wall-clock speed."""

from __future__ import annotations

import itertools
import time

import can

from hil.bus import open_bus
from hil.softbus import SoftwareBus
from hil.softbus.timing import frame_bits, worst_case_frame_bits

BITRATE = 250_000


def _drain(bus: can.BusABC, n: int, timeout: float) -> list[can.Message]:
    out: list[can.Message] = []
    deadline = time.monotonic() + timeout
    while len(out) < n and time.monotonic() < deadline:
        msg = bus.recv(0.2)
        if msg is not None:
            out.append(msg)
    return out


def test_paced_bus_carries_no_more_than_the_bit_rate() -> None:
    n = 1500
    with SoftwareBus(port=0, bitrate=BITRATE) as softbus:
        a, b = open_bus(softbus.spec()), open_bus(softbus.spec())
        try:
            start = time.monotonic()
            for i in range(n):
                a.send(can.Message(arbitration_id=0x18FEF100 | (i & 0xFF), is_extended_id=True,
                                   data=i.to_bytes(2, "little") + bytes(6)))
            got = _drain(b, n, timeout=20)
            wall = time.monotonic() - start
        finally:
            a.shutdown()
            b.shutdown()
    assert len(got) == n
    for prev, cur in itertools.pairwise(got):
        bits = frame_bits(cur.arbitration_id, True, bytes(cur.data))
        assert cur.timestamp - prev.timestamp >= bits / BITRATE - 2e-6
    span = got[-1].timestamp - got[0].timestamp
    assert (n - 1) / span <= BITRATE / min(frame_bits(m.arbitration_id, True, bytes(m.data))
                                           for m in got) + 1e-6
    # the frames really took wire time: 1,500 frames of ~130-160 bits at 250 kbit/s ≈ 0.8-1 s
    assert span >= (n - 1) * 120 / BITRATE
    assert (n - 1) / span > 0.5 * BITRATE / worst_case_frame_bits(True, 8)  # it keeps up
    print(f"\npaced 250 kbit/s: {(n - 1) / span:,.0f} frames/s on the wire stamps, "
          f"wall {wall:.2f} s")


def test_contended_frames_are_ordered_by_identifier() -> None:
    with SoftwareBus(port=0, bitrate=BITRATE) as softbus:
        a, b = open_bus(softbus.spec()), open_bus(softbus.spec())
        try:
            time.sleep(0.1)
            a.send(can.Message(arbitration_id=0x300, is_extended_id=False, data=bytes(8)))
            for _ in range(60):
                a.send(can.Message(arbitration_id=0x7F0, is_extended_id=False, data=bytes(8)))
            for can_id in (0x250, 0x100, 0x200):
                a.send(can.Message(arbitration_id=can_id, is_extended_id=False, data=bytes(8)))
            got = [m.arbitration_id for m in _drain(b, 64, timeout=10)]
        finally:
            a.shutdown()
            b.shutdown()
    assert len(got) == 64 and got[0] == 0x300
    i = got.index(0x100)
    # the three low ids overtake the queued 0x7F0 backlog, lowest first
    assert got[i:i + 3] == [0x100, 0x200, 0x250]
    assert i < 30, f"low ids waited behind {i - 1} backlog frames"
