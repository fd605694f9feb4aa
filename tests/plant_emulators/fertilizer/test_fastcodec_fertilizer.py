"""The compiled frame layouts give cantools' bytes and values, and cantools' errors.

:class:`FertilizerDatabase` encodes and decodes through layouts compiled from the DBC
(:mod:`hil.rig.fastcodec`) and falls back to cantools for anything they do not cover. Here
every frame of the DBC goes through both paths with random in-range values, random payloads,
edge values and bad input: same ``can.Message``, same decoded values (and types, and order),
same error messages.
"""

from __future__ import annotations

import math

import can
import cantools
import numpy as np
import pytest

from hil.rig.fastcodec import FrameLayout
from plant_emulators.fertilizer.frames import FertilizerDatabase, FrameError


@pytest.fixture(scope="module")
def db() -> FertilizerDatabase:
    return FertilizerDatabase()


def _same_frame(a: can.Message, b: can.Message) -> None:
    assert (a.arbitration_id, a.is_extended_id, a.dlc, bytes(a.data)) == \
        (b.arbitration_id, b.is_extended_id, b.dlc, bytes(b.data))


def _random_value(sig, rng: np.random.Generator) -> float | int:
    """A value inside [min, max], on or off the resolution grid, sometimes at an end."""
    lo = sig.minimum if sig.minimum is not None else sig.offset
    hi = sig.maximum if sig.maximum is not None else lo + 100 * sig.scale
    pick = rng.integers(0, 6)
    if pick == 0:
        return lo
    if pick == 1:
        return hi
    value = float(rng.uniform(lo, hi))
    if pick == 2 and isinstance(sig.scale, int) and isinstance(sig.offset, int):
        return min(max(round(value), math.ceil(lo)), math.floor(hi))    # a plain int
    if pick == 3:      # on the grid, as devices usually send
        return min(max(round((value - sig.offset) / sig.scale) * sig.scale + sig.offset, lo), hi)
    return value


def test_every_frame_of_the_dbc_is_compiled(db: FertilizerDatabase) -> None:
    assert set(db._fast) == {m.name for m in db.db.messages}


def test_random_in_range_values_encode_as_cantools_does(db: FertilizerDatabase) -> None:
    rng = np.random.default_rng(20240611)
    for message in db.db.messages:
        fast = db._fast[message.name]
        for _ in range(300):
            values = {s.name: _random_value(s, rng) for s in message.signals}
            if rng.random() < 0.3:      # signals with a DBC start value may be left out
                values = {k: v for k, v in values.items()
                          if message.get_signal_by_name(k).raw_initial is None}
            strict = bool(rng.random() < 0.8)
            assert fast.encode(values, strict) is not None, (message.name, values)
            _same_frame(db.encode(message.name, values, strict=strict),
                        db._encode_cantools(message.name, values, strict=strict))


def test_random_payloads_decode_as_cantools_does(db: FertilizerDatabase) -> None:
    rng = np.random.default_rng(7)
    for message in db.db.messages:
        for _ in range(300):
            data = bytes(rng.integers(0, 256, message.length + int(rng.integers(0, 2)),
                                      dtype=np.uint8))
            msg = can.Message(arbitration_id=message.frame_id,
                              is_extended_id=message.is_extended_frame, data=data)
            name, values = db.decode(msg)
            expected = dict(message.decode(data, decode_choices=False))
            assert name == message.name
            assert list(values) == list(expected)
            for key, value in expected.items():
                assert type(values[key]) is type(value) and values[key] == value, key


def test_an_isobus_frame_from_another_address_decodes_by_pgn(db: FertilizerDatabase) -> None:
    good = db.encode("GroundBasedSpeedDist", {
        "GroundBasedMachineSpeed": 1.5, "GroundBasedMachineDistance": 12.0,
        "MachineDirection": 1})
    other = can.Message(arbitration_id=(good.arbitration_id & ~0xFF) | 0x27,
                        is_extended_id=True, data=good.data)
    assert db.decode(other) == db.decode(good)
    assert db.decode(other)[0] == "GroundBasedSpeedDist"


BAD_VALUES = [math.nan, math.inf, -math.inf, None, "1", 1e12, -1.0, -1e-9, True,
              np.float64(1.25), np.int64(3)]


@pytest.mark.parametrize("strict", [True, False])
def test_bad_and_edge_values_give_the_same_frame_or_the_same_error(db: FertilizerDatabase,
                                                                   strict: bool) -> None:
    rng = np.random.default_rng(3)
    for message in db.db.messages:
        base = {s.name: _random_value(s, rng) for s in message.signals}
        for sig in message.signals:
            raw_max = (1 << sig.length) - 1 if not sig.is_signed else (1 << (sig.length - 1)) - 1
            raw_min = 0 if not sig.is_signed else -(1 << (sig.length - 1))
            edges = [sig.offset + sig.scale * (raw_max + 0.5),      # half an LSB above the field
                     sig.offset + sig.scale * (raw_max + 0.49),
                     sig.offset + sig.scale * (raw_min - 0.5),
                     sig.offset + sig.scale * (raw_min - 0.51),
                     (sig.maximum or 0) + sig.scale * 1e-7, (sig.minimum or 0) - sig.scale * 1e-7]
            for value in [*BAD_VALUES, *edges]:
                _same_outcome(db, message.name, {**base, sig.name: value}, strict)
        _same_outcome(db, message.name, {**base, "NoSuchSignal": 1}, True)
        for sig in message.signals:
            _same_outcome(db, message.name, {k: v for k, v in base.items() if k != sig.name},
                          True)


def _same_outcome(db: FertilizerDatabase, name: str, values: dict, strict: bool) -> None:
    """``encode`` gives the frame, or raises the error, that the cantools path gives."""
    try:
        expected = db._encode_cantools(name, values, strict=strict)
    except Exception as exc:
        with pytest.raises(type(exc)) as info:
            db.encode(name, values, strict=strict)
        assert str(info.value) == str(exc)
        return
    _same_frame(db.encode(name, values, strict=strict), expected)


def test_short_payloads_and_unknown_ids_still_raise(db: FertilizerDatabase) -> None:
    with pytest.raises(FrameError, match="FlowModule1"):
        db.decode(can.Message(arbitration_id=0x181, is_extended_id=False, data=b"\x01\x02"))
    with pytest.raises(FrameError, match="no frame"):
        db.decode(can.Message(arbitration_id=0x5FF, is_extended_id=False, data=b""))
    with pytest.raises(FrameError, match="unknown frame"):
        db.encode("NoSuchFrame", {})


def test_the_parsed_database_is_shared_while_the_file_is_unchanged(
        db: FertilizerDatabase) -> None:
    again = FertilizerDatabase()
    assert again.db is db.db and again._fast is db._fast


BIG_ENDIAN_DBC = """VERSION ""
BS_:
BU_: A
BO_ 256 Motorola: 8 A
 SG_ Big : 7|16@0+ (1,0) [0|65535] "" A
BO_ 257 Floaty: 8 A
 SG_ F : 0|32@1+ (1,0) [0|1] "" A
SIG_VALTYPE_ 257 F : 1;
BO_ 258 Plain: 8 A
 SG_ Lo : 0|12@1- (0.5,-3) [-1000|1000] "" A
 SG_ Hi : 12|20@1+ (1,0) [0|1000000] "" A
"""


def test_layouts_only_compile_what_they_reproduce() -> None:
    dbc = cantools.database.load_string(BIG_ENDIAN_DBC, database_format="dbc")
    assert FrameLayout.build(dbc.get_message_by_name("Motorola")) is None
    assert FrameLayout.build(dbc.get_message_by_name("Floaty")) is None
    plain = dbc.get_message_by_name("Plain")
    layout = FrameLayout.build(plain)
    assert layout is not None
    rng = np.random.default_rng(11)
    for _ in range(500):
        raws = [int(rng.integers(s.raw_min, s.raw_max + 1)) for s in layout.signals]
        values = {s.name: r for s, r in zip(layout.signals, raws, strict=True)}
        for padding in (False, True):
            assert layout.pack(raws, padding=padding) == plain.encode(
                values, scaling=False, padding=padding, strict=False)
        assert layout.unpack(layout.pack(raws, padding=True)) == raws
        scaled = plain.decode(layout.pack(raws, padding=False))
        for sig, raw in zip(layout.signals, raws, strict=True):
            assert sig.to_scaled(raw) == scaled[sig.name]
            assert sig.to_raw(scaled[sig.name]) == raw
