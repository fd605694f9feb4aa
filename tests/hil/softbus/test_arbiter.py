from __future__ import annotations

import itertools

import pytest

from hil.softbus.arbiter import Arbiter
from hil.softbus.timing import frame_bits

BITRATE = 250_000


def _offer(arb: Arbiter, can_id: int, ready: float, extended: bool = False) -> None:
    arb.offer(can_id, can_id=can_id, extended=extended, data=bytes(8), ready=ready)


def test_contending_frames_go_out_lowest_id_first() -> None:
    arb: Arbiter[int] = Arbiter(BITRATE)
    _offer(arb, 0x300, 0.0)           # takes the idle wire at once
    for can_id in (0x250, 0x100, 0x200, 0x050):
        _offer(arb, can_id, 1e-5)     # all ready while 0x300 is on the wire
    order = [tx.payload for tx in arb.due(1.0)]
    assert order == [0x300, 0x050, 0x100, 0x200, 0x250]


def test_frames_hold_the_wire_for_their_bit_time_back_to_back() -> None:
    arb: Arbiter[int] = Arbiter(BITRATE)
    for i in range(10):
        _offer(arb, 0x100 + i, 0.0)
    txs = arb.due(10.0)
    for prev, cur in itertools.pairwise(txs):
        assert cur.start == prev.end
    for tx in txs:
        assert tx.end - tx.start == pytest.approx(frame_bits(tx.payload, False, bytes(8)) / BITRATE)


def test_a_late_lower_id_does_not_preempt_an_earlier_slot() -> None:
    arb: Arbiter[int] = Arbiter(BITRATE)
    _offer(arb, 0x300, 0.0)
    _offer(arb, 0x200, 0.0001)        # waits for 0x300
    _offer(arb, 0x001, 10.0)          # arrives long after both went out
    assert [tx.payload for tx in arb.due(100.0)] == [0x300, 0x200, 0x001]


def test_lazy_polling_gives_the_same_schedule() -> None:
    eager: Arbiter[int] = Arbiter(BITRATE)
    lazy: Arbiter[int] = Arbiter(BITRATE)
    arrivals = [(0x10 * (i % 7) + 1, i * 0.0003) for i in range(50)]
    eager_out = []
    for can_id, ready in arrivals:
        eager_out += eager.due(ready)
        _offer(eager, can_id, ready)
        _offer(lazy, can_id, ready)
    eager_out += eager.due(1.0)
    lazy_out = lazy.due(1.0)
    assert [(t.payload, t.start) for t in eager_out] == [(t.payload, t.start) for t in lazy_out]


def test_queue_is_bounded() -> None:
    arb: Arbiter[int] = Arbiter(BITRATE, max_pending=3)
    assert all(arb.offer(i, can_id=i, extended=False, data=b"", ready=0.0) for i in range(3))
    assert not arb.offer(9, can_id=9, extended=False, data=b"", ready=0.0)
    assert arb.overflows == 1
