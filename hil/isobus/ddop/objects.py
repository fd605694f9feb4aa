"""The five object types of a device descriptor object pool (ISO 11783-10, annex A, version 4).

Each object is a frozen dataclass holding every field the binary form carries, as the bytes the
client sent (designators are :class:`bytes`, UTF-8 in version 4, ISO 8859-1 before it), so that a
parsed pool serialises back to exactly the bytes it came from. Text accessors decode them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum, IntFlag

NULL_OBJECT_ID = 0xFFFF
"""The object id that references nothing (a process data without a presentation)."""
MAX_ELEMENT_NUMBER = 4095
"""Element numbers are 12 bits on the bus (process data byte 1 high nibble + byte 2)."""
LABEL_LENGTH = 7
"""Bytes of a structure label and of a localization label."""


class ElementType(IntEnum):
    """Device element types (DET byte 6)."""

    DEVICE = 1
    FUNCTION = 2
    BIN = 3
    SECTION = 4
    UNIT = 5
    CONNECTOR = 6
    NAVIGATION_REFERENCE = 7


class ProcessDataProperty(IntFlag):
    """DPD properties bit field (byte 8)."""

    MEMBER_OF_DEFAULT_SET = 0x01
    SETTABLE = 0x02
    CONTROL_SOURCE = 0x04
    """Version 4; excludes :attr:`SETTABLE`."""


class TriggerMethod(IntFlag):
    """DPD available trigger methods bit field (byte 9)."""

    TIME_INTERVAL = 0x01
    DISTANCE_INTERVAL = 0x02
    THRESHOLD_LIMITS = 0x04
    ON_CHANGE = 0x08
    TOTAL = 0x10


@dataclass(frozen=True)
class Device:
    """DVC: the device (one per pool).

    Attributes
    ----------
    object_id : int
    designator, software_version, serial_number : bytes
    name : int
        The client's 64-bit ISO 11783-5 NAME.
    structure_label : bytes
        7 bytes; changes whenever the pool's structure changes.
    localization_label : bytes
        7 bytes: language (2 ASCII), number/time/date/unit formats, reserved.
    extended_structure_label : bytes
        Version 4 only (0 .. 32 bytes); absent from a version 3 pool.
    """

    object_id: int
    designator: bytes
    software_version: bytes
    name: int
    serial_number: bytes
    structure_label: bytes
    localization_label: bytes
    extended_structure_label: bytes = b""

    TABLE = b"DVC"


@dataclass(frozen=True)
class DeviceElement:
    """DET: a device element (the device, a boom, a bin, a section, a connector ...)."""

    object_id: int
    element_type: int
    designator: bytes
    element_number: int
    parent_id: int
    children: tuple[int, ...] = field(default=())

    TABLE = b"DET"


@dataclass(frozen=True)
class ProcessData:
    """DPD: a process data entity of an element (a DDI the TC can read, set or log)."""

    object_id: int
    ddi: int
    properties: int
    trigger_methods: int
    designator: bytes
    presentation_id: int = NULL_OBJECT_ID

    TABLE = b"DPD"


@dataclass(frozen=True)
class Property:
    """DPT: a fixed property of an element (an offset, a width): a DDI with a constant value."""

    object_id: int
    ddi: int
    value: int
    designator: bytes
    presentation_id: int = NULL_OBJECT_ID

    TABLE = b"DPT"


@dataclass(frozen=True)
class ValuePresentation:
    """DVP: how a value is shown: ``(raw + offset) * scale`` with ``decimals`` decimals."""

    object_id: int
    offset: int
    scale: float
    decimals: int
    designator: bytes

    TABLE = b"DVP"


DdopObject = Device | DeviceElement | ProcessData | Property | ValuePresentation
"""Any object of a pool."""

TABLE_NAMES: dict[bytes, str] = {
    b"DVC": "device",
    b"DET": "device element",
    b"DPD": "device process data",
    b"DPT": "device property",
    b"DVP": "device value presentation",
}
