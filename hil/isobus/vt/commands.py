"""A working set's commands applied to its pool, each answered as ISO 11783-6 says.

:func:`apply` takes one command (the ECU to VT message) and returns a :class:`CommandResult`:
the response to send (``None`` for a command inside a macro, which is not answered), the
error bits, whether what the operator sees may have changed, and a line for the record. Error
bits per command are the standard's (bit 0 first); "not applicable" objects (a hide/show to a
button) get the command's invalid object id bit.

What a hostile working set cannot do with them: a macro may execute macros, 8 deep at most and
:data:`MAX_MACRO_COMMANDS` commands in all for one command from the bus (a macro listing itself
a thousand times would otherwise run 1000^8 commands); the rest are abandoned and the execute
macro response has its "any other error" bit. An object pointer (or external object pointer)
set to an object that contains it, or that makes an object draw more than the VT draws
(:func:`hil.isobus.vt.pool.ObjectPool.check_drawable`), is refused with "invalid value".
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass

from hil.isobus.vt.codec import VtObject
from hil.isobus.vt.errors import NO_OBJECT
from hil.isobus.vt.layouts import ATTRIBUTE_IDS, ObjectType
from hil.isobus.vt.messages import Function, get16, get32, pad, u16, u32
from hil.isobus.vt.pool import VtPoolError, drawn_parts
from hil.isobus.vt.workingset import INPUTS, NUMERIC, STRINGS, WorkingSet

T = ObjectType
MASKS = (T.DATA_MASK, T.ALARM_MASK)
MAX_MACRO_DEPTH = 8
MAX_MACRO_COMMANDS = 1_000
"""Commands the macros one bus command starts may run in all (nested macros included)."""


@dataclass(frozen=True)
class CommandResult:
    """What one command did."""

    function: int
    object_id: int
    error: int
    response: bytes | None
    changed: bool
    detail: str


Handler = Callable[[WorkingSet, bytes, float], tuple[int, int, bytes, bool, str]]
"""(ws, data, now) -> (object id, error bits, response payload after the function byte,
changed, detail)."""


def _hide_show(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, value = get16(d, 1), d[3]
    obj = ws.obj(oid)
    error = 0
    if obj is None or obj.type not in (T.CONTAINER, T.WINDOW_MASK):
        error = 0x02
    elif value > 1:
        error = 0x04
    changed = False
    if not error and obj is not None and obj.type == T.CONTAINER:
        changed = obj.attrs["hidden"] != (0 if value else 1)
        obj.attrs["hidden"] = 0 if value else 1
    return oid, error, u16(oid) + bytes([value, error]), changed, \
        f"{'show' if value else 'hide'} {oid}"


def _enable_disable(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, value = get16(d, 1), d[3]
    obj = ws.obj(oid)
    error = 0
    if obj is None or obj.type not in INPUTS | {T.BUTTON, T.ANIMATION}:
        error = 0x02
    elif value > 1:
        error = 0x04
    elif not value and ws.open_input == oid:
        error = 0x08
    if not error and obj is not None:
        set_enabled(obj, bool(value))
    return oid, error, u16(oid) + bytes([value, error]), not error, \
        f"{'enable' if value else 'disable'} {oid}"


def is_enabled(obj: VtObject) -> bool:
    """Whether an input object or button takes the operator's input."""
    if obj.type in (T.INPUT_NUMBER,):
        return bool(obj.attrs["options2"] & 0x01)
    if obj.type == T.INPUT_LIST:
        return bool(obj.attrs["options"] & 0x01)
    if obj.type == T.BUTTON:
        return not obj.attrs["options"] & 0x10      # version 4: bit 4 = disabled
    return bool(obj.attrs.get("enabled", 1))


def set_enabled(obj: VtObject, value: bool) -> None:
    """Enable or disable an input object or button (the attribute each type keeps it in)."""
    if obj.type == T.INPUT_NUMBER:
        obj.attrs["options2"] = (obj.attrs["options2"] & ~0x01) | int(value)
    elif obj.type == T.INPUT_LIST:
        obj.attrs["options"] = (obj.attrs["options"] & ~0x01) | int(value)
    elif obj.type == T.BUTTON:
        obj.attrs["options"] = (obj.attrs["options"] & ~0x10) | (0 if value else 0x10)
    else:
        obj.attrs["enabled"] = int(value)


def _select_input(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, option = get16(d, 1), d[3]
    obj = ws.obj(oid)
    error, response = 0, 0
    if oid == NO_OBJECT:
        ws.open_input = None
    elif obj is None or obj.type not in INPUTS | {T.BUTTON, T.KEY}:
        error = 0x02
    elif option not in (0x00, 0xFF):
        error = 0x20
    elif not is_enabled(obj):
        error = 0x01
    elif not ws.is_shown(oid):
        error = 0x04
    else:
        response = 2 if option == 0 and obj.type in INPUTS else 1
        ws.open_input = oid if response == 2 else None
    return oid, error, u16(oid) + bytes([response, error]), not error, f"select input {oid}"


def _audio(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    return NO_OBJECT, 0, bytes([0]), False, (
        f"audio: {d[1]} x {get16(d, 2)} Hz, {get16(d, 4)} ms on, {get16(d, 6)} ms off")


def _volume(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    error = 0x01 if d[1] > 100 else 0
    return NO_OBJECT, error, bytes([error]), False, f"audio volume {d[1]} %"


def _size(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, width, height = get16(d, 1), get16(d, 3), get16(d, 5)
    obj = ws.obj(oid)
    error = 0
    if obj is None or "width" not in obj.attrs:
        error = 0x01
    else:
        obj.attrs["width"] = width
        if "height" in obj.attrs:
            obj.attrs["height"] = height
    return oid, error, u16(oid) + bytes([error]), not error, f"size {oid} {width}x{height}"


def _background(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, colour = get16(d, 1), d[3]
    obj = ws.obj(oid)
    error = 0 if obj is not None and "background_colour" in obj.attrs else 0x01
    if not error and obj is not None:
        obj.attrs["background_colour"] = colour
    return oid, error, u16(oid) + bytes([error, colour]), not error, \
        f"background {oid} colour {colour}"


def _numeric(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, value = get16(d, 1), get32(d, 4)
    obj = ws.obj(oid)
    error = 0
    if obj is None or obj.type not in NUMERIC:
        error = 0x01
    elif _bad_number(ws, obj.type, value, oid):
        error = 0x02
    elif ws.open_input == oid:
        error = 0x04
    if not error and obj is not None:
        ref = obj.get("variable_reference", NO_OBJECT)
        target = ws.obj(ref) if ref != NO_OBJECT else None
        (target or obj).attrs["value"] = value
    return oid, error, u16(oid) + bytes([error]) + u32(value), not error, \
        f"numeric value {oid} = {value}"


def _bad_number(ws: WorkingSet, otype: ObjectType, value: int, oid: int = NO_OBJECT) -> bool:
    if otype == T.OBJECT_POINTER:
        if value != NO_OBJECT and ws.obj(value) is None:
            return True
        return not keeps_drawable(ws, oid, "value", value)
    if otype == T.INPUT_BOOLEAN:
        return value > 1
    return otype in (T.INPUT_LIST, T.OUTPUT_LIST) and value > 255


def keeps_drawable(ws: WorkingSet, oid: int, attribute: str, value: int) -> bool:
    """Whether setting a pointer's ``attribute`` to ``value`` leaves a pool the VT can draw
    (no object inside itself, none drawing more than it may). A pointer moved from one
    object that draws nothing else to another is not checked again (the counts stay)."""
    obj, pool = ws.obj(oid), ws.pool
    if obj is None or pool is None:
        return True
    old = obj.attrs[attribute]
    if value == old:
        return True
    if not drawn_parts(pool, value) and old != NO_OBJECT and old in pool and \
            not drawn_parts(pool, old):
        return True
    obj.attrs[attribute] = value
    try:
        pool.check_drawable()
    except VtPoolError:
        return False
    finally:
        obj.attrs[attribute] = old
    return True


def _attribute_font(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid = get16(d, 1)
    obj = ws.obj(oid)
    error = 0
    if obj is None or obj.type != T.FONT_ATTRIBUTES:
        error = 0x01
    elif d[4] > 14:
        error = 0x04
    elif d[5] not in (0, 1, 2, 4, 5, 7, 0xFF):
        error = 0x08
    else:
        obj.attrs.update(font_colour=d[3], font_size=d[4], font_type=d[5], font_style=d[6])
    return oid, error, u16(oid) + bytes([error]), not error, f"font attributes {oid}"


def _attribute_line(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid = get16(d, 1)
    obj = ws.obj(oid)
    error = 0 if obj is not None and obj.type == T.LINE_ATTRIBUTES else 0x01
    if not error and obj is not None:
        obj.attrs.update(line_colour=d[3], line_width=d[4], line_art=get16(d, 5))
    return oid, error, u16(oid) + bytes([error]), not error, f"line attributes {oid}"


def _attribute_fill(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, pattern = get16(d, 1), get16(d, 5)
    obj = ws.obj(oid)
    error = 0
    if obj is None or obj.type != T.FILL_ATTRIBUTES:
        error = 0x01
    elif d[3] > 3:
        error = 0x02
    elif pattern != NO_OBJECT and getattr(ws.obj(pattern), "type", None) != T.PICTURE_GRAPHIC:
        error = 0x08
    else:
        obj.attrs.update(fill_type=d[3], fill_colour=d[4], fill_pattern=pattern)
    return oid, error, u16(oid) + bytes([error]), not error, f"fill attributes {oid}"


def _active_mask(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    ws_id, mask_id = get16(d, 1), get16(d, 3)
    error = 0
    pool = ws.pool
    assert pool is not None and pool.working_set is not None
    mask = ws.obj(mask_id)
    if ws_id != pool.working_set.object_id:
        error |= 0x01
    if mask is None or mask.type not in (*MASKS, T.WINDOW_MASK):
        error |= 0x02
    changed = False
    if not error:
        changed = pool.working_set.attrs["active_mask"] != mask_id
        pool.working_set.attrs["active_mask"] = mask_id
        ws.open_input = None
    return mask_id, error, u16(mask_id) + bytes([error]), changed, f"active mask {mask_id}"


def _soft_key_mask(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    kind, mask_id, keys_id = d[1], get16(d, 2), get16(d, 4)
    mask = ws.obj(mask_id)
    keys = ws.obj(keys_id)
    error = 0
    if mask is None or mask.type not in MASKS or kind not in (1, 2) or \
            (kind == 1) != (mask.type == T.DATA_MASK):
        error |= 0x01
    if keys_id != NO_OBJECT and (keys is None or keys.type != T.SOFT_KEY_MASK):
        error |= 0x02
    if not error and mask is not None:
        mask.attrs["soft_key_mask"] = keys_id
    return mask_id, error, u16(mask_id) + u16(keys_id) + bytes([error]), \
        not error and mask_id == ws.active_mask, f"soft key mask of {mask_id} = {keys_id}"


def _attribute(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, aid, raw = get16(d, 1), d[3], d[4:8]
    obj = ws.obj(oid)
    error = 0
    detail = f"attribute {aid} of {oid}"
    if obj is None:
        error = 0x01
    else:
        f = ATTRIBUTE_IDS.get(obj.type, {}).get(aid)
        if f is None:
            error = 0x02
        else:
            value: int | float
            if f.fmt == "f":
                value = struct.unpack("<f", raw)[0]
                bad = not math.isfinite(value)
            else:
                size = struct.calcsize(f.fmt)
                unsigned = int.from_bytes(raw, "little")
                value = struct.unpack("<" + f.fmt, raw[:size])[0]
                bad = unsigned >= 1 << (8 * size) and f.fmt in "BHI"
            if not bad and f.values is not None:
                bad = value not in f.values
            if not bad and f.maximum is not None:
                bad = value > f.maximum
            if not bad and f.ref is not None and value != NO_OBJECT:
                target = ws.obj(int(value))
                bad = target is None or target.type not in f.ref
            if not bad and obj.type == T.EXTERNAL_OBJECT_POINTER and \
                    f.name == "default_object":
                bad = not keeps_drawable(ws, oid, f.name, int(value))
            if bad:
                error = 0x04
            else:
                obj.attrs[f.name] = value
                detail = f"{f.name} of {oid} = {value}"
    return oid, error, u16(oid) + bytes([aid, error]), not error, detail


def _priority(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, priority = get16(d, 1), d[3]
    obj = ws.obj(oid)
    error = 0
    if obj is None or obj.type != T.ALARM_MASK:
        error = 0x01
    elif priority > 2:
        error = 0x02
    else:
        obj.attrs["priority"] = priority
    return oid, error, u16(oid) + bytes([priority, error]), not error, \
        f"priority of {oid} = {priority}"


def _string(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    oid, length = get16(d, 1), get16(d, 3)
    value = bytes(d[5:5 + length])
    obj = ws.obj(oid)
    error = 0
    if obj is None or obj.type not in STRINGS or len(value) != length:
        error = 0x02
    else:
        ref = obj.get("variable_reference", NO_OBJECT)
        target = ws.obj(ref) if ref != NO_OBJECT else None
        holder = target or obj
        limit = holder.attrs["length"]
        if length > limit:
            error = 0x04
        else:
            holder.attrs["value"] = value + b" " * (limit - length)
    return oid, error, b"\xff\xff" + u16(oid) + bytes([error]), not error, \
        f"string value {oid} = {value.decode('latin-1')!r}"


def _child_location(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    parent_id, child_id, dx, dy = get16(d, 1), get16(d, 3), d[5] - 127, d[6] - 127
    return _move(ws, parent_id, child_id, dx, dy, relative=True)


def _child_position(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    parent_id, child_id = get16(d, 1), get16(d, 3)
    x, y = struct.unpack_from("<hh", d, 5) if len(d) >= 9 else (0, 0)
    return _move(ws, parent_id, child_id, x, y, relative=False)


def _move(ws: WorkingSet, parent_id: int, child_id: int, x: int, y: int,
          relative: bool) -> tuple[int, int, bytes, bool, str]:
    parent = ws.obj(parent_id)
    error = 0
    if parent is None or "children" not in parent.attrs:
        error = 0x01
    else:
        children = parent.attrs["children"]
        index = next((i for i, c in enumerate(children) if c[0] == child_id), None)
        if index is None:
            error = 0x02
        else:
            _, cx, cy = children[index]
            children[index] = (child_id, cx + x, cy + y) if relative else (child_id, x, y)
    return child_id, error, u16(parent_id) + u16(child_id) + bytes([error]), not error, \
        f"move {child_id} in {parent_id} {'by' if relative else 'to'} ({x}, {y})"


def _lock(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    command, mask_id, timeout_ms = d[1], get16(d, 2), get16(d, 4)
    error = 0
    if command == 1:
        if mask_id != ws.active_mask:
            error = 0x01
        elif ws.locked_mask is not None:
            error = 0x02
        else:
            ws.locked_mask = mask_id
            ws.lock_until_s = now + timeout_ms / 1000.0 if timeout_ms else None
    elif command == 0:
        if ws.locked_mask is None:
            error = 0x04
        else:
            ws.locked_mask = ws.lock_until_s = None
    else:
        error = 0x80
    # an unlock shows what changed while the mask was locked
    return mask_id, error, bytes([command, error]), not error and command == 0, \
        f"{'lock' if command == 1 else 'unlock'} mask {mask_id}" + (
            f" for {timeout_ms} ms" if command == 1 else "")


def _delete_pool(ws: WorkingSet, d: bytes, now: float) -> tuple[int, int, bytes, bool, str]:
    ws.pool = None
    ws.transfers.clear()
    return NO_OBJECT, 0, bytes([0]), True, "delete object pool"


HANDLERS: dict[int, Handler] = {
    Function.HIDE_SHOW: _hide_show,
    Function.ENABLE_DISABLE: _enable_disable,
    Function.SELECT_INPUT_OBJECT: _select_input,
    Function.CONTROL_AUDIO_SIGNAL: _audio,
    Function.SET_AUDIO_VOLUME: _volume,
    Function.CHANGE_CHILD_LOCATION: _child_location,
    Function.CHANGE_SIZE: _size,
    Function.CHANGE_BACKGROUND_COLOUR: _background,
    Function.CHANGE_NUMERIC_VALUE: _numeric,
    Function.CHANGE_FONT_ATTRIBUTES: _attribute_font,
    Function.CHANGE_LINE_ATTRIBUTES: _attribute_line,
    Function.CHANGE_FILL_ATTRIBUTES: _attribute_fill,
    Function.CHANGE_ACTIVE_MASK: _active_mask,
    Function.CHANGE_SOFT_KEY_MASK: _soft_key_mask,
    Function.CHANGE_ATTRIBUTE: _attribute,
    Function.CHANGE_PRIORITY: _priority,
    Function.DELETE_OBJECT_POOL: _delete_pool,
    Function.CHANGE_STRING_VALUE: _string,
    Function.CHANGE_CHILD_POSITION: _child_position,
    Function.LOCK_UNLOCK_MASK: _lock,
}

#: bytes each macro command takes (change string value: 5 + its length; the rest 8)
_MACRO_LENGTH = {Function.CHANGE_CHILD_POSITION: 9}


class _Budget:
    """Commands the macros of one bus command may still run."""

    def __init__(self) -> None:
        self.left = MAX_MACRO_COMMANDS


def apply(ws: WorkingSet, data: bytes, now: float, *, depth: int = 0,
          budget: _Budget | None = None) -> CommandResult | None:
    """Apply one command; ``None`` when the rig's VT does not have the function."""
    if not data:
        return None
    if len(data) < 8:
        data = pad(data)
    function = data[0]
    if function in (Function.EXECUTE_MACRO, Function.EXECUTE_EXTENDED_MACRO):
        return _execute_macro(ws, data, now, depth, budget or _Budget())
    handler = HANDLERS.get(function)
    if handler is None:
        return None
    body = data if len(data) >= 8 else pad(data)
    oid, error, payload, changed, detail = handler(ws, body, now)
    response = None if depth else pad(bytes([function]) + payload)
    return CommandResult(function, oid, error, response, changed, detail)


def _execute_macro(ws: WorkingSet, data: bytes, now: float, depth: int,
                   budget: _Budget) -> CommandResult:
    extended = data[0] == Function.EXECUTE_EXTENDED_MACRO
    macro_id = get16(data, 1) if extended else data[1]
    macro = ws.obj(macro_id)
    error = 0
    changed = False
    if macro is None:
        error = 0x01
    elif macro.type != T.MACRO:
        error = 0x02
    elif depth >= MAX_MACRO_DEPTH:
        error = 0x04
    else:
        commands = macro["commands"]
        pos = 0
        while pos < len(commands):
            if budget.left <= 0:
                error = 0x04        # the rest abandoned: any other error
                break
            budget.left -= 1
            function = commands[pos]
            if function == Function.CHANGE_STRING_VALUE:
                size = 5 + get16(commands, pos + 3) if pos + 5 <= len(commands) else 8
            else:
                size = _MACRO_LENGTH.get(function, 8)
            result = apply(ws, commands[pos:pos + size], now, depth=depth + 1, budget=budget)
            changed |= bool(result and result.changed)
            if result is not None and result.error and \
                    function in (Function.EXECUTE_MACRO, Function.EXECUTE_EXTENDED_MACRO):
                error |= result.error & 0x04
            pos += size
    payload = u16(macro_id) if extended else bytes([macro_id, 0xFF])
    response = None if depth else pad(bytes([data[0]]) + payload[:2] + bytes([error]))
    return CommandResult(data[0], macro_id, error, response, changed,
                         f"execute macro {macro_id}")
