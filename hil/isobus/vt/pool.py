"""A working set's object pool as the VT holds it: objects by id, checked as the standard says.

:meth:`ObjectPool.from_transfers` parses the transfers a client sent before its end of object
pool message (a later transfer replaces objects of the same id) and validates the whole:

- exactly one working set object;
- every object reference (children, attribute objects, variables, soft key masks, list
  items, macros) names an object the pool has (else ``UNKNOWN_REFERENCE``) of a type the
  attribute may name (else ``ANY_OTHER``);
- the working set's active mask is a data or alarm mask;
- the VT can draw it: no object contains itself (through children, keys, list items or object
  pointers), and no object draws more than :data:`MAX_DRAWN` objects (an object shown twice
  counts twice: 32 levels of containers each listing the next one twice would be 4 billion
  objects drawn from 64 bytes of pool). Both are ``ANY_OTHER``, naming the object.

The first fault in pool order raises :class:`~hil.isobus.vt.errors.VtPoolError` naming the
object and its parent (the first object that lists it), so the end of object pool response
names them as the standard asks.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Iterator

from hil.isobus.vt.codec import VtObject, parse_objects, serialise_object
from hil.isobus.vt.errors import NO_OBJECT, PoolErrorCode, VtPoolError
from hil.isobus.vt.layouts import LAYOUTS, F, ObjectType, Var, VarKind

T = ObjectType

MAX_DRAWN = 4_096
"""Objects one object may draw at most, counting each showing (its children, theirs, ...):
drawing 4,096 objects takes the rig ~60 ms (Pillow), a mask of the 100 kB sample pool 62."""
_DRAWN_VIA = frozenset({"children", "keys", "items", "object_refs"})
#: per type, the variable parts drawing follows: (attribute, whether it is a child list)
_DRAWING_PARTS: dict[ObjectType, tuple[tuple[str, bool], ...]] = {
    otype: tuple((item.name, item.kind == VarKind.CHILDREN) for item in items
                 if isinstance(item, Var) and item.name in _DRAWN_VIA
                 and item.kind in (VarKind.CHILDREN, VarKind.REFS))
    for otype, items in LAYOUTS.items()}


class ObjectPool:
    """Objects by id, with their parents; built by :meth:`from_transfers` or :meth:`build`."""

    def __init__(self, objects: dict[int, VtObject], version: int, raw: tuple[bytes, ...],
                 ) -> None:
        self.objects = objects
        self.version = version
        #: the transfers as received (what a stored version keeps)
        self.raw = raw
        self.parents: dict[int, int] = {}
        for obj in objects.values():
            for child in _listed(obj):
                self.parents.setdefault(child, obj.object_id)
        ws = [o for o in objects.values() if o.type == T.WORKING_SET]
        self.working_set: VtObject | None = ws[0] if len(ws) == 1 else None

    # -- building -------------------------------------------------------------------------------

    @classmethod
    def from_transfers(cls, transfers: Iterable[bytes], version: int = 4) -> ObjectPool:
        """Parse and validate the transfers of one pool (each without its 0x11 byte).

        Raises
        ------
        VtPoolError
            The pool's first fault, naming the object.
        """
        objects: dict[int, VtObject] = {}
        raw = tuple(bytes(t) for t in transfers)
        for part in raw:
            seen: set[int] = set()
            for obj in parse_objects(part, version):
                if obj.object_id in seen:
                    raise VtPoolError(f"object id {obj.object_id} is used twice in one "
                                      f"transfer", object_id=obj.object_id,
                                      code=PoolErrorCode.ANY_OTHER)
                seen.add(obj.object_id)
                objects[obj.object_id] = obj
        pool = cls(objects, version, raw)
        pool.validate()
        return pool

    @classmethod
    def build(cls, objects: Iterable[VtObject], version: int = 4) -> ObjectPool:
        """A pool from objects made in code; its one transfer is their bytes in order."""
        data = b"".join(serialise_object(o) for o in objects)
        return cls.from_transfers([data], version)

    def to_bytes(self) -> bytes:
        """All transfers as one byte string (what a client's pool file holds)."""
        return b"".join(self.raw)

    # -- look-ups -------------------------------------------------------------------------------

    def __contains__(self, object_id: object) -> bool:
        return object_id in self.objects

    def __iter__(self) -> Iterator[VtObject]:
        return iter(self.objects.values())

    def __len__(self) -> int:
        return len(self.objects)

    def get(self, object_id: int) -> VtObject | None:
        """The object with this id, ``None`` if there is none."""
        return self.objects.get(object_id)

    def of_type(self, *types: ObjectType) -> list[VtObject]:
        """The objects of the given types, in id order."""
        return sorted((o for o in self.objects.values() if o.type in types),
                      key=lambda o: o.object_id)

    @property
    def size(self) -> int:
        """Bytes transferred."""
        return sum(len(r) for r in self.raw)

    @property
    def sha256(self) -> str:
        """Hash of the transferred bytes (hex)."""
        digest = hashlib.sha256()
        for part in self.raw:
            digest.update(part)
        return digest.hexdigest()

    def parent_of(self, object_id: int) -> int:
        """The first object that lists ``object_id`` (:data:`NO_OBJECT` if none)."""
        return self.parents.get(object_id, NO_OBJECT)

    def counts(self) -> dict[str, int]:
        """How many objects of each type (the pool's listing)."""
        out: dict[str, int] = {}
        for obj in self.objects.values():
            key = obj.type.name.lower()
            out[key] = out.get(key, 0) + 1
        return dict(sorted(out.items()))

    # -- the standard's rules -------------------------------------------------------------------

    def validate(self) -> None:
        """Raise the first fault (see the module docstring)."""
        ws = [o for o in self.objects.values() if o.type == T.WORKING_SET]
        if len(ws) != 1:
            raise VtPoolError(f"the pool has {len(ws)} working set objects, not one",
                              object_id=ws[1].object_id if len(ws) > 1 else NO_OBJECT,
                              code=PoolErrorCode.ANY_OTHER)
        for obj in self.objects.values():
            self._check_references(obj)
        active = self.objects.get(ws[0]["active_mask"])
        if active is None:
            raise VtPoolError(f"the working set's active mask {ws[0]['active_mask']} does "
                              f"not exist", object_id=ws[0].object_id,
                              code=PoolErrorCode.UNKNOWN_REFERENCE)
        self.check_drawable()

    def check_drawable(self) -> None:
        """Raise when an object contains itself or draws more than :data:`MAX_DRAWN` objects
        (one pass over the objects that draw others, each once)."""
        parts: dict[int, list[int]] = {}
        for oid in self.objects:
            listed = drawn_parts(self, oid)
            if listed:
                parts[oid] = listed
        drawn: dict[int, int] = {}
        on_path: set[int] = set()
        for root in parts:
            if root in drawn:
                continue
            # iterative depth-first walk: a chain of 10,000 containers is no recursion error
            stack: list[tuple[int, list[int]]] = [(root, list(parts[root]))]
            on_path.add(root)
            while stack:
                oid, todo = stack[-1]
                if todo:
                    nxt = todo.pop()
                    if nxt in drawn or nxt not in parts:
                        continue
                    if nxt in on_path:
                        obj = self.objects[oid]
                        raise VtPoolError(f"{obj.type.name.lower()} draws object {nxt}, which "
                                          f"contains it: the VT cannot draw an object inside "
                                          f"itself", object_id=oid,
                                          parent_id=self.parent_of(oid),
                                          code=PoolErrorCode.ANY_OTHER)
                    stack.append((nxt, list(parts[nxt])))
                    on_path.add(nxt)
                    continue
                stack.pop()
                on_path.discard(oid)
                count = 1 + sum(drawn.get(part, 1) for part in parts[oid]
                                if part in self.objects)
                if count > MAX_DRAWN:
                    obj = self.objects[oid]
                    raise VtPoolError(f"{obj.type.name.lower()} draws {count} objects (each "
                                      f"showing counted), more than the VT's {MAX_DRAWN}",
                                      object_id=oid, parent_id=self.parent_of(oid),
                                      code=PoolErrorCode.ANY_OTHER)
                drawn[oid] = count

    def _check_references(self, obj: VtObject) -> None:
        for item in LAYOUTS[obj.type]:
            if isinstance(item, F):
                if item.ref is None:
                    continue
                self._check_ref(obj, item.name, obj.attrs[item.name], item.ref, True)
            elif item.kind == VarKind.CHILDREN:
                for child, _x, _y in obj.attrs[item.name]:
                    self._check_ref(obj, "children", child, item.ref, False)
            elif item.kind == VarKind.REFS and item.ref is not None:
                for ref in obj.attrs[item.name]:
                    self._check_ref(obj, item.name, ref, item.ref, item.null_ok)
            elif item.kind == VarKind.MACROS:
                for _event, macro in obj.attrs[item.name]:
                    self._check_ref(obj, "macros", macro, frozenset({T.MACRO}), False)

    def _check_ref(self, obj: VtObject, what: str, ref: int,
                   allowed: frozenset[ObjectType] | None, null_ok: bool) -> None:
        if ref == NO_OBJECT:
            if null_ok:
                return
            raise VtPoolError(f"{obj.type.name.lower()} {what} lists object 65535 (no object)",
                              object_id=obj.object_id, parent_id=self.parent_of(obj.object_id),
                              code=PoolErrorCode.UNKNOWN_REFERENCE)
        target = self.objects.get(ref)
        if target is None:
            raise VtPoolError(f"{obj.type.name.lower()} {what} names object {ref}, which the "
                              f"pool does not have", object_id=obj.object_id,
                              parent_id=self.parent_of(obj.object_id),
                              code=PoolErrorCode.UNKNOWN_REFERENCE)
        if allowed is not None and target.type not in allowed:
            raise VtPoolError(f"{obj.type.name.lower()} {what} names object {ref}, a "
                              f"{target.type.name.lower()}, which it may not",
                              object_id=obj.object_id, parent_id=self.parent_of(obj.object_id),
                              code=PoolErrorCode.ANY_OTHER)


def drawn_parts(pool: ObjectPool, object_id: int) -> list[int]:
    """The ids drawing ``object_id`` draws: its children, keys, list items and window
    objects, an object pointer's value, an external object pointer's default object (each
    as often as it is listed)."""
    obj = pool.objects.get(object_id)
    if obj is None:
        return []
    if obj.type == T.OBJECT_POINTER:
        return [int(obj["value"])] if obj["value"] != NO_OBJECT else []
    if obj.type == T.EXTERNAL_OBJECT_POINTER:
        return [int(obj["default_object"])] if obj["default_object"] != NO_OBJECT else []
    out: list[int] = []
    for name, children in _DRAWING_PARTS[obj.type]:
        if children:
            out.extend(child for child, _x, _y in obj.attrs[name])
        else:
            out.extend(ref for ref in obj.attrs[name] if ref != NO_OBJECT)
    return out


def _listed(obj: VtObject) -> Iterator[int]:
    """The ids an object lists as its parts (children, keys, list items, window refs)."""
    for item in LAYOUTS[obj.type]:
        if isinstance(item, Var):
            if item.kind == VarKind.CHILDREN:
                for child, _x, _y in obj.attrs[item.name]:
                    yield child
            elif item.kind == VarKind.REFS:
                yield from obj.attrs[item.name]
