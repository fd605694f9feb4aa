"""Making VT object pools in code: tests, the reference implement's operator interface.

:class:`PoolBuilder` hands out object ids, fills every attribute the caller leaves out with a
neutral default (0, no object for references, scale 1), and builds an
:class:`~hil.isobus.vt.pool.ObjectPool` that is validated as a VT validates it::

    b = PoolBuilder()
    font = b.font(size=3)
    rate = b.number_variable(2500)
    keys = b.soft_key_mask([b.key(b.output_string("Master", font=font), key_code=1)])
    home = b.data_mask([(b.output_number(rate, font=font, width=120, height=24), 10, 10)],
                       soft_key_mask=keys)
    b.working_set(home)
    pool = b.build()            # raises VtPoolError naming a faulty object
    data = pool.to_bytes()      # the .iop bytes a client transfers
"""

from __future__ import annotations

from typing import Any

from hil.isobus.vt.codec import VtObject
from hil.isobus.vt.errors import NO_OBJECT
from hil.isobus.vt.layouts import LAYOUTS, F, ObjectType, Var, VarKind
from hil.isobus.vt.pool import ObjectPool

T = ObjectType
Child = tuple[int, int, int]


def _default(f: F) -> Any:
    if f.ref is not None:
        return NO_OBJECT
    if f.fmt == "f":
        return 1.0
    if f.values is not None:
        return f.values[0]
    return 0


class PoolBuilder:
    """Objects made one call at a time; ids from ``first_id`` up unless given."""

    def __init__(self, first_id: int = 1, version: int = 4) -> None:
        self.version = version
        self.objects: list[VtObject] = []
        self._next = first_id
        self._used: set[int] = set()

    # -- the generic form -----------------------------------------------------------------------

    def add(self, otype: ObjectType, object_id: int | None = None, **attrs: Any) -> int:
        """Add an object of ``otype``; attributes by their layout names; returns its id."""
        if object_id is None:
            while self._next in self._used:
                self._next += 1
            object_id = self._next
        elif object_id in self._used:
            raise ValueError(f"object id {object_id} is already used in this pool")
        self._used.add(object_id)
        full: dict[str, Any] = {}
        for item in LAYOUTS[otype]:
            if isinstance(item, F):
                full[item.name] = attrs.pop(item.name, _default(item))
            else:
                empty: Any = b"" if item.kind == VarKind.BYTES else []
                full[item.name] = attrs.pop(item.name, empty)
        if attrs:
            raise TypeError(f"{otype.name.lower()} has no attribute {', '.join(attrs)}")
        for item in LAYOUTS[otype]:
            if isinstance(item, Var):
                full[item.count] = len(full[item.name])
        self.objects.append(VtObject(object_id, otype, full))
        return object_id

    def build(self) -> ObjectPool:
        """The pool, validated (raises :class:`~hil.isobus.vt.errors.VtPoolError`)."""
        return ObjectPool.build(self.objects, self.version)

    # -- conveniences ----------------------------------------------------------------------------

    def working_set(self, active_mask: int, children: list[Child] | None = None,
                    object_id: int | None = None, **attrs: Any) -> int:
        """The working set object (its children are the working set's designator)."""
        return self.add(T.WORKING_SET, object_id, active_mask=active_mask, selectable=1,
                        children=children or [], **attrs)

    def data_mask(self, children: list[Child], soft_key_mask: int = NO_OBJECT,
                  object_id: int | None = None, **attrs: Any) -> int:
        """A data mask with its children at (x, y)."""
        return self.add(T.DATA_MASK, object_id, children=children,
                        soft_key_mask=soft_key_mask, **attrs)

    def alarm_mask(self, children: list[Child], soft_key_mask: int = NO_OBJECT,
                   priority: int = 1, acoustic_signal: int = 3, object_id: int | None = None,
                   **attrs: Any) -> int:
        """An alarm mask (priority 0 high, 1 medium, 2 low; signal 3: none)."""
        return self.add(T.ALARM_MASK, object_id, children=children,
                        soft_key_mask=soft_key_mask, priority=priority,
                        acoustic_signal=acoustic_signal, **attrs)

    def soft_key_mask(self, keys: list[int], object_id: int | None = None, **attrs: Any) -> int:
        """A soft key mask listing key objects."""
        return self.add(T.SOFT_KEY_MASK, object_id, keys=keys, **attrs)

    def key(self, label: int | None = None, key_code: int = 0, object_id: int | None = None,
            **attrs: Any) -> int:
        """A soft key drawing ``label`` (an object id, e.g. an output string) at (0, 0)."""
        children = [(label, 0, 0)] if label is not None else []
        return self.add(T.KEY, object_id, key_code=key_code, children=children,
                        background_colour=attrs.pop("background_colour", 7), **attrs)

    def button(self, label: int | None = None, width: int = 80, height: int = 40,
               key_code: int = 0, object_id: int | None = None, **attrs: Any) -> int:
        """A button drawing ``label`` at (2, 2)."""
        children = [(label, 2, 2)] if label is not None else []
        return self.add(T.BUTTON, object_id, width=width, height=height, key_code=key_code,
                        children=children, background_colour=attrs.pop("background_colour", 7),
                        **attrs)

    def font(self, size: int = 2, colour: int = 0, object_id: int | None = None,
             **attrs: Any) -> int:
        """Font attributes (size 0 is 6x8 ... 14 is 128x192; see :mod:`hil.isobus.vt.render`)."""
        return self.add(T.FONT_ATTRIBUTES, object_id, font_size=size, font_colour=colour,
                        **attrs)

    def number_variable(self, value: int = 0, object_id: int | None = None) -> int:
        """A number variable."""
        return self.add(T.NUMBER_VARIABLE, object_id, value=value)

    def string_variable(self, value: str | bytes, object_id: int | None = None) -> int:
        """A string variable."""
        raw = value.encode("latin-1") if isinstance(value, str) else value
        return self.add(T.STRING_VARIABLE, object_id, value=raw)

    def output_string(self, text: str | bytes = b"", font: int = NO_OBJECT, width: int = 100,
                      height: int = 20, object_id: int | None = None, **attrs: Any) -> int:
        """An output string (its own text, or ``variable_reference``'s)."""
        raw = text.encode("latin-1") if isinstance(text, str) else text
        return self.add(T.OUTPUT_STRING, object_id, value=raw, font_attributes=font,
                        width=width, height=height,
                        background_colour=attrs.pop("background_colour", 1), **attrs)

    def output_number(self, variable: int = NO_OBJECT, font: int = NO_OBJECT, width: int = 100,
                      height: int = 20, object_id: int | None = None, **attrs: Any) -> int:
        """An output number shown as ``(value + offset) * scale`` with ``decimals``."""
        return self.add(T.OUTPUT_NUMBER, object_id, variable_reference=variable,
                        font_attributes=font, width=width, height=height,
                        background_colour=attrs.pop("background_colour", 1), **attrs)

    def input_number(self, variable: int = NO_OBJECT, font: int = NO_OBJECT, width: int = 100,
                     height: int = 20, min_value: int = 0, max_value: int = 0xFFFFFFFF,
                     object_id: int | None = None, **attrs: Any) -> int:
        """An input number (enabled: ``options2`` bit 0)."""
        return self.add(T.INPUT_NUMBER, object_id, variable_reference=variable,
                        font_attributes=font, width=width, height=height,
                        min_value=min_value, max_value=max_value,
                        options2=attrs.pop("options2", 1),
                        background_colour=attrs.pop("background_colour", 1), **attrs)

    def input_string(self, variable: int = NO_OBJECT, font: int = NO_OBJECT, width: int = 100,
                     height: int = 20, object_id: int | None = None, **attrs: Any) -> int:
        """An input string, enabled."""
        return self.add(T.INPUT_STRING, object_id, variable_reference=variable,
                        font_attributes=font, width=width, height=height,
                        enabled=attrs.pop("enabled", 1),
                        background_colour=attrs.pop("background_colour", 1), **attrs)

    def rectangle(self, width: int, height: int, line: int = NO_OBJECT, fill: int = NO_OBJECT,
                  object_id: int | None = None, **attrs: Any) -> int:
        """An output rectangle."""
        return self.add(T.OUTPUT_RECTANGLE, object_id, width=width, height=height,
                        line_attributes=line, fill_attributes=fill, **attrs)

    def container(self, children: list[Child], width: int, height: int, hidden: bool = False,
                  object_id: int | None = None) -> int:
        """A container of children."""
        return self.add(T.CONTAINER, object_id, children=children, width=width, height=height,
                        hidden=int(hidden))

    def macro(self, commands: bytes, object_id: int | None = None) -> int:
        """A macro: command bytes (8 per command, as the ECU would send them)."""
        return self.add(T.MACRO, object_id, commands=commands)
