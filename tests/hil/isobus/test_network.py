"""The network as a rig device: identifiers, delivery, ports, the Device contract."""

from __future__ import annotations

import itertools
import math

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.errors import FrameError
from hil.isobus.can_id import decode_id, encode_id, is_pdu1
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.port import IsobusPort, Received
from hil.isobus.wire import ScriptedNode, VirtualWire
from hil.rig.device import Device

A = IsobusName(identity_number=1, function=134)
B = IsobusName(identity_number=2, function=130)


@settings(deadline=None)     # no wall-clock limit: the machine is shared
@given(st.integers(0, 7), st.integers(0, 0x3FFFF), st.integers(0, 255), st.integers(0, 255))
def test_identifier_round_trip(priority: int, pgn: int, source: int, destination: int) -> None:
    if is_pdu1(pgn):
        pgn &= 0x3FF00
    else:
        destination = 0xFF
    fid = decode_id(encode_id(priority, pgn, source, destination))
    assert (fid.priority, fid.pgn, fid.source, fid.destination) == (priority, pgn, source,
                                                                    destination)


def test_known_identifiers() -> None:
    assert encode_id(3, 0xFE48, 0x80) == 0x0CFE4880          # wheel-based speed, PDU2
    assert encode_id(6, 0xEA00, 0x80, 0x26) == 0x18EA2680    # request, PDU1
    with pytest.raises(FrameError, match="PDU2"):
        encode_id(3, 0xFE48, 0x80, 0x26)
    with pytest.raises(FrameError, match="low byte"):
        encode_id(6, 0xEA26, 0x80, 0x26)
    with pytest.raises(FrameError, match="priority"):
        encode_id(8, 0xFE48, 0x80)


def test_an_internal_function_is_an_isobus_port_and_the_network_a_device() -> None:
    net = IsobusNetwork()
    cf = net.add(A, 0x80)
    assert isinstance(net, Device)
    port: IsobusPort = cf          # the Protocol's shape, checked by the type checker too
    assert port.address is None and port.name_of(0x80) is None


def test_single_frames_pdu1_to_one_pdu2_to_all_and_delivery_by_address() -> None:
    rig = IsobusNetwork()
    a = rig.add(A, 0x80)
    b = rig.add(B, 0xF7)                     # both on the rig: frames go round inside
    dut = IsobusNetwork()
    c = dut.add(IsobusName(identity_number=3), 0x26)
    wire = VirtualWire([rig, dut])
    wire.run_until(0.5)
    got: dict[str, list[Received]] = {"a": [], "b": [], "c": []}
    for key, cf in (("a", a), ("b", b), ("c", c)):
        cf.subscribe(0xEF00, got[key].append)
        cf.subscribe(0xFE48, got[key].append)
    a.send(0xEF00, b"\x01\x02", destination=0x26, priority=5)   # to the DUT only
    a.send(0xFE48, bytes(8), priority=3)                        # to everyone
    wire.run_until(0.6)
    sent = [f.frame for f in wire.frames if f.time_s > 0.5]
    assert [m.arbitration_id for m in sent] == [0x14EF2680, 0x0CFE4880]
    assert [bytes(m.data) for m in sent] == [b"\x01\x02", bytes(8)]
    assert [(m.pgn, m.destination) for m in got["c"]] == [(0xEF00, 0x26), (0xFE48, 0xFF)]
    assert [m.pgn for m in got["b"]] == [0xFE48]        # heard inside the rig, not its own
    assert got["a"] == []                               # a does not hear itself
    assert got["c"][0].priority == 5 and got["c"][0].source == 0x80


def test_tp_between_two_functions_of_one_network_needs_no_bus() -> None:
    rig = IsobusNetwork()
    a = rig.add(A, 0x80)
    b = rig.add(B, 0xF7)
    got: list[bytes] = []
    b.subscribe(0xEF00, lambda m: got.append(m.data))
    wire = VirtualWire([rig])
    wire.run_until(0.5)
    a.send(0xEF00, bytes(range(256)) * 10, destination=0xF7)     # 2560 bytes: ETP
    wire.run_until(1.0)
    assert got == [bytes(range(256)) * 10]


def test_next_due_is_always_later_and_a_send_from_outside_goes_at_once() -> None:
    net = IsobusNetwork(start_s=1.0)
    cf = net.add(A, 0x80)
    assert net.next_due(-1.0) == 1.0
    assert net.emit(0.5) == []                           # not started: nothing
    assert [m.arbitration_id for m in net.emit(1.0)] == [0x18EEFF80]
    assert net.next_due(1.0) == 1.25
    net.emit(1.25)
    assert cf.address == 0x80 and net.next_due(1.25) > 1.25
    cf.send(0xFE48, bytes(8))
    due = net.next_due(2.0)
    assert 2.0 < due <= math.nextafter(2.0, math.inf)
    assert [m.arbitration_id for m in net.emit(due)] == [0x18FE4880]


def test_a_pdu2_group_to_one_address_is_refused_naming_it() -> None:
    net = IsobusNetwork()
    cf = net.add(A, 0x80)
    with pytest.raises(FrameError, match="0x0FE48"):
        cf.send(0xFE48, bytes(8), destination=0x26)


def test_only_extended_data_frames_are_accepted() -> None:
    net = IsobusNetwork()
    assert net.accepts(can.Message(arbitration_id=0x18EEFF80, is_extended_id=True))
    assert not net.accepts(can.Message(arbitration_id=0x180, is_extended_id=False))
    assert not net.accepts(can.Message(arbitration_id=0x18EEFF80, is_extended_id=True,
                                       is_error_frame=True))


def test_the_table_names_external_functions_and_follows_moves() -> None:
    rig = IsobusNetwork()
    cf = rig.add(A, 0x80)
    other = IsobusName(identity_number=9)
    claim = lambda sa: can.Message(arbitration_id=encode_id(6, 0xEE00, sa),  # noqa: E731
                                   data=other.to_bytes(), is_extended_id=True)
    peer = ScriptedNode([(1.0, claim(0x30)), (2.0, claim(0x31)), (3.0, claim(0xFE))])
    wire = VirtualWire([rig, peer])
    wire.run_until(1.5)
    assert rig.external() == {0x30: other.value} and cf.name_of(0x30) == other.value
    wire.run_until(2.5)
    assert rig.external() == {0x31: other.value}
    wire.run_until(3.5)
    assert rig.external() == {}
    assert cf.name_of(0x80) == A.value


def test_two_functions_with_one_name_are_refused() -> None:
    net = IsobusNetwork()
    net.add(A, 0x80)
    with pytest.raises(FrameError, match="two internal control functions"):
        net.add(A, 0x81)


def test_applications_are_ticked_with_the_run_time() -> None:
    class Counter:
        def __init__(self) -> None:
            self.times: list[float] = []

        def tick(self, now_s: float) -> None:
            self.times.append(now_s)

    net = IsobusNetwork()
    cf = net.add(A, 0x80)
    app = Counter()
    cf.run(app)
    VirtualWire([net]).run_until(0.1)
    assert len(app.times) >= 10 and all(b > a for a, b in itertools.pairwise(app.times))
    assert app.times[-1] <= 0.1
