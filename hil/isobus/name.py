"""The 64-bit NAME of an ISO 11783-5 control function.

A control function identifies itself on the bus by its NAME, sent little-endian as the 8 data
bytes of the address-claimed parameter group (PGN 0xEE00). Read as an unsigned 64-bit integer,
the lower NAME wins an address contention. Bit layout (ISO 11783-5, clause 4.3; the same as
SAE J1939-81):

========  =====  ===========================
bits      width  field
========  =====  ===========================
0-20      21     identity number
21-31     11     manufacturer code
32-34     3      ECU instance
35-39     5      function instance
40-47     8      function
48        1      reserved (sent as 0)
49-55     7      device class
56-59     4      device class instance
60-62     3      industry group
63        1      self-configurable address
========  =====  ===========================
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import total_ordering

from hil.errors import FrameError

#: (field, lowest bit, width) of the NAME, in bit order
NAME_LAYOUT: tuple[tuple[str, int, int], ...] = (
    ("identity_number", 0, 21),
    ("manufacturer_code", 21, 11),
    ("ecu_instance", 32, 3),
    ("function_instance", 35, 5),
    ("function", 40, 8),
    ("device_class", 49, 7),
    ("device_class_instance", 56, 4),
    ("industry_group", 60, 3),
    ("self_configurable", 63, 1),
)

#: industry group 2: agricultural and forestry equipment (ISO 11783-1, annex B)
INDUSTRY_GROUP_AGRICULTURAL = 2


@total_ordering
@dataclass(frozen=True)
class IsobusName:
    """A control function's NAME, field by field.

    Parameters
    ----------
    identity_number : int
        Serial number of the ECU, 21 bits.
    manufacturer_code : int
        ISO 11783 / J1939 manufacturer code, 11 bits.
    ecu_instance : int
        Which of several ECUs of one function, 3 bits.
    function_instance : int
        Which of several functions of one kind, 5 bits.
    function : int
        Function code, 8 bits (0-127 global; 128-255 depend on industry group and device class).
    device_class : int
        Device class, 7 bits (group 2: 0 non-specific, 1 tractor, 4 planters/seeders,
        5 fertilizers, 6 sprayers).
    device_class_instance : int
        Which of several devices of one class, 4 bits.
    industry_group : int
        Industry group, 3 bits (2: agricultural and forestry).
    self_configurable : bool
        The control function can claim another address when it loses its preferred one.

    Raises
    ------
    FrameError
        A field does not fit its width (the message names the field).
    """

    identity_number: int = 0
    manufacturer_code: int = 0
    ecu_instance: int = 0
    function_instance: int = 0
    function: int = 0
    device_class: int = 0
    device_class_instance: int = 0
    industry_group: int = INDUSTRY_GROUP_AGRICULTURAL
    self_configurable: bool = False

    def __post_init__(self) -> None:
        for name, _, width in NAME_LAYOUT:
            value = int(getattr(self, name))
            if not 0 <= value < (1 << width):
                raise FrameError(f"NAME field {name} = {value} does not fit {width} bits "
                                 f"(0 .. {(1 << width) - 1})")

    @property
    def value(self) -> int:
        """The NAME as an unsigned 64-bit integer (the order of contention)."""
        out = 0
        for name, shift, _ in NAME_LAYOUT:
            out |= int(getattr(self, name)) << shift
        return out

    def to_bytes(self) -> bytes:
        """The 8 data bytes of an address-claimed message (little-endian)."""
        return self.value.to_bytes(8, "little")

    @classmethod
    def from_int(cls, value: int) -> IsobusName:
        """Split a 64-bit NAME into its fields (the reserved bit 48 is dropped).

        Raises
        ------
        FrameError
            ``value`` is not an unsigned 64-bit integer.
        """
        if not 0 <= value < (1 << 64):
            raise FrameError(f"a NAME is an unsigned 64-bit integer, got {value}")
        kwargs: dict[str, int | bool] = {}
        for name, shift, width in NAME_LAYOUT:
            kwargs[name] = (value >> shift) & ((1 << width) - 1)
        kwargs["self_configurable"] = bool(kwargs["self_configurable"])
        return cls(**kwargs)  # type: ignore[arg-type]

    @classmethod
    def from_bytes(cls, data: bytes) -> IsobusName:
        """Decode the 8 data bytes of an address-claimed message.

        Raises
        ------
        FrameError
            ``data`` is not 8 bytes long.
        """
        if len(data) != 8:
            raise FrameError(f"an address-claimed message carries an 8-byte NAME, got "
                             f"{len(data)} bytes: {bytes(data).hex()}")
        return cls.from_int(int.from_bytes(data, "little"))

    def __lt__(self, other: object) -> bool:
        if not isinstance(other, IsobusName):
            return NotImplemented
        return self.value < other.value

    def describe(self) -> str:
        """One line naming every field, for logs."""
        parts = [f"{f.name}={int(getattr(self, f.name))}" for f in fields(self)]
        return f"NAME 0x{self.value:016X} ({', '.join(parts)})"


def name_value(name: IsobusName | int) -> int:
    """The 64-bit integer of ``name``, whether given as fields or as an integer."""
    return name.value if isinstance(name, IsobusName) else int(name)
