"""The reference implement's operator interface: its Virtual Terminal object pool (ISO 11783-6).

Three masks, as a market meter's terminal pages:

- **Run** (the home mask): the rate set-point (kg/ha), the actual rate of each row (kg/ha),
  the master switch's state; soft keys *Master* (metering on/off) and *Calib.*;
- **Calibration**: the operator's calibration test as two inputs, grams per revolution of
  one row's meter shaft and the shaft speed of the test (rpm); soft key *Back*;
- **Alarm** (priority high, a beep): "Row N: flow lost" for a row whose flow stopped while
  metering; soft key *Ack*.

:func:`meter_vt_pool` builds it (version 4); :class:`VtIds` are its object ids (the C build
carries the same bytes).
"""

from __future__ import annotations

from dataclasses import dataclass

from hil.isobus.vt.builder import PoolBuilder
from hil.isobus.vt.pool import ObjectPool

VERSION_LABEL = b"AGF-VT1"
"""The label the pool is stored under on the VT (a new pool needs a new label)."""
ALARM_TEXT_LENGTH = 24
MASTER_TEXT_LENGTH = 3


@dataclass(frozen=True)
class VtIds:
    """Object ids of the meter's pool (rows' ids follow the first row's)."""

    working_set: int = 0
    run: int = 1000
    calibration: int = 1001
    alarm: int = 1002
    run_keys: int = 2000
    calibration_keys: int = 2001
    alarm_keys: int = 2002
    key_master: int = 3000
    key_calibration: int = 3001
    key_back: int = 3002
    key_ack: int = 3003
    rate_var: int = 5000
    rate_out: int = 5100
    row_var_1: int = 5001
    row_out_1: int = 5101
    master_var: int = 5200
    master_out: int = 5201
    cal_grams_in: int = 5300
    cal_grams_var: int = 5301
    cal_rpm_in: int = 5302
    cal_rpm_var: int = 5303
    alarm_var: int = 5400
    alarm_out: int = 5401
    font_large: int = 8000
    font_small: int = 8001

    def row_var(self, row: int) -> int:
        """The number variable of row ``row`` (1-based): actual kg/ha x 10."""
        return self.row_var_1 + row - 1

    def row_out(self, row: int) -> int:
        """The output number of row ``row`` (1-based)."""
        return self.row_out_1 + row - 1


IDS = VtIds()
#: colours (the VT palette): white, black, green, silver
WHITE, BLACK, GREEN, SILVER, RED = 1, 0, 2, 7, 12


def meter_vt_pool(rows: int) -> ObjectPool:
    """The meter's pool for ``rows`` rows (1 .. 16)."""
    if not 1 <= rows <= 16:
        raise ValueError(f"rows must be 1 .. 16, got {rows}")
    i = IDS
    b = PoolBuilder(first_id=100, version=4)
    large = b.font(size=4, colour=BLACK, object_id=i.font_large)
    small = b.font(size=3, colour=BLACK, object_id=i.font_small)

    def label(text: str, width: int = 200, font: int = small) -> int:
        return b.output_string(text, font=font, width=width, height=20,
                               background_colour=WHITE, options=0x01)

    def key(text: str, object_id: int, code: int) -> int:
        return b.key(b.output_string(text, font=small, width=76, height=20,
                                     background_colour=SILVER, options=0x01),
                     key_code=code, object_id=object_id)

    master = key("Master", i.key_master, 1)
    calib = key("Calib.", i.key_calibration, 2)
    back = key("Back", i.key_back, 3)
    ack = key("Ack", i.key_ack, 4)
    b.soft_key_mask([master, calib], object_id=i.run_keys)
    b.soft_key_mask([back], object_id=i.calibration_keys)
    b.soft_key_mask([ack], object_id=i.alarm_keys)

    b.number_variable(0, object_id=i.rate_var)
    b.output_number(i.rate_var, font=large, width=160, height=24, scale=0.1, decimals=1,
                    background_colour=WHITE, justification=0x02, object_id=i.rate_out)
    b.string_variable("OFF", object_id=i.master_var)
    b.output_string(b"", font=large, width=60, height=24, background_colour=WHITE,
                    variable_reference=i.master_var, object_id=i.master_out)
    children = [(label("Rate set-point (kg/ha)", 280), 10, 10), (i.rate_out, 300, 8),
                (label("Master", 100), 10, 44), (i.master_out, 300, 40)]
    for row in range(1, rows + 1):
        b.number_variable(0, object_id=i.row_var(row))
        b.output_number(i.row_var(row), font=small, width=120, height=20, scale=0.1,
                        decimals=1, background_colour=WHITE, justification=0x02,
                        object_id=i.row_out(row))
        y = 80 + 24 * (row - 1)
        children += [(label(f"Row {row} actual (kg/ha)", 280), 10, y), (i.row_out(row), 300, y)]
    b.data_mask(children, soft_key_mask=i.run_keys, background_colour=WHITE, object_id=i.run)

    b.number_variable(0, object_id=i.cal_grams_var)
    b.input_number(i.cal_grams_var, font=large, width=160, height=24, min_value=1,
                   max_value=5000, scale=0.1, decimals=1, background_colour=WHITE,
                   object_id=i.cal_grams_in)
    b.number_variable(210, object_id=i.cal_rpm_var)
    b.input_number(i.cal_rpm_var, font=large, width=160, height=24, min_value=10,
                   max_value=2000, scale=0.1, decimals=1, background_colour=WHITE,
                   object_id=i.cal_rpm_in)
    b.data_mask([(label("Calibration test", 280, large), 10, 10),
                 (label("Grams per revolution", 280), 10, 50), (i.cal_grams_in, 300, 48),
                 (label("Shaft speed (rpm)", 280), 10, 84), (i.cal_rpm_in, 300, 82)],
                soft_key_mask=i.calibration_keys, background_colour=WHITE,
                object_id=i.calibration)

    b.string_variable(" " * ALARM_TEXT_LENGTH, object_id=i.alarm_var)
    b.output_string(b"", font=large, width=440, height=30, background_colour=RED,
                    variable_reference=i.alarm_var, object_id=i.alarm_out)
    b.alarm_mask([(label("ALARM", 200, large), 10, 10), (i.alarm_out, 10, 60)],
                 soft_key_mask=i.alarm_keys, priority=0, acoustic_signal=0,
                 background_colour=WHITE, object_id=i.alarm)
    b.working_set(i.run, children=[(label("Fertilizer meter", 200), 0, 0)],
                  object_id=i.working_set, background_colour=WHITE)
    return b.build()
