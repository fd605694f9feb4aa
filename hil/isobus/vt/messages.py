"""The VT's messages (ISO 11783-6): parameter groups, function codes, byte helpers.

Every VT message is one parameter group: PGN 0xE600 from the VT to a working set, 0xE700 from a
working set to the VT; the first data byte is the function. Messages are 8 bytes padded with
0xFF; longer ones (object pool transfer, change string value with a long string, versions
lists) go by TP or ETP.
"""

from __future__ import annotations

from enum import IntEnum

VT_TO_ECU_PGN = 0xE600
ECU_TO_VT_PGN = 0xE700
WORKING_SET_MASTER_PGN = 0xFE0D
ACKNOWLEDGEMENT_PGN = 0xE800
LABEL_LENGTH = 7
"""Bytes of a version label (extended versions: 32)."""
EXTENDED_LABEL_LENGTH = 32


class Function(IntEnum):
    """Function codes (first data byte) the rig's VT sends or handles."""

    SOFT_KEY_ACTIVATION = 0x00
    BUTTON_ACTIVATION = 0x01
    POINTING_EVENT = 0x02
    VT_SELECT_INPUT_OBJECT = 0x03
    VT_ESC = 0x04
    VT_CHANGE_NUMERIC_VALUE = 0x05
    VT_CHANGE_ACTIVE_MASK = 0x06
    VT_CHANGE_SOFT_KEY_MASK = 0x07
    VT_CHANGE_STRING_VALUE = 0x08
    OBJECT_POOL_TRANSFER = 0x11
    END_OF_OBJECT_POOL = 0x12
    HIDE_SHOW = 0xA0
    ENABLE_DISABLE = 0xA1
    SELECT_INPUT_OBJECT = 0xA2
    CONTROL_AUDIO_SIGNAL = 0xA3
    SET_AUDIO_VOLUME = 0xA4
    CHANGE_CHILD_LOCATION = 0xA5
    CHANGE_SIZE = 0xA6
    CHANGE_BACKGROUND_COLOUR = 0xA7
    CHANGE_NUMERIC_VALUE = 0xA8
    CHANGE_END_POINT = 0xA9
    CHANGE_FONT_ATTRIBUTES = 0xAA
    CHANGE_LINE_ATTRIBUTES = 0xAB
    CHANGE_FILL_ATTRIBUTES = 0xAC
    CHANGE_ACTIVE_MASK = 0xAD
    CHANGE_SOFT_KEY_MASK = 0xAE
    CHANGE_ATTRIBUTE = 0xAF
    CHANGE_PRIORITY = 0xB0
    CHANGE_LIST_ITEM = 0xB1
    DELETE_OBJECT_POOL = 0xB2
    CHANGE_STRING_VALUE = 0xB3
    CHANGE_CHILD_POSITION = 0xB4
    EXECUTE_EXTENDED_MACRO = 0xBC
    LOCK_UNLOCK_MASK = 0xBD
    EXECUTE_MACRO = 0xBE
    GET_MEMORY = 0xC0
    GET_SUPPORTED_WIDECHARS = 0xC1
    GET_NUMBER_OF_SOFT_KEYS = 0xC2
    GET_TEXT_FONT_DATA = 0xC3
    GET_WINDOW_MASK_DATA = 0xC4
    GET_SUPPORTED_OBJECTS = 0xC5
    GET_HARDWARE = 0xC7
    STORE_VERSION = 0xD0
    LOAD_VERSION = 0xD1
    DELETE_VERSION = 0xD2
    EXTENDED_GET_VERSIONS = 0xD3
    EXTENDED_STORE_VERSION = 0xD4
    EXTENDED_LOAD_VERSION = 0xD5
    EXTENDED_DELETE_VERSION = 0xD6
    GET_VERSIONS = 0xDF
    GET_VERSIONS_RESPONSE = 0xE0
    UNSUPPORTED_FUNCTION = 0xFD
    VT_STATUS = 0xFE
    WORKING_SET_MAINTENANCE = 0xFF


class KeyActivation(IntEnum):
    """Byte 2 of a soft key or button activation."""

    RELEASED = 0
    PRESSED = 1
    STILL_HELD = 2
    ABORTED = 3


def pad(data: bytes | bytearray | list[int]) -> bytes:
    """``data`` padded with 0xFF to 8 bytes (longer messages are left as they are)."""
    raw = bytes(data)
    return raw + b"\xff" * (8 - len(raw)) if len(raw) < 8 else raw


def u16(value: int) -> bytes:
    """Two bytes, little-endian."""
    return bytes([value & 0xFF, (value >> 8) & 0xFF])


def u32(value: int) -> bytes:
    """Four bytes, little-endian."""
    return (value & 0xFFFFFFFF).to_bytes(4, "little")


def get16(data: bytes, at: int) -> int:
    """Little-endian u16 at ``at``."""
    return data[at] | data[at + 1] << 8


def get32(data: bytes, at: int) -> int:
    """Little-endian u32 at ``at``."""
    return int.from_bytes(data[at:at + 4], "little")
