"""The rig's tractor (TECU and TC) under a hostile or broken peer, in virtual time (issue 43,
items 1, 2, 3, 5 and 7): what each peer did used to stop the serve, feed the implement's record
with a stranger's values, serve the global address, grow the TC's log a line per frame, or take
the TC off the bus silently."""

from __future__ import annotations

import itertools

from hil.isobus import ddi
from hil.isobus import process_data as pd
from hil.isobus.ddop import ActivationError, ElementType, PoolError
from hil.isobus.ddop.samples import section_control_pool
from hil.isobus.name import IsobusName
from hil.isobus.process_data import Command, ElementCommand
from hil.isobus.tc import EventKind
from tests.hil.isobus.hostile import (
    IMPLEMENT,
    IMPLEMENT_ADDRESS,
    WSM,
    bench,
    frame,
    good_pool,
)
from tests.hil.isobus.peers import claim

OTHER = IsobusName(identity_number=10, manufacturer_code=300, function=130, device_class=5)


def _tecu_on_time(times: list[float], until_s: float) -> None:
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert gaps and max(gaps) < 0.1 + 1e-6 and times[-1] > until_s - 0.15, max(gaps)


def test_a_pool_the_tractor_cannot_use_is_refused_at_activation_and_nothing_else_stops() -> None:
    # a section without a working width follows every rule of ISO 11783-10's pool, but the
    # tractor cannot make a boom of it: it used to be activated and then end the serve
    broken = section_control_pool(sections=2, section_width_mm=0, name=OTHER.value)
    b = bench((good_pool(), IMPLEMENT, IMPLEMENT_ADDRESS), (broken, OTHER, 0x86))
    b.wire.run_until(8.0)
    good, refused = b.clients
    assert good.connected
    assert refused.refusal is not None and not refused.connected
    section = next(e for e in broken.elements if e.element_type == ElementType.SECTION)
    assert refused.refusal.activation_errors == ActivationError.ERRORS_IN_DDOP
    assert refused.refusal.pool_errors == PoolError.ANY_OTHER_ERROR
    assert (refused.refusal.object_id, refused.refusal.parent_id) == (section.object_id,
                                                                     section.parent_id)
    events = b.tractor.tc.events
    assert any(e.kind == EventKind.REFUSED and e.address == 0x86 and "working width" in e.detail
               for e in events)
    assert b.tractor.tc.event_counts[EventKind.CLIENT_ERROR] == 0
    _tecu_on_time(b.tecu_times(), 8.0)
    assert [v for v in b.tractor.tc.values if v.address == IMPLEMENT_ADDRESS
            and v.time_s > 7.0], "the good implement's values are still taken"


def test_a_session_belongs_to_a_name_a_newcomer_at_its_address_gets_nothing_of_it() -> None:
    # at 5 s another NAME (a lower one, so it wins) claims the implement's address and sends
    # values from it, 100 a second
    bin_element = next(e.element_number for e in good_pool().elements
                       if e.element_type == ElementType.BIN)
    value = pd.encode(ElementCommand(Command.VALUE, bin_element, ddi.ACTUAL_MASS_PER_AREA_RATE,
                                     99_999))
    script = [(5.0, claim(IMPLEMENT_ADDRESS, name=0x1000)),
              *[(5.3 + k * 0.01, frame(pd.PROCESS_DATA_PGN, value, IMPLEMENT_ADDRESS))
                for k in range(300)]]
    b = bench((good_pool(), IMPLEMENT, IMPLEMENT_ADDRESS), script=script, drive_after_s=2.0)
    b.wire.run_until(9.0)
    tc = b.tractor.tc
    ended = [e for e in tc.events if e.kind == EventKind.SESSION_ENDED]
    assert [(e.time_s, e.address) for e in ended] == [(5.0, IMPLEMENT_ADDRESS)]
    assert "0000000000001000 claimed 0x85" in ended[0].detail
    assert IMPLEMENT_ADDRESS not in tc.sessions
    assert not [v for v in tc.values if v.value == 99_999], "the newcomer's values recorded"
    setpoints = [m for t, m in b.to(IMPLEMENT_ADDRESS, since_s=5.0)
                 if isinstance(m, ElementCommand)]
    assert setpoints == [], "set-points sent to the newcomer"
    # its messages are rejected at a bounded rate: a count, not a line per frame
    rejected = [e for e in tc.events if e.kind == EventKind.REJECTED_MESSAGE]
    assert 1 <= len(rejected) <= 8
    assert sum(int(e.detail.split()[0]) for e in rejected if "more message" in e.detail) + \
        sum(1 for e in rejected if "more message" not in e.detail) == 300
    assert b.tractor.implement_address() is None
    record = b.tractor.as_applied()
    assert record is not None and len(record), "the implement's own record is kept"


def test_the_global_and_null_addresses_are_never_served() -> None:
    pool = good_pool().to_bytes()
    script = []
    for source in (0xFF, 0xFE):
        script += [(1.0, frame(pd.WORKING_SET_MASTER_PGN, WSM, source, 0xFF)),
                   (1.1, frame(pd.PROCESS_DATA_PGN, pd.encode(pd.RequestVersion()), source)),
                   (1.2, frame(pd.PROCESS_DATA_PGN, pd.encode(
                       pd.RequestObjectPoolTransfer(len(pool))), source)),
                   (1.3, frame(pd.PROCESS_DATA_PGN, pd.encode(pd.ObjectPoolActivate(True)),
                               source))]
    b = bench(script=script)
    b.wire.run_until(4.0)
    assert b.tractor.tc.sessions == {}
    to_everyone = [m for _, m in b.to(0xFF) if not isinstance(m, pd.TaskControllerStatus)]
    assert to_everyone == []
    assert b.tractor.network.dropped["source 0xFF"] == 4


def test_a_flood_from_addresses_without_a_session_is_logged_as_counts() -> None:
    # 20 addresses (never claimed) send 200 requests a second each for 5 s: 20,000 frames
    request = pd.encode(pd.RequestStructureLabel())
    script = [(1.0 + k * 0.005, frame(pd.PROCESS_DATA_PGN, request, 0x90 + a))
              for a in range(20) for k in range(1000)]
    b = bench(script=script)
    b.wire.run_until(7.0)
    tc = b.tractor.tc
    rejected = [e for e in tc.events if e.kind == EventKind.REJECTED_MESSAGE]
    # one line per address and second, and one count per address and second
    assert len(rejected) <= 20 * 6 * 2
    counted = sum(int(e.detail.split()[0]) for e in rejected if "more message" in e.detail)
    assert counted + sum(1 for e in rejected if "more message" not in e.detail) == 20_000
    nacks = [f for f in b.wire.frames
             if (f.frame.arbitration_id >> 8) & 0x3FF00 == 0xE800]
    assert len(nacks) <= 20 * 6
    _tecu_on_time(b.tecu_times(), 7.0)


def test_the_tc_that_loses_its_address_says_so_moves_and_its_client_follows() -> None:
    # at 4 s a NAME lower than the TC's claims 0xF7: the TC (self-configurable) moves to a free
    # address of 128-247 and says so; the implement finds it there by its status
    script = [(4.0, claim(0xF7, name=0x0000_0000_0000_0001))]
    b = bench((good_pool(), IMPLEMENT, IMPLEMENT_ADDRESS), script=script)
    b.wire.run_until(20.0)
    tc = b.tractor.tc
    moved_to = b.tractor.tc_function.address
    assert moved_to is not None and moved_to not in (0xF7, 0x80, IMPLEMENT_ADDRESS)
    assert 128 <= moved_to <= 247
    kinds = [(e.time_s, e.kind) for e in tc.events
             if e.kind in (EventKind.ADDRESS_LOST, EventKind.ADDRESS_CLAIMED)]
    assert kinds == [(0.25, EventKind.ADDRESS_CLAIMED), (4.0, EventKind.ADDRESS_LOST),
                     (4.25, EventKind.ADDRESS_CLAIMED)]
    lost = next(e for e in tc.events if e.kind == EventKind.ADDRESS_LOST)
    assert "lost 0xF7 to NAME 0000000000000001" in lost.detail
    assert any(e.kind == EventKind.SESSION_ENDED and e.time_s == 4.0 for e in tc.events)
    session = tc.sessions.get(IMPLEMENT_ADDRESS)
    assert session is not None and session.pool is not None and session.connected_s > 4.0
    assert b.clients[0].connected


def test_a_tc_that_claims_its_address_again_after_a_power_cycle_lost_nothing() -> None:
    # the rigs' tc_down fault: the TC's claim starts again; no one took 0xF7, so no "address
    # lost", and it holds 0xF7 again 250 ms later
    b = bench()
    b.wire.run_until(3.0)
    b.tractor.tc_function.claimer.start(3.0)
    b.wire.run_until(5.0)
    kinds = [(e.time_s, e.kind) for e in b.tractor.tc.events]
    assert kinds == [(0.25, EventKind.ADDRESS_CLAIMED), (3.25, EventKind.ADDRESS_CLAIMED)]
