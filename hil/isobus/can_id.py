"""The 29-bit identifier of an ISO 11783 frame (ISO 11783-3, clause 5.2; as SAE J1939-21).

``priority (3) | extended data page (1) | data page (1) | PDU format (8) | PDU specific (8) |
source address (8)``. With a PDU format below 240 (PDU1) the PDU specific byte is the
destination address and the parameter group number carries 0 there; from 240 (PDU2) it is the
group extension, part of the PGN, and the frame goes to everyone.
"""

from __future__ import annotations

from dataclasses import dataclass

import can

from hil.errors import FrameError
from hil.isobus.port import GLOBAL_ADDRESS


def is_pdu1(pgn: int) -> bool:
    """Whether ``pgn`` is destination-specific (PDU format < 240)."""
    return ((pgn >> 8) & 0xFF) < 240


@dataclass(frozen=True)
class FrameId:
    """The fields of a 29-bit ISO 11783 identifier.

    Attributes
    ----------
    priority : int
        0 (highest) .. 7.
    pgn : int
        Parameter group number; for PDU1 groups with the destination byte cleared.
    source : int
        Sender's address.
    destination : int
        Receiver's address; :data:`~hil.isobus.port.GLOBAL_ADDRESS` for PDU2 groups.
    """

    priority: int
    pgn: int
    source: int
    destination: int = GLOBAL_ADDRESS

    @property
    def can_id(self) -> int:
        """The 29-bit arbitration id."""
        return encode_id(self.priority, self.pgn, self.source, self.destination)


def encode_id(priority: int, pgn: int, source: int, destination: int = GLOBAL_ADDRESS) -> int:
    """Compose a 29-bit identifier.

    Raises
    ------
    FrameError
        A field out of range, or a PDU2 group sent to one address (PDU2 has no destination).
    """
    if not 0 <= priority <= 7:
        raise FrameError(f"priority {priority} is not 0 .. 7 (PGN 0x{pgn:05X})")
    if not 0 <= pgn < (1 << 18):
        raise FrameError(f"PGN 0x{pgn:X} does not fit 18 bits")
    if not 0 <= source <= 0xFF or not 0 <= destination <= 0xFF:
        raise FrameError(f"PGN 0x{pgn:05X}: address out of 0 .. 255 "
                         f"(source {source}, destination {destination})")
    if is_pdu1(pgn):
        if pgn & 0xFF:
            raise FrameError(f"PGN 0x{pgn:05X} is PDU1 (destination-specific): its low byte "
                             f"must be 0, the destination goes there")
        ps = destination
    else:
        if destination != GLOBAL_ADDRESS:
            raise FrameError(f"PGN 0x{pgn:05X} is PDU2 (broadcast only): it cannot be sent to "
                             f"address 0x{destination:02X}")
        ps = pgn & 0xFF
    return (priority << 26) | ((pgn & 0x3FF00) << 8) | (ps << 8) | source


def decode_id(can_id: int) -> FrameId:
    """Split a 29-bit identifier into priority, PGN, source and destination."""
    priority = (can_id >> 26) & 0x7
    pf = (can_id >> 16) & 0xFF
    ps = (can_id >> 8) & 0xFF
    source = can_id & 0xFF
    page = (can_id >> 24) & 0x3
    if pf < 240:
        return FrameId(priority, (page << 16) | (pf << 8), source, ps)
    return FrameId(priority, (page << 16) | (pf << 8) | ps, source, GLOBAL_ADDRESS)


def make_frame(priority: int, pgn: int, source: int, destination: int,
               data: bytes) -> can.Message:
    """An extended-id python-can frame of up to 8 bytes."""
    if len(data) > 8:
        raise FrameError(f"PGN 0x{pgn:05X}: {len(data)} bytes do not fit one frame")
    return can.Message(arbitration_id=encode_id(priority, pgn, source, destination),
                       data=bytes(data), is_extended_id=True)
