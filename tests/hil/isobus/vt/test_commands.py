"""A connected working set's commands: applied to its pool, answered with the standard's bytes."""

from __future__ import annotations

import struct

import pytest

from hil.isobus.vt.bench import IMPLEMENT_ADDRESS, VtBench
from hil.isobus.vt.messages import Function, pad, u16, u32
from hil.isobus.vt.workingset import WorkingSet

from .pools import IDS, implement_pool


@pytest.fixture
def bench() -> VtBench:
    b = VtBench([implement_pool().to_bytes()])
    b.run_until(3.0)
    assert b.client is not None and b.client.state == "connected"
    return b


def ws_of(bench: VtBench) -> WorkingSet:
    return bench.vt.sessions[IMPLEMENT_ADDRESS]


def send(bench: VtBench, data: bytes) -> bytes:
    """Send one command; the VT's response to it."""
    assert bench.client is not None
    before = len(bench.client.responses)
    bench.client.command(data)
    bench.run_for(0.2)
    answers = [r for _, r in bench.client.responses[before:] if r[0] == data[0]]
    assert len(answers) == 1, bench.client.responses[before:]
    return answers[0]


def test_change_numeric_value_sets_the_variable(bench: VtBench) -> None:
    changes: list[str] = []
    bench.vt.on_change.append(lambda ws, t, why: changes.append(why))
    r = send(bench, bytes([0xA8]) + u16(IDS.rate_out) + b"\xff" + u32(3100))
    assert r == bytes([0xA8]) + u16(IDS.rate_out) + bytes([0]) + u32(3100)
    ws = ws_of(bench)
    assert ws.obj(IDS.rate_var)["value"] == 3100              # type: ignore[index]
    assert changes == [f"numeric value {IDS.rate_out} = 3100"]
    r = send(bench, bytes([0xA8]) + u16(4321) + b"\xff" + u32(1))
    assert r[3] == 0x01                                        # invalid object id
    record = bench.vt.commands[-1]
    assert (record.function, record.object_id, record.error) == (0xA8, 4321, 0x01)


def test_change_active_mask_and_soft_key_mask(bench: VtBench) -> None:
    r = send(bench, pad(bytes([0xAD]) + u16(IDS.ws) + u16(IDS.settings)))
    assert r == pad(bytes([0xAD]) + u16(IDS.settings) + bytes([0]))
    assert ws_of(bench).active_mask == IDS.settings
    r = send(bench, pad(bytes([0xAD]) + u16(IDS.ws) + u16(IDS.rate_out)))
    assert r[3] == 0x02 and ws_of(bench).active_mask == IDS.settings
    r = send(bench, pad(bytes([0xAE, 1]) + u16(IDS.settings) + u16(IDS.alarm_keys)))
    assert r == pad(bytes([0xAE]) + u16(IDS.settings) + u16(IDS.alarm_keys) + bytes([0]))
    assert ws_of(bench).soft_key_mask == IDS.alarm_keys
    r = send(bench, pad(bytes([0xAE, 2]) + u16(IDS.settings) + u16(IDS.keys)))
    assert r[5] == 0x01                                        # a data mask is not type 2
    bench.run_for(1.0)                                         # the status says so
    status = [bytes(f.frame.data) for f in bench.wire.frames
              if f.frame.data[0] == Function.VT_STATUS]
    assert status[-1][2:6] == u16(IDS.settings) + u16(IDS.alarm_keys)


def test_hide_show_enable_disable_and_select_input(bench: VtBench) -> None:
    r = send(bench, pad(bytes([0xA0]) + u16(IDS.box) + bytes([0])))
    assert r == pad(bytes([0xA0]) + u16(IDS.box) + bytes([0, 0]))
    ws = ws_of(bench)
    assert not ws.is_shown(IDS.box)
    assert send(bench, pad(bytes([0xA0]) + u16(IDS.rate_out) + bytes([1])))[4] == 0x02
    assert send(bench, pad(bytes([0xA1]) + u16(IDS.button) + bytes([0])))[4] == 0
    assert ws.obj(IDS.button)["options"] & 0x10                 # type: ignore[index]
    send(bench, pad(bytes([0xAD]) + u16(IDS.ws) + u16(IDS.settings)))
    r = send(bench, pad(bytes([0xA2]) + u16(IDS.cal_in) + bytes([0])))
    assert r == pad(bytes([0xA2]) + u16(IDS.cal_in) + bytes([2, 0]))   # opened for edit
    assert ws.open_input == IDS.cal_in
    r = send(bench, pad(bytes([0xA2]) + u16(IDS.rate_out) + bytes([0xFF])))
    assert r[4] == 0x02                                        # not an input object


def test_change_attribute_size_string_and_child_position(bench: VtBench) -> None:
    ws = ws_of(bench)
    scale = struct.pack("<f", 0.5)
    r = send(bench, bytes([0xAF]) + u16(IDS.rate_out) + bytes([8]) + scale)
    assert r == pad(bytes([0xAF]) + u16(IDS.rate_out) + bytes([8, 0]))
    assert ws.obj(IDS.rate_out)["scale"] == 0.5                 # type: ignore[index]
    r = send(bench, bytes([0xAF]) + u16(IDS.rate_out) + bytes([4]) + u32(IDS.home))
    assert r[4] == 0x04                                        # a data mask is not a font
    assert send(bench, bytes([0xAF]) + u16(IDS.rate_out) + bytes([99]) + u32(0))[4] == 0x02
    r = send(bench, pad(bytes([0xA6]) + u16(IDS.rate_out) + u16(200) + u16(30)))
    assert r == pad(bytes([0xA6]) + u16(IDS.rate_out) + bytes([0]))
    assert (ws.obj(IDS.rate_out)["width"], ws.obj(IDS.rate_out)["height"]) == (200, 30)  # type: ignore[index]
    r = send(bench, pad(bytes([0xB3]) + u16(IDS.name_var) + u16(5) + b"North"))
    assert r == pad(bytes([0xB3, 0xFF, 0xFF]) + u16(IDS.name_var) + bytes([0]))
    assert ws.text(ws.obj(IDS.name_in)) == "North"             # type: ignore[arg-type]
    r = send(bench, pad(bytes([0xB3]) + u16(IDS.name_var) + u16(12) + b"far too long"))
    assert r[5] == 0x04                                        # string too long
    r = send(bench, bytes([0xB4]) + u16(IDS.home) + u16(IDS.rate_out) + u16(40) + u16(50))
    assert r[5] == 0
    assert (IDS.rate_out, 40, 50) in ws.obj(IDS.home).children  # type: ignore[union-attr]


def test_lock_unlock_audio_and_macro(bench: VtBench) -> None:
    ws = ws_of(bench)
    changes: list[str] = []
    bench.vt.on_change.append(lambda w, t, why: changes.append(why))
    r = send(bench, pad(bytes([0xBD, 1]) + u16(IDS.home) + u16(500)))
    assert r == pad(bytes([0xBD, 1, 0]))
    assert ws.locked_mask == IDS.home
    send(bench, bytes([0xA8]) + u16(IDS.rate_out) + b"\xff" + u32(1))
    assert not changes                                         # locked: nothing redrawn
    bench.run_for(0.5)                                         # the lock times out
    assert ws.locked_mask is None and changes == ["unlock"]
    assert any(r == pad(bytes([0xBD, 0, 0x10])) for _, r in bench.client.responses)  # type: ignore[union-attr]
    assert send(bench, pad(bytes([0xBD, 0]) + u16(IDS.home)))[2] == 0x04   # not locked
    r = send(bench, bytes([0xA3, 2]) + u16(1000) + u16(100) + u16(50))
    assert r == pad(bytes([0xA3, 0]))
    assert bench.vt.commands[-1].detail == "audio: 2 x 1000 Hz, 100 ms on, 50 ms off"
    r = send(bench, pad(bytes([0xBE, IDS.macro])))
    assert r == pad(bytes([0xBE, IDS.macro, 0xFF, 0]))
    assert not ws.is_shown(IDS.box)                            # the macro hid the box
    assert send(bench, pad(bytes([0xBE, 99])))[3] == 0x01


def test_a_command_before_a_pool_is_negatively_acknowledged() -> None:
    bench = VtBench(client=False)
    bench.run_until(1.0)
    cf = bench.implement_cf
    cf.send(0xE700, pad(bytes([Function.HIDE_SHOW]) + u16(1) + bytes([1])), 0x26, 5)
    bench.run_for(0.1)
    nacks = [f for f in bench.wire.frames if (f.frame.arbitration_id >> 8) & 0x3FF00 == 0xE800]
    assert len(nacks) == 1 and bytes(nacks[0].frame.data)[4] == IMPLEMENT_ADDRESS
    assert [e.kind for e in bench.vt.events] == ["connected", "out of order"]
