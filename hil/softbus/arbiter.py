"""Bit-rate pacing: which frame holds the wire next, and when it has been delivered.

The arbiter is a small discrete-event model of one CAN segment. Frames are offered with the
time they became ready (the moment the server read them). When the wire falls idle at time
``t``, every frame ready by ``t`` contends and the lowest arbitration key wins; the winner
occupies the wire for its exact bit count divided by the bit rate. The model is lazy: the
server may call :meth:`Arbiter.due` late (event loops wake with millisecond granularity) and
still gets the same schedule and the same delivery times as a wire would produce.
"""

from __future__ import annotations

import heapq
from collections import deque
from dataclasses import dataclass, field
from typing import Generic, TypeVar

from hil.softbus.timing import arbitration_key, frame_bits

P = TypeVar("P")


@dataclass(order=True)
class _Contender(Generic[P]):
    key: tuple[int, int, int]
    seq: int
    ready: float = field(compare=False)
    bits: int = field(compare=False)
    payload: P = field(compare=False)


@dataclass(frozen=True)
class Transmission(Generic[P]):
    """A frame that won the wire: it started at ``start`` and was delivered at ``end``."""

    payload: P
    start: float
    end: float
    bits: int


class Arbiter(Generic[P]):
    """Schedule frames on a wire of ``bitrate`` bit/s; ``max_pending`` bounds the queue."""

    def __init__(self, bitrate: int, *, max_pending: int = 65536) -> None:
        if bitrate <= 0:
            raise ValueError(f"bitrate must be positive, got {bitrate}")
        self.bitrate = bitrate
        self.max_pending = max_pending
        self._arrivals: deque[_Contender[P]] = deque()
        self._contending: list[_Contender[P]] = []
        self._seq = 0
        self._free_at = float("-inf")
        self._current: Transmission[P] | None = None
        self.busy_s = 0.0
        self.overflows = 0

    def __len__(self) -> int:
        return len(self._arrivals) + len(self._contending) + (self._current is not None)

    def offer(self, payload: P, *, can_id: int, extended: bool, data: bytes,
              ready: float, bits: int | None = None) -> bool:
        """Queue a frame that became ready at ``ready``; False when the queue is full."""
        if len(self._arrivals) + len(self._contending) >= self.max_pending:
            self.overflows += 1
            return False
        self._seq += 1
        n_bits = bits if bits is not None else frame_bits(can_id, extended, data)
        self._arrivals.append(_Contender(arbitration_key(can_id, extended), self._seq, ready,
                                         n_bits, payload))
        return True

    def due(self, now: float) -> list[Transmission[P]]:
        """Every transmission that has finished by ``now``, in wire order."""
        done: list[Transmission[P]] = []
        while True:
            if self._current is None:
                self._current = self._start_next()
                if self._current is None:
                    break
            if self._current.end > now:
                break
            done.append(self._current)
            self._current = None
        return done

    def next_event(self) -> float | None:
        """When the frame now on the wire (or the next to start) will be delivered."""
        if self._current is None:
            self._current = self._start_next()
        return None if self._current is None else self._current.end

    def _start_next(self) -> Transmission[P] | None:
        if not self._contending and not self._arrivals:
            return None
        start = self._free_at
        if not self._contending and self._arrivals[0].ready > start:
            start = self._arrivals[0].ready
        while self._arrivals and self._arrivals[0].ready <= start:
            heapq.heappush(self._contending, self._arrivals.popleft())
        winner = heapq.heappop(self._contending)
        duration = winner.bits / self.bitrate
        self._free_at = start + duration
        self.busy_s += duration
        return Transmission(winner.payload, start, self._free_at, winner.bits)
