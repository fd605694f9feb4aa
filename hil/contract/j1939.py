"""J1939 / ISO 11783 identifiers: a frame id from priority, PGN and addresses, and back.

Example
-------
>>> hex(j1939_frame_id(priority=3, pgn=65096, source_address=0xF0))
'0xcfe48f0'
>>> j1939_pgn(0x0CFE48F0)
65096
"""

from __future__ import annotations

__all__ = ["j1939_frame_id", "j1939_pgn"]


def j1939_frame_id(*, priority: int, pgn: int, source_address: int,
                   destination: int | None = None) -> int:
    """The 29-bit identifier of a J1939 / ISO 11783 frame.

    Parameters
    ----------
    priority : int
        0 (highest) .. 7.
    pgn : int
        Parameter group number (18 bits).
    source_address : int
        Sender's address, 0..253.
    destination : int, optional
        Destination address for PDU1 PGNs (PF < 240); must be omitted for PDU2.

    Returns
    -------
    int
        The identifier (without any extended-frame flag bit).
    """
    if not 0 <= priority <= 7:
        raise ValueError(f"priority must be 0..7, got {priority}")
    if not 0 <= pgn < (1 << 18):
        raise ValueError(f"pgn must be an 18-bit number, got {pgn}")
    if not 0 <= source_address <= 0xFF:
        raise ValueError(f"source_address must be 0..255, got {source_address}")
    pdu_format = (pgn >> 8) & 0xFF
    if pdu_format < 240:
        if destination is None:
            raise ValueError(f"PGN {pgn} is PDU1: a destination address is required")
        pgn = (pgn & 0x3FF00) | (destination & 0xFF)
    elif destination is not None:
        raise ValueError(f"PGN {pgn} is PDU2 (broadcast): no destination address")
    return (priority << 26) | (pgn << 8) | source_address


def j1939_pgn(frame_id: int) -> int:
    """The PGN carried by a 29-bit identifier (destination address removed for PDU1)."""
    pgn = (frame_id >> 8) & 0x3FFFF
    if ((pgn >> 8) & 0xFF) < 240:
        pgn &= 0x3FF00
    return pgn
