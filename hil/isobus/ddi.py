"""The ISO 11783-11 data dictionary entries the rig's Task Controller and its clients use.

A data dictionary identifier (DDI) names what a process data value means: its unit, the weight of
one bit (the resolution) and its range. Values travel on the bus as 32-bit integers; the physical
value is ``raw * resolution`` in the DDI's unit.

Source: the ISO 11783-11 online data base (isobus.net) as exported into AgIsoStack++'s
``isobus/src/isobus_data_dictionary.cpp`` (generated 28 October 2025; Open-Agriculture/
AgIsoStack-plus-plus at commit 509a920c). Each entry below is copied from that table, number,
name, unit, resolution and range, for the DDIs this rig sends, logs or finds in a client's
device descriptor. Two corrections to what one might expect from the numbering:

- the section control look-ahead times a client declares are DDI 205 (SC setpoint turn-on time)
  and DDI 206 (SC setpoint turn-off time); DDI 203/204 are tank agitation pressures, and the
  physical set-point/actual value time latencies are DDI 142/143;
- the maximum working width is DDI 70 (DDI 46 is the set-point count per time rate).

A DDI not in this table is still a valid DDI on the bus (the server logs it as a raw value); the
table only gives meaning to the ones the rig reasons about.
"""

from __future__ import annotations

from dataclasses import dataclass

from hil.errors import HilError

INT32_MIN = -(2**31)
INT32_MAX = 2**31 - 1
UINT32_MAX = 2**32 - 1

PROPRIETARY_FIRST = 0xE000
"""First DDI of the manufacturer-proprietary range (57344 .. 65534)."""
PROPRIETARY_LAST = 0xFFFE
"""Last DDI of the manufacturer-proprietary range."""
RESERVED = 0xFFFF
"""DDI 65535, reserved: never a valid process data entity."""


class UnknownDdiError(HilError, KeyError):
    """A DDI the table does not hold was looked up."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else "unknown DDI"


@dataclass(frozen=True)
class DdiEntry:
    """One data dictionary entry.

    Attributes
    ----------
    number : int
        The DDI (0 .. 65535).
    name : str
        The dictionary's name for it.
    unit : str
        Unit of the physical value (``""`` for states and bit fields).
    resolution : float
        Weight of one bit: physical value = raw * resolution.
    raw_min, raw_max : int
        Range of the raw 32-bit value. A range above :data:`INT32_MAX` (the condensed work
        states) marks an unsigned bit field.
    """

    number: int
    name: str
    unit: str
    resolution: float
    raw_min: int
    raw_max: int

    @property
    def unsigned(self) -> bool:
        """Whether the raw value is an unsigned 32-bit field (the condensed work states)."""
        return self.raw_max > INT32_MAX

    def physical(self, raw: int) -> float:
        """The physical value of ``raw`` in :attr:`unit`."""
        return raw * self.resolution

    def raw(self, value: float) -> int:
        """The raw integer for physical ``value``, rounded to the nearest bit.

        Raises
        ------
        ValueError
            When the value is outside the entry's range.
        """
        raw = round(value / self.resolution)
        if not self.raw_min <= raw <= self.raw_max:
            raise ValueError(
                f"DDI {self.number} ({self.name}): {value} {self.unit} is outside "
                f"{self.physical(self.raw_min)} .. {self.physical(self.raw_max)}"
            )
        return raw

    def in_range(self, raw: int) -> bool:
        """Whether ``raw`` lies within the entry's range."""
        return self.raw_min <= raw <= self.raw_max


# Named DDIs (the numbers other modules use by name).
SETPOINT_VOLUME_PER_AREA_RATE = 1
ACTUAL_VOLUME_PER_AREA_RATE = 2
DEFAULT_VOLUME_PER_AREA_RATE = 3
MINIMUM_VOLUME_PER_AREA_RATE = 4
MAXIMUM_VOLUME_PER_AREA_RATE = 5
SETPOINT_MASS_PER_AREA_RATE = 6
ACTUAL_MASS_PER_AREA_RATE = 7
DEFAULT_MASS_PER_AREA_RATE = 8
MINIMUM_MASS_PER_AREA_RATE = 9
MAXIMUM_MASS_PER_AREA_RATE = 10
SETPOINT_COUNT_PER_AREA_RATE = 11
ACTUAL_COUNT_PER_AREA_RATE = 12
DEFAULT_COUNT_PER_AREA_RATE = 13
MINIMUM_COUNT_PER_AREA_RATE = 14
MAXIMUM_COUNT_PER_AREA_RATE = 15
ACTUAL_VOLUME_PER_TIME_RATE = 37
SETPOINT_MASS_PER_TIME_RATE = 41
ACTUAL_MASS_PER_TIME_RATE = 42
DEFAULT_MASS_PER_TIME_RATE = 43
SETPOINT_SEEDING_DEPTH = 56
ACTUAL_SEEDING_DEPTH = 57
DEFAULT_SEEDING_DEPTH = 58
MINIMUM_SEEDING_DEPTH = 59
MAXIMUM_SEEDING_DEPTH = 60
SETPOINT_WORKING_WIDTH = 66
ACTUAL_WORKING_WIDTH = 67
DEFAULT_WORKING_WIDTH = 68
MINIMUM_WORKING_WIDTH = 69
MAXIMUM_WORKING_WIDTH = 70
APPLICATION_TOTAL_VOLUME = 80
APPLICATION_TOTAL_MASS = 81
APPLICATION_TOTAL_COUNT = 82
TOTAL_AREA = 116
EFFECTIVE_TOTAL_DISTANCE = 117
INEFFECTIVE_TOTAL_DISTANCE = 118
EFFECTIVE_TOTAL_TIME = 119
DEVICE_ELEMENT_OFFSET_X = 134
DEVICE_ELEMENT_OFFSET_Y = 135
DEVICE_ELEMENT_OFFSET_Z = 136
ACTUAL_WORK_STATE = 141
PHYSICAL_SETPOINT_TIME_LATENCY = 142
PHYSICAL_ACTUAL_VALUE_TIME_LATENCY = 143
CONNECTOR_TYPE = 157
PRESCRIPTION_CONTROL_STATE = 158
SECTION_CONTROL_STATE = 160
ACTUAL_CONDENSED_WORK_STATE_1_16 = 161
ACTUAL_CONDENSED_WORK_STATE_241_256 = 176
ACTUAL_CULTURAL_PRACTICE = 179
SC_SETPOINT_TURN_ON_TIME = 205
SC_SETPOINT_TURN_OFF_TIME = 206
SETPOINT_WORK_STATE = 289
SETPOINT_CONDENSED_WORK_STATE_1_16 = 290
SETPOINT_CONDENSED_WORK_STATE_241_256 = 305
ACTUAL_SPEED = 397
PGN_BASED_DATA = 57342
REQUEST_DEFAULT_PROCESS_DATA = 0xDFFF  # 57343

SECTIONS_PER_CONDENSED_DDI = 16
"""Sections one condensed work state DDI carries, 2 bits each."""

_MAX = INT32_MAX


def _e(number: int, name: str, unit: str, resolution: float, raw_min: int, raw_max: int,
       ) -> DdiEntry:
    return DdiEntry(number, name, unit, resolution, raw_min, raw_max)


_ENTRIES: list[DdiEntry] = [
    _e(1, "Setpoint Volume Per Area Application Rate as [mm³/m²]", "mm³/m²", 0.01, 0, _MAX),
    _e(2, "Actual Volume Per Area Application Rate as [mm³/m²]", "mm³/m²", 0.01, 0, _MAX),
    _e(3, "Default Volume Per Area Application Rate as [mm³/m²]", "mm³/m²", 0.01, 0, _MAX),
    _e(4, "Minimum Volume Per Area Application Rate as [mm³/m²]", "mm³/m²", 0.01, 0, _MAX),
    _e(5, "Maximum Volume Per Area Application Rate as [mm³/m²]", "mm³/m²", 0.01, 0, _MAX),
    _e(6, "Setpoint Mass Per Area Application Rate", "mg/m²", 1.0, 0, _MAX),
    _e(7, "Actual Mass Per Area Application Rate", "mg/m²", 1.0, 0, _MAX),
    _e(8, "Default Mass Per Area Application Rate", "mg/m²", 1.0, 0, _MAX),
    _e(9, "Minimum Mass Per Area Application Rate", "mg/m²", 1.0, 0, _MAX),
    _e(10, "Maximum Mass Per Area Application Rate", "mg/m²", 1.0, 0, _MAX),
    _e(11, "Setpoint Count Per Area Application Rate", "/m²", 0.001, 0, _MAX),
    _e(12, "Actual Count Per Area Application Rate", "/m²", 0.001, 0, _MAX),
    _e(13, "Default Count Per Area Application Rate", "/m²", 0.001, 0, _MAX),
    _e(14, "Minimum Count Per Area Application Rate", "/m²", 0.001, 0, _MAX),
    _e(15, "Maximum Count Per Area Application Rate", "/m²", 0.001, 0, _MAX),
    _e(37, "Actual Volume Per Time Application Rate", "mm³/s", 1.0, 0, _MAX),
    _e(41, "Setpoint Mass Per Time Application Rate", "mg/s", 1.0, 0, _MAX),
    _e(42, "Actual Mass Per Time Application Rate", "mg/s", 1.0, 0, _MAX),
    _e(43, "Default Mass Per Time Application Rate", "mg/s", 1.0, 0, _MAX),
    _e(56, "Setpoint Seeding Depth", "mm", 1.0, 0, _MAX),
    _e(57, "Actual Seeding Depth", "mm", 1.0, 0, _MAX),
    _e(58, "Default Seeding Depth", "mm", 1.0, 0, _MAX),
    _e(59, "Minimum Seeding Depth", "mm", 1.0, 0, _MAX),
    _e(60, "Maximum Seeding Depth", "mm", 1.0, 0, _MAX),
    _e(66, "Setpoint Working Width", "mm", 1.0, 0, _MAX),
    _e(67, "Actual Working Width", "mm", 1.0, 0, _MAX),
    _e(68, "Default Working Width", "mm", 1.0, 0, _MAX),
    _e(69, "Minimum Working Width", "mm", 1.0, 0, _MAX),
    _e(70, "Maximum Working Width", "mm", 1.0, 0, _MAX),
    _e(80, "Application Total Volume as [L]", "L", 1.0, 0, _MAX),
    _e(81, "Application Total Mass in [kg]", "kg", 1.0, 0, _MAX),
    _e(82, "Application Total Count", "#", 1.0, 0, _MAX),
    _e(116, "Total Area", "m²", 1.0, 0, _MAX),
    _e(117, "Effective Total Distance", "mm", 1.0, 0, _MAX),
    _e(118, "Ineffective Total Distance", "mm", 1.0, 0, _MAX),
    _e(119, "Effective Total Time", "s", 1.0, 0, _MAX),
    _e(134, "Device Element Offset X", "mm", 1.0, INT32_MIN, _MAX),
    _e(135, "Device Element Offset Y", "mm", 1.0, INT32_MIN, _MAX),
    _e(136, "Device Element Offset Z", "mm", 1.0, INT32_MIN, _MAX),
    _e(141, "Actual Work State", "", 1.0, 0, 3),
    _e(142, "Physical Setpoint Time Latency", "ms", 1.0, 0, _MAX),
    _e(143, "Physical Actual Value Time Latency", "ms", 1.0, INT32_MIN, _MAX),
    _e(157, "Connector Type", "", 1.0, -1, 10),
    _e(158, "Prescription Control State", "", 1.0, 0, 3),
    _e(160, "Section Control State", "", 1.0, 0, 3),
    *(
        _e(161 + i, f"Actual Condensed Work State ({16 * i + 1}-{16 * i + 16})", "", 1.0, 0,
           UINT32_MAX)
        for i in range(16)
    ),
    _e(179, "Actual Cultural Practice", "", 1.0, 0, _MAX),
    _e(205, "SC Setpoint Turn On Time", "ms", 1.0, INT32_MIN, _MAX),
    _e(206, "SC Setpoint Turn Off Time", "ms", 1.0, INT32_MIN, _MAX),
    _e(289, "Setpoint Work State", "", 1.0, 0, 3),
    *(
        _e(290 + i, f"Setpoint Condensed Work State ({16 * i + 1}-{16 * i + 16})", "", 1.0, 0,
           UINT32_MAX)
        for i in range(16)
    ),
    _e(397, "Actual Speed", "mm/s", 1.0, INT32_MIN, _MAX),
    _e(57342, "PGN Based Data", "", 1.0, INT32_MIN, _MAX),
    _e(57343, "Request Default Process Data", "", 1.0, 0, 0),
]

DDI_TABLE: dict[int, DdiEntry] = {entry.number: entry for entry in _ENTRIES}
"""Every entry of this module, by DDI number."""


def lookup(ddi: int) -> DdiEntry:
    """The table's entry for ``ddi``.

    Raises
    ------
    UnknownDdiError
        When the table holds no entry for it (it may still be a valid DDI on the bus).
    """
    try:
        return DDI_TABLE[ddi]
    except KeyError:
        raise UnknownDdiError(f"DDI {ddi} (0x{ddi:04X}) is not in hil.isobus.ddi's table") \
            from None


def name_of(ddi: int) -> str:
    """A readable name for any DDI: the table's, or what range it falls in."""
    entry = DDI_TABLE.get(ddi)
    if entry is not None:
        return entry.name
    if PROPRIETARY_FIRST <= ddi <= PROPRIETARY_LAST:
        return f"Proprietary DDI {ddi}"
    if ddi == RESERVED:
        return "Reserved DDI 65535"
    return f"DDI {ddi}"


def condensed_work_state_ddi(section: int, *, setpoint: bool) -> tuple[int, int]:
    """The condensed work state DDI carrying ``section`` and the section's slot in it.

    Parameters
    ----------
    section : int
        Section index from 0 (the first section) to 255.
    setpoint : bool
        ``True`` for the set-point DDIs (290-305), ``False`` for the actual ones (161-176).

    Returns
    -------
    tuple of int
        ``(ddi, slot)``: slot 0 is the two least significant bits of the value.
    """
    if not 0 <= section < 16 * SECTIONS_PER_CONDENSED_DDI:
        raise ValueError(f"section index {section} is outside 0 .. 255")
    first = SETPOINT_CONDENSED_WORK_STATE_1_16 if setpoint else ACTUAL_CONDENSED_WORK_STATE_1_16
    return first + section // SECTIONS_PER_CONDENSED_DDI, section % SECTIONS_PER_CONDENSED_DDI


def pack_condensed_work_state(states: list[int]) -> int:
    """Pack up to 16 two-bit section states (0 off, 1 on, 2 error, 3 not installed).

    Slots past the end of ``states`` are 3 (not installed), as ISO 11783-11 asks.
    """
    if len(states) > SECTIONS_PER_CONDENSED_DDI:
        raise ValueError(f"{len(states)} section states do not fit one condensed DDI (16)")
    value = 0
    for slot in range(SECTIONS_PER_CONDENSED_DDI):
        state = states[slot] if slot < len(states) else 3
        if not 0 <= state <= 3:
            raise ValueError(f"section state {state} in slot {slot} is not 0 .. 3")
        value |= state << (2 * slot)
    return value


def unpack_condensed_work_state(value: int) -> list[int]:
    """The 16 two-bit section states of a condensed work state value (slot 0 first)."""
    value &= UINT32_MAX
    return [(value >> (2 * slot)) & 0x3 for slot in range(SECTIONS_PER_CONDENSED_DDI)]
