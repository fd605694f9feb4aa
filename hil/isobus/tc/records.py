"""What the TC keeps of a run: every value it received, acknowledgements, connection events."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


@dataclass(frozen=True)
class LoggedValue:
    """One value a client sent (process data command 3, or 10 with acknowledge).

    Attributes
    ----------
    time_s : float
        Run time the message arrived.
    address : int
        Client's source address.
    element : int
        Element number.
    ddi : int
    value : int
        The raw 32-bit value, signed (use ``value & 0xFFFFFFFF`` for a condensed state).
    """

    time_s: float
    address: int
    element: int
    ddi: int
    value: int


@dataclass(frozen=True)
class ReceivedAcknowledge:
    """A process data acknowledge a client sent (to a command of the TC)."""

    time_s: float
    address: int
    element: int
    ddi: int
    errors: int
    command: int


class EventKind(Enum):
    """What happened to a client connection."""

    CONNECTED = "connected"
    """Working-set master seen: a new session."""
    VERSION = "version"
    POOL_TRANSFERRED = "pool transferred"
    ACTIVATED = "activated"
    REFUSED = "refused"
    DEACTIVATED = "deactivated"
    DELETED = "deleted"
    TIMED_OUT = "timed out"
    REJECTED_MESSAGE = "rejected message"
    SERVER_RESTARTED = "server restarted"


@dataclass(frozen=True)
class Event:
    """One connection event, with words for a person."""

    time_s: float
    address: int | None
    kind: EventKind
    detail: str = ""
