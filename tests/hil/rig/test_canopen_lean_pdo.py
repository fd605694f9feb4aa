"""The CANopen node's lean PDO paths give what canopen's own paths give.

``CanopenDevice._sample`` replaces ``LocalNode.get_data`` for the integer variables of a
byte-aligned TPDO (see its docstring for why); these tests hold it to canopen's bytes and
exceptions for every kind of value a read callback may return, show that the check made when a
plan is built leaves a disagreeing variable to canopen, and that the cached heartbeat period
follows every way 0x1017 can change. (The sowing-depth drive's frames and object dictionary,
lean against canopen's per-variable path over a run, are compared in
``tests/plant_emulators/sowing_depth/test_perf_sowing_rig.py``.)
"""

from __future__ import annotations

import logging
import struct
from pathlib import Path
from typing import Any

import can
import pytest

from hil.rig.canopen_device import CanopenDevice, _packer

EDS = Path(__file__).parent / "data" / "io_module.eds"
NODE = 5
SYNC = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)


def _outcome(call: Any) -> tuple[str, Any]:
    try:
        return "bytes", bytes(call())
    except Exception as exc:              # the exception's type is compared
        return "raised", type(exc)


@pytest.mark.parametrize("value", [0, 1, -1, 32767, -32768, 32768, -32769, 150, -150, 7.9,
                                   True, b"\x01\x02", None])
def test_a_lean_sample_is_canopens_bytes_or_its_exception(value: object,
                                                          caplog: pytest.LogCaptureFixture
                                                          ) -> None:
    dev = CanopenDevice("io", NODE, EDS)
    obj = dev.node.object_dictionary[0x6401][1]            # INTEGER16, mapped in TPDO 1
    obj.min, obj.max = -100, 100                            # EDS LowLimit/HighLimit
    dev.write(0x6401, 1, 42)                                # the data store's value
    dev.node.add_read_callback(
        lambda index, subindex, od: value if (index, subindex) == (0x6401, 1) else None)
    packer, lo, hi = _packer(obj)
    assert (lo, hi) == (-100, 100)
    with caplog.at_level(logging.WARNING, logger="canopen"):
        lean = _outcome(lambda: dev._sample(obj, 0x6401, 1, packer, lo, hi))
        lean_logged = [r.getMessage() for r in caplog.records]
        caplog.clear()
        canopen_own = _outcome(lambda: dev.node.get_data(0x6401, 1))
        canopen_logged = [r.getMessage() for r in caplog.records]
    assert lean == canopen_own
    assert lean_logged == canopen_logged                    # the range warning, when there is one


def test_the_lean_tpdo_frame_is_canopens() -> None:
    devices = [CanopenDevice("io", NODE, EDS) for _ in range(2)]
    lean, library = devices
    library._byte_plan = lambda pdo: None                   # type: ignore[method-assign]
    for dev in devices:
        dev.emit(0.0)
    for k, value in enumerate([0, 1, -1, 1234, -32768, 32767]):
        frames = []
        for dev in devices:
            dev.write(0x6401, 1, value)
            frames.append([(m.arbitration_id, bytes(m.data)) for m in
                           dev.on_frame(SYNC, 0.1 * (k + 1))])
        assert frames[0] == frames[1] != []
        assert struct.unpack_from("<h", frames[0][0][1])[0] == value
    plan = lean._byte_plan(lean._tpdos[0])
    assert plan is not None and all(step[6] is not None for step in plan)   # all lean


def test_a_variable_whose_lean_sample_disagrees_is_left_to_canopen() -> None:
    dev = CanopenDevice("io", NODE, EDS)
    dev.emit(0.0)
    dev.write(0x6401, 1, 300)
    honest = dev._sample
    dev._sample = (lambda obj, index, subindex, packer, lo, hi:   # type: ignore[method-assign]
                   b"\xff" * len(honest(obj, index, subindex, packer, lo, hi)))
    plan = dev._byte_plan(dev._tpdos[0])
    assert plan is not None and all(step[6] is None for step in plan)
    frame = dev.on_frame(SYNC, 0.1)[0]
    assert struct.unpack_from("<h", bytes(frame.data))[0] == 300    # canopen's bytes


def test_the_heartbeat_period_follows_every_write_of_0x1017() -> None:
    dev = CanopenDevice("io", NODE, EDS)
    dev.emit(0.0)
    assert dev.heartbeat_period_s() == 0.5
    dev.write(0x1017, 0, 200)                               # from the device side
    assert dev.heartbeat_period_s() == 0.2
    dev.node.sdo[0x1017].raw = 300                          # canopen's own SDO access
    assert dev.heartbeat_period_s() == 0.3
    download = can.Message(arbitration_id=0x600 + NODE, is_extended_id=False,
                           data=bytes([0x2B, 0x17, 0x10, 0x00]) + (250).to_bytes(2, "little")
                           + b"\x00\x00")                   # the master's SDO download
    replies = dev.on_frame(download, 0.1)
    assert [bytes(m.data)[0] for m in replies] == [0x60]
    assert dev.heartbeat_period_s() == 0.25
    dev.on_frame(can.Message(arbitration_id=0, data=bytes([0x81, NODE]), is_extended_id=False),
                 0.2)                                       # reset node: the EDS's 500 ms
    assert dev.heartbeat_period_s() == 0.5
