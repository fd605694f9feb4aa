"""The device descriptor object pool (DDOP) of ISO 11783-10: objects, binary form, rules.

A Task Controller client describes itself to the TC with a DDOP: one device (DVC), a tree of
device elements (DET: the device, booms, bins, sections), their process data (DPD: DDIs the TC
reads, sets and logs) and properties (DPT: fixed values such as offsets and widths), and value
presentations (DVP). :func:`parse_pool` and :func:`serialise_pool` convert the binary form
exactly; :func:`problems` lists the standard's rules a pool breaks, each a :class:`DdopError`
naming the object with the activate response's error codes; :class:`PoolBuilder` makes pools in
code; :class:`ObjectPool` holds one and answers the TC's look-ups.
"""

from hil.isobus.ddop.builder import PoolBuilder
from hil.isobus.ddop.codec import parse_pool, serialise_object, serialise_pool
from hil.isobus.ddop.errors import ActivationError, DdopError, DdopParseError, PoolError
from hil.isobus.ddop.objects import (
    NULL_OBJECT_ID,
    DdopObject,
    Device,
    DeviceElement,
    ElementType,
    ProcessData,
    ProcessDataProperty,
    Property,
    TriggerMethod,
    ValuePresentation,
)
from hil.isobus.ddop.pool import ObjectPool
from hil.isobus.ddop.validate import check, problems

__all__ = [
    "NULL_OBJECT_ID",
    "ActivationError",
    "DdopError",
    "DdopObject",
    "DdopParseError",
    "Device",
    "DeviceElement",
    "ElementType",
    "ObjectPool",
    "PoolBuilder",
    "PoolError",
    "ProcessData",
    "ProcessDataProperty",
    "Property",
    "TriggerMethod",
    "ValuePresentation",
    "check",
    "parse_pool",
    "problems",
    "serialise_object",
    "serialise_pool",
]
