"""FMI-LS-BUS 1.0 CAN operations: the bytes of ``Tx_Data``/``Rx_Data``, encoded and decoded.

An LS-BUS buffer is a sequence of operations, each an 8-byte header (``opCode``, ``length``:
little-endian ``uint32`` each, ``length`` counting the header) and its fields, packed with no
padding (``#pragma pack(1)`` in ``fmi3LsBusCan.h``, vendored under
``firmware/fmu/third_party/fmi-ls-bus``). Operation codes and layouts are the header's:

======================  ======  =======================================================
operation               code    fields after the header
======================  ======  =======================================================
format error            0x01    dataLength u16, data
CAN transmit            0x10    id u32, ide u8, rtr u8, dataLength u16, data
CAN FD transmit         0x11    id u32, ide u8, brs u8, esi u8, dataLength u16, data
CAN XL transmit         0x12    id u32, ide u8, sec u8, sdt u8, vcid u8, af u32,
                                dataLength u16, data
confirm                 0x20    id u32
arbitration lost        0x30    id u32
bus error               0x31    id u32, errorCode u8, errorFlag u8, isSender u8
configuration           0x40    parameterType u8, then baudrate u32 (types 1-3) or
                                arbitrationLostBehavior u8 (type 4)
status                  0x41    status u8 (1 error active, 2 error passive, 3 bus off)
wake-up                 0x42    (none)
======================  ======  =======================================================

The header's own packing macros write the host's byte order; every FMI platform agrihil runs
on is little-endian, as is this module.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from hil.errors import FrameError

__all__ = [
    "ArbitrationLost", "BusError", "CanFdTransmit", "CanTransmit", "CanXlTransmit",
    "Configuration", "Confirm", "FormatError", "Operation", "Status", "Unknown", "Wakeup",
    "decode", "encode",
]

OP_FORMAT_ERROR = 0x0001
OP_CAN_TRANSMIT = 0x0010
OP_CANFD_TRANSMIT = 0x0011
OP_CANXL_TRANSMIT = 0x0012
OP_CONFIRM = 0x0020
OP_ARBITRATION_LOST = 0x0030
OP_BUS_ERROR = 0x0031
OP_CONFIGURATION = 0x0040
OP_STATUS = 0x0041
OP_WAKEUP = 0x0042

#: bus error codes (``FMI3_LS_BUS_CAN_BUSERROR_PARAM_ERROR_CODE_*``)
ERROR_CODES = {1: "bit error", 2: "bit stuffing error", 3: "form error", 4: "CRC error",
               5: "ACK error", 6: "broken error frame"}
BIT_ERROR, STUFF_ERROR, FORM_ERROR, CRC_ERROR, ACK_ERROR, BROKEN_ERROR_FRAME = range(1, 7)
PRIMARY_ERROR_FLAG, SECONDARY_ERROR_FLAG = 1, 2
#: status kinds
ERROR_ACTIVE, ERROR_PASSIVE, BUS_OFF = 1, 2, 3
STATUS_NAMES = {ERROR_ACTIVE: "error active", ERROR_PASSIVE: "error passive", BUS_OFF: "bus off"}
#: configuration parameter types
CAN_BAUDRATE, CANFD_BAUDRATE, CANXL_BAUDRATE, ARBITRATION_LOST_BEHAVIOR = 1, 2, 3, 4
#: arbitration-lost behaviours
BUFFER_AND_RETRANSMIT, DISCARD_AND_NOTIFY = 1, 2

_HEADER = struct.Struct("<II")


@dataclass(frozen=True)
class CanTransmit:
    """A classic CAN frame (0x10)."""

    id: int
    data: bytes
    ide: bool = False
    rtr: bool = False
    code = OP_CAN_TRANSMIT

    def body(self) -> bytes:
        return struct.pack("<IBBH", self.id, self.ide, self.rtr, len(self.data)) + self.data


@dataclass(frozen=True)
class CanFdTransmit:
    """A CAN FD frame (0x11)."""

    id: int
    data: bytes
    ide: bool = False
    brs: bool = False
    esi: bool = False
    code = OP_CANFD_TRANSMIT

    def body(self) -> bytes:
        return struct.pack("<IBBBH", self.id, self.ide, self.brs, self.esi,
                           len(self.data)) + self.data


@dataclass(frozen=True)
class CanXlTransmit:
    """A CAN XL frame (0x12)."""

    id: int
    data: bytes
    ide: bool = False
    sec: int = 0
    sdt: int = 0
    vcid: int = 0
    af: int = 0
    code = OP_CANXL_TRANSMIT

    def body(self) -> bytes:
        return struct.pack("<IBBBBIH", self.id, self.ide, self.sec, self.sdt, self.vcid,
                           self.af, len(self.data)) + self.data


@dataclass(frozen=True)
class Confirm:
    """The frame ``id`` the FMU sent was transmitted (0x20)."""

    id: int
    code = OP_CONFIRM

    def body(self) -> bytes:
        return struct.pack("<I", self.id)


@dataclass(frozen=True)
class ArbitrationLost:
    """The FMU's frame ``id`` lost arbitration (0x30)."""

    id: int
    code = OP_ARBITRATION_LOST

    def body(self) -> bytes:
        return struct.pack("<I", self.id)


@dataclass(frozen=True)
class BusError:
    """A bus error while frame ``id`` was on the bus (0x31)."""

    id: int
    error_code: int
    error_flag: int = PRIMARY_ERROR_FLAG
    is_sender: bool = True
    code = OP_BUS_ERROR

    def body(self) -> bytes:
        return struct.pack("<IBBB", self.id, self.error_code, self.error_flag, self.is_sender)


@dataclass(frozen=True)
class Configuration:
    """A configuration parameter (0x40): a baud rate (types 1-3) or the arbitration-lost
    behaviour (type 4)."""

    parameter: int
    value: int
    code = OP_CONFIGURATION

    def body(self) -> bytes:
        if self.parameter == ARBITRATION_LOST_BEHAVIOR:
            return struct.pack("<BB", self.parameter, self.value)
        return struct.pack("<BI", self.parameter, self.value)


@dataclass(frozen=True)
class Status:
    """The node's error state (0x41)."""

    status: int
    code = OP_STATUS

    def body(self) -> bytes:
        return struct.pack("<B", self.status)


@dataclass(frozen=True)
class Wakeup:
    """A wake-up (0x42)."""

    code = OP_WAKEUP

    def body(self) -> bytes:
        return b""


@dataclass(frozen=True)
class FormatError:
    """The receiver could not read an operation (0x01); ``data`` is what it could not read."""

    data: bytes
    code = OP_FORMAT_ERROR

    def body(self) -> bytes:
        return struct.pack("<H", len(self.data)) + self.data


@dataclass(frozen=True)
class Unknown:
    """An operation of a code this module does not know (kept whole, to be refused by name)."""

    code: int
    payload: bytes

    def body(self) -> bytes:
        return self.payload


Operation = (CanTransmit | CanFdTransmit | CanXlTransmit | Confirm | ArbitrationLost | BusError
             | Configuration | Status | Wakeup | FormatError | Unknown)


def encode(ops: Iterable[Operation]) -> bytes:
    """The buffer of ``ops``, in order."""
    out = bytearray()
    for op in ops:
        body = op.body()
        out += _HEADER.pack(op.code, _HEADER.size + len(body)) + body
    return bytes(out)


def _transmit(code: int, fixed: str, body: bytes, where: str) -> Operation:
    size = struct.calcsize(fixed)
    if len(body) < size:
        raise FrameError(f"{where}: operation 0x{code:02X} is {len(body) + 8} bytes, shorter "
                         f"than its fields ({size + 8})")
    fields = struct.unpack_from(fixed, body)
    length = fields[-1]
    data = body[size:]
    if len(data) != length:
        raise FrameError(f"{where}: operation 0x{code:02X} says dataLength {length} but carries "
                         f"{len(data)} bytes")
    if code == OP_CAN_TRANSMIT:
        return CanTransmit(id=fields[0], ide=bool(fields[1]), rtr=bool(fields[2]), data=data)
    if code == OP_CANFD_TRANSMIT:
        return CanFdTransmit(id=fields[0], ide=bool(fields[1]), brs=bool(fields[2]),
                             esi=bool(fields[3]), data=data)
    return CanXlTransmit(id=fields[0], ide=bool(fields[1]), sec=fields[2], sdt=fields[3],
                         vcid=fields[4], af=fields[5], data=data)


_FIXED = {OP_CONFIRM: "<I", OP_ARBITRATION_LOST: "<I", OP_BUS_ERROR: "<IBBB",
          OP_STATUS: "<B", OP_WAKEUP: ""}


def _operation(code: int, body: bytes, where: str) -> Operation:
    if code == OP_CAN_TRANSMIT:
        return _transmit(code, "<IBBH", body, where)
    if code == OP_CANFD_TRANSMIT:
        return _transmit(code, "<IBBBH", body, where)
    if code == OP_CANXL_TRANSMIT:
        return _transmit(code, "<IBBBBIH", body, where)
    if code == OP_CONFIGURATION:
        if len(body) == 2 and body[0] == ARBITRATION_LOST_BEHAVIOR:
            return Configuration(parameter=body[0], value=body[1])
        if len(body) == 5 and body[0] in (CAN_BAUDRATE, CANFD_BAUDRATE, CANXL_BAUDRATE):
            return Configuration(parameter=body[0], value=struct.unpack_from("<I", body, 1)[0])
        raise FrameError(f"{where}: configuration operation of {len(body) + 8} bytes with "
                         f"parameter type {body[0] if body else None}: not one LS-BUS 1.0 "
                         f"defines")
    if code == OP_FORMAT_ERROR:
        if len(body) < 2 or struct.unpack_from("<H", body)[0] != len(body) - 2:
            raise FrameError(f"{where}: format error operation with a wrong dataLength")
        return FormatError(data=body[2:])
    fixed = _FIXED.get(code)
    if fixed is None:
        return Unknown(code=code, payload=body)
    if len(body) != struct.calcsize(fixed):
        raise FrameError(f"{where}: operation 0x{code:02X} is {len(body) + 8} bytes, LS-BUS "
                         f"1.0 says {struct.calcsize(fixed) + 8}")
    fields = struct.unpack(fixed, body) if fixed else ()
    if code == OP_CONFIRM:
        return Confirm(id=fields[0])
    if code == OP_ARBITRATION_LOST:
        return ArbitrationLost(id=fields[0])
    if code == OP_BUS_ERROR:
        return BusError(id=fields[0], error_code=fields[1], error_flag=fields[2],
                        is_sender=bool(fields[3]))
    if code == OP_STATUS:
        return Status(status=fields[0])
    return Wakeup()


def iter_decode(buffer: bytes, *, where: str = "Tx_Data") -> Iterator[Operation]:
    """The operations of ``buffer``, in order.

    Raises
    ------
    FrameError
        A truncated header, a length that runs past the buffer or below the header's size,
        or an operation whose fields do not fit its length (naming ``where`` and the offset).
    """
    pos = 0
    while pos < len(buffer):
        if len(buffer) - pos < _HEADER.size:
            raise FrameError(f"{where}: {len(buffer) - pos} bytes at offset {pos} are not an "
                             f"operation header (8 bytes)")
        code, length = _HEADER.unpack_from(buffer, pos)
        if length < _HEADER.size or pos + length > len(buffer):
            raise FrameError(f"{where}: operation 0x{code:02X} at offset {pos} says length "
                             f"{length}; the buffer holds {len(buffer) - pos} bytes from there")
        yield _operation(code, bytes(buffer[pos + _HEADER.size:pos + length]),
                         f"{where} offset {pos}")
        pos += length


def decode(buffer: bytes, *, where: str = "Tx_Data") -> list[Operation]:
    """:func:`iter_decode` as a list."""
    return list(iter_decode(buffer, where=where))
