"""A refused object pool: the end of object pool response's error codes and the faulty object.

ISO 11783-6 end of object pool response (VT to ECU, function 0x12): byte 2 error codes (bit 0:
there are errors in the pool, bit 1: the VT ran out of memory during the transfer), bytes 3-4
the faulty object's parent id, bytes 5-6 the faulty object's id, byte 7 the object pool error
codes below (0xFFFF for an id that is not known).
"""

from __future__ import annotations

from enum import IntFlag

from hil.errors import HilError

NO_OBJECT = 0xFFFF


class EndOfPoolError(IntFlag):
    """Byte 2 of the end of object pool response."""

    NONE = 0
    ERRORS_IN_POOL = 0x01
    OUT_OF_MEMORY = 0x02


class PoolErrorCode(IntFlag):
    """Byte 7 of the end of object pool response (object pool error codes).

    How the rig uses them: an object type the VT does not know or does not support in its
    version, and an attribute outside the values the standard allows, are ``NOT_SUPPORTED``
    ("method or attribute not supported by the VT"); a reference to an object the pool does not
    have (child, attribute object, variable, macro) is ``UNKNOWN_REFERENCE``; everything else
    (a truncated object, an id used twice in one transfer, a reference to an object of the
    wrong type, no working set object) is ``ANY_OTHER``.
    """

    NONE = 0
    NOT_SUPPORTED = 0x01
    UNKNOWN_REFERENCE = 0x02
    ANY_OTHER = 0x04
    DELETED = 0x08


class VtPoolError(HilError, ValueError):
    """A pool the VT refuses, with the codes its end of object pool response carries.

    Attributes
    ----------
    object_id, parent_id : int
        The faulty object and its parent (:data:`NO_OBJECT` when not known).
    code : PoolErrorCode
        The object pool error code.
    """

    def __init__(self, message: str, *, object_id: int = NO_OBJECT,
                 parent_id: int = NO_OBJECT,
                 code: PoolErrorCode = PoolErrorCode.ANY_OTHER) -> None:
        self.object_id = object_id
        self.parent_id = parent_id
        self.code = code
        where = f"object {object_id}: " if object_id != NO_OBJECT else ""
        super().__init__(f"{where}{message}")

    def response(self) -> bytes:
        """The 8-byte end of object pool response that refuses the pool."""
        return bytes([0x12, int(EndOfPoolError.ERRORS_IN_POOL),
                      self.parent_id & 0xFF, self.parent_id >> 8,
                      self.object_id & 0xFF, self.object_id >> 8, int(self.code), 0xFF])
