"""Fuzzing the rig's tractor (TECU and TC) and its ISOBUS network layer from a peer's side
(issue 43): claims, TP/ETP sequences, DDOP bytes over TP/ETP, process data at high rates, from
any address. Whatever the peer sends, no client's input raises inside the TC, no session is
served to 0xFE/0xFF or outlives its NAME, transport sessions stay within their bounds, the
TECU's speeds keep their 100 ms in run time, the TC's status its 2 s, and memory stays bounded.

The default run takes a few seconds; ``-m slow`` adds the longer forms (more examples, a
minute of run time under a flood with tracemalloc)."""

from __future__ import annotations

import tracemalloc

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.isobus import ddi
from hil.isobus import process_data as pd
from hil.isobus.can_id import make_frame
from hil.isobus.ddop.samples import section_control_pool
from hil.isobus.process_data import Command, ElementCommand
from hil.isobus.tc import EventKind
from hil.isobus.tp_messages import PGN_TP_CM, CmFrame, Control, encode_cm
from tests.fuzz.isobus_peer import (
    PEER_NAMES,
    SAMPLE_POOL,
    build,
    check_invariants,
    connection,
    group,
    raw_frame,
)

RUN_S = 4.0
times = st.floats(0.3, RUN_S - 0.3, allow_nan=False).map(lambda t: round(t, 3))


@st.composite
def scenario(draw: st.DrawFn, max_raw: int = 40, max_groups: int = 10):
    raw = draw(st.lists(st.tuples(times, raw_frame()), max_size=max_raw))
    groups = [(t, *g) for t, g in draw(st.lists(st.tuples(times, group()),
                                                 max_size=max_groups))]
    if draw(st.booleans()):       # a whole connection, so activation and set-points are fuzzed
        groups += connection(0x92, draw(times), SAMPLE_POOL)
    burst = draw(st.integers(0, 3))
    if burst:                     # values at a high rate, 1 ms apart, from a claimed peer
        t0 = draw(times)
        value = pd.encode(ElementCommand(Command.VALUE, 3, ddi.ACTUAL_MASS_PER_AREA_RATE, 7))
        raw += [(round(t0 + k * 0.001, 4), make_frame(5, pd.PROCESS_DATA_PGN, 0x92, 0xF7, value))
                for k in range(burst * 100)]
    return raw, groups


def _run(raw, groups, until_s: float = RUN_S):
    peer = build(raw, groups)
    peer.wire.run_until(until_s)
    check_invariants(peer, until_s)
    return peer


@settings(max_examples=12)
@given(scenario())
def test_whatever_a_peer_sends_the_tractor_keeps_its_invariants(case) -> None:
    raw, groups = case
    _run(raw, groups)


@pytest.mark.slow
@settings(max_examples=300)
@given(scenario(max_raw=150, max_groups=30))
def test_whatever_a_peer_sends_the_tractor_keeps_its_invariants_long(case) -> None:
    raw, groups = case
    _run(raw, groups, until_s=RUN_S)


def test_a_good_client_connects_through_the_fuzz_peer_and_its_pool_is_activated() -> None:
    # the fuzz's own connection works when nothing else happens: the invariants are checked
    # on a run where the TC really activates a pool and sends set-points
    peer = _run([], connection(0x92, 0.5, SAMPLE_POOL), until_s=4.0)
    assert peer.tractor.tc.sessions[0x92].pool is not None
    assert peer.tractor.tc.event_counts[EventKind.ACTIVATED] == 1


def test_the_invariants_fail_a_tractor_that_breaks_them() -> None:
    # the checks can fail: a session for the global address, a stranger's session, a TECU
    # that paused, a client error, each makes them raise
    def broken(change) -> None:
        peer = build([], connection(0x92, 0.5, SAMPLE_POOL))
        peer.wire.run_until(3.0)
        check_invariants(peer, 3.0)
        change(peer)
        with pytest.raises(AssertionError):
            check_invariants(peer, 3.0)

    def global_session(peer) -> None:
        tc = peer.tractor.tc
        tc.sessions[0xFF] = tc.sessions[0x92]

    def strangers_session(peer) -> None:
        peer.tractor.network.table.on_claim(0x92, 1)     # another NAME holds 0x92 now

    def tecu_pause(peer) -> None:
        peer.wire.frames[:] = [f for f in peer.wire.frames if not 1.0 < f.time_s < 1.5]

    def client_error(peer) -> None:
        peer.tractor.tc.end_session(0x92, 3.0, "a bug")

    for change in (global_session, strangers_session, tecu_pause, client_error):
        broken(change)


def _flood(until_s: float):
    """A connected client sending 5,000 values a second, 20 unclaimed addresses sending
    process data and opening TP sessions 500 times a second in all, for ``until_s`` of run
    time; the TC recording as the serve has it (to a recorder, not memory)."""
    value = pd.encode(ElementCommand(Command.VALUE, 3, ddi.ACTUAL_MASS_PER_AREA_RATE, 7))
    rts = encode_cm(CmFrame(Control.RTS, 0xCB00, size=20, packets=3, max_per_cts=255))
    request = pd.encode(pd.RequestStructureLabel())
    raw = []
    n = int((until_s - 2.0) * 1000)
    for k in range(n):
        t = round(2.0 + k * 0.001, 4)
        raw += [(t, make_frame(5, pd.PROCESS_DATA_PGN, 0x92, 0xF7, value)) for _ in range(5)]
        if k % 2 == 0:
            a = 0xA0 + (k // 2) % 20
            raw.append((t, make_frame(5, pd.PROCESS_DATA_PGN, a, 0xF7, request)))
            raw.append((t, make_frame(7, PGN_TP_CM, a, 0xF7, rts)))
    task = pd.encode(pd.ClientTask(True))      # the client keeps its session alive
    raw += [(2.0 * k + 0.1, make_frame(5, pd.PROCESS_DATA_PGN, 0x92, 0xF7, task))
            for k in range(int(until_s / 2.0) + 1)]
    peer = build(raw, connection(0x92, 0.3, SAMPLE_POOL))
    peer.tractor.tc.keep_records = False
    peer.tractor.tc.recorder = lambda record: None     # the serve writes them to tc.jsonl
    return peer


def _memory_growth(until_s: float, warm_s: float) -> tuple[int, object]:
    """What the rig's objects grew by (tracemalloc) between ``warm_s`` (the network's frame
    log of its last 2,000 frames full, 0.3 s into the flood) and ``until_s``."""
    peer = _flood(until_s)
    peer.wire.run_until(warm_s)
    tracemalloc.start()
    try:
        before = tracemalloc.take_snapshot()
        peer.wire.frames.clear()
        peer.raw.heard.clear()
        peer.wire.run_until(until_s)
        peer.wire.frames.clear()       # the test's own wire keeps every frame: not the rig's
        peer.raw.heard.clear()
        after = tracemalloc.take_snapshot()
    finally:
        tracemalloc.stop()
    growth = sum(s.size_diff for s in after.compare_to(before, "filename"))
    return growth, peer


def test_memory_stays_bounded_under_a_flood_of_values_and_unsolicited_traffic() -> None:
    growth, peer = _memory_growth(until_s=3.4, warm_s=2.6)
    tc = peer.tractor.tc
    assert tc.counts["values"] >= 7_000, tc.counts    # the flood reached the TC
    assert tc.values == [] and len(tc.events) == 0
    assert growth < 128 * 1024, f"{growth} bytes more after 0.8 s of flood"


@pytest.mark.slow
def test_memory_stays_bounded_under_a_minute_of_flood() -> None:
    growth, peer = _memory_growth(until_s=34.0, warm_s=4.0)
    assert peer.tractor.tc.counts["values"] >= 150_000
    assert growth < 128 * 1024, f"{growth} bytes more after 30 s of flood"


def test_a_ddop_transfer_of_any_size_is_bounded_by_the_tcs_memory() -> None:
    # an ETP RTS announcing more than the TC takes is refused at once, nothing kept
    big = section_control_pool(sections=1, name=PEER_NAMES[0x92].value).to_bytes()
    peer = _run([], [(0.5, 0x92, pd.PROCESS_DATA_PGN, pd.encode(pd.ObjectPoolTransfer(
        big * 20_000)), 0xF7)], until_s=2.0)
    refused = [e for e in peer.tractor.network.transport.events if e.kind == "refused"]
    assert refused and "at most" in refused[-1].detail
