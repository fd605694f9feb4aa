"""Errors of a device descriptor object pool, each naming the object and mapping onto the codes
of the object pool activate response (ISO 11783-10, process data command 1, parameter 9)."""

from __future__ import annotations

from enum import IntFlag

from hil.errors import HilError


class ActivationError(IntFlag):
    """Object pool activate response, byte 2 (activation error bits)."""

    NONE = 0x00
    ERRORS_IN_DDOP = 0x01
    OUT_OF_MEMORY = 0x02
    ANY_OTHER_ERROR = 0x04
    DIFFERENT_DDOP_SAME_STRUCTURE_LABEL = 0x08


class PoolError(IntFlag):
    """Object pool activate response, byte 7 (object pool error bits)."""

    NONE = 0x00
    METHOD_OR_ATTRIBUTE_NOT_SUPPORTED = 0x01
    UNKNOWN_OBJECT_REFERENCE = 0x02
    ANY_OTHER_ERROR = 0x04
    DDOP_DELETED_FROM_VOLATILE_MEMORY = 0x08


NO_OBJECT = 0xFFFF


class DdopError(HilError, ValueError):
    """A pool that cannot be parsed or breaks a rule of ISO 11783-10.

    Attributes
    ----------
    object_id : int or None
        The offending object (``None`` when the bytes end before an object id).
    parent_id : int or None
        The offending object's parent element, when it has one.
    reason : str
        What is wrong, in words.
    pool_error : PoolError
        The object pool error bit the activate response carries for this error.
    activation_error : ActivationError
        The activation error bit.
    """

    def __init__(self, reason: str, *, object_id: int | None, parent_id: int | None = None,
                 pool_error: PoolError = PoolError.ANY_OTHER_ERROR,
                 activation_error: ActivationError = ActivationError.ERRORS_IN_DDOP,
                 offset: int | None = None) -> None:
        self.reason = reason
        self.object_id = object_id
        self.parent_id = parent_id
        self.pool_error = pool_error
        self.activation_error = activation_error
        self.offset = offset
        where = f"DDOP object {object_id}" if object_id is not None else "DDOP"
        if offset is not None:
            where += f" at byte {offset}"
        super().__init__(f"{where}: {reason}")


class DdopParseError(DdopError):
    """The bytes are not a well-formed object pool (truncated, unknown table id, bad length)."""
