"""The software bus's event loop: a poller over file descriptors, timers, and a wake-up channel.

Why not asyncio (which the server used before): the bus does one thing per event (read a
socket, hand the frames on) and asyncio's machinery around it (handles, the ready queue, the
selector's key objects, transports) cost the server ~15 µs of CPU per round trip of the
latency benchmark (asyncio 107-122, this loop 90-95 µs, both dominated by the kernel's TCP and
wake-up work). Owning the loop also lets the bus do what asyncio cannot: bounded busy polling
after traffic (:attr:`EventLoop.busy_poll`), and being driven from another thread, one step at
a time, by a client that lives in the same process (:meth:`EventLoop.run_once`).

The loop is not thread-safe by itself: one thread at a time runs it (the server's ownership
lock sees to that); :meth:`call_soon_threadsafe` and :meth:`wake` may be called from anywhere.
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import os
import select
import socket
import time
from collections import deque
from collections.abc import Callable
from typing import Any

READ = 1
WRITE = 4
Handler = Callable[[int], None]


class _Poller:
    """epoll where there is one (Linux), poll() elsewhere: same calls, timeout in seconds."""

    def __init__(self) -> None:
        self._epoll = getattr(select, "epoll", None)
        if self._epoll is not None:
            self._p: Any = self._epoll()
            self._in, self._out = select.EPOLLIN, select.EPOLLOUT
            self._err = select.EPOLLERR | select.EPOLLHUP
        else:  # pragma: no cover - macOS and the BSDs
            self._p = select.poll()
            self._in, self._out = select.POLLIN, select.POLLOUT
            self._err = select.POLLERR | select.POLLHUP

    def _mask(self, events: int) -> int:
        return (self._in if events & READ else 0) | (self._out if events & WRITE else 0)

    def register(self, fd: int, events: int) -> None:
        self._p.register(fd, self._mask(events))

    def modify(self, fd: int, events: int) -> None:
        self._p.modify(fd, self._mask(events))

    def unregister(self, fd: int) -> None:
        with contextlib.suppress(KeyError, OSError, ValueError):
            self._p.unregister(fd)

    def poll(self, timeout: float | None) -> list[tuple[int, int]]:
        """Ready (fd, READ|WRITE) pairs; an error or hang-up counts as readable (the read
        then sees it)."""
        if self._epoll is not None:
            raw = self._p.poll(-1 if timeout is None else timeout)
        else:  # pragma: no cover
            raw = self._p.poll(None if timeout is None else timeout * 1000)
        if not raw:
            return []
        rd, wr, err = self._in | self._err, self._out, self._err
        return [(fd, (READ if ev & rd else 0) | (WRITE if ev & wr and not ev & err else 0))
                for fd, ev in raw]

    def close(self) -> None:
        if self._epoll is not None:
            self._p.close()


class Timer:
    """A callback due at a monotonic time; :meth:`cancel` before it runs to drop it."""

    __slots__ = ("args", "callback", "cancelled", "when")

    def __init__(self, when: float, callback: Callable[..., Any], args: tuple[Any, ...]) -> None:
        self.when = when
        self.callback = callback
        self.args = args
        self.cancelled = False

    def cancel(self) -> None:
        self.cancelled = True


class BusyPoll:
    """Bounded, adaptive busy polling: after traffic, keep polling without blocking for up to
    ``window_s`` before going to sleep, so that the next frame finds the loop awake.

    The window adapts, in the manner of Linux's guest halt polling: when the loop slept and
    was woken by traffic that came within ``limit_s`` of the previous traffic, the window
    grows to cover that gap (a quarter more, at least double, at most ``limit_s``); when the
    gap was longer than the limit, or a spin caught nothing, it halves, and below ``start_s``
    it is off. An idle bus therefore costs no CPU: after the last frame the loop spins at most
    ``limit_s``, then sleeps. Every spin gives the CPU away (``sched_yield``) between polls,
    so a process that shares the vCPU with the loop runs instead of waiting for the spin's end.
    """

    def __init__(self, limit_us: float, *, start_us: float | None = None) -> None:
        self.limit_s = max(0.0, limit_us) / 1e6
        self.start_s = min(self.limit_s, (start_us if start_us is not None
                                          else limit_us / 4) / 1e6)
        self.window_s = self.start_s
        self.spins = 0
        self.hits = 0
        self.spin_s = 0.0

    def __bool__(self) -> bool:
        return self.limit_s > 0.0

    def hit(self) -> None:
        """A spin caught traffic."""
        self.hits += 1

    def miss(self) -> None:
        """A spin ran its whole window without traffic: halve it (below start: off)."""
        half = self.window_s / 2
        self.window_s = half if half >= self.start_s else 0.0

    def woke(self, gap_s: float) -> None:
        """The loop slept and traffic woke it ``gap_s`` after the previous traffic."""
        if gap_s <= self.limit_s:
            self.window_s = min(self.limit_s,
                                max(self.start_s, self.window_s * 2, gap_s * 1.25))
        else:
            self.miss()

    def stats(self) -> dict[str, float]:
        return {"limit_us": self.limit_s * 1e6, "window_us": round(self.window_s * 1e6, 1),
                "spins": self.spins, "hits": self.hits, "spin_s": round(self.spin_s, 6)}


#: give the CPU to another runnable task on this vCPU, if any (a no-op where unsupported)
sched_yield: Callable[[], None] = getattr(os, "sched_yield", lambda: None)


class EventLoop:
    """Readers and writers by fd, timers, thread-safe wake-ups, optional busy polling."""

    def __init__(self, *, busy_poll_us: float = 0.0) -> None:
        self._poller = _Poller()
        self._handlers: dict[int, Handler] = {}
        self._interest: dict[int, int] = {}
        self._timers: list[tuple[float, int, Timer]] = []
        self._seq = itertools.count()
        self._threadsafe: deque[Callable[[], Any]] = deque()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._wake_pending = False
        self.add(self._wake_r.fileno(), READ, self._on_wake)
        self.busy_poll = BusyPoll(busy_poll_us)
        self._last_traffic = 0.0  # perf_counter of the last socket traffic (busy polling)
        self.closed = False

    # registration --------------------------------------------------------------------------
    def add(self, fd: int, events: int, handler: Handler) -> None:
        self._handlers[fd] = handler
        self._interest[fd] = events
        self._poller.register(fd, events)

    def set_events(self, fd: int, events: int) -> None:
        if self._interest.get(fd) != events and fd in self._handlers:
            self._interest[fd] = events
            self._poller.modify(fd, events)

    def remove(self, fd: int) -> None:
        if self._handlers.pop(fd, None) is not None:
            self._interest.pop(fd, None)
            self._poller.unregister(fd)

    # timers and cross-thread calls ---------------------------------------------------------
    def call_later(self, delay: float, callback: Callable[..., Any], *args: Any) -> Timer:
        timer = Timer(time.monotonic() + max(0.0, delay), callback, args)
        heapq.heappush(self._timers, (timer.when, next(self._seq), timer))
        return timer

    def call_soon_threadsafe(self, callback: Callable[[], Any]) -> None:
        self._threadsafe.append(callback)
        self.wake()

    def has_threadsafe_calls(self) -> bool:
        return bool(self._threadsafe)

    def wake(self) -> None:
        """Make a :meth:`run_once` that blocks in the poller return (from any thread)."""
        if not self._wake_pending:
            self._wake_pending = True
            with contextlib.suppress(OSError):  # full: a wake-up is pending anyway
                self._wake_w.send(b"\0")

    def _on_wake(self, _events: int) -> None:
        self._wake_pending = False
        with contextlib.suppress(OSError):
            while self._wake_r.recv(4096):
                pass

    # running ----------------------------------------------------------------------------
    def _timeout(self, limit: float | None) -> float | None:
        if self._threadsafe:
            return 0.0
        timers = self._timers
        while timers and timers[0][2].cancelled:
            heapq.heappop(timers)
        if not timers:
            return limit
        due = max(0.0, timers[0][0] - time.monotonic())
        return due if limit is None else min(due, limit)

    def _dispatch(self, events: list[tuple[int, int]]) -> None:
        handlers = self._handlers
        for fd, ev in events:
            handler = handlers.get(fd)
            if handler is not None:
                handler(ev)

    def _run_timers(self) -> None:
        timers = self._timers
        if not timers:
            return
        now = time.monotonic()
        while timers and timers[0][0] <= now:
            timer = heapq.heappop(timers)[2]
            if not timer.cancelled:
                timer.callback(*timer.args)

    def _run_threadsafe(self) -> None:
        calls = self._threadsafe
        while calls:
            calls.popleft()()

    def run_once(self, timeout: float | None = None, *, spin: bool = True) -> bool:
        """Wait up to ``timeout`` s (None: until something happens) and handle what is ready:
        sockets, due timers, cross-thread calls. With busy polling on (and ``spin``), keep
        polling for the adaptive window after traffic. True if any socket had traffic."""
        wait = self._timeout(timeout)
        poll = self._poller.poll
        busy = self.busy_poll
        events = poll(wait)
        if events and busy and spin:
            now = time.perf_counter()
            if wait != 0.0:
                busy.woke(now - self._last_traffic)
            self._last_traffic = now
        if events:
            self._dispatch(events)
        self._run_timers()
        if self._threadsafe:
            self._run_threadsafe()
        if not events or not spin or not busy or busy.window_s <= 0.0:
            return bool(events)
        # bounded busy poll: the next frame of a conversation usually follows within
        # microseconds; polling for it keeps this vCPU from halting (waking a halted vCPU
        # costs ~35-45 µs on the VMs this project runs on)
        clock = time.perf_counter
        start = clock()
        end = start + busy.window_s
        if timeout is not None:
            end = min(end, start + timeout)
        busy.spins += 1
        caught = False
        while True:
            sched_yield()
            more = poll(0.0)
            if more:
                caught = True
                self._last_traffic = clock()
                self._dispatch(more)
                self._run_timers()
                end = clock() + busy.window_s  # the conversation goes on: so does the spin
                if timeout is not None:
                    end = min(end, start + timeout)
            if self._threadsafe:
                self._run_threadsafe()
            if clock() >= end:
                break
        done = clock()
        busy.spin_s += done - start
        if caught:
            busy.hit()
        else:
            busy.miss()
        return True

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self.remove(self._wake_r.fileno())
        self._poller.close()
        self._wake_r.close()
        self._wake_w.close()
