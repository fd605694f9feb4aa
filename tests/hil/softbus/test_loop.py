"""The software bus's own event loop: readers, writers, timers, cross-thread wake-ups, and the
adaptive busy poll (which must cost nothing once traffic stops)."""

from __future__ import annotations

import socket
import threading
import time

import pytest

from hil.softbus.loop import READ, WRITE, BusyPoll, EventLoop


@pytest.fixture
def loop() -> EventLoop:
    ev = EventLoop()
    yield ev
    ev.close()


def test_readers_get_their_events_and_can_be_removed(loop: EventLoop) -> None:
    a, b = socket.socketpair()
    seen: list[int] = []
    loop.add(a.fileno(), READ, seen.append)
    assert loop.run_once(0.0) is False and seen == []
    b.send(b"x")
    assert loop.run_once(1.0) is True and seen == [READ]
    loop.set_events(a.fileno(), READ | WRITE)
    loop.run_once(0.0)
    assert seen[-1] == READ | WRITE
    loop.remove(a.fileno())
    seen.clear()
    assert loop.run_once(0.0) is False and seen == []
    a.close()
    b.close()


def test_timers_run_in_order_and_cancelled_ones_do_not(loop: EventLoop) -> None:
    ran: list[str] = []
    loop.call_later(0.02, ran.append, "late")
    loop.call_later(0.0, ran.append, "now")
    loop.call_later(0.01, ran.append, "cancelled").cancel()
    deadline = time.monotonic() + 2.0
    while len(ran) < 2 and time.monotonic() < deadline:
        loop.run_once(1.0)
    assert ran == ["now", "late"]


def test_a_blocked_loop_wakes_for_a_call_from_another_thread(loop: EventLoop) -> None:
    ran = threading.Event()
    threading.Timer(0.05, loop.call_soon_threadsafe, args=(ran.set,)).start()
    start = time.monotonic()
    loop.run_once(5.0)   # would block 5 s without the wake-up
    assert ran.is_set() and time.monotonic() - start < 2.0


def test_busy_poll_window_adapts_and_switches_off_when_traffic_stops() -> None:
    busy = BusyPoll(200.0)
    assert busy and busy.window_s == pytest.approx(50e-6)
    busy.woke(120e-6)                 # traffic 120 µs after the last: cover that gap
    assert busy.window_s == pytest.approx(150e-6)
    busy.woke(180e-6)
    assert busy.window_s == pytest.approx(200e-6)  # never beyond the limit
    busy.miss()
    busy.miss()
    assert busy.window_s == pytest.approx(50e-6)
    busy.miss()
    assert busy.window_s == 0.0       # off: the loop blocks at once
    busy.woke(5.0)                    # a long gap keeps it off
    assert busy.window_s == 0.0
    assert not BusyPoll(0.0)


def test_busy_poll_spins_after_traffic_then_sleeps() -> None:
    spinning = EventLoop(busy_poll_us=2000.0)
    a, b = socket.socketpair()
    got: list[bytes] = []
    spinning.add(a.fileno(), READ, lambda _ev: got.append(a.recv(100)))
    try:
        b.send(b"1")
        spinning.run_once(1.0)       # the first traffic after a long quiet: no spin
        assert got == [b"1"] and spinning.busy_poll.spins == 0
        b.send(b"2")                 # then traffic close behind: the loop spins after it
        spinning.run_once(1.0)
        assert got == [b"1", b"2"] and spinning.busy_poll.spins == 1
        # no more traffic: the spin ran out, the window shrank; an idle bus costs no CPU
        cpu0 = time.thread_time()
        assert spinning.run_once(0.2) is False
        assert time.thread_time() - cpu0 < 0.05
    finally:
        spinning.close()
        a.close()
        b.close()


def test_traffic_during_a_spin_is_handled_by_it() -> None:
    spinning = EventLoop(busy_poll_us=200_000.0)  # a wide window: robust on a loaded machine
    a, b = socket.socketpair()
    got: list[bytes] = []

    def on_read(_ev: int) -> None:
        got.append(a.recv(100))
        if got == [b"y"]:   # the request handled: its reply comes 2 ms later, during the spin
            threading.Timer(0.002, b.send, args=(b"z",)).start()

    spinning.add(a.fileno(), READ, on_read)
    try:
        spinning.busy_poll.window_s = spinning.busy_poll.limit_s
        # the reply's timer starts from the handler, not beside the request: on a loaded
        # machine a timer started before the request was sent could send first ("zy")
        b.send(b"y")
        spinning.run_once(1.0)
        assert b"".join(got) == b"yz" and spinning.busy_poll.hits == 1
    finally:
        spinning.close()
        a.close()
        b.close()
