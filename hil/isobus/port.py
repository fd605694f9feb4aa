"""The seam between the ISOBUS network layer and the applications that use it.

An application (the Task Controller server, the tractor ECU's messages) sends and receives
whole parameter groups: the network layer picks a single frame, TP (up to 1,785 bytes, BAM when
broadcast, RTS/CTS to one address) or ETP (beyond) by length, and claims the application's
address before anything is sent. Nothing here reads the wall clock: the owner of the network
calls :meth:`Application.tick` with the run's time, so the same code runs in lockstep and in
real time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

GLOBAL_ADDRESS = 0xFF
"""Destination of a broadcast parameter group."""
NULL_ADDRESS = 0xFE
"""Source address of a control function that could not claim one."""


@dataclass(frozen=True)
class Received:
    """One whole parameter group as it arrived (after transport reassembly).

    Attributes
    ----------
    pgn : int
        Parameter group number, destination byte removed for PDU1 groups.
    data : bytes
        The payload: 8 bytes for a single frame, any length after TP or ETP.
    source : int
        Sender's address.
    destination : int
        Receiver's address, :data:`GLOBAL_ADDRESS` for a broadcast.
    time_s : float
        Run time of the last frame.
    priority : int
        The frame's priority (0 highest .. 7).
    """

    pgn: int
    data: bytes
    source: int
    destination: int
    time_s: float
    priority: int = 6


Handler = Callable[[Received], None]


class IsobusPort(Protocol):
    """What an application sees of the network: its own address, send, subscribe."""

    @property
    def address(self) -> int | None:
        """The application's claimed address, ``None`` until the claim has settled."""

    def send(self, pgn: int, data: bytes, destination: int = GLOBAL_ADDRESS,
             priority: int = 6) -> None:
        """Queue a parameter group; the layer picks single frame, TP or ETP by length."""

    def subscribe(self, pgn: int, handler: Handler) -> None:
        """Call ``handler`` with every whole ``pgn`` addressed to this application or to all."""

    def name_of(self, address: int) -> int | None:
        """The 64-bit NAME that claimed ``address`` on the bus, ``None`` if nothing did."""


class Application(Protocol):
    """Something that runs on a port and keeps its own timers (status messages, timeouts)."""

    def tick(self, now_s: float) -> None:
        """Advance to run time ``now_s``: send what is due, time out what is late."""
