"""A small implement pool for the VT tests: a home mask, a settings mask, an alarm mask."""

from __future__ import annotations

from dataclasses import dataclass

from hil.isobus.vt.builder import PoolBuilder
from hil.isobus.vt.codec import serialise_object
from hil.isobus.vt.pool import ObjectPool


@dataclass(frozen=True)
class Ids:
    ws: int = 0
    home: int = 1000
    settings: int = 1001
    alarm: int = 1002
    keys: int = 2000
    alarm_keys: int = 2001
    key_master: int = 3000
    key_settings: int = 3001
    key_ack: int = 3002
    button: int = 4000
    rate_var: int = 5000
    rate_out: int = 5001
    cal_in: int = 5002
    cal_var: int = 5003
    name_in: int = 5004
    name_var: int = 5005
    box: int = 6000
    macro: int = 7
    font: int = 8000


IDS = Ids()


def implement_pool() -> ObjectPool:
    b = PoolBuilder()
    i = IDS
    font = b.font(size=3, object_id=i.font)
    master = b.key(b.output_string("Master", font=font), key_code=1, object_id=i.key_master)
    settings = b.key(b.output_string("Settings", font=font), key_code=2,
                     object_id=i.key_settings)
    ack = b.key(b.output_string("Ack", font=font), key_code=3, object_id=i.key_ack)
    b.soft_key_mask([master, settings], object_id=i.keys)
    b.soft_key_mask([ack], object_id=i.alarm_keys)
    b.number_variable(2500, object_id=i.rate_var)
    rate = b.output_number(i.rate_var, font=font, scale=0.01, decimals=1, width=150,
                           object_id=i.rate_out)
    button = b.button(b.output_string("Start", font=font), key_code=9, object_id=i.button)
    box = b.container([(b.output_string("Hidden box", font=font), 0, 0)], 100, 20,
                      object_id=i.box)
    b.macro(bytes([0xA0]) + i.box.to_bytes(2, "little") + bytes([0, 0xFF, 0xFF, 0xFF, 0xFF]),
            object_id=i.macro)
    b.data_mask([(rate, 10, 10), (button, 10, 60), (box, 10, 120)], soft_key_mask=i.keys,
                object_id=i.home)
    b.number_variable(120, object_id=i.cal_var)
    cal = b.input_number(i.cal_var, font=font, min_value=10, max_value=1000, scale=0.1,
                         decimals=1, object_id=i.cal_in)
    b.string_variable("Field 1   ", object_id=i.name_var)
    name = b.input_string(i.name_var, font=font, object_id=i.name_in)
    b.data_mask([(cal, 10, 10), (name, 10, 40)], soft_key_mask=i.keys, object_id=i.settings)
    b.alarm_mask([(b.output_string("Row 3 blocked", font=font), 10, 10)],
                 soft_key_mask=i.alarm_keys, priority=0, object_id=i.alarm)
    b.working_set(i.home, children=[(b.output_string("Spreader", font=font), 0, 0)],
                  object_id=i.ws)
    return b.build()


def split(pool: ObjectPool, parts: int) -> list[bytes]:
    """The pool's objects in ``parts`` transfers (objects never split)."""
    objs = [serialise_object(o) for o in pool]
    step = -(-len(objs) // parts)
    return [b"".join(objs[k:k + step]) for k in range(0, len(objs), step)]
