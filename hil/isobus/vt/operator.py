"""The operator, scripted: soft keys and buttons, numeric and string input, alarm acknowledgement.

An :class:`Operator` acts on the VT's active working set (or the one at ``address``) at run
times, through the VT server's timers, so a script runs the same in lockstep and in real time:

- ``press(target, at_s, hold_s)``: a soft key or button, by object id or by its label (the
  text it shows); the VT reports it pressed, still held every 0.2 s while held, released;
- ``enter(target, value, at_s)``: a number into an input number (in the units it shows:
  ``value / scale - offset`` is sent), an index into an input list, 0/1 into an input boolean;
- ``type(target, text, at_s)``: text into an input string;
- ``acknowledge(at_s, key=None)``: the active alarm mask acknowledged by pressing a key of its
  soft key mask (the first, or ``key``): ISO 11783-6 leaves acknowledgement to the working
  set's own soft keys, and a terminal's ACK key is one of them;
- ``escape(at_s)``: ESC.

A target the pool does not have is refused before the run by :func:`check_steps` (a setup
error naming the step and the object); at run time a key that is not on the screen at that
moment is not pressed and the VT's log says so (the operator cannot press what he does not
see).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from hil.config import from_mapping, read_toml
from hil.errors import ConfigError
from hil.isobus.vt.codec import VtObject
from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.messages import KeyActivation
from hil.isobus.vt.pool import ObjectPool
from hil.isobus.vt.server import KEY_REPEAT_S, VirtualTerminalServer
from hil.isobus.vt.steps import OperatorStep
from hil.isobus.vt.workingset import WorkingSet

T = ObjectType
__all__ = ["ENTERABLE", "PRESSABLE", "Operator", "OperatorStep", "Target", "check_steps",
           "find", "read_operator_steps", "shown_value", "to_raw"]
Target = int | str
PRESSABLE = (T.KEY, T.BUTTON)
ENTERABLE = (T.INPUT_NUMBER, T.INPUT_LIST, T.INPUT_BOOLEAN)


def find(ws: WorkingSet, target: Target, types: Sequence[ObjectType]) -> VtObject:
    """The object ``target`` names in the working set's pool: an id, or the label of a key or
    button (exact text; a number in a string is an id).

    Raises
    ------
    LookupError
        No such object, of the wrong type, or a label several objects show.
    """
    assert ws.pool is not None
    if isinstance(target, str) and target.strip().isdigit():
        target = int(target)
    kinds = "/".join(t.name.lower() for t in types)
    if isinstance(target, int):
        obj = ws.resolve(target)
        if obj is None:
            raise LookupError(f"the pool has no object {target}")
        if obj.type not in types:
            raise LookupError(f"object {target} is a {obj.type.name.lower()}, not a {kinds}")
        return obj
    found = [o for o in ws.pool if o.type in types and ws.label(o.object_id) == target]
    if not found:
        labels = sorted({ws.label(o.object_id) for o in ws.pool if o.type in types} - {""})
        raise LookupError(f"no {kinds} labelled {target!r} in the pool (labels: "
                          f"{', '.join(repr(x) for x in labels) or 'none'})")
    if len(found) > 1:
        raise LookupError(f"{len(found)} objects are labelled {target!r}: "
                          f"{', '.join(str(o.object_id) for o in found)}; use an id")
    return found[0]


def check_steps(steps: Sequence[OperatorStep], pool: ObjectPool,
                path: str | None = None, key: str = "operator") -> None:
    """Refuse, before the run, a step that names an object the pool does not have.

    Raises
    ------
    ConfigError
        Naming the file, the step (``operator[i]``) and the object.
    """
    ws = WorkingSet(0, 0, None, 0.0, 0.0, pool=pool)
    for i, step in enumerate(steps):
        try:
            if step.press is not None:
                find(ws, step.press, PRESSABLE)
            elif step.enter is not None:
                find(ws, step.enter, ENTERABLE)
            elif step.type is not None:
                find(ws, step.type, (T.INPUT_STRING,))
            elif step.acknowledge not in (None, True):
                assert step.acknowledge is not None and step.acknowledge is not False
                find(ws, step.acknowledge, (T.KEY,))
        except LookupError as exc:
            raise ConfigError(f"{step.what}: {exc}", path=path, key=f"{key}[{i}]") from None


class Operator:
    """Scripted operator input through the VT (see the module docstring)."""

    def __init__(self, vt: VirtualTerminalServer, address: int | None = None) -> None:
        self.vt = vt
        self.address = address
        #: steps that could not be done, with why (also in the VT's events)
        self.missed: list[tuple[float, str]] = []

    def _ws(self) -> WorkingSet:
        return self.vt._working_set(self.address)

    def schedule(self, steps: Sequence[OperatorStep]) -> None:
        """Put every step on the VT's timeline."""
        for step in steps:
            if step.press is not None:
                self.press(step.press, step.at_s, step.hold_s)
            elif step.enter is not None:
                assert step.value is not None
                self.enter(step.enter, step.value, step.at_s)
            elif step.type is not None:
                assert step.text is not None
                self.type(step.type, step.text, step.at_s)
            elif step.acknowledge is not None:
                self.acknowledge(step.at_s, None if step.acknowledge is True
                                 else step.acknowledge)  # type: ignore[arg-type]
            else:
                self.vt.at(step.at_s, lambda now: self._guard(now, "ESC",
                                                              lambda: self.vt.escape(now)))

    def _guard(self, now: float, what: str, action: object) -> bool:
        try:
            action()  # type: ignore[operator]
        except (ValueError, LookupError) as exc:
            self.missed.append((now, f"{what}: {exc}"))
            self.vt._event(now, self.address, "operator", f"{what} not done: {exc}")
            return False
        return True

    def press(self, target: Target, at_s: float, hold_s: float = 0.2) -> None:
        """Press a soft key or button at ``at_s`` for ``hold_s``."""
        state: dict[str, int] = {}

        def down(now: float) -> None:
            def go() -> None:
                ws = self._ws()
                obj = find(ws, target, PRESSABLE)
                if not ws.is_shown(obj.object_id):
                    raise LookupError(f"{obj.type.name.lower()} {obj.object_id} "
                                      f"({ws.label(obj.object_id)!r}) is not on the screen")
                state["id"] = obj.object_id
                self.vt.key_event(obj.object_id, KeyActivation.PRESSED, now, self.address)
            if not self._guard(now, f"press {target!r}", go):
                return
            t = at_s + KEY_REPEAT_S
            while t < at_s + hold_s - 1e-9:
                self.vt.at(t, held)
                t += KEY_REPEAT_S
            self.vt.at(at_s + hold_s, up)

        def held(now: float) -> None:
            self._guard(now, f"hold {target!r}", lambda: self.vt.key_event(
                state["id"], KeyActivation.STILL_HELD, now, self.address))

        def up(now: float) -> None:
            self._guard(now, f"release {target!r}", lambda: self.vt.key_event(
                state["id"], KeyActivation.RELEASED, now, self.address))

        self.vt.at(at_s, down)

    def enter(self, target: Target, value: float, at_s: float) -> None:
        """Enter ``value`` (displayed units) into an input number, list or boolean."""
        def go(now: float) -> None:
            def act() -> None:
                ws = self._ws()
                obj = find(ws, target, ENTERABLE)
                raw = to_raw(obj, value)
                self.vt.enter_number(obj.object_id, raw, now, self.address)
            self._guard(now, f"enter {value:g} into {target!r}", act)
        self.vt.at(at_s, go)

    def type(self, target: Target, text: str, at_s: float) -> None:
        """Type ``text`` into an input string."""
        def go(now: float) -> None:
            def act() -> None:
                obj = find(self._ws(), target, (T.INPUT_STRING,))
                self.vt.enter_string(obj.object_id, text, now, self.address)
            self._guard(now, f"type into {target!r}", act)
        self.vt.at(at_s, go)

    def acknowledge(self, at_s: float, key: Target | None = None, hold_s: float = 0.2) -> None:
        """Acknowledge the active alarm mask with a key of its soft key mask."""
        def go(now: float) -> None:
            def act() -> None:
                ws = self._ws()
                mask = ws.obj(ws.active_mask)
                if mask is None or mask.type != T.ALARM_MASK:
                    raise LookupError("no alarm mask is shown")
                keys = ws.resolve(ws.soft_key_mask)
                if key is None:
                    if keys is None or not keys["keys"]:
                        raise LookupError(f"alarm mask {mask.object_id} has no soft key")
                    chosen: Target = keys["keys"][0]
                else:
                    chosen = key
                self.press(chosen, now, hold_s)
            self._guard(now, "acknowledge", act)
        self.vt.at(at_s, go)


def to_raw(obj: VtObject, shown: float) -> int:
    """The raw value an input object takes for the ``shown`` value (number: ``shown / scale -
    offset``, rounded; list and boolean: the index)."""
    if obj.type != T.INPUT_NUMBER:
        return round(shown)
    scale = float(obj["scale"]) or 1.0
    return round(shown / scale - obj["offset"])


def shown_value(obj: VtObject, raw: int) -> float:
    """What a number object shows for ``raw``: ``(raw + offset) * scale``, to its decimals."""
    scale = float(obj.get("scale", 1.0))
    return round((raw + int(obj.get("offset", 0))) * scale, int(obj.get("decimals", 0)))


def read_operator_steps(path: str | Path, key: str = "operator") -> tuple[OperatorStep, ...]:
    """The ``[[operator]]`` list of a scenario file, sorted by time (empty without one).

    Raises
    ------
    ConfigError
        Not a list of tables, or a step with a bad key or value (naming the file and
        ``operator[i]``).
    """
    data = read_toml(Path(path), "scenario")
    raw = data.get(key, [])
    if not isinstance(raw, list):
        raise ConfigError("expected a list of tables ([[operator]])", path=str(path), key=key)
    steps = [from_mapping(OperatorStep, entry, path=str(path), prefix=f"{key}[{i}]")
             for i, entry in enumerate(raw)]
    return tuple(sorted(steps, key=lambda s: s.at_s))
