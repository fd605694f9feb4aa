"""A parsed device descriptor object pool and the look-ups a Task Controller needs of it."""

from __future__ import annotations

from dataclasses import dataclass, field

from hil.isobus.ddop.codec import parse_pool, serialise_pool
from hil.isobus.ddop.objects import (
    DdopObject,
    Device,
    DeviceElement,
    ProcessData,
    Property,
    ValuePresentation,
)
from hil.isobus.ddop.validate import check


@dataclass(frozen=True)
class ObjectPool:
    """A device descriptor object pool: its objects in transfer order and the client's version.

    Build one with :meth:`from_bytes` (a pool received from a client) or with
    :class:`~hil.isobus.ddop.builder.PoolBuilder` (a pool made in code).
    """

    objects: tuple[DdopObject, ...]
    version: int = 4
    _by_id: dict[int, DdopObject] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        by_id: dict[int, DdopObject] = {}
        for obj in self.objects:
            by_id.setdefault(obj.object_id, obj)
        object.__setattr__(self, "_by_id", by_id)

    @classmethod
    def from_bytes(cls, data: bytes, *, version: int = 4, validate: bool = True) -> ObjectPool:
        """Parse (and by default validate) a binary pool.

        Raises
        ------
        DdopError
            A :class:`~hil.isobus.ddop.errors.DdopParseError` for malformed bytes, or the first
            rule the pool breaks; either names the object.
        """
        pool = cls(parse_pool(data, version=version), version)
        if validate:
            pool.validate()
        return pool

    def to_bytes(self) -> bytes:
        """The binary pool, byte for byte what :meth:`from_bytes` read."""
        return serialise_pool(self.objects, version=self.version)

    def validate(self) -> None:
        """Raise the first broken rule (see :func:`hil.isobus.ddop.validate.problems`)."""
        check(self.objects, version=self.version)

    @property
    def device(self) -> Device:
        """The pool's device object."""
        for obj in self.objects:
            if isinstance(obj, Device):
                return obj
        raise LookupError("the pool has no device object")

    @property
    def elements(self) -> tuple[DeviceElement, ...]:
        """The device elements in pool order."""
        return tuple(o for o in self.objects if isinstance(o, DeviceElement))

    def get(self, object_id: int) -> DdopObject | None:
        """The object with ``object_id``, or ``None``."""
        return self._by_id.get(object_id)

    def element(self, element_number: int) -> DeviceElement | None:
        """The element with ``element_number``, or ``None``."""
        for element in self.elements:
            if element.element_number == element_number:
                return element
        return None

    def children(self, element: DeviceElement) -> tuple[ProcessData | Property, ...]:
        """The DPD and DPT objects ``element`` lists, in its order (missing ids skipped)."""
        found = (self._by_id.get(i) for i in element.children)
        return tuple(o for o in found if isinstance(o, ProcessData | Property))

    def process_data(self, element_number: int, ddi: int) -> ProcessData | None:
        """The DPD of ``ddi`` on element ``element_number``, or ``None``."""
        element = self.element(element_number)
        if element is None:
            return None
        for child in self.children(element):
            if isinstance(child, ProcessData) and child.ddi == ddi:
                return child
        return None

    def property_value(self, element_number: int, ddi: int) -> int | None:
        """The value of the DPT of ``ddi`` on element ``element_number``, or ``None``."""
        element = self.element(element_number)
        if element is None:
            return None
        for child in self.children(element):
            if isinstance(child, Property) and child.ddi == ddi:
                return child.value
        return None

    def presentation(self, obj: ProcessData | Property) -> ValuePresentation | None:
        """The DVP ``obj`` refers to, or ``None``."""
        target = self._by_id.get(obj.presentation_id)
        return target if isinstance(target, ValuePresentation) else None

    def element_path(self, element: DeviceElement) -> tuple[DeviceElement, ...]:
        """``element`` and its ancestors up to the device element (stops on a broken chain)."""
        path = [element]
        seen = {element.object_id}
        parent = self._by_id.get(element.parent_id)
        while isinstance(parent, DeviceElement) and parent.object_id not in seen:
            path.append(parent)
            seen.add(parent.object_id)
            parent = self._by_id.get(parent.parent_id)
        return tuple(path)
