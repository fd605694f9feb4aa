"""Running rig devices without the rig: a virtual-time wire, and a real-time pump on a bus.

:class:`VirtualWire` joins several :class:`~hil.rig.device.Device` nodes (an
:class:`~hil.isobus.network.IsobusNetwork` as the rig, another as a stand-in DUT) and moves
them from due time to due time, handing each frame to every other node at the time it was
sent: the lockstep clock reduced to what the network layer needs, for tests and probes.

:func:`drive` runs one device against a python-can bus in real time (the run time is the
monotonic clock since the start): what ``hil isobus serve`` or a probe against another stack
needs.
"""

from __future__ import annotations

import bisect
import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import can

from hil.rig.device import Device


@dataclass(frozen=True)
class WireFrame:
    """One frame on the wire: when, from which node (its index), and the frame."""

    time_s: float
    sender: int
    frame: can.Message


class VirtualWire:
    """Several devices on one bus in virtual time.

    Parameters
    ----------
    nodes : sequence of Device
        The nodes; a frame one sends reaches all the others.
    drop : callable, optional
        ``drop(frame, sender)``: True to lose the frame on the wire (it is still recorded in
        :attr:`frames`, with a negative sender index ``-1 - sender``).
    """

    def __init__(self, nodes: Sequence[Device],
                 drop: Callable[[can.Message, int], bool] | None = None) -> None:
        self.nodes = list(nodes)
        self.now = 0.0
        self.frames: list[WireFrame] = []
        self._drop = drop

    def run_until(self, end_s: float, max_steps: int = 1_000_000) -> None:
        """Advance to ``end_s``, running every node at each of its due times.

        Raises
        ------
        RuntimeError
            More than ``max_steps`` due times (a node that is always due).
        """
        for _ in range(max_steps):
            due = min((n.next_due(self.now) for n in self.nodes), default=math.inf)
            if due > end_s:
                self.now = end_s
                return
            self.now = due
            for i, node in enumerate(self.nodes):
                if node.next_due(math.nextafter(due, -math.inf)) <= due:
                    self._carry(i, node.emit(due))
        raise RuntimeError(f"the wire did not reach t = {end_s} s in {max_steps} steps")

    def inject(self, frame: can.Message, sender: int = -1) -> None:
        """Put ``frame`` on the wire now, as if from node ``sender`` (-1: from outside)."""
        self._carry(sender, [frame])

    def _carry(self, sender: int, frames: list[can.Message]) -> None:
        queue = deque((sender, f) for f in frames)
        while queue:
            origin, frame = queue.popleft()
            if self._drop is not None and self._drop(frame, origin):
                self.frames.append(WireFrame(self.now, -1 - origin, frame))
                continue
            self.frames.append(WireFrame(self.now, origin, frame))
            for j, node in enumerate(self.nodes):
                if j != origin and node.accepts(frame):
                    queue.extend((j, r) for r in node.on_frame(frame, self.now))


def drive(device: Device, bus: can.BusABC, duration_s: float,
          clock: Callable[[], float] = time.monotonic,
          until: Callable[[], bool] | None = None, start_s: float = 0.0) -> float:
    """Run ``device`` on ``bus`` in real time for ``duration_s`` (or until ``until()``).

    The run time is ``start_s`` plus the ``clock()`` time since the call. Frames are handed to
    the device as they arrive; the device's frames are sent when :meth:`Device.next_due` says.
    To go on with a run, pass the time the last call returned as ``start_s``.

    Returns
    -------
    float
        The run time reached.
    """
    t0 = clock() - start_s
    now = last = start_s
    end = start_s + duration_s
    while now < end and not (until is not None and until()):
        if device.next_due(last) <= now:
            for frame in device.emit(now):
                bus.send(frame)
            last = now
        wait = min(device.next_due(last), end) - now
        msg = bus.recv(timeout=min(max(wait, 0.0), 0.005))
        now = clock() - t0
        if msg is not None and device.accepts(msg):
            for frame in device.on_frame(msg, now):
                bus.send(frame)
    return now


class ScriptedNode(Device):
    """A peer that sends given frames at given times and records what it hears.

    For probing a stack with frames no well-behaved stack would send (a bad sequence number,
    a CTS out of turn): the frames are the ones a bus analyser would show.

    Parameters
    ----------
    script : sequence of (time, frame)
        Frames to send and when.
    name : str
        The node's name.
    """

    def __init__(self, script: Sequence[tuple[float, can.Message]] = (),
                 name: str = "scripted") -> None:
        self.name = name
        self.script: list[tuple[float, can.Message]] = sorted(script, key=lambda p: p[0])
        self.heard: list[tuple[float, can.Message]] = []

    def at(self, time_s: float, frame: can.Message) -> None:
        """Add a frame to send at ``time_s`` (after those scripted for the same time)."""
        bisect.insort_right(self.script, (time_s, frame), key=lambda p: p[0])

    def next_due(self, time_s: float) -> float:
        """The time of the next scripted frame (at once if one is overdue)."""
        if not self.script:
            return math.inf
        return max(self.script[0][0], math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        """The scripted frames due by ``time_s`` (each once)."""
        n = bisect.bisect_right(self.script, time_s, key=lambda p: p[0])
        due = [f for _, f in self.script[:n]]
        del self.script[:n]     # the script is sorted: a long one costs its length once
        return due

    def accepts(self, msg: can.Message) -> bool:
        """Everything: it records the whole bus."""
        return True

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        """Record the frame; answer nothing."""
        self.heard.append((time_s, msg))
        return []
