"""A CANopen node's error state (CiA 301): error register, pre-defined error field, EMCY payloads.

Pure logic, no bus: :class:`~hil.rig.canopen_device.CanopenDevice` owns one and sends the EMCY
frames. What CiA 301 asks, and what this does:

* 0x1001 *error register*: bit 0 (generic) is set while any error is active, the other bits
  (current, voltage, temperature, communication, device profile, manufacturer) are those of the
  active errors.
* EMCY: an error that occurs gives one EMCY with its error code and the error register; an
  error that goes away gives one EMCY with error code 0x0000 ("error reset or no error") and
  the error register of the errors still active (0 when none is left). A master clears its list
  of active errors on that code (canopen's ``EmcyConsumer.active``).
* 0x1003 *pre-defined error field*: the history of errors that occurred, newest at sub-index 1,
  at most as many as the object has sub-indices; sub-index 0 holds how many are stored, and
  writing 0 to it clears the history (any other value is refused with abort 0x06090030).
  Each entry is the error code in bits 0-15 and additional information in bits 16-31.

Example
-------
>>> errors = ErrorState(history_length=4)
>>> errors.occur(0x2310, ErrorRegister.CURRENT)
(8976, 3)
>>> errors.register, errors.history
(3, [8976])
>>> errors.clear(0x2310)
(0, 0)
>>> errors.register, errors.history
(0, [8976])
"""

from __future__ import annotations

import enum
import struct

__all__ = ["ABORT_NO_DATA", "ABORT_VALUE_RANGE", "ErrorRegister", "ErrorState", "emcy_payload"]

#: SDO abort: value range of parameter exceeded (a write to 0x1003:00 other than 0)
ABORT_VALUE_RANGE = 0x06090030
#: SDO abort: no data available (a 0x1003 sub-index beyond the stored count)
ABORT_NO_DATA = 0x08000024

_EMCY = struct.Struct("<HB5s")


class ErrorRegister(enum.IntFlag):
    """Bits of object 0x1001 (CiA 301 table 48)."""

    GENERIC = 0x01
    CURRENT = 0x02
    VOLTAGE = 0x04
    TEMPERATURE = 0x08
    COMMUNICATION = 0x10
    DEVICE_PROFILE = 0x20
    MANUFACTURER = 0x80


def register_bits_of(code: int) -> int:
    """The error register bits an error code implies by its class (CiA 301 table 21).

    >>> hex(register_bits_of(0x2310)), hex(register_bits_of(0x8130)), hex(register_bits_of(0x5000))
    ('0x3', '0x11', '0x1')
    >>> hex(register_bits_of(0x8210)), hex(register_bits_of(0x8611))
    ('0x11', '0x21')
    """
    bits = ErrorRegister.GENERIC
    high = code & 0xF000
    if high == 0x2000:
        bits |= ErrorRegister.CURRENT
    elif high == 0x3000:
        bits |= ErrorRegister.VOLTAGE
    elif high == 0x4000:
        bits |= ErrorRegister.TEMPERATURE
    elif code & 0xFF00 in (0x8100, 0x8200):    # communication, protocol (PDO length …)
        bits |= ErrorRegister.COMMUNICATION
    elif high == 0x8000:
        bits |= ErrorRegister.DEVICE_PROFILE
    elif code & 0xFF00 == 0xFF00:
        bits |= ErrorRegister.MANUFACTURER
    return int(bits)


def emcy_payload(code: int, register: int, manufacturer: bytes = b"") -> bytes:
    """The 8 data bytes of an EMCY frame (code little-endian, register, 5 bytes of data)."""
    return _EMCY.pack(code, register, manufacturer)


class ErrorState:
    """The errors of one node: which are active, the register, the history of 0x1003.

    Parameters
    ----------
    history_length
        How many entries 0x1003 holds (its highest sub-index); 0 if the node has no 0x1003.
    """

    def __init__(self, history_length: int = 0) -> None:
        self.history_length = max(0, int(history_length))
        #: active errors: code → its error register bits
        self.active: dict[int, int] = {}
        #: 0x1003 entries, newest first
        self.history: list[int] = []

    @property
    def register(self) -> int:
        """Object 0x1001: the OR of the active errors' bits (0 when none is active)."""
        reg = 0
        for bits in self.active.values():
            reg |= bits
        return reg

    def occur(self, code: int, bits: int | None = None, info: int = 0) -> tuple[int, int] | None:
        """Error ``code`` occurs: record it, return (code, register) for its EMCY.

        ``bits``: its error register bits (default: from the code's class; bit 0 always).
        Returns None if the error is already active (no second EMCY for the same error).
        """
        code &= 0xFFFF
        if code == 0:
            raise ValueError("error code 0x0000 means 'no error'; use clear()")
        if code in self.active:
            return None
        self.active[code] = int((register_bits_of(code) if bits is None else int(bits))
                                | ErrorRegister.GENERIC)
        if self.history_length:
            self.history.insert(0, ((int(info) & 0xFFFF) << 16) | code)
            del self.history[self.history_length:]
        return code, self.register

    def clear(self, code: int) -> tuple[int, int] | None:
        """Record that error ``code`` went away.

        Returns
        -------
        tuple of (int, int) or None
            (0x0000, register of the errors left) for the error-reset EMCY, or None if the error
            was not active.
        """
        if self.active.pop(code & 0xFFFF, None) is None:
            return None
        return 0, self.register

    def clear_all(self) -> tuple[int, int] | None:
        """Record that every active error went away (a fault reset).

        Returns
        -------
        tuple of (int, int) or None
            (0x0000, 0) for the error-reset EMCY, or None if no error was active.
        """
        if not self.active:
            return None
        self.active.clear()
        return 0, 0

    def clear_history(self) -> None:
        """0 written to 0x1003:00."""
        self.history.clear()

    def field(self, subindex: int) -> int:
        """Object 0x1003 at ``subindex`` (0: the count).

        Raises
        ------
        LookupError
            For a sub-index beyond the stored entries (the SDO server aborts 0x08000024).
        """
        if subindex == 0:
            return len(self.history)
        if 1 <= subindex <= len(self.history):
            return self.history[subindex - 1]
        raise LookupError(f"0x1003:{subindex:02X}: no error stored there")
