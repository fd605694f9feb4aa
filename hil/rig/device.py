"""Rig-side CAN nodes: what the controller under test sees on the bus.

A :class:`Device` says when it next wants to transmit (:meth:`next_due`, in seconds of run
time), what it transmits then (:meth:`emit`), and which frames it consumes (:meth:`accepts`,
:meth:`on_frame`). The runner does the scheduling, so the same device works under the real-time
and the lockstep clock. Devices never read the wall clock.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import can


class Device(ABC):
    """A CAN node the rig plays. Subclasses fill :meth:`emit` and, if they listen, the rest."""

    name: str = "device"
    #: while True the node sends nothing (a fault: the node went silent)
    silent: bool = False

    @abstractmethod
    def next_due(self, time_s: float) -> float:
        """The earliest time > ``time_s`` at which :meth:`emit` must run (``inf``: never)."""

    @abstractmethod
    def emit(self, time_s: float) -> list[can.Message]:
        """Frames to send now (called at or just after the time :meth:`next_due` gave)."""

    def accepts(self, msg: can.Message) -> bool:
        """Whether this node consumes ``msg`` (then :meth:`on_frame` gets it); default: no frame."""
        return False

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        """Consume a frame addressed to this node; return immediate replies (SDO, say)."""
        return []


class PeriodicDevice(Device):
    """A device that transmits every ``period_s``, first at ``offset_s``."""

    def __init__(self, name: str, period_s: float, offset_s: float = 0.0) -> None:
        if period_s <= 0:
            raise ValueError(f"{name}: period must be positive, got {period_s}")
        self.name = name
        self.period_s = period_s
        self.offset_s = offset_s

    def next_due(self, time_s: float) -> float:
        """The next multiple of ``period_s`` after ``offset_s`` that is later than ``time_s``."""
        if time_s < self.offset_s:
            return self.offset_s
        k = math.floor((time_s - self.offset_s) / self.period_s + 1e-9) + 1
        return self.offset_s + k * self.period_s

    def emit(self, time_s: float) -> list[can.Message]:
        """The frames of this period (:meth:`frames`), or none while the node is silent."""
        if self.silent:
            return []
        return self.frames(time_s)

    @abstractmethod
    def frames(self, time_s: float) -> list[can.Message]:
        """The frames of one period."""


class Heartbeat(PeriodicDevice):
    """CANopen heartbeat producer (COB-ID 0x700 + node id; state 0x05 operational)."""

    def __init__(self, name: str, node_id: int, period_s: float = 1.0,
                 state: int = 0x05) -> None:
        super().__init__(f"{name} heartbeat", period_s, offset_s=0.0)
        self.node_id = node_id
        self.state = state

    def frames(self, time_s: float) -> list[can.Message]:
        """The heartbeat frame: the node's state byte on COB-ID 0x700 + node id."""
        return [can.Message(arbitration_id=0x700 + self.node_id, data=bytes([self.state]),
                            is_extended_id=False)]
