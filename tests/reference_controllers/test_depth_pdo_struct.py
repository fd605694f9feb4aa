"""The depth controller's PDO structs give canopen's bytes and values (issue 29's fast path).

:class:`~reference_controllers.sowing_depth.pdo_struct.PdoStruct` packs and unpacks the drive's
PDOs without canopen's per-variable path; these tests hold it to canopen on every map of the
drive's EDS, show its self-check refusing a layout that disagrees and the maps it does not
cover, and run the controller with and without the structs on the same frames.
"""

from __future__ import annotations

import can
import canopen
import numpy as np
import pytest

from hil.rig.canopen_device import OutboxNetwork
from plant_emulators.sowing_depth.frames import (
    EDS_PATH,
    DepthSetpoint,
    FrameCodec,
    GroundSpeed,
    InclinometerFrame,
)
from plant_emulators.sowing_depth.sensors import calibration_signal_mv
from reference_controllers.sowing_depth.adapter import DepthController
from reference_controllers.sowing_depth.pdo_struct import PdoStruct


def _drive() -> canopen.RemoteNode:
    network = OutboxNetwork()
    node = canopen.RemoteNode(1, str(EDS_PATH))
    network.add_node(node)
    node.rpdo.read(from_od=True)
    node.tpdo.read(from_od=True)
    return node


def _maps(node: canopen.RemoteNode) -> list[object]:
    return [*node.tpdo.map.values(), *node.rpdo.map.values()]


def test_every_map_of_the_drive_packs_and_unpacks_as_canopen() -> None:
    node = _drive()
    rng = np.random.default_rng(29)
    maps = _maps(node)
    assert len(maps) == 6
    for pdo in maps:
        layout = PdoStruct.build(pdo)
        assert layout is not None, pdo.name
        assert layout.cob_id == pdo.cob_id and layout.size == len(pdo.data)
        for _ in range(200):
            values = {name: int(rng.integers(lo, hi, endpoint=True))
                      for name, (lo, hi) in zip(layout.names, layout.ranges, strict=True)}
            pdo.data = bytearray(layout.size)
            for name, value in values.items():
                pdo[name].raw = value
            assert layout.pack(values) == bytes(pdo.data)
            payload = bytes(rng.integers(0, 256, layout.size + 2, dtype=np.uint8))
            pdo.data = bytearray(payload)          # what canopen's on_message stores
            assert layout.unpack(payload) == tuple(pdo[name].raw for name in layout.names)


def test_what_canopen_must_do_is_left_to_it() -> None:
    node = _drive()
    layout = PdoStruct.build(node.tpdo[1])
    assert layout is not None
    assert layout.unpack(b"\x00" * (layout.size - 1)) is None        # shorter than the map
    assert layout.pack({"Statusword": 70000, "Position actual value": 0}) is None
    assert layout.pack({"Statusword": 1.0, "Position actual value": 0}) is None
    assert layout.pack({"Statusword": True, "Position actual value": 0}) is None
    pdo = node.tpdo[2]
    pdo.clear()
    pdo.add_variable(0x6041, 0, 12)                                    # not whole bytes
    assert PdoStruct.build(pdo) is None
    pdo.clear()
    assert PdoStruct.build(pdo) is None                                # nothing mapped


def test_the_self_check_refuses_a_layout_that_disagrees_with_canopen() -> None:
    node = _drive()
    pdo = node.tpdo[1]
    good = PdoStruct.build(pdo)
    assert good is not None and good._agrees(pdo)
    for fmt in (">Hl", "<HL", "<hl", "<Hq"):                           # byte order, sign, size
        bad = PdoStruct(pdo.cob_id, good.names, fmt, good.ranges)
        assert not bad._agrees(pdo), fmt
    assert bytes(pdo.data) == b"\x00" * 6                              # the buffer restored


def _frames(ctl: DepthController, steps: int) -> list[tuple[int, bytes]]:
    """Boot the drive, enable it and regulate towards a depth step: every frame out."""
    codec = FrameCodec()
    node = ctl.node_id
    out: list[can.Message] = []
    rng = np.random.default_rng(5)
    statusword, position = 0x0250, 1000
    out += ctl.on_frame(can.Message(arbitration_id=0x700 + node, data=b"\x7f",
                                    is_extended_id=False))
    out += ctl.on_frame(can.Message(arbitration_id=0x700 + node, data=b"\x05",
                                    is_extended_id=False))
    speed = codec.encode(GroundSpeed(speed_mps=1.2, distance_m=0.0))
    setpoint = codec.encode(DepthSetpoint(target_depth_mm=35.0, manual_roller_position_mm=0.0,
                                          enable="on", mode="automatic", counter=0))
    out += ctl.on_frame(setpoint)
    for k in range(steps):
        if k == 3:
            statusword = 0x0237                                        # operation enabled
        position += int(rng.integers(-40, 40))
        depth = 30.0 + 8.0 * np.sin(k / 15.0)
        x_mv = round(calibration_signal_mv(depth))
        out += ctl.on_frame(codec.encode(InclinometerFrame(
            x_mv=x_mv, y_mv=2500, x_status="ok", y_status="ok", counter=k % 16)))
        out += ctl.on_frame(speed)
        tpdo1 = statusword.to_bytes(2, "little") + position.to_bytes(4, "little", signed=True)
        tpdo2 = statusword.to_bytes(2, "little") + (k * 7).to_bytes(4, "little", signed=True)
        out += ctl.on_frame(can.Message(arbitration_id=0x180 + node, data=tpdo1,
                                        is_extended_id=False))
        out += ctl.on_frame(can.Message(arbitration_id=0x280 + node, data=tpdo2,
                                        is_extended_id=False))
        out += ctl.on_frame(can.Message(arbitration_id=0x080, data=b"", is_extended_id=False))
    return [(m.arbitration_id, bytes(m.data)) for m in out]


def test_the_controller_sends_the_same_frames_with_and_without_the_structs() -> None:
    fast, slow = DepthController(), DepthController()
    assert all(v is not None for v in fast._tpdo_structs.values())
    assert fast._command is not None
    slow._tpdo_structs = {1: None, 2: None}                           # canopen's own paths
    slow._command = None
    frames = _frames(fast, 120)
    assert frames == _frames(slow, 120)
    commands = [data for can_id, data in frames if can_id == 0x300 + fast.node_id]
    assert len(commands) == 120 and len(set(commands)) > 20           # it regulated
    assert (fast.statusword, fast.position_mm) == (slow.statusword, slow.position_mm)


def test_a_short_tpdo_is_left_to_canopen_which_raises() -> None:
    ctl = DepthController()
    short = can.Message(arbitration_id=0x180 + ctl.node_id, data=b"\x37\x02\x00",
                        is_extended_id=False)
    with pytest.raises(canopen.objectdictionary.ObjectDictionaryError):
        ctl.on_frame(short)
