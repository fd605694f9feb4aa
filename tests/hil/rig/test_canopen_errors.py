"""CiA 301 error behaviour of the rig's CANopen nodes (:class:`CanopenDevice`), frame by frame.

EMCY on occurrence and the error-reset EMCY (0x0000) when the error goes away; 0x1001; 0x1003
history (count in sub 0, write 0 clears); EMCY COB-ID 0x1014 valid bit; inhibit time 0x1015;
NMT state rules (no PDO outside operational, stopped answers only NMT and sends heartbeats,
reset sends boot-up and goes pre-operational). Read back through canopen's own consumer.
"""

from __future__ import annotations

import itertools
import struct
from pathlib import Path

import can
import canopen
import pytest
from canopen.emcy import EmcyConsumer

from hil.rig.canopen_device import CanopenDevice
from hil.rig.canopen_errors import ErrorState, register_bits_of

BASE_EDS = Path(__file__).parent / "data" / "io_module.eds"
NODE = 5


def _var(index: int, name: str, dtype: str, access: str, default: str) -> str:
    return (f"[{index:04X}]\nParameterName={name}\nObjectType=0x7\nDataType={dtype}\n"
            f"AccessType={access}\nDefaultValue={default}\nPDOMapping=0\n\n")


def _eds(tmp_path: Path, *, inhibit_100us: int | None = None, emcy_cob: str = "$NODEID+0x80",
         history: int = 4) -> Path:
    """The test I/O module's EDS with EMCY objects (0x1014, 0x1003, optionally 0x1015)."""
    text = BASE_EDS.read_text() + "\n" + _var(0x1014, "COB-ID EMCY", "0x0007", "rw", emcy_cob)
    if inhibit_100us is not None:
        text += _var(0x1015, "Inhibit time EMCY", "0x0006", "rw", str(inhibit_100us))
    if history:
        text += (f"[1003]\nParameterName=Pre-defined error field\nObjectType=0x8\n"
                 f"SubNumber={history + 1}\n\n")
        text += ("[1003sub0]\nParameterName=Number of errors\nObjectType=0x7\n"
                 "DataType=0x0005\nAccessType=rw\nDefaultValue=0\nPDOMapping=0\n\n")
        for sub in range(1, history + 1):
            text += (f"[1003sub{sub}]\nParameterName=Standard error field\nObjectType=0x7\n"
                     "DataType=0x0007\nAccessType=ro\nDefaultValue=0\nPDOMapping=0\n\n")
    path = tmp_path / "io_module_emcy.eds"
    path.write_text(text)
    return path


def _booted(eds: Path) -> CanopenDevice:
    dev = CanopenDevice("io", NODE, eds)
    dev.emit(0.0)
    return dev


def _sync() -> can.Message:
    return can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)


def _nmt(command: int) -> can.Message:
    return can.Message(arbitration_id=0x000, data=bytes([command, NODE]), is_extended_id=False)


def _emcys(frames: list[can.Message]) -> list[tuple[int, int]]:
    return [struct.unpack_from("<HB", bytes(m.data)) for m in frames
            if m.arbitration_id == 0x80 + NODE]


def test_error_state_register_and_history() -> None:
    errors = ErrorState(history_length=2)
    assert errors.occur(0x2310) == (0x2310, 0x03)
    assert errors.occur(0x2310) is None                 # already active: no second EMCY
    assert errors.occur(0x8130) == (0x8130, 0x13)
    assert errors.clear(0x2310) == (0, 0x11)            # the communication error is left
    assert errors.occur(0x3220) == (0x3220, 0x15)
    assert errors.history == [0x3220, 0x8130]           # newest first, at most 2
    assert errors.clear_all() == (0, 0) and errors.register == 0
    assert errors.clear_all() is None
    with pytest.raises(LookupError):
        errors.field(3)
    assert register_bits_of(0xFF01) == 0x81 and register_bits_of(0x8611) == 0x21
    with pytest.raises(ValueError):
        errors.occur(0)


def test_emcy_on_error_and_reset_clears_a_masters_active_list(tmp_path: Path) -> None:
    dev = _booted(_eds(tmp_path))
    consumer = EmcyConsumer()
    dev.raise_error(0x2310)
    frames = dev.on_frame(_sync(), 0.01)
    assert _emcys(frames) == [(0x2310, 0x03)]
    assert dev.read(0x1001) == 0x03
    for m in frames:
        if m.arbitration_id == 0x85:
            consumer.on_emcy(m.arbitration_id, bytes(m.data), 0.01)
    assert [e.code for e in consumer.active] == [0x2310]
    dev.clear_error(0x2310)
    frames = dev.on_frame(_sync(), 0.02)
    assert _emcys(frames) == [(0x0000, 0x00)]
    for m in frames:
        if m.arbitration_id == 0x85:
            consumer.on_emcy(m.arbitration_id, bytes(m.data), 0.02)
    assert consumer.active == []
    assert dev.read(0x1001) == 0


def test_emcy_goes_out_in_pre_operational_at_the_heartbeat(tmp_path: Path) -> None:
    dev = _booted(_eds(tmp_path))
    dev.on_frame(_nmt(0x80), 0.1)                        # enter pre-operational
    dev.raise_error(0x5000)
    assert dev.on_frame(_sync(), 0.2) == []              # no SYNC consumer outside operational
    assert dev.next_due(0.2) <= 0.2 + 1e-3               # it asks to send now
    assert _emcys(dev.emit(0.2 + 1e-6)) == [(0x5000, 0x01)]


def test_pre_defined_error_field(tmp_path: Path) -> None:
    dev = _booted(_eds(tmp_path, history=3))
    for code in (0x2310, 0x3220, 0x4210, 0x5000):
        dev.raise_error(code)
        dev.clear_error(code)
    sdo = dev.node.sdo
    assert sdo[0x1003][0].raw == 3
    assert [sdo[0x1003][sub].raw for sub in (1, 2, 3)] == [0x5000, 0x4210, 0x3220]
    with pytest.raises(canopen.SdoAbortedError) as info:
        sdo[0x1003][0].raw = 2
    assert info.value.code == 0x06090030
    sdo[0x1003][0].raw = 0
    assert sdo[0x1003][0].raw == 0
    with pytest.raises(canopen.SdoAbortedError) as info:
        _ = sdo[0x1003][1].raw
    assert info.value.code == 0x08000024


def test_inhibit_time_spaces_emcys(tmp_path: Path) -> None:
    dev = _booted(_eds(tmp_path, inhibit_100us=500))     # 50 ms
    for code in (0x2310, 0x3220, 0x4210):
        dev.raise_error(code)
    sent = []
    t = 0.01
    while t < 0.2:
        sent += [(round(t, 3), code) for code, _ in _emcys(dev.on_frame(_sync(), t))]
        t += 0.01
    assert [code for _, code in sent] == [0x2310, 0x3220, 0x4210]
    times = [ts for ts, _ in sent]
    assert all(b - a >= 0.05 - 1e-9 for a, b in itertools.pairwise(times))


def test_no_emcy_when_the_cob_id_is_marked_invalid(tmp_path: Path) -> None:
    dev = _booted(_eds(tmp_path, emcy_cob="0x80000085"))
    dev.raise_error(0x2310)
    assert _emcys(dev.on_frame(_sync(), 0.01)) == []
    assert dev.read(0x1001) == 0x03                      # the error is still recorded


def test_stopped_answers_only_nmt_and_heartbeat(tmp_path: Path) -> None:
    dev = _booted(_eds(tmp_path))
    assert dev.operational
    assert dev.on_frame(_nmt(0x02), 0.1) == []           # stop
    sdo_read = can.Message(arbitration_id=0x600 + NODE,
                           data=bytes([0x40, 0x00, 0x10, 0, 0, 0, 0, 0]), is_extended_id=False)
    assert dev.on_frame(sdo_read, 0.11) == []
    assert dev.on_frame(_sync(), 0.12) == []
    dev.raise_error(0x2310)
    beat = dev.emit(0.5)
    assert [(m.arbitration_id, bytes(m.data)) for m in beat] == [(0x700 + NODE, b"\x04")]
    # the EMCY waits for the node to leave stopped, and goes out as it does
    assert _emcys(dev.on_frame(_nmt(0x80), 0.6)) == [(0x2310, 0x03)]
    answer = dev.on_frame(sdo_read, 0.61)
    assert [m.arbitration_id for m in answer] == [0x580 + NODE]


def test_pre_operational_takes_sdo_but_no_pdo(tmp_path: Path) -> None:
    dev = _booted(_eds(tmp_path))
    dev.on_frame(_nmt(0x80), 0.1)
    rpdo = can.Message(arbitration_id=0x205, data=struct.pack("<hh", 7000, -5),
                       is_extended_id=False)
    before = dev.read(0x6411, 1)
    dev.on_frame(rpdo, 0.11)
    assert dev.read(0x6411, 1) == before                 # RPDO ignored
    assert dev.on_frame(_sync(), 0.12) == []             # no TPDO
    sdo_read = can.Message(arbitration_id=0x600 + NODE,
                           data=bytes([0x40, 0x00, 0x10, 0, 0, 0, 0, 0]), is_extended_id=False)
    assert [m.arbitration_id for m in dev.on_frame(sdo_read, 0.13)] == [0x580 + NODE]


@pytest.mark.parametrize("command", [0x81, 0x82])        # reset node, reset communication
def test_reset_sends_boot_up_and_goes_pre_operational(tmp_path: Path, command: int) -> None:
    dev = CanopenDevice("io", NODE, _eds(tmp_path), autostart=False)
    dev.emit(0.0)
    dev.on_frame(_nmt(0x01), 0.05)
    assert dev.operational
    out = dev.on_frame(_nmt(command), 0.1)
    assert [(m.arbitration_id, bytes(m.data)) for m in out] == [(0x700 + NODE, b"\x00")]
    assert dev.node.nmt.state == "PRE-OPERATIONAL"
    beat = dev.emit(dev.next_due(0.1))
    assert [bytes(m.data) for m in beat if m.arbitration_id == 0x700 + NODE] == [b"\x7f"]
