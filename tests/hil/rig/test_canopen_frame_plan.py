"""A TPDO framed by one struct of the application's readers is the frame canopen's path gives.

:meth:`CanopenDevice._frame_plan` (issue 29) reads each mapped variable with the function
:meth:`CanopenDevice.app_reader` gives instead of asking the read callbacks. Shown here: the
frames are the byte plan's and canopen's, on the I/O module and on the depth rig's drive over
a run; a reader that disagrees with the callbacks is refused when the plan is built; a value
the struct must not pack is framed by canopen's rules; a new read callback rebuilds the plan.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest

from hil.rig import RigContext
from hil.rig.canopen_device import CanopenDevice
from plant_emulators.sowing_depth.rig import SowingDepthRig

EDS = Path(__file__).parent / "data" / "io_module.eds"
NODE = 5
SYNC = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
ENTRY = (0x6401, 1)                  # INTEGER16, the I/O module's TPDO 1


class _Module(CanopenDevice):
    """An I/O module whose application answers 0x6401:01 from ``value`` (callback and reader)."""

    def __init__(self, reader: Callable[[], Any] | None = None) -> None:
        super().__init__("io", NODE, EDS)
        self.value: Any = 0
        self._reader = reader
        self.node.add_read_callback(self._on_read)

    def _on_read(self, index: int, subindex: int, od: Any) -> Any:
        return self.value if (index, subindex) == ENTRY else None

    def app_reader(self, index: int, subindex: int) -> Callable[[], Any] | None:
        if (index, subindex) != ENTRY:
            return None
        return self._reader or (lambda: self.value)


def _frames(dev: CanopenDevice, values: list[Any]) -> list[Any]:
    out: list[Any] = []
    for k, value in enumerate(values):
        dev.value = value                                    # type: ignore[attr-defined]
        try:
            out.append([bytes(m.data) for m in dev.on_frame(SYNC, 0.1 * (k + 1))])
        except Exception as exc:                             # the exception's type is compared
            out.append(type(exc))
    return out


def test_the_struct_frame_is_the_byte_plans_and_canopens() -> None:
    fast, plan, library = _Module(), _Module(), _Module()
    plan._frame_plan = lambda pdo: None                      # type: ignore[method-assign]
    library._byte_plan = lambda pdo: None                    # type: ignore[method-assign]
    for dev in (fast, plan, library):
        dev.emit(0.0)
    values = [0, 1, -1, 1234, -32768, 32767, 7]
    assert _frames(fast, values) == _frames(plan, values) == _frames(library, values)
    assert fast._frame_plan(fast._tpdos[0]) is not None      # the struct framed them
    assert struct.unpack("<h", _frames(fast, [-1234])[0][0])[0] == -1234


def test_a_value_the_struct_must_not_pack_is_framed_by_canopens_rules() -> None:
    fast, library = _Module(), _Module()
    library._byte_plan = lambda pdo: None                    # type: ignore[method-assign]
    for dev in (fast, library):
        dev.emit(0.0)
    values = [5, 40000, -40000, 7.9, True, b"\x01\x02", 6]
    theirs = _frames(library, values)
    assert _frames(fast, values) == theirs
    assert ValueError in theirs and theirs[0] == [b"\x05\x00"]


def test_a_reader_that_disagrees_with_the_callbacks_is_refused() -> None:
    dev = _Module(reader=lambda: 99)                         # the callback says dev.value
    dev.emit(0.0)
    assert dev._frame_plan(dev._tpdos[0]) is None
    assert _frames(dev, [3]) == [[b"\x03\x00"]]                # the callbacks' value
    float_reader = _Module(reader=lambda: 0.0)               # equal, but not the same type
    float_reader.emit(0.0)
    assert float_reader._frame_plan(float_reader._tpdos[0]) is None


def test_a_new_read_callback_rebuilds_the_plan() -> None:
    dev = _Module()
    dev.emit(0.0)
    tpdo = dev._tpdos[0]
    first = dev._frame_plan(tpdo)
    assert first is not None and dev._frame_plan(tpdo) is first        # cached
    dev.node.add_read_callback(lambda index, subindex, od: None)
    again = dev._frame_plan(tpdo)
    assert again is not None and again is not first


@pytest.mark.parametrize("seed", [4, 11])
def test_the_depth_drives_tpdos_are_the_byte_plans_over_a_run(seed: int) -> None:
    rigs = [SowingDepthRig(RigContext(seed=seed, rng=np.random.default_rng(seed)))
            for _ in range(2)]
    fast, slow = rigs
    slow.drive._frame_plan = lambda pdo: None                # type: ignore[method-assign]
    rng = np.random.default_rng(seed)
    try:
        for r in rigs:
            r.drive.emit(0.0)
            r.drive.on_frame(can.Message(arbitration_id=0x000, is_extended_id=False,
                                         data=bytes([0x01, r.drive.node_id])), 0.0)
            r.set_input("ground_speed_mps", 1.5, 0.0)
        node = fast.drive.node_id
        for k in range(300):
            controlword = [0x06, 0x07, 0x0F][min(k, 2)] if k != 150 else 0x80
            velocity = int(rng.integers(-5000, 5000))
            frames = [can.Message(arbitration_id=0x300 + node, is_extended_id=False,
                                  data=controlword.to_bytes(2, "little")
                                  + velocity.to_bytes(4, "little", signed=True)), SYNC]
            if k == 0:
                frames.insert(0, can.Message(arbitration_id=0x400 + node,
                                             is_extended_id=False, data=bytes([3])))
            out = []
            for r in rigs:
                sent = []
                for msg in frames:
                    sent += r.drive.on_frame(msg, k * 0.01)
                r.advance(10, 0.001)
                out.append([(m.arbitration_id, bytes(m.data)) for m in sent])
            assert out[0] == out[1] and len(out[0]) >= 3
        assert all(fast.drive._frame_plan(t) is not None for t in fast.drive._tpdos)
        assert fast.drive.node.data_store == slow.drive.node.data_store
        assert fast.plant.rod_position_mm == slow.plant.rod_position_mm
    finally:
        for r in rigs:
            r.close()
