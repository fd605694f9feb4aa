"""The drive's object dictionary: which objects, their types and access, units, error codes.

Units: position 0.01 mm (0x60A8 = 0xFB010000, 10⁻⁵ m); velocity 0.01 mm/s (0x60A9 =
0xFB010300); acceleration 0.01 mm/s²; times in ms; torque and current in ‰ of the rated values
(0x6076 in mN·m, 0x6075 in mA); 0x6079 in mV; 0x2001 rod force in N. Position 0 is the rod fully
retracted (multi-turn absolute encoder, no homing). ``servo_cylinder_cia402.eds`` declares the
same objects (a test checks type, access, mapping and default of each).

Example
-------
>>> mm_to_increments(42.5), increments_to_mm(4250)
(4250, 42.5)
>>> OBJECTS[(0x6041, 0)].name
'Statusword'
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from hil.errors import HilError

__all__ = [
    "DATA_TYPE_RANGES",
    "MODE_NO_MODE",
    "MODE_PROFILE_POSITION",
    "MODE_PROFILE_VELOCITY",
    "OBJECTS",
    "POSITION_UNIT_MM",
    "SI_UNIT_POSITION",
    "SI_UNIT_VELOCITY",
    "SUPPORTED_DRIVE_MODES",
    "SUPPORTED_MODES",
    "DriveObjectError",
    "ErrorCode",
    "ObjectSpec",
    "clip_to_type",
    "increments_to_mm",
    "mm_to_increments",
]

#: One position increment of the object dictionary, in mm.
POSITION_UNIT_MM = 0.01
_INC_PER_MM = 100.0

MODE_NO_MODE = 0
MODE_PROFILE_POSITION = 1
MODE_PROFILE_VELOCITY = 3
SUPPORTED_MODES = (MODE_NO_MODE, MODE_PROFILE_POSITION, MODE_PROFILE_VELOCITY)

SI_UNIT_POSITION = 0xFB010000        # 10^-5 m = 0.01 mm
SI_UNIT_VELOCITY = 0xFB010300        # 10^-5 m/s = 0.01 mm/s
SUPPORTED_DRIVE_MODES = 0x00000005   # 0x6502: bit 0 pp, bit 2 pv

#: Value ranges of the CANopen integer types used.
DATA_TYPE_RANGES = {
    "U8": (0, 0xFF), "I8": (-0x80, 0x7F), "U16": (0, 0xFFFF), "I16": (-0x8000, 0x7FFF),
    "U32": (0, 0xFFFFFFFF), "I32": (-0x80000000, 0x7FFFFFFF),
}


def increments_to_mm(increments: int) -> float:
    """Object-dictionary increments (0.01 mm, mm/s, mm/s²) to mm."""
    return increments * POSITION_UNIT_MM


def mm_to_increments(mm: float) -> int:
    """mm (or mm/s, mm/s²) to the nearest object-dictionary increment."""
    return round(mm * _INC_PER_MM)


def clip_to_type(value: int, data_type: str) -> int:
    """Saturate ``value`` to the range of ``data_type``."""
    lo, hi = DATA_TYPE_RANGES[data_type]
    return lo if value < lo else hi if value > hi else value


class DriveObjectError(HilError, ValueError):
    """An object-dictionary access the drive refuses; ``abort_code`` is the SDO abort code.

    The rig's CANopen node raises ``canopen.SdoAbortedError(exc.abort_code)`` from it.
    """

    def __init__(self, message: str, *, abort_code: int) -> None:
        self.abort_code = abort_code
        super().__init__(message)


class ErrorCode(enum.IntEnum):
    """Error codes (0x603F and EMCY) the drive raises, from CiA 301/402."""

    NO_ERROR = 0x0000
    GENERIC = 0x1000
    CONTINUOUS_OVER_CURRENT = 0x2310
    DC_LINK_UNDER_VOLTAGE = 0x3220
    FOLLOWING_ERROR = 0x8611


@dataclass(frozen=True)
class ObjectSpec:
    """One object the drive implements (index, sub-index, CANopen data type, access)."""

    index: int
    subindex: int
    name: str
    data_type: str      # "U8", "I8", "U16", "I16", "U32", "I32"
    access: str         # "ro", "rw", "const"
    pdo_mappable: bool = False


def _spec(index: int, subindex: int, name: str, data_type: str, access: str,
          pdo: bool = False) -> ObjectSpec:
    return ObjectSpec(index, subindex, name, data_type, access, pdo)


#: Every object the drive reads or writes; the EDS declares the same ones.
OBJECTS: dict[tuple[int, int], ObjectSpec] = {
    (s.index, s.subindex): s for s in (
        _spec(0x1001, 0, "Error register", "U8", "ro", True),
        _spec(0x2001, 0, "Rod force actual value", "I32", "ro", True),
        _spec(0x2002, 0, "Overload time", "U16", "rw"),
        _spec(0x603F, 0, "Error code", "U16", "ro", True),
        _spec(0x6040, 0, "Controlword", "U16", "rw", True),
        _spec(0x6041, 0, "Statusword", "U16", "ro", True),
        _spec(0x605A, 0, "Quick stop option code", "I16", "rw"),
        _spec(0x605E, 0, "Fault reaction option code", "I16", "rw"),
        _spec(0x6060, 0, "Modes of operation", "I8", "rw", True),
        _spec(0x6061, 0, "Modes of operation display", "I8", "ro", True),
        _spec(0x6062, 0, "Position demand value", "I32", "ro", True),
        _spec(0x6064, 0, "Position actual value", "I32", "ro", True),
        _spec(0x6065, 0, "Following error window", "U32", "rw"),
        _spec(0x6066, 0, "Following error time out", "U16", "rw"),
        _spec(0x6067, 0, "Position window", "U32", "rw"),
        _spec(0x6068, 0, "Position window time", "U16", "rw"),
        _spec(0x606B, 0, "Velocity demand value", "I32", "ro", True),
        _spec(0x606C, 0, "Velocity actual value", "I32", "ro", True),
        _spec(0x606D, 0, "Velocity window", "U16", "rw"),
        _spec(0x606E, 0, "Velocity window time", "U16", "rw"),
        _spec(0x606F, 0, "Velocity threshold", "U16", "rw"),
        _spec(0x6070, 0, "Velocity threshold time", "U16", "rw"),
        _spec(0x6072, 0, "Max torque", "U16", "rw", True),
        _spec(0x6075, 0, "Motor rated current", "U32", "const"),
        _spec(0x6076, 0, "Motor rated torque", "U32", "const"),
        _spec(0x6077, 0, "Torque actual value", "I16", "ro", True),
        _spec(0x6078, 0, "Current actual value", "I16", "ro", True),
        _spec(0x6079, 0, "DC link circuit voltage", "U32", "ro", True),
        _spec(0x607A, 0, "Target position", "I32", "rw", True),
        _spec(0x607D, 0, "Highest sub-index supported", "U8", "const"),
        _spec(0x607D, 1, "Min position limit", "I32", "rw"),
        _spec(0x607D, 2, "Max position limit", "I32", "rw"),
        _spec(0x607F, 0, "Max profile velocity", "U32", "rw"),
        _spec(0x6080, 0, "Max motor speed", "U32", "const"),
        _spec(0x6081, 0, "Profile velocity", "U32", "rw", True),
        _spec(0x6083, 0, "Profile acceleration", "U32", "rw", True),
        _spec(0x6084, 0, "Profile deceleration", "U32", "rw", True),
        _spec(0x6085, 0, "Quick stop deceleration", "U32", "rw"),
        _spec(0x6086, 0, "Motion profile type", "I16", "rw"),
        _spec(0x60A8, 0, "SI unit position", "U32", "const"),
        _spec(0x60A9, 0, "SI unit velocity", "U32", "const"),
        _spec(0x60F4, 0, "Following error actual value", "I32", "ro", True),
        _spec(0x60FF, 0, "Target velocity", "I32", "rw", True),
        _spec(0x6502, 0, "Supported drive modes", "U32", "const"),
    )
}
