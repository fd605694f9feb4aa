"""Address claim (ISO 11783-5) between two networks on a virtual wire, frame by frame."""

from __future__ import annotations

import can

from hil.isobus.can_id import decode_id, encode_id
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.wire import ScriptedNode, VirtualWire

TECU = IsobusName(identity_number=1, manufacturer_code=100, function=134, device_class=1)
LOW = IsobusName(identity_number=0)                      # lower than every NAME here
IMPLEMENT = IsobusName(identity_number=7, manufacturer_code=200, function=130, device_class=6)
IMPLEMENT_SC = IsobusName(identity_number=7, manufacturer_code=200, function=130,
                          device_class=6, self_configurable=True)


def claims(wire: VirtualWire) -> list[tuple[float, int, int]]:
    """(time, source address, NAME) of every address-claimed frame on the wire."""
    out = []
    for f in wire.frames:
        fid = decode_id(f.frame.arbitration_id)
        if fid.pgn == 0xEE00:
            out.append((f.time_s, fid.source, int.from_bytes(f.frame.data, "little")))
    return out


def pair(rig_name: IsobusName, dut_name: IsobusName, address: int = 0x80):
    rig, dut = IsobusNetwork(name="rig"), IsobusNetwork(name="dut")
    a = rig.add(rig_name, address, "rig")
    b = dut.add(dut_name, address, "dut")
    return rig, dut, a, b, VirtualWire([rig, dut])


def test_uncontested_claim_settles_after_250_ms_and_holds_traffic_until_then() -> None:
    rig = IsobusNetwork()
    cf = rig.add(TECU, 0x80)
    listener = ScriptedNode()
    wire = VirtualWire([rig, listener])
    cf.send(0xFE48, bytes(8))              # queued before the claim
    wire.run_until(0.2)
    assert cf.address is None
    wire.run_until(0.3)
    assert cf.address == 0x80
    frames = [(t, m) for t, m in listener.heard]
    assert frames[0][1].arbitration_id == 0x18EEFF80
    assert bytes(frames[0][1].data) == TECU.to_bytes()
    speed = [t for t, m in frames if decode_id(m.arbitration_id).pgn == 0xFE48]
    assert speed and speed[0] >= 0.25


def test_rig_with_lower_name_defends_and_self_configurable_dut_moves() -> None:
    rig, dut, a, b, wire = pair(TECU, IMPLEMENT_SC)
    wire.run_until(1.0)
    assert (a.address, b.address) == (0x80, 0x81)
    seen = [(src, name) for _, src, name in claims(wire)]
    assert seen == [(0x80, TECU.value), (0x80, IMPLEMENT_SC.value), (0x80, TECU.value),
                    (0x81, IMPLEMENT_SC.value)]
    assert rig.external() == {0x81: IMPLEMENT_SC.value}
    assert dut.external() == {0x80: TECU.value}


def test_dut_without_self_configuration_sends_cannot_claim_from_null() -> None:
    rig, _dut, a, b, wire = pair(TECU, IMPLEMENT)
    wire.run_until(1.0)
    assert a.address == 0x80 and b.address is None and b.claimer.cannot_claim
    assert claims(wire)[-1][1:] == (0xFE, IMPLEMENT.value)
    assert rig.external() == {}     # a cannot-claim holds no address


def test_rig_loses_to_a_lower_name_both_ways() -> None:
    _rig, _dut, a, b, wire = pair(IMPLEMENT, TECU)        # now the rig's NAME is higher
    wire.run_until(1.0)
    assert a.address is None and a.claimer.cannot_claim and b.address == 0x80
    _rig2, _dut2, a2, b2, wire2 = pair(IMPLEMENT_SC, TECU)
    wire2.run_until(1.0)
    assert (a2.address, b2.address) == (0x81, 0x80)


def test_a_later_lower_claim_takes_a_settled_address() -> None:
    rig = IsobusNetwork()
    cf = rig.add(IMPLEMENT_SC, 0x80)
    intruder = ScriptedNode([(2.0, can.Message(arbitration_id=encode_id(6, 0xEE00, 0x80),
                                               data=LOW.to_bytes(), is_extended_id=True))])
    wire = VirtualWire([rig, intruder])
    wire.run_until(1.0)
    assert cf.address == 0x80
    wire.run_until(2.1)
    assert cf.address is None                   # claiming 0x81, 250 ms not yet over
    wire.run_until(2.3)
    assert cf.address == 0x81
    assert rig.table.name_of(0x80) == LOW.value


def test_a_higher_claim_on_our_address_is_answered_with_our_claim() -> None:
    rig = IsobusNetwork()
    cf = rig.add(TECU, 0x80)
    high = IsobusName(identity_number=99, self_configurable=True)
    intruder = ScriptedNode([(1.0, can.Message(arbitration_id=encode_id(6, 0xEE00, 0x80),
                                               data=high.to_bytes(), is_extended_id=True))])
    wire = VirtualWire([rig, intruder])
    wire.run_until(1.5)
    answers = [(t, m) for t, m in intruder.heard if m.arbitration_id == 0x18EEFF80]
    assert len(answers) == 2 and answers[0][0] < 0.001 and answers[1][0] == 1.0
    assert cf.address == 0x80
    assert rig.table.name_of(0x80) == TECU.value      # the lower NAME keeps the entry


def test_request_for_address_claimed_global_and_to_one_address() -> None:
    rig = IsobusNetwork()
    rig.add(TECU, 0x80)
    tc = IsobusName(identity_number=2, function=130)
    rig.add(tc, 0xF7)
    request_all = can.Message(arbitration_id=encode_id(6, 0xEA00, 0x10, 0xFF),
                              data=bytes([0x00, 0xEE, 0x00]), is_extended_id=True)
    request_tc = can.Message(arbitration_id=encode_id(6, 0xEA00, 0x10, 0xF7),
                             data=bytes([0x00, 0xEE, 0x00]), is_extended_id=True)
    asker = ScriptedNode([(1.0, request_all), (2.0, request_tc)])
    wire = VirtualWire([rig, asker])
    wire.run_until(3.0)
    at_1 = sorted(m.arbitration_id for t, m in asker.heard if t == 1.0)
    at_2 = sorted(m.arbitration_id for t, m in asker.heard if t == 2.0)
    assert at_1 == [0x18EEFF80, 0x18EEFFF7]
    assert at_2 == [0x18EEFFF7]


def test_cannot_claim_is_repeated_on_request() -> None:
    _rig, _dut, a, _b, wire = pair(TECU, IMPLEMENT)
    wire.run_until(1.0)
    before = len(claims(wire))
    a.send(0xEA00, bytes([0x00, 0xEE, 0x00]))    # the rig's TECU asks everyone
    wire.run_until(1.1)
    answers = claims(wire)[before:]
    # the requester answers its own global request too (ISO 11783-5 / J1939-81)
    assert sorted((src, name) for _, src, name in answers) == [(0x80, TECU.value),
                                                               (0xFE, IMPLEMENT.value)]


def test_two_internal_functions_contend_inside_one_network() -> None:
    rig = IsobusNetwork()
    low = rig.add(TECU, 0x80)
    high = rig.add(IMPLEMENT_SC, 0x80)
    listener = ScriptedNode()
    wire = VirtualWire([rig, listener])
    wire.run_until(1.0)
    assert (low.address, high.address) == (0x80, 0x81)
    assert low.name_of(0x81) == IMPLEMENT_SC.value and high.name_of(0x80) == TECU.value
