"""Fuzzing the rig's VT from a peer's side on the real network layer (issue 39's "VT command
handling not fuzzed from a peer's side"): claims, TP/ETP frames of any content from any address,
working set messages in any order (commands before or without a pool, pools of any bytes or
past the VT's memory, pools the VT cannot draw, store/load/delete version with hostile labels,
macros), two working sets at once beside a well-behaved implement. Whatever the peer sends,
nothing raises inside the VT, no working set is served to 0xFE/0xFF or outlives its NAME, the
VT status keeps its second and the TECU its 100 ms in run time, the good implement connects,
and memory and the version store stay bounded (:func:`hostile_vt.check_vt`).

The default run takes a few seconds; ``-m slow`` adds the longer forms (more examples, 30 s of
run time under a flood with tracemalloc)."""

from __future__ import annotations

import gc
import tracemalloc

import can
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hil.isobus.can_id import make_frame
from hil.isobus.port import GLOBAL_ADDRESS
from hil.isobus.tp_messages import (
    PGN_ADDRESS_CLAIMED,
    PGN_ETP_CM,
    PGN_ETP_DT,
    PGN_REQUEST,
    PGN_TP_CM,
    PGN_TP_DT,
    Control,
)
from hil.isobus.vt import server as vt_server
from hil.isobus.vt.bench import IMPLEMENT_ADDRESS
from hil.isobus.vt.builder import PoolBuilder
from hil.isobus.vt.codec import serialise_object
from hil.isobus.vt.messages import ECU_TO_VT_PGN, WORKING_SET_MASTER_PGN, Function, pad, u16
from hil.isobus.vt.samples import large_pool
from hil.isobus.vt.server import VT_ADDRESS, VtOptions
from tests.fuzz.isobus_peer import _mutated

from .hostile_vt import (
    END_OF_POOL,
    PEER_NAMES,
    build,
    change_numeric,
    check_vt,
    connection,
    delete_version,
    get_memory,
    keep_alive,
    load_version,
    maintenance,
    raw_vt,
    store_version,
    took_over,
    transfer,
)
from .pools import IDS, implement_pool

RUN_S = 5.0
SAMPLE_POOL = implement_pool().to_bytes()
BIG_POOL = large_pool(30_000).to_bytes()
SOURCES = [IMPLEMENT_ADDRESS, VT_ADDRESS, 0x90, 0x92, 0x93, 0xFE, 0xFF]
DESTINATIONS = [VT_ADDRESS, GLOBAL_ADDRESS, IMPLEMENT_ADDRESS, 0x92]
HOSTILE_LABELS = [b"../../x", b"/etc/pa", b"..\\..\\a", b"\x00" * 7, b"*", b"GOOD", b"V1",
                  b"../" * 10 + b"..", b"\xff" * 32]
times = st.floats(0.3, RUN_S - 0.3, allow_nan=False).map(lambda t: round(t, 3))


def _serialised(builder: PoolBuilder) -> bytes:
    return b"".join(serialise_object(o) for o in builder.objects)


def _cyclic_pool() -> bytes:
    b = PoolBuilder()
    text = b.output_string("x", font=b.font())
    box = b.container([(text, 0, 0), (500, 0, 0), (500, 1, 1)], 50, 50, object_id=500)
    b.working_set(b.data_mask([(box, 0, 0)]))
    return _serialised(b)


def _fan_pool(levels: int) -> bytes:
    b = PoolBuilder()
    inner = b.output_string("x", font=b.font())
    for _ in range(levels):
        inner = b.container([(inner, 0, 0), (inner, 1, 1)], 50, 50)
    b.working_set(b.data_mask([(inner, 0, 0)]))
    return _serialised(b)


def _macro_pool(fan: int) -> bytes:
    b = PoolBuilder()
    b.macro(pad([Function.EXECUTE_MACRO, 7]) * fan, object_id=7)
    b.working_set(b.data_mask([(b.output_string("x", font=b.font()), 0, 0)]))
    return _serialised(b)


ADVERSARIAL_POOLS = [_cyclic_pool(), _fan_pool(24), _macro_pool(4), BIG_POOL]


@st.composite
def pool_bytes(draw: st.DrawFn) -> bytes:
    """A pool's bytes: the sample mutated, one the VT cannot draw, a big one, noise."""
    kind = draw(st.integers(0, 3))
    if kind == 0:
        return _mutated(SAMPLE_POOL, draw)
    if kind == 1:
        return draw(st.sampled_from(ADVERSARIAL_POOLS))
    if kind == 2:
        return SAMPLE_POOL
    return draw(st.binary(min_size=1, max_size=300))


@st.composite
def vt_message(draw: st.DrawFn) -> bytes:
    """A message a working set could send the VT, right or wrong."""
    kind = draw(st.integers(0, 8))
    if kind == 0:
        return maintenance(draw(st.booleans()), draw(st.integers(0, 255)))
    if kind == 1:
        return get_memory(draw(st.integers(0, 2**32 - 1)))
    if kind == 2:
        return transfer(draw(pool_bytes()))
    if kind == 3:
        return END_OF_POOL
    if kind == 4:
        label = draw(st.sampled_from(HOSTILE_LABELS) | st.binary(max_size=32))
        make = draw(st.sampled_from([store_version, load_version, delete_version]))
        return make(label, draw(st.booleans()))
    if kind == 5:
        oid = draw(st.sampled_from([IDS.rate_var, IDS.home, IDS.box, IDS.cal_in, 7, 500,
                                    0xFFFF]) | st.integers(0, 0xFFFF))
        return change_numeric(oid, draw(st.integers(0, 2**32 - 1)))
    if kind == 6:
        return pad([Function.EXECUTE_MACRO, draw(st.sampled_from([7, IDS.macro, 0]))])
    if kind == 7:
        function = draw(st.integers(0xA0, 0xBF))
        return bytes([function]) + draw(st.binary(min_size=7, max_size=12))
    function = draw(st.sampled_from([int(f) for f in Function]) | st.integers(0, 255))
    return bytes([function]) + draw(st.binary(max_size=40))


@st.composite
def raw_frame(draw: st.DrawFn) -> can.Message:
    """One frame from any address: a claim, TP/ETP connection management or data, a VT
    message, a working set master, a request."""
    source = draw(st.sampled_from(SOURCES) | st.integers(0, 255))
    destination = draw(st.sampled_from(DESTINATIONS))
    kind = draw(st.integers(0, 5))
    if kind == 0:
        name = draw(st.sampled_from([0, 1, PEER_NAMES[0x92].value]) | st.integers(0, 2**64 - 1))
        return make_frame(6, PGN_ADDRESS_CLAIMED, source, GLOBAL_ADDRESS,
                          name.to_bytes(8, "little"))
    if kind == 1:
        data = bytes([draw(st.sampled_from([int(c) for c in Control]))]) + draw(
            st.binary(min_size=7, max_size=7))
        return make_frame(7, draw(st.sampled_from([PGN_TP_CM, PGN_ETP_CM])), source,
                          destination, data)
    if kind == 2:
        return make_frame(7, draw(st.sampled_from([PGN_TP_DT, PGN_ETP_DT])), source,
                          destination, draw(st.binary(min_size=1, max_size=8)))
    if kind == 3:
        return raw_vt(source, draw(vt_message()), destination)
    if kind == 4:
        return make_frame(6, WORKING_SET_MASTER_PGN, source, GLOBAL_ADDRESS,
                          draw(st.binary(max_size=8)))
    pgn = draw(st.sampled_from([PGN_ADDRESS_CLAIMED, 0xFE0D, 0xE600]))
    return make_frame(6, PGN_REQUEST, source, destination, pgn.to_bytes(3, "little"))


@st.composite
def scenario(draw: st.DrawFn, max_raw: int = 30, max_groups: int = 12):
    raw = draw(st.lists(st.tuples(times, raw_frame()), max_size=max_raw))
    groups = []
    for t, message in draw(st.lists(st.tuples(times, vt_message()), max_size=max_groups)):
        source = draw(st.sampled_from(sorted(PEER_NAMES)))
        groups.append((t, source, ECU_TO_VT_PGN, message, VT_ADDRESS))
    for source in sorted(PEER_NAMES):
        if draw(st.booleans()):     # a whole connection, so commands meet an active pool
            label = draw(st.sampled_from([None, *HOSTILE_LABELS[:4]]))
            groups += connection(source, draw(times), draw(pool_bytes()), label)
            groups += keep_alive(source, 1.0, RUN_S)
    return raw, groups


def _run(raw, groups, until_s: float = RUN_S, **kwargs):
    bench = build(raw, groups, **kwargs)
    bench.wire.run_until(until_s)
    spoofed = any(f.arbitration_id & 0xFF in (IMPLEMENT_ADDRESS, VT_ADDRESS) for _, f in raw)
    check_vt(bench, until_s, good_connects=not spoofed
             and not took_over(raw, IMPLEMENT_ADDRESS, VT_ADDRESS))
    return bench


@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenario())
def test_whatever_a_peer_sends_the_vt_keeps_its_invariants(case) -> None:
    raw, groups = case
    _run(raw, groups)


@pytest.mark.slow
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=scenario(max_raw=120, max_groups=40))
def test_whatever_a_peer_sends_the_vt_keeps_its_invariants_long(tmp_path_factory, case) -> None:
    raw, groups = case
    from hil.isobus.vt.store import VersionStore
    store = VersionStore(tmp_path_factory.mktemp("vt-store") / "store")
    _run(raw, groups, store=store, options=VtOptions(store_max_versions_per_name=4,
                                                     memory_bytes=200_000))


def test_each_adversarial_pool_from_a_connected_peer_keeps_the_invariants() -> None:
    # the fuzz's hardest pools, each uploaded for certain, beside the good implement
    groups = []
    for k, pool in enumerate(ADVERSARIAL_POOLS[:3]):
        source = 0x92 if k % 2 == 0 else 0x93
        groups += connection(source, 0.3 + 1.5 * k, pool, b"ADV%d" % k)
    groups += keep_alive(0x92, 1.0, 6.0) + keep_alive(0x93, 1.0, 6.0)
    groups.append((5.0, 0x92, ECU_TO_VT_PGN, pad([Function.EXECUTE_MACRO, 7]), VT_ADDRESS))
    bench = _run([], groups, until_s=6.0)
    assert bench.vt.counts["event refused"] >= 2      # the cyclic and the fanned-out pools


def _flood(until_s: float):
    """A connected working set sending 1,000 commands a second (values of an object not on
    its shown mask, so no screen is drawn for them), 50 version stores a second, and 20
    addresses that never claimed sending 500 messages a second in all, for ``until_s``."""
    value = change_numeric(IDS.cal_var, 7)
    raw = []
    groups = connection(0x92, 0.3, SAMPLE_POOL, b"FLOOD") + keep_alive(0x92, 1.0, until_s)
    n = int((until_s - 2.0) * 1000)
    for k in range(n):
        t = round(2.0 + k * 0.001, 4)
        groups.append((t, 0x92, ECU_TO_VT_PGN, value, VT_ADDRESS))
        if k % 20 == 0:
            label = b"S%d" % (k // 20 % 40)
            groups.append((t, 0x92, ECU_TO_VT_PGN, store_version(label), VT_ADDRESS))
        if k % 2 == 0:
            a = 0xA0 + (k // 2) % 20
            raw.append((t, raw_vt(a, change_numeric(1, k))))
    return build(raw, groups, options=VtOptions(store_max_versions_per_name=8),
                 log_frames=300, good=False)


def _memory_growth(until_s: float, warm_s: float, trace_s: float):
    """What the rig's objects grew by (tracemalloc) between ``warm_s`` (the VT's records and
    the network's frame log full) and ``until_s``, traced from ``trace_s`` (so that what the
    bounded records drop after ``warm_s`` counts against what they take)."""
    bench = _flood(until_s)
    bench.wire.run_until(trace_s)
    bench.wire.frames.clear()      # the test's own wire keeps every frame: not the rig's
    bench.raw.heard.clear()
    tracemalloc.start()
    try:
        bench.wire.run_until(warm_s)
        bench.wire.frames.clear()
        bench.raw.heard.clear()
        gc.collect()            # a full collection empties the free lists tracemalloc counts
        before = tracemalloc.take_snapshot()
        bench.wire.run_until(until_s)
        bench.wire.frames.clear()
        bench.raw.heard.clear()
        gc.collect()
        after = tracemalloc.take_snapshot()
    finally:
        tracemalloc.stop()
    growth = sum(s.size_diff for s in after.compare_to(before, "filename"))
    return growth, bench


def test_memory_stays_bounded_under_a_flood_of_commands_stores_and_strangers(monkeypatch,
                                                                            ) -> None:
    # the VT's records kept short, so that they are full before the measurement starts (the
    # slow form measures with the VT's own bounds)
    monkeypatch.setattr(vt_server, "COMMANDS_KEPT", 100)
    monkeypatch.setattr(vt_server, "EVENTS_KEPT", 20)
    growth, bench = _memory_growth(until_s=2.85, warm_s=2.6, trace_s=2.4)
    vt = bench.vt
    assert vt.counts["commands"] >= 800 and vt.counts["rejected"] >= 400, vt.counts
    assert vt.counts["event store refused"] >= 30, vt.counts
    assert len(vt.events) <= 20 and len(vt.commands) <= 100
    assert growth < 32 * 1024, f"{growth} bytes more after 0.25 s of flood"


@pytest.mark.slow
def test_memory_stays_bounded_under_20_s_of_flood(monkeypatch) -> None:
    # the VT's own bounds but for its events (2,000 take ~40 s of this flood to fill)
    monkeypatch.setattr(vt_server, "EVENTS_KEPT", 400)
    growth, bench = _memory_growth(until_s=34.0, warm_s=14.0, trace_s=6.0)
    assert bench.vt.counts["commands"] >= 31_000 and len(bench.vt.commands) <= 5_000
    assert bench.store.count <= 8 and len(bench.vt.events) <= 400
    assert growth < 128 * 1024, f"{growth} bytes more after 20 s of flood"


def test_etp_transfers_cut_short_or_from_an_unclaimed_address_leave_no_trace() -> None:
    # ETP RTS and 2 data packets of 5,000 bytes from the claimed peer, then nothing; the same
    # from an address that never claimed: nothing reaches the VT (the first times out, the
    # second is not answered), and the good implement's pool goes through
    from hil.isobus.tp_messages import CmFrame, encode_cm
    rts = encode_cm(CmFrame(Control.ETP_RTS, ECU_TO_VT_PGN, size=5_000, packets=0,
                            max_per_cts=255))
    raw = []
    for source, t0 in ((0x92, 0.6), (0x97, 0.8)):
        raw.append((t0, make_frame(7, PGN_ETP_CM, source, VT_ADDRESS, rts)))
        raw += [(t0 + 0.05 + k * 0.01, make_frame(7, PGN_ETP_DT, source, VT_ADDRESS,
                                                  bytes([k + 1]) + b"\x11" * 7))
                for k in range(2)]
    b = build(raw, [(0.5, 0x92, ECU_TO_VT_PGN, maintenance(True), VT_ADDRESS),
                    *keep_alive(0x92, 1.0, 5.0)])
    b.wire.run_until(5.0)
    assert 0x97 not in b.vt.sessions and b.vt.sessions[0x92].transfers == []
    assert b.vt.counts["event transferred"] == 2      # the good implement's two transfers
    check_vt(b, 5.0)


@pytest.mark.slow
def test_two_hostile_working_sets_and_the_good_one_at_once() -> None:
    groups = (connection(0x92, 0.4, SAMPLE_POOL, b"A") + connection(0x93, 0.45, BIG_POOL, b"B")
              + keep_alive(0x92, 1.0, 8.0) + keep_alive(0x93, 1.0, 8.0))
    groups += [(4.0 + k * 0.01, 0x92 + k % 2, ECU_TO_VT_PGN,
                pad(bytes([Function.HIDE_SHOW]) + u16(IDS.box) + bytes([k % 2])), VT_ADDRESS)
               for k in range(200)]
    bench = _run([], groups, until_s=8.0)
    assert {a for a, ws in bench.vt.sessions.items() if ws.pool is not None} == {
        0x92, 0x93, IMPLEMENT_ADDRESS}
