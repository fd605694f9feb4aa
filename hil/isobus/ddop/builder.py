"""Make a device descriptor object pool in code.

>>> from hil.isobus.ddop import ElementType, PoolBuilder
>>> b = PoolBuilder()
>>> dvc = b.device("Planter", software_version="1.0", name=0xA00C80000AE00002,
...                structure_label=b"AGRIHIL")
>>> dev = b.element(ElementType.DEVICE, "Planter", parent=dvc)
>>> rate = b.presentation("kg/ha", scale=0.01, decimals=1)
>>> _ = b.process_data(dev, ddi=6, designator="Target rate", settable=True, presentation=rate)
>>> len(b.build().to_bytes())
107

Object ids are given in call order from 0 and element numbers from 0 unless stated; each
:meth:`PoolBuilder.process_data` and :meth:`PoolBuilder.property` call adds the new object to
its element's children. :meth:`PoolBuilder.build` validates the pool.
"""

from __future__ import annotations

import struct
from dataclasses import replace

from hil.isobus.ddop.objects import (
    LABEL_LENGTH,
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

DEFAULT_LOCALIZATION = b"en\x00\x00\x00\x00\xff"
"""English, metric formats, reserved byte 0xFF."""


class PoolBuilder:
    """Collects objects and hands out object ids and element numbers.

    Parameters
    ----------
    version : int
        The ISO 11783-10 version the pool is for (designator encoding, extended label).
    """

    def __init__(self, *, version: int = 4) -> None:
        self.version = version
        self._objects: list[DdopObject] = []
        self._next_id = 0
        self._next_element = 0

    def _id(self, object_id: int | None) -> int:
        if object_id is None:
            used = {o.object_id for o in self._objects}
            while self._next_id in used:
                self._next_id += 1
            object_id = self._next_id
            self._next_id += 1
        return object_id

    def _text(self, value: str) -> bytes:
        return value.encode("utf-8" if self.version >= 4 else "latin-1")

    def device(self, designator: str, *, software_version: str, name: int,
               serial_number: str = "1", structure_label: bytes = b"\x00" * LABEL_LENGTH,
               localization_label: bytes = DEFAULT_LOCALIZATION,
               extended_structure_label: bytes = b"", object_id: int | None = None) -> int:
        """Add the device object (DVC); returns its object id."""
        oid = self._id(object_id)
        self._objects.append(Device(
            oid, self._text(designator), self._text(software_version), name,
            self._text(serial_number), bytes(structure_label).ljust(LABEL_LENGTH, b" "),
            bytes(localization_label), bytes(extended_structure_label)))
        return oid

    def element(self, element_type: ElementType | int, designator: str, *, parent: int,
                element_number: int | None = None, object_id: int | None = None) -> int:
        """Add a device element (DET) under ``parent`` (the DVC for the device element)."""
        oid = self._id(object_id)
        if element_number is None:
            element_number = self._next_element
        self._next_element = max(self._next_element, element_number + 1)
        self._objects.append(DeviceElement(oid, int(element_type), self._text(designator),
                                           element_number, parent))
        return oid

    def _add_child(self, element_id: int, child_id: int) -> None:
        for i, obj in enumerate(self._objects):
            if isinstance(obj, DeviceElement) and obj.object_id == element_id:
                self._objects[i] = replace(obj, children=(*obj.children, child_id))
                return
        raise KeyError(f"no device element with object id {element_id} to add {child_id} to")

    def process_data(self, element: int, *, ddi: int, designator: str = "",
                     settable: bool = False, default_set: bool = True,
                     control_source: bool = False,
                     triggers: TriggerMethod | int = TriggerMethod.ON_CHANGE,
                     presentation: int = NULL_OBJECT_ID, object_id: int | None = None) -> int:
        """Add a process data object (DPD) to ``element``; returns its object id."""
        oid = self._id(object_id)
        properties = ((ProcessDataProperty.MEMBER_OF_DEFAULT_SET if default_set else 0)
                      | (ProcessDataProperty.SETTABLE if settable else 0)
                      | (ProcessDataProperty.CONTROL_SOURCE if control_source else 0))
        self._objects.append(ProcessData(oid, ddi, int(properties), int(triggers),
                                         self._text(designator), presentation))
        self._add_child(element, oid)
        return oid

    def property(self, element: int, *, ddi: int, value: int, designator: str = "",
                 presentation: int = NULL_OBJECT_ID, object_id: int | None = None) -> int:
        """Add a property object (DPT) with a fixed ``value`` to ``element``."""
        oid = self._id(object_id)
        self._objects.append(Property(oid, ddi, value, self._text(designator), presentation))
        self._add_child(element, oid)
        return oid

    def presentation(self, designator: str, *, offset: int = 0, scale: float = 1.0,
                     decimals: int = 0, object_id: int | None = None) -> int:
        """Add a value presentation (DVP); returns its object id.

        The scale is stored as the float32 the binary form carries, so a built pool equals the
        pool parsed from its bytes.
        """
        oid = self._id(object_id)
        (scale32,) = struct.unpack("<f", struct.pack("<f", scale))
        self._objects.append(ValuePresentation(oid, offset, scale32, decimals,
                                               self._text(designator)))
        return oid

    def add(self, obj: DdopObject) -> int:
        """Add a ready-made object as it is (for pools that break a rule on purpose)."""
        self._objects.append(obj)
        return obj.object_id

    def objects(self) -> tuple[DdopObject, ...]:
        """The objects so far, unvalidated."""
        return tuple(self._objects)

    def build(self, *, validate: bool = True) -> ObjectPool:
        """The pool; validated unless ``validate`` is false.

        Raises
        ------
        DdopError
            The first rule the pool breaks, naming the object.
        """
        pool = ObjectPool(tuple(self._objects), self.version)
        if validate:
            pool.validate()
        return pool
