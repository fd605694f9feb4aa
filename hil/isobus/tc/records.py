"""What the TC keeps of a run: every value it received, acknowledgements, connection events.

The server hands each record to its ``recorder`` as it happens, and keeps it in memory too
unless told not to (``keep_records=False``: what ``hil isobus serve`` does, writing them to
``tc.jsonl`` instead, so that a long serve does not grow)."""

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
    """A message the TC does not take (before a working-set master, malformed, from an address
    that never claimed); the first per address and second, then a count."""
    SERVER_RESTARTED = "server restarted"
    SESSION_ENDED = "session ended"
    """The client's address changed hands (another NAME claimed it) or its NAME moved: the
    session belonged to the NAME and ends; the newcomer must connect on its own."""
    CLIENT_ERROR = "client error"
    """Handling a client's message or its set-points raised: its session ends, the TC goes on
    (a TC that isolates its clients, as the rig's tractor does)."""
    ADDRESS_LOST = "address lost"
    """The TC lost its own address to a lower NAME (ISO 11783-5): every session ends."""
    ADDRESS_CLAIMED = "address claimed"
    """The TC holds an address (again): its status goes out from there."""


@dataclass(frozen=True)
class Event:
    """One connection event, with words for a person."""

    time_s: float
    address: int | None
    kind: EventKind
    detail: str = ""


Record = Event | LoggedValue | ReceivedAcknowledge
"""Anything the TC records."""
