"""The connection-management and data frames of TP and ETP (ISO 11783-3, clauses 5.10-5.11).

TP: connection management PGN 0xEC00 (TP.CM), data PGN 0xEB00 (TP.DT), up to 1,785 bytes
(255 packets of 7). ETP: PGN 0xC800 (ETP.CM) and 0xC700 (ETP.DT), 1,786 to 117,440,505 bytes
(16,777,215 packets of 7), destination-specific only. Every CM frame ends with the PGN of the
message it carries (3 bytes, little-endian); unused bytes are 0xFF.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from hil.errors import FrameError

PGN_REQUEST = 0xEA00
PGN_ADDRESS_CLAIMED = 0xEE00
PGN_TP_CM = 0xEC00
PGN_TP_DT = 0xEB00
PGN_ETP_CM = 0xC800
PGN_ETP_DT = 0xC700
TRANSPORT_PGNS = frozenset({PGN_TP_CM, PGN_TP_DT, PGN_ETP_CM, PGN_ETP_DT})

TP_MAX_BYTES = 1785
"""Largest TP message: 255 packets of 7 bytes."""
ETP_MAX_BYTES = 117_440_505
"""Largest ETP message: 16,777,215 packets of 7 bytes."""
BYTES_PER_PACKET = 7


class Control(enum.IntEnum):
    """Control byte (byte 1) of a TP.CM or ETP.CM frame."""

    RTS = 16
    CTS = 17
    EOMA = 19
    BAM = 32
    ETP_RTS = 20
    ETP_CTS = 21
    ETP_DPO = 22
    ETP_EOMA = 23
    ABORT = 255


class AbortReason(enum.IntEnum):
    """Connection abort reasons (ISO 11783-3, table 5; the same values as SAE J1939-21)."""

    ALREADY_IN_SESSION = 1
    """Already in one or more connection-managed sessions and cannot support another."""
    RESOURCES_NEEDED = 2
    """System resources were needed for another task, so this connection was aborted."""
    TIMEOUT = 3
    """A timeout occurred."""
    CTS_DURING_TRANSFER = 4
    """CTS received while a data transfer was in progress."""
    MAX_RETRANSMIT = 5
    """Maximum retransmit request limit reached."""
    UNEXPECTED_DATA = 6
    """Unexpected data transfer packet."""
    BAD_SEQUENCE = 7
    """Bad sequence number."""
    DUPLICATE_SEQUENCE = 8
    """Duplicate sequence number."""
    UNEXPECTED_DPO = 9
    """Unexpected ETP data packet offset (DPO) packet."""
    DPO_PGN = 10
    """The PGN of an ETP DPO differs from the connection's."""
    DPO_PACKETS_EXCEED_CTS = 11
    """An ETP DPO announces more packets than the CTS allowed."""
    BAD_DPO_OFFSET = 12
    """An ETP DPO's offset is not the one the CTS asked for."""
    CTS_PGN = 14
    """The PGN of an ETP CTS differs from the connection's."""
    CTS_EXCEEDS_SIZE = 15
    """An ETP CTS asks for packets beyond the message."""
    OTHER = 250
    """Any other reason."""


def packets_for(size: int) -> int:
    """How many 7-byte packets carry ``size`` bytes."""
    return math.ceil(size / BYTES_PER_PACKET)


def _pgn_bytes(pgn: int) -> bytes:
    return pgn.to_bytes(3, "little")


@dataclass(frozen=True)
class CmFrame:
    """A decoded TP.CM or ETP.CM frame (fields that the control byte does not use are 0).

    Attributes
    ----------
    control : Control
        The control byte.
    pgn : int
        The PGN of the message the connection carries.
    size : int
        Message size in bytes (RTS, BAM, EOMA, ETP RTS, ETP EOMA).
    packets : int
        Total packets (RTS, BAM, EOMA), packets this CTS allows (CTS, ETP CTS), packets the
        offset applies to (ETP DPO).
    max_per_cts : int
        RTS: most packets the sender takes per CTS (255: no limit).
    next_packet : int
        CTS, ETP CTS: the next packet number to send (1-based).
    offset : int
        ETP DPO: the data packet offset.
    reason : int
        Abort: the abort reason.
    """

    control: Control
    pgn: int
    size: int = 0
    packets: int = 0
    max_per_cts: int = 0
    next_packet: int = 0
    offset: int = 0
    reason: int = 0


def encode_cm(cm: CmFrame) -> bytes:
    """The 8 data bytes of a connection-management frame."""
    c, tail = cm.control, _pgn_bytes(cm.pgn)
    if c == Control.RTS:
        body = bytes([c]) + cm.size.to_bytes(2, "little") + bytes([cm.packets, cm.max_per_cts])
    elif c in (Control.BAM, Control.EOMA):
        body = bytes([c]) + cm.size.to_bytes(2, "little") + bytes([cm.packets, 0xFF])
    elif c == Control.CTS:
        body = bytes([c, cm.packets, cm.next_packet, 0xFF, 0xFF])
    elif c in (Control.ETP_RTS, Control.ETP_EOMA):
        body = bytes([c]) + cm.size.to_bytes(4, "little")
    elif c == Control.ETP_CTS:
        body = bytes([c, cm.packets]) + cm.next_packet.to_bytes(3, "little")
    elif c == Control.ETP_DPO:
        body = bytes([c, cm.packets]) + cm.offset.to_bytes(3, "little")
    elif c == Control.ABORT:
        body = bytes([c, cm.reason, 0xFF, 0xFF, 0xFF])
    else:  # pragma: no cover - Control is closed
        raise FrameError(f"no encoding for control byte {c}")
    return body + tail


def decode_cm(data: bytes, *, extended: bool) -> CmFrame:
    """Decode the 8 data bytes of a TP.CM (``extended`` False) or ETP.CM frame.

    Raises
    ------
    FrameError
        Fewer than 8 bytes, or a control byte that this kind of CM frame does not have.
    """
    kind = "ETP.CM" if extended else "TP.CM"
    if len(data) < 8:
        raise FrameError(f"{kind} frame of {len(data)} bytes (8 expected): {bytes(data).hex()}")
    try:
        c = Control(data[0])
    except ValueError:
        raise FrameError(f"{kind} frame with unknown control byte {data[0]}: "
                         f"{bytes(data).hex()}") from None
    pgn = int.from_bytes(data[5:8], "little")
    etp_controls = (Control.ETP_RTS, Control.ETP_CTS, Control.ETP_DPO, Control.ETP_EOMA)
    if c != Control.ABORT and (c in etp_controls) != extended:
        raise FrameError(f"{kind} frame with control byte {int(c)}, which belongs to the "
                         f"{'TP' if extended else 'ETP'}: {bytes(data).hex()}")
    if c in (Control.RTS, Control.BAM, Control.EOMA):
        return CmFrame(c, pgn, size=int.from_bytes(data[1:3], "little"), packets=data[3],
                       max_per_cts=data[4])
    if c == Control.CTS:
        return CmFrame(c, pgn, packets=data[1], next_packet=data[2])
    if c in (Control.ETP_RTS, Control.ETP_EOMA):
        return CmFrame(c, pgn, size=int.from_bytes(data[1:5], "little"))
    if c == Control.ETP_CTS:
        return CmFrame(c, pgn, packets=data[1], next_packet=int.from_bytes(data[2:5], "little"))
    if c == Control.ETP_DPO:
        return CmFrame(c, pgn, packets=data[1], offset=int.from_bytes(data[2:5], "little"))
    return CmFrame(c, pgn, reason=data[1])


def data_packet(sequence: int, chunk: bytes) -> bytes:
    """A TP.DT / ETP.DT frame: the sequence number and 7 bytes, the last padded with 0xFF."""
    return bytes([sequence]) + chunk + b"\xff" * (BYTES_PER_PACKET - len(chunk))
