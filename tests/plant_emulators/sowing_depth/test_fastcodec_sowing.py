"""The compiled frame layouts of :class:`FrameCodec` give cantools' bytes, values and errors.

Every frame of ``sowing_depth.dbc`` goes through the compiled path and through cantools with
random in-range values (numbers and choice names), random payloads, edge values and bad input.
"""

from __future__ import annotations

import math

import can
import numpy as np
import pytest

from plant_emulators.sowing_depth.frames import (
    DepthSetpoint,
    FrameCodec,
    FrameError,
    GroundSpeed,
    InclinometerFrame,
)


@pytest.fixture(scope="module")
def codec() -> FrameCodec:
    return FrameCodec()


def _same_frame(a: can.Message, b: can.Message) -> None:
    assert (a.arbitration_id, a.is_extended_id, a.dlc, bytes(a.data)) == \
        (b.arbitration_id, b.is_extended_id, b.dlc, bytes(b.data))


def _random_value(sig, rng: np.random.Generator):
    if sig.choices and rng.random() < 0.5:
        return str(list(sig.choices.values())[int(rng.integers(0, len(sig.choices)))])
    lo, hi = sig.minimum, sig.maximum
    pick = rng.integers(0, 5)
    if pick == 0:
        return lo
    if pick == 1:
        return hi
    value = float(rng.uniform(lo, hi))
    if pick == 2 and float(sig.scale).is_integer():
        return int(min(max(round(value), math.ceil(lo)), math.floor(hi)))
    return value


def test_every_frame_of_the_dbc_is_compiled(codec: FrameCodec) -> None:
    assert set(codec._fast) == {m.name for m in codec.db.messages}


def test_random_in_range_values_encode_as_cantools_does(codec: FrameCodec) -> None:
    rng = np.random.default_rng(5)
    for message in codec.db.messages:
        fast = codec._fast[message.name]
        for _ in range(300):
            values = {s.name: _random_value(s, rng) for s in message.signals}
            assert fast.encode(values) is not None, (message.name, values)
            _same_frame(codec.encode_signals(message.name, values),
                        codec._encode_cantools(message.name, values))


def test_random_payloads_decode_as_cantools_does(codec: FrameCodec) -> None:
    rng = np.random.default_rng(8)
    for message in codec.db.messages:
        for _ in range(300):
            data = bytes(rng.integers(0, 256, message.length + int(rng.integers(0, 2)),
                                      dtype=np.uint8))
            msg = can.Message(arbitration_id=message.frame_id, is_extended_id=True, data=data)
            fast = codec.decode_signals(msg)
            slow = codec._decode_cantools(message, msg)
            assert fast[0] == slow[0] and list(fast[1]) == list(slow[1])
            for key, value in slow[1].items():
                assert type(fast[1][key]) is type(value) and fast[1][key] == value, key


BAD = [math.nan, math.inf, None, True, False, "no such choice", 1e9, -1e9, np.float64(1.0),
       np.int64(1)]


def test_bad_and_edge_values_give_the_same_frame_or_the_same_error(codec: FrameCodec) -> None:
    rng = np.random.default_rng(9)
    for message in codec.db.messages:
        base = {s.name: _random_value(s, rng) for s in message.signals}
        for sig in message.signals:
            tol = abs(sig.scale) * 1e-6
            edges = [sig.minimum - tol, sig.minimum - 2 * tol, sig.maximum + tol,
                     sig.maximum + 2 * tol, *(sig.choices or {})]          # raw table values
            for value in [*BAD, *edges]:
                _same_outcome(codec, message.name, {**base, sig.name: value})
            _same_outcome(codec, message.name, {k: v for k, v in base.items() if k != sig.name})
        _same_outcome(codec, message.name, {**base, "NoSuchSignal": 1})


def _same_outcome(codec: FrameCodec, name: str, values: dict) -> None:
    """``encode_signals`` gives the frame, or raises the error, that the cantools path gives."""
    try:
        expected = codec._encode_cantools(name, values)
    except Exception as exc:
        with pytest.raises(type(exc)) as info:
            codec.encode_signals(name, values)
        assert str(info.value) == str(exc)
        return
    _same_frame(codec.encode_signals(name, values), expected)


def test_typed_frames_and_errors_are_unchanged(codec: FrameCodec) -> None:
    msg = codec.encode(GroundSpeed(speed_mps=1.111, distance_m=25.0))
    assert codec.decode(msg) == GroundSpeed(speed_mps=1.111, distance_m=25.0,
                                            direction="forward")
    frame = InclinometerFrame(x_mv=3698, y_mv=2500, x_status="below range", counter=7)
    assert codec.decode(codec.encode(frame)) == frame
    standard = can.Message(arbitration_id=msg.arbitration_id, is_extended_id=False,
                           data=msg.data)
    with pytest.raises(FrameError, match="identifier format"):
        codec.decode(standard)
    with pytest.raises(FrameError, match="GBSD"):
        codec.decode(can.Message(arbitration_id=msg.arbitration_id, data=b"\x00"))
    with pytest.raises(FrameError, match="not one of"):
        codec.encode(DepthSetpoint(target_depth_mm=30.0, enable="maybe"))
