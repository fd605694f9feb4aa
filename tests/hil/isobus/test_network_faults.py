"""Fault injection for the DUT's stack: the frames on the wire and the DUT's answer.

The DUT here is our own stack on a second network (what the standard says it must do is what
it does, tested elsewhere); the rig's network carries the faults.
"""

from __future__ import annotations

import tomllib

import pytest

from hil.errors import ConfigError
from hil.isobus.can_id import decode_id
from hil.isobus.faults import (
    AbortTransfer,
    Contend,
    DropCts,
    IsobusFaults,
    LatePacket,
    parse_faults,
)
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.port import Received
from hil.isobus.tp_messages import (
    PGN_ETP_CM,
    PGN_ETP_DT,
    PGN_TP_CM,
    PGN_TP_DT,
    AbortReason,
    Control,
)
from hil.isobus.wire import VirtualWire

RIG = IsobusName(identity_number=1, function=134)
DUT = IsobusName(identity_number=50, function=130, device_class=5)
DUT_SC = IsobusName(identity_number=50, function=130, device_class=5, self_configurable=True)
PGN = 0xEF00


def bench(faults: IsobusFaults, dut_name: IsobusName = DUT):
    rig, dut = IsobusNetwork(faults=faults, name="rig"), IsobusNetwork(name="dut")
    r = rig.add(RIG, 0x80)
    d = dut.add(dut_name, 0x90)
    got: list[Received] = []
    r.subscribe(PGN, got.append)
    d.subscribe(PGN, got.append)
    wire = VirtualWire([rig, dut])
    wire.run_until(0.5)
    return rig, dut, r, d, wire, got


def analyser(wire: VirtualWire, since: float = 0.5) -> list[tuple[float, str, int, int, str]]:
    """What a bus analyser shows: (time, sender, source, destination, what)."""
    out = []
    for f in wire.frames:
        if f.time_s < since:
            continue
        fid = decode_id(f.frame.arbitration_id)
        data = bytes(f.frame.data)
        who = "rig" if f.sender == 0 else "dut"
        if fid.pgn in (PGN_TP_CM, PGN_ETP_CM):
            what = Control(data[0]).name + (f"({data[1]})" if data[0] == Control.ABORT else "")
        elif fid.pgn in (PGN_TP_DT, PGN_ETP_DT):
            what = f"DT{data[0]}"
        elif fid.pgn == 0xEE00:
            what = f"CLAIM 0x{int.from_bytes(data, 'little'):X}"
        else:
            what = f"PGN 0x{fid.pgn:X}"
        out.append((round(f.time_s, 6), who, fid.source, fid.destination, what))
    return out


@pytest.mark.parametrize(("dut_name", "after"), [(DUT, 0xFE), (DUT_SC, 0x80)])
def test_a_contender_with_a_lower_name_takes_the_duts_address(dut_name: IsobusName,
                                                              after: int) -> None:
    faults = IsobusFaults(contend=[Contend(at_s=2.0, address=0x90, name=0)])
    _rig, _dut, _r, d, wire, _got = bench(faults, dut_name)
    wire.run_until(3.0)
    seen = analyser(wire)
    assert seen[0] == (2.0, "rig", 0x90, 0xFF, "CLAIM 0x0")
    if after == 0xFE:
        assert seen[1] == (2.0, "dut", 0xFE, 0xFF, f"CLAIM 0x{DUT.value:X}")
        assert d.address is None and d.claimer.cannot_claim
    else:       # self-configurable: moves to the first free address of 128-247 (0x80 is ours)
        assert seen[1] == (2.0, "dut", 0x81, 0xFF, f"CLAIM 0x{DUT_SC.value:X}")
        assert d.address == 0x81
    assert len(faults.fired) == 1


@pytest.mark.parametrize("size", [100, 3000])
def test_a_dropped_cts_makes_the_sender_time_out_after_t3(size: int) -> None:
    faults = IsobusFaults(dropped_cts=[DropCts(nth=1, peer=0x90)])
    rig, dut, _r, d, wire, got = bench(faults)
    d.send(PGN, bytes(size), destination=0x80)
    wire.run_until(5.0)
    rts = "RTS" if size <= 1785 else "ETP_RTS"
    assert analyser(wire) == [(0.5, "dut", 0x90, 0x80, rts),
                              (1.75, "dut", 0x90, 0x80, "ABORT(3)")]
    assert got == []
    assert dut.transport.events[-1].kind == "timeout"
    assert rig.transport.events[-1].kind == "peer-aborted"


def test_a_dropped_second_cts_cuts_a_transfer_between_windows() -> None:
    faults = IsobusFaults(dropped_cts=[DropCts(nth=2)])
    _rig, _dut, _r, d, wire, _got = bench(faults)
    d.send(PGN, bytes(200), destination=0x80)            # 29 packets: windows of 16 + 13
    wire.run_until(5.0)
    seen = [w for _, _, _, _, w in analyser(wire)]
    assert seen == ["RTS", "CTS"] + [f"DT{i}" for i in range(1, 17)] + ["ABORT(3)"]


@pytest.mark.parametrize("rig_sends", [True, False])
def test_an_abort_mid_transfer_with_a_reason(rig_sends: bool) -> None:
    faults = IsobusFaults(aborts=[AbortTransfer(after_packets=5,
                                                reason=AbortReason.RESOURCES_NEEDED)])
    rig, dut, r, d, wire, got = bench(faults)
    if rig_sends:
        r.send(PGN, bytes(100), destination=0x90)
    else:
        d.send(PGN, bytes(100), destination=0x80)
    wire.run_until(3.0)
    seen = analyser(wire)
    aborts = [s for s in seen if s[4].startswith("ABORT")]
    assert aborts == [(0.5, "rig", 0x80, 0x90, "ABORT(2)")]
    dts = sum(1 for s in seen if s[4].startswith("DT"))
    # the rig as sender stops after 5; as receiver it aborts on the 5th, while the DUT's
    # window of 15 is already on the wire back to back (as on a real bus)
    assert dts == (5 if rig_sends else 15)
    rig_end = rig.transport.events[-1]
    assert (rig_end.kind, rig_end.reason, rig_end.detail) == (
        "aborted", 2, "fault injected after 5 packets")
    assert got == []
    dut_end = dut.transport.events[-1]
    assert (dut_end.kind, dut_end.reason) == ("peer-aborted", 2)


def test_a_late_packet_makes_the_receiver_time_out_after_t1() -> None:
    faults = IsobusFaults(late_packets=[LatePacket(packet=3, delay_s=1.0)])
    _rig, _dut, r, _d, wire, got = bench(faults)
    r.send(PGN, bytes(100), destination=0x90)
    wire.run_until(3.0)
    seen = analyser(wire)
    assert [w for _, _, _, _, w in seen] == ["RTS", "CTS", "DT1", "DT2", "ABORT(3)"]
    assert seen[-1] == (0.5 + 0.75, "dut", 0x90, 0x80, "ABORT(3)")
    assert got == []


def test_a_late_packet_within_t1_is_no_fault() -> None:
    faults = IsobusFaults(late_packets=[LatePacket(packet=3, delay_s=0.7)])
    _rig, _dut, r, _d, wire, got = bench(faults)
    r.send(PGN, bytes(100), destination=0x90)
    wire.run_until(3.0)
    assert [m.data for m in got] == [bytes(100)]


def test_faults_from_a_toml_file() -> None:
    text = """
    [[isobus.faults]]
    kind = "contend"
    at_s = 2.0
    address = 0x90
    name = 1

    [[isobus.faults]]
    kind = "drop_cts"
    nth = 2
    peer = 0x90

    [[isobus.faults]]
    kind = "abort"
    after_packets = 3
    reason = 2

    [[isobus.faults]]
    kind = "late_packet"
    packet = 4
    delay_s = 0.9
    """
    faults = parse_faults(tomllib.loads(text)["isobus"]["faults"], path="bench.toml")
    assert faults.contend == [Contend(2.0, 0x90, 1)]
    assert faults.dropped_cts == [DropCts(2, 0x90)]
    assert faults.aborts == [AbortTransfer(3, 2, None)]
    assert faults.late_packets == [LatePacket(4, 0.9, None)]


@pytest.mark.parametrize(("entry", "key"), [
    ({"kind": "jam"}, "isobus.faults[0].kind"),
    ({"kind": "contend", "at_s": 1.0, "address": 0x90}, "isobus.faults[0].name"),
    ({"kind": "contend", "at_s": 1.0, "address": 254, "name": 0}, "isobus.faults[0].address"),
    ({"kind": "late_packet", "packet": 2, "delay_s": -1}, "isobus.faults[0].delay_s"),
    ({"kind": "abort", "after_packets": 0}, "isobus.faults[0].after_packets"),
    ({"kind": "drop_cts", "when": 1}, "isobus.faults[0]"),
])
def test_a_bad_fault_entry_names_the_file_and_key(entry: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse_faults([entry], path="bench.toml")
    assert err.value.key == key and str(err.value).startswith("bench.toml: ")
