"""Faults the network injects to test the DUT's ISOBUS stack, declared as a small config.

Each fault makes the frames a bus analyser would see from a misbehaving peer:

- ``contend``: at ``at_s`` a claim of ``address`` with the NAME ``name`` (lower than the DUT's,
  to take its address), sent from that address as a real contender would; the DUT must give
  the address up (move, or cannot-claim).
- ``drop_cts``: the network, receiving a TP/ETP transfer from ``peer``, leaves out its CTS
  number ``nth`` (1 = the first); the DUT must time out after T3 and abort (reason 3).
- ``abort``: a transfer with ``peer`` (either way) is aborted by the network with ``reason``
  after ``after_packets`` data packets; the DUT must drop it.
- ``late_packet``: the network, sending to ``peer``, sends data packet ``packet`` ``delay_s``
  late (beyond T1 = 0.75 s); the DUT must time out and abort (reason 3).

In a file (TOML, say) they read::

    [[isobus.faults]]
    kind = "contend"
    at_s = 2.0
    address = 0x81
    name = 0x0000000000000001

``peer`` is optional: without it the fault applies to the first transfer with anyone.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from hil.errors import ConfigError
from hil.isobus.tp_messages import AbortReason
from hil.isobus.transport import Session

KINDS = ("contend", "drop_cts", "abort", "late_packet")


@dataclass(frozen=True)
class Contend:
    """Claim ``address`` with NAME ``name`` at run time ``at_s``."""

    at_s: float
    address: int
    name: int


@dataclass(frozen=True)
class DropCts:
    """Leave out the ``nth`` CTS this network would send to ``peer`` (``None``: anyone)."""

    nth: int = 1
    peer: int | None = None


@dataclass(frozen=True)
class AbortTransfer:
    """Abort a transfer with ``peer`` with ``reason`` after ``after_packets`` data packets."""

    after_packets: int
    reason: int = AbortReason.OTHER
    peer: int | None = None


@dataclass(frozen=True)
class LatePacket:
    """Send data packet ``packet`` to ``peer`` ``delay_s`` late."""

    packet: int
    delay_s: float = 1.0
    peer: int | None = None


@dataclass
class IsobusFaults:
    """The faults of one run; each transport fault fires once, on the first session it fits.

    Implements :class:`hil.isobus.transport.TransportHooks`.
    """

    contend: list[Contend] = field(default_factory=list)
    dropped_cts: list[DropCts] = field(default_factory=list)
    aborts: list[AbortTransfer] = field(default_factory=list)
    late_packets: list[LatePacket] = field(default_factory=list)
    #: (fault, session) pairs that fired, in order
    fired: list[tuple[object, str]] = field(default_factory=list)
    _spent: set[int] = field(default_factory=set, repr=False)

    def _take(self, fault: object, s: Session, peer: int | None) -> bool:
        """Whether ``fault`` fires on ``s`` now: it fits the peer and has not fired yet."""
        other = s.destination if s.role == "sender" else s.source
        if (peer is not None and other != peer) or id(fault) in self._spent:
            return False
        self._spent.add(id(fault))
        self.fired.append((fault, _describe(s)))
        return True

    def drop_cts(self, session: Session) -> bool:
        """Transport hook: drop this CTS?"""
        for f in self.dropped_cts:
            if session.ctses == f.nth and self._take(f, session, f.peer):
                return True
        return False

    def abort_reason(self, session: Session, packets_done: int) -> int | None:
        """Transport hook: abort now, and why?"""
        for f in self.aborts:
            if packets_done == f.after_packets and self._take(f, session, f.peer):
                return int(f.reason)
        return None

    def packet_delay_s(self, session: Session, packet_number: int) -> float:
        """Transport hook: how late to send this packet."""
        if session.role != "sender":
            return 0.0
        for f in self.late_packets:
            if packet_number == f.packet and self._take(f, session, f.peer):
                return f.delay_s
        return 0.0



def _describe(s: Session) -> str:
    return (f"{s.protocol} {s.role} PGN 0x{s.pgn:05X} 0x{s.source:02X}->0x{s.destination:02X} "
            f"{s.size} B")


def _int(entry: Mapping[str, Any], key: str, where: str, path: str | None, lo: int, hi: int,
         default: int | None = None) -> int:
    value = entry.get(key, default)
    if value is None:
        raise ConfigError(f"missing {key!r}", path=path, key=f"{where}.{key}")
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ConfigError(f"{key} = {value!r} is not an integer {lo} .. {hi}", path=path,
                          key=f"{where}.{key}")
    return value


def _float(entry: Mapping[str, Any], key: str, where: str, path: str | None,
           default: float | None = None) -> float:
    value = entry.get(key, default)
    if (isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0
            or value == float("inf")):
        raise ConfigError(f"{key} = {value!r} is not a finite number of seconds >= 0",
                          path=path, key=f"{where}.{key}")
    return float(value)


def parse_faults(entries: Sequence[Mapping[str, Any]], path: str | None = None) -> IsobusFaults:
    """Read a list of fault tables (``[[isobus.faults]]``) into :class:`IsobusFaults`.

    Raises
    ------
    ConfigError
        An unknown kind or key, or a value out of range (naming the entry and key).
    """
    faults = IsobusFaults()
    allowed = {"contend": {"kind", "at_s", "address", "name"},
               "drop_cts": {"kind", "nth", "peer"},
               "abort": {"kind", "after_packets", "reason", "peer"},
               "late_packet": {"kind", "packet", "delay_s", "peer"}}
    for i, entry in enumerate(entries):
        where = f"isobus.faults[{i}]"
        kind = entry.get("kind")
        if kind not in KINDS:
            raise ConfigError(f"{where}: kind = {kind!r}, expected one of {', '.join(KINDS)}",
                              path=path, key=f"{where}.kind")
        unknown = set(entry) - allowed[kind]
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {', '.join(sorted(unknown))} for "
                              f"kind {kind!r}", path=path, key=where)
        peer = (None if entry.get("peer") is None
                else _int(entry, "peer", where, path, 0, 253))
        if kind == "contend":
            faults.contend.append(Contend(_float(entry, "at_s", where, path),
                                          _int(entry, "address", where, path, 0, 253),
                                          _int(entry, "name", where, path, 0, 2**64 - 1)))
        elif kind == "drop_cts":
            faults.dropped_cts.append(DropCts(_int(entry, "nth", where, path, 1, 2**24, 1),
                                              peer))
        elif kind == "abort":
            reason = _int(entry, "reason", where, path, 1, 255, int(AbortReason.OTHER))
            faults.aborts.append(AbortTransfer(_int(entry, "after_packets", where, path, 1,
                                                    2**24), reason, peer))
        else:
            faults.late_packets.append(LatePacket(_int(entry, "packet", where, path, 1, 2**24),
                                                  _float(entry, "delay_s", where, path, 1.0),
                                                  peer))
    return faults
