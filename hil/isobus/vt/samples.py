"""Sample pools made with the builder: a large one for the parser's and the upload's figures."""

from __future__ import annotations

from hil.isobus.vt.builder import PoolBuilder
from hil.isobus.vt.codec import serialise_object
from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.pool import ObjectPool


def large_pool(target_bytes: int = 100_000, version: int = 4) -> ObjectPool:
    """A pool of about ``target_bytes``: masks of numbers, strings, rectangles, soft keys,
    and 8-bit picture graphics (as a market implement's pool is mostly its pictures: the
    examples of AgIsoStack++ are 75-99 % picture data by bytes)."""
    b = PoolBuilder(version=version)
    fonts = [b.font(size=s) for s in range(0, 15, 2)]
    line = b.add(ObjectType.LINE_ATTRIBUTES, line_width=1, line_art=0xFFFF)
    fill = b.add(ObjectType.FILL_ATTRIBUTES, fill_type=2, fill_colour=2)
    keys = b.soft_key_mask([b.key(b.output_string(f"Key {i}", font=fonts[1]), key_code=i)
                            for i in range(6)])
    masks: list[int] = []
    size = 0
    counted = 0
    i = 0
    while size < target_bytes:
        children = []
        for j in range(20):
            var = b.number_variable(i * 100 + j)
            children.append((b.output_number(var, font=fonts[j % len(fonts)], scale=0.01,
                                             decimals=2), 10, 10 + 20 * j))
            children.append((b.output_string(f"Value {i}.{j}", font=fonts[1]), 120,
                             10 + 20 * j))
            children.append((b.rectangle(100, 18, line=line, fill=fill), 5, 9 + 20 * j))
        picture = b.add(ObjectType.PICTURE_GRAPHIC, width=64, actual_width=64,
                        actual_height=48, format=2,
                        raw_data=bytes((k * 7 + i) & 0xFF for k in range(64 * 48)))
        children.append((picture, 300, 10))
        masks.append(b.data_mask(children, soft_key_mask=keys))
        size += sum(len(serialise_object(o)) for o in b.objects[counted:])
        counted = len(b.objects)
        i += 1
    b.working_set(masks[0])
    return b.build()
