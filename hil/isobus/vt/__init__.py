"""The rig's Virtual Terminal (ISO 11783-6): object pools, the VT server, the scripted operator.

:mod:`~hil.isobus.vt.layouts` and :mod:`~hil.isobus.vt.codec` read and write the objects of a
pool, :class:`~hil.isobus.vt.pool.ObjectPool` validates a whole pool as a VT does and names
the faulty object (:class:`~hil.isobus.vt.errors.VtPoolError`), and
:class:`~hil.isobus.vt.builder.PoolBuilder` makes pools in code.
"""

from hil.isobus.vt.builder import PoolBuilder
from hil.isobus.vt.codec import VtObject, parse_objects, serialise_object
from hil.isobus.vt.errors import NO_OBJECT, EndOfPoolError, PoolErrorCode, VtPoolError
from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.pool import ObjectPool

__all__ = [
    "NO_OBJECT",
    "EndOfPoolError",
    "ObjectPool",
    "ObjectType",
    "PoolBuilder",
    "PoolErrorCode",
    "VtObject",
    "VtPoolError",
    "parse_objects",
    "serialise_object",
]
