"""A parsed device descriptor object pool and the look-ups a Task Controller needs of it."""

from __future__ import annotations

from dataclasses import dataclass, field

from hil.isobus.ddop.codec import parse_pool, serialise_pool
from hil.isobus.ddop.objects import (
    DdopObject,
    Device,
    DeviceElement,
    ProcessData,
    ProcessDataProperty,
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
    _by_number: dict[int, DeviceElement] = field(init=False, repr=False, compare=False)
    _entities: dict[tuple[int, int], ProcessData | Property] = field(
        init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # Look-ups by id, element number and (element number, DDI), built once: the TC answers
        # every value a client sends with them.
        by_id: dict[int, DdopObject] = {}
        for obj in self.objects:
            by_id.setdefault(obj.object_id, obj)
        by_number: dict[int, DeviceElement] = {}
        entities: dict[tuple[int, int], ProcessData | Property] = {}
        for obj in self.objects:
            if isinstance(obj, DeviceElement):
                by_number.setdefault(obj.element_number, obj)
        for number, element in by_number.items():
            for child_id in element.children:
                child = by_id.get(child_id)
                if isinstance(child, ProcessData | Property):
                    entities.setdefault((number, child.ddi) if isinstance(child, ProcessData)
                                        else (number, -1 - child.ddi), child)
        object.__setattr__(self, "_by_id", by_id)
        object.__setattr__(self, "_by_number", by_number)
        object.__setattr__(self, "_entities", entities)

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
        return self._by_number.get(element_number)

    def children(self, element: DeviceElement) -> tuple[ProcessData | Property, ...]:
        """The DPD and DPT objects ``element`` lists, in its order (missing ids skipped)."""
        found = (self._by_id.get(i) for i in element.children)
        return tuple(o for o in found if isinstance(o, ProcessData | Property))

    def process_data(self, element_number: int, ddi: int) -> ProcessData | None:
        """The (first) DPD of ``ddi`` on element ``element_number``, or ``None``."""
        found = self._entities.get((element_number, ddi))
        return found if isinstance(found, ProcessData) else None

    def property_value(self, element_number: int, ddi: int) -> int | None:
        """The value of the (first) DPT of ``ddi`` on element ``element_number``, or ``None``."""
        found = self._entities.get((element_number, -1 - ddi))
        return found.value if isinstance(found, Property) else None

    def settable(self) -> tuple[tuple[int, int], ...]:
        """``(element number, DDI)`` of every settable DPD, in pool order."""
        return tuple(key for key, entity in self._entities.items()
                     if isinstance(entity, ProcessData)
                     and entity.properties & ProcessDataProperty.SETTABLE)

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
