"""One working set as the VT knows it: its connection, its pool, what its masks show now.

The pool's objects are the VT's working copy: the client's commands change their attributes
(values, hidden, sizes, the working set's active mask), so what is drawn is always the pool's
present state. A stored version keeps the transfers as received, never this copy.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

from hil.isobus.vt.codec import VtObject
from hil.isobus.vt.errors import NO_OBJECT
from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.pool import ObjectPool
from hil.isobus.vt.store import ClientKey

T = ObjectType

#: objects an operator can enter a value into
INPUTS = frozenset({T.INPUT_BOOLEAN, T.INPUT_STRING, T.INPUT_NUMBER, T.INPUT_LIST})
#: objects whose number the change numeric value command sets
NUMERIC = frozenset({T.INPUT_BOOLEAN, T.INPUT_NUMBER, T.INPUT_LIST, T.OUTPUT_NUMBER,
                     T.OUTPUT_LIST, T.OUTPUT_METER, T.OUTPUT_LINEAR_BAR_GRAPH,
                     T.OUTPUT_ARCHED_BAR_GRAPH, T.NUMBER_VARIABLE, T.OBJECT_POINTER,
                     T.ANIMATION, T.EXTERNAL_OBJECT_POINTER, T.SCALED_GRAPHIC})
STRINGS = frozenset({T.INPUT_STRING, T.OUTPUT_STRING, T.STRING_VARIABLE})


@dataclass
class WorkingSet:
    """The VT's state of one working set master (lost when the VT restarts)."""

    address: int
    key: ClientKey
    name: int | None
    connected_s: float
    last_seen_s: float
    maintenance_s: float | None = None
    memory_asked_s: float | None = None
    version: int | None = None
    transfers: list[bytes] = field(default_factory=list)
    pool: ObjectPool | None = None
    activated_s: float | None = None
    loaded_label: bytes | None = None
    stored_labels: list[bytes] = field(default_factory=list)
    locked_mask: int | None = None
    lock_until_s: float | None = None
    open_input: int | None = None

    @property
    def active(self) -> bool:
        """Whether its pool is active (parsed, validated, shown)."""
        return self.pool is not None

    # -- what is shown ---------------------------------------------------------------------------

    @property
    def active_mask(self) -> int:
        """The data or alarm mask the working set shows (:data:`NO_OBJECT` without a pool)."""
        if self.pool is None or self.pool.working_set is None:
            return NO_OBJECT
        return int(self.pool.working_set["active_mask"])

    @property
    def soft_key_mask(self) -> int:
        """The active mask's soft key mask."""
        mask = self.obj(self.active_mask)
        return int(mask.get("soft_key_mask", NO_OBJECT)) if mask is not None else NO_OBJECT

    def obj(self, object_id: int) -> VtObject | None:
        """An object of the pool."""
        return self.pool.get(object_id) if self.pool is not None else None

    def resolve(self, object_id: int) -> VtObject | None:
        """The object, following object pointers (a pointer to nothing is ``None``)."""
        seen = 0
        obj = self.obj(object_id)
        while obj is not None and obj.type == T.OBJECT_POINTER and seen < 16:
            obj = self.obj(obj["value"])
            seen += 1
        return obj

    def visible(self, root: int | None = None) -> Iterator[tuple[VtObject, int, int, int]]:
        """(object, x, y, parent id) of everything drawn on ``root`` (the active mask and its
        soft keys when ``None``), depth first, hidden containers left out."""
        roots = [self.active_mask, self.soft_key_mask] if root is None else [root]
        for r in roots:
            obj = self.resolve(r)
            if obj is None:
                continue
            if obj.type == T.SOFT_KEY_MASK:
                for key_id in obj["keys"]:
                    key = self.resolve(key_id)
                    if key is not None:
                        yield key, 0, 0, obj.object_id
                        yield from self._children(key, 0, 0, 0)
            else:
                yield obj, 0, 0, NO_OBJECT
                yield from self._children(obj, 0, 0, 0)

    def _children(self, obj: VtObject, x: int, y: int, depth: int,
                  ) -> Iterator[tuple[VtObject, int, int, int]]:
        if depth > 32:
            return
        for child_id, cx, cy in obj.children:
            child = self.resolve(child_id)
            if child is None:
                continue
            if child.type == T.CONTAINER and child["hidden"]:
                continue
            yield child, x + cx, y + cy, obj.object_id
            yield from self._children(child, x + cx, y + cy, depth + 1)

    def is_shown(self, object_id: int) -> bool:
        """Whether the object is drawn now (on the active mask or its soft key mask)."""
        return any(o.object_id == object_id for o, *_ in self.visible())

    # -- values ----------------------------------------------------------------------------------

    def number(self, obj: VtObject) -> int:
        """An object's numeric value (its variable's, when it references one)."""
        ref = obj.get("variable_reference", NO_OBJECT)
        var = self.obj(ref) if ref != NO_OBJECT else None
        return int(var["value"]) if var is not None else int(obj.get("value", 0))

    def text(self, obj: VtObject) -> str:
        """An object's string value (its variable's, when it references one)."""
        ref = obj.get("variable_reference", NO_OBJECT)
        var = self.obj(ref) if ref != NO_OBJECT else None
        raw = var["value"] if var is not None else obj.get("value", b"")
        return decode_text(raw)

    def label(self, object_id: int) -> str:
        """What a key or button says: the texts of its children, joined."""
        obj = self.resolve(object_id)
        if obj is None:
            return ""
        parts = []
        for child, *_ in self._children(obj, 0, 0, 0):
            if child.type in STRINGS:
                parts.append(self.text(child))
        return " ".join(p for p in parts if p)


def decode_text(raw: bytes) -> str:
    """A VT string as text: UTF-16 when it starts with the byte order mark 0xFEFF (version 4),
    else ISO 8859-1; trailing spaces and NULs removed."""
    if raw[:2] == b"\xff\xfe":
        return raw[2:].decode("utf-16-le", "replace").rstrip(" \x00")
    return raw.decode("latin-1").rstrip(" \x00")
