"""ISOBUS bus conformance (hil.conformance.isobus): each measurement fails on a log made to
break its rule and passes on logs of our own stack playing the DUT on a virtual wire."""

from __future__ import annotations

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.conformance import isobus as iso
from hil.conformance.framelog import parse_candump
from hil.isobus.can_id import make_frame
from hil.isobus.faults import Contend, DropCts, IsobusFaults, LatePacket
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.process_data import PROCESS_DATA_PGN, ClientTask, encode
from hil.isobus.tp_messages import (
    PGN_ADDRESS_CLAIMED,
    PGN_ETP_CM,
    PGN_REQUEST,
    PGN_TP_CM,
    PGN_TP_DT,
    CmFrame,
    Control,
    data_packet,
    encode_cm,
)
from hil.isobus.wire import VirtualWire
from hil.measurements import Outcome

RIG = IsobusName(identity_number=1, function=134)
DUT = IsobusName(identity_number=50, function=130, device_class=5)
DUT_SC = IsobusName(identity_number=50, function=130, device_class=5, self_configurable=True)
PGN = 0xEF00
Log = list[tuple[float, can.Message, bool]]


class ClientTaskSender:
    """A stand-in for a TC client's task message, every ``period_s`` once claimed."""

    def __init__(self, port, period_s: float = 2.0) -> None:
        self.port, self.period_s, self.next_s = port, period_s, None

    def tick(self, now_s: float) -> None:
        if self.port.address is None:
            return
        if self.next_s is None:
            self.next_s = now_s
        while now_s >= self.next_s - 1e-9:
            self.port.send(PROCESS_DATA_PGN, encode(ClientTask(False, 0)), destination=0x80)
            self.next_s += self.period_s


def bench(faults: IsobusFaults | None = None, name: IsobusName = DUT,
          period_s: float = 2.0):
    rig, dut = IsobusNetwork(faults=faults, name="rig"), IsobusNetwork(name="dut")
    r, d = rig.add(RIG, 0x80), dut.add(name, 0x90)
    d.run(ClientTaskSender(d, period_s))
    return VirtualWire([rig, dut]), r, d


def log_of(wire: VirtualWire) -> Log:
    """The bus as the rig recorded it: the DUT's frames are the received ones (rx); frames
    injected from outside (sender -1) are the rig's (the wire drops nothing here)."""
    return [(w.time_s, w.frame, w.sender == 1) for w in wire.frames]


def judge(log, resolution_s: float = 0.0) -> dict[str, list]:
    out: dict[str, list] = {}
    for m in iso.isobus_conformance(log, resolution_s=resolution_s):
        out.setdefault(m.name, []).append(m)
    return out


def outcomes(log, **kw) -> dict[str, str]:
    return {k: ",".join(m.outcome.value for m in v) for k, v in judge(log, **kw).items()}


def frame(t: float, pgn: int, source: int, data: bytes, dest: int = 0xFF, rx: bool = True,
          priority: int = 6):
    return (t, make_frame(priority, pgn, source, dest, data), rx)


def claim(t: float, source: int, name: int, rx: bool = True):
    return frame(t, PGN_ADDRESS_CLAIMED, source, name.to_bytes(8, "little"), rx=rx)


def cm(t: float, source: int, dest: int, c: CmFrame, rx: bool, pgn: int = PGN_TP_CM):
    return frame(t, pgn, source, encode_cm(c), dest, rx, priority=7)


def dt(t: float, source: int, dest: int, seq: int, rx: bool = True):
    return frame(t, PGN_TP_DT, source, data_packet(seq, b"\x01" * 7), dest, rx, priority=7)


# -- good logs: our stack as the DUT ------------------------------------------------------------

def test_our_stack_as_the_dut_passes_every_isobus_measurement() -> None:
    wire, r, d = bench()
    wire.run_until(0.5)
    d.send(PGN, bytes(range(100)), destination=0x80)       # TP RTS/CTS, DUT sends
    d.send(0xFE00 | 0x42, bytes(40))                        # BAM, DUT sends
    r.send(PGN, bytes(3000), destination=0x90)              # ETP, DUT receives
    wire.run_until(1.0)
    wire.inject(make_frame(6, PGN_REQUEST, 0x80, 0xFF, b"\x00\xee\x00"))
    wire.run_until(9.0)
    log = log_of(wire)
    found = judge(log)
    assert {k: [m.outcome for m in v] for k, v in found.items()} == {
        "isobus.claim.frames_before": [Outcome.PASS],
        "isobus.claim.request_answered": [Outcome.PASS],
        "isobus.claim.contention": [Outcome.PASS],
        "isobus.transport.violations": [Outcome.PASS],
        "isobus.pgn.rate": [Outcome.PASS]}
    assert "1 request(s)" in found["isobus.claim.request_answered"][0].note
    assert "3 TP/ETP session(s)" in found["isobus.transport.violations"][0].note
    rate = found["isobus.pgn.rate"][0]
    assert rate.value == 0.0 and rate.conditions["message"] == "TC client task"


@pytest.mark.parametrize("name", [DUT, DUT_SC])
def test_our_stack_losing_its_address_stops_using_it(name: IsobusName) -> None:
    wire, _r, _d = bench(IsobusFaults(contend=[Contend(at_s=3.0, address=0x90, name=0)]),
                         name=name)
    wire.run_until(8.0)
    m = judge(log_of(wire))["isobus.claim.contention"][0]
    assert m.outcome is Outcome.PASS and m.note.startswith("1 address(es) lost")
    # the self-configurable one moved to 0x81 and waited its 250 ms there too
    assert outcomes(log_of(wire))["isobus.claim.frames_before"] == "pass"


@pytest.mark.parametrize("fault", [DropCts(nth=1, peer=0x90), LatePacket(packet=3)])
def test_our_stack_under_transport_faults_closes_its_sessions(fault) -> None:
    faults = (IsobusFaults(dropped_cts=[fault]) if isinstance(fault, DropCts)
              else IsobusFaults(late_packets=[fault]))
    wire, r, d = bench(faults)
    wire.run_until(0.5)
    if isinstance(fault, DropCts):
        d.send(PGN, bytes(100), destination=0x80)
    else:
        r.send(PGN, bytes(100), destination=0x90)
    wire.run_until(5.0)
    m = judge(log_of(wire))["isobus.transport.violations"][0]
    assert m.outcome is Outcome.PASS, m.note


def test_a_frame_log_read_from_candump_gives_the_same_result() -> None:
    wire, _r, d = bench()
    wire.run_until(0.5)
    d.send(PGN, bytes(100), destination=0x80)
    wire.run_until(5.0)
    log = log_of(wire)
    lines = "".join(f"({t:.6f}) can0 {m.arbitration_id:08X}#{bytes(m.data).hex().upper()} "
                    f"{'R' if rx else 'T'}\n" for t, m, rx in log)
    framelog = parse_candump(lines.encode())
    assert [(m.name, m.value, m.note) for m in iso.isobus_conformance(framelog)] == \
        [(m.name, m.value, m.note) for m in iso.isobus_conformance(log)]


# -- bad logs: each rule broken ------------------------------------------------------------------

def test_a_dut_that_sends_before_claiming_fails() -> None:
    wire, _r, _d = bench()
    wire.run_until(5.0)
    log = log_of(wire)
    early = [frame(0.0, PROCESS_DATA_PGN, 0x90, encode(ClientTask(False, 0)), 0x80),
             frame(0.1, PROCESS_DATA_PGN, 0x90, bytes(8), 0x80)]
    m = judge(sorted(early + log, key=lambda r: r[0]))["isobus.claim.frames_before"][0]
    assert m.outcome is Outcome.FAIL and m.value == 2
    assert "before any claim: 1" in m.note and "within 250 ms of the claim: 1" in m.note


def test_a_dut_that_sends_within_250_ms_of_its_claim_fails_unless_the_resolution_hides_it() \
        -> None:
    log = [claim(1.0, 0x90, DUT.value), frame(1.24, 0xFE42, 0x90, bytes(8)),
           frame(1.26, 0xFE42, 0x90, bytes(8))]
    assert judge(log)["isobus.claim.frames_before"][0].value == 1
    assert judge(log, resolution_s=0.01)["isobus.claim.frames_before"][0].value == 0
    # a DUT that never claims: its frames all count
    assert judge(log[1:])["isobus.claim.frames_before"][0].value == 2


def test_a_dut_that_keeps_its_address_after_losing_it_fails() -> None:
    log = [claim(0.0, 0x90, DUT.value), frame(1.0, 0xFE42, 0x90, bytes(8)),
           claim(2.0, 0x90, 0, rx=False),                      # the contender, lower NAME
           frame(2.1, 0xFE42, 0x90, bytes(8)), claim(2.2, 0x90, DUT.value)]
    m = judge(log)["isobus.claim.contention"][0]
    assert m.outcome is Outcome.FAIL and m.value == 2
    assert "claim of a lost address: 1" in m.note and "frame from a lost address: 1" in m.note
    # a contender with a higher NAME loses: the DUT keeps the address
    log[2] = claim(2.0, 0x90, DUT.value + 1, rx=False)
    assert judge(log)["isobus.claim.contention"][0].value == 0


def test_a_request_for_address_claimed_left_unanswered_fails() -> None:
    request = frame(1.0, PGN_REQUEST, 0x80, b"\x00\xee\x00", rx=False)
    log = [claim(0.0, 0x90, DUT.value), request, frame(2.0, 0xFE42, 0x90, bytes(8))]
    m = judge(log)["isobus.claim.request_answered"][0]
    assert m.outcome is Outcome.FAIL and m.value == 1
    late = [*log[:2], claim(1.3, 0x90, DUT.value), *log[2:]]          # 300 ms: too late
    assert judge(late)["isobus.claim.request_answered"][0].value == 1
    good = [*log[:2], claim(1.15, 0x90, DUT.value), *log[2:]]
    assert judge(good)["isobus.claim.request_answered"][0].value == 0
    # cannot-claim from the null address is an answer too
    cannot = [*log[:2], claim(1.1, 0xFE, DUT.value), *log[2:]]
    assert judge(cannot)["isobus.claim.request_answered"][0].value == 0


def _rts(t: float, size: int, max_per_cts: int = 255, rx: bool = True):
    return cm(t, 0x90, 0x80, CmFrame(Control.RTS, PGN, size=size,
                                     packets=min(255, -(-size // 7)), max_per_cts=max_per_cts),
              rx)


def _cts(t: float, packets: int, first: int):
    return cm(t, 0x80, 0x90, CmFrame(Control.CTS, PGN, packets=packets, next_packet=first),
              rx=False)


def _eoma(t: float, size: int):
    return cm(t, 0x80, 0x90, CmFrame(Control.EOMA, PGN, size=size, packets=-(-size // 7)),
              rx=False)


def violations(log) -> tuple[float, str]:
    m = judge([claim(0.0, 0x90, DUT.value), *log])["isobus.transport.violations"][0]
    return m.value, m.note


def test_a_correct_rts_cts_transfer_has_no_violations() -> None:
    log = [_rts(1.0, 20), _cts(1.01, 2, 1), dt(1.02, 0x90, 0x80, 1), dt(1.03, 0x90, 0x80, 2),
           _cts(1.04, 1, 3), dt(1.05, 0x90, 0x80, 3), _eoma(1.06, 20)]
    assert violations(log)[0] == 0


def test_a_tp_sender_that_ignores_cts_fails() -> None:
    no_cts = [_rts(1.0, 20), dt(1.02, 0x90, 0x80, 1), dt(1.03, 0x90, 0x80, 2),
              dt(1.04, 0x90, 0x80, 3), _eoma(1.06, 20)]
    value, note = violations(no_cts)
    assert value == 3 and "data-without-cts: 3" in note
    beyond = [_rts(1.0, 20), _cts(1.01, 1, 1), dt(1.02, 0x90, 0x80, 1),
              dt(1.03, 0x90, 0x80, 2), dt(1.04, 0x90, 0x80, 3), _eoma(1.06, 20)]
    value, note = violations(beyond)
    assert value == 2 and "packets-beyond-cts: 2" in note


def test_a_bad_sequence_number_fails() -> None:
    log = [_rts(1.0, 20), _cts(1.01, 3, 1), dt(1.02, 0x90, 0x80, 1), dt(1.03, 0x90, 0x80, 3),
           dt(1.04, 0x90, 0x80, 3), _eoma(1.06, 20)]
    value, note = violations(log)
    assert value == 2 and "sequence: 2" in note


def _bam(t: float, size: int, source: int = 0x90, rx: bool = True):
    return cm(t, source, 0xFF, CmFrame(Control.BAM, PGN & 0, size=size,
                                       packets=-(-size // 7)), rx)


def test_a_bam_too_fast_fails_and_one_at_the_minimum_passes() -> None:
    fast = [_bam(1.0, 21)] + [dt(1.0 + 0.005 * i, 0x90, 0xFF, i) for i in (1, 2, 3)]
    value, note = violations(fast)
    assert value == 3 and "bam-too-fast: 3" in note
    ok = [_bam(1.0, 21)] + [dt(1.0 + 0.010 * i, 0x90, 0xFF, i) for i in (1, 2, 3)]
    assert violations(ok)[0] == 0
    # held to SAE J1939-21's 50 ms instead
    m = iso.transport_violations([claim(0.0, 0x90, DUT.value), *ok], bam_min_s=0.05)
    assert m.value == 3 and m.outcome is Outcome.FAIL
    slow = [_bam(1.0, 21)] + [dt(1.0 + 0.3 * i, 0x90, 0xFF, i) for i in (1, 2, 3)]
    assert "bam-too-slow: 3" in violations(slow)[1]


def test_wrong_sizes_for_tp_and_etp_fail() -> None:
    etp_small = [cm(1.0, 0x90, 0x80, CmFrame(Control.ETP_RTS, PGN, size=1000), True,
                    pgn=PGN_ETP_CM),
                 cm(1.01, 0x90, 0x80, CmFrame(Control.ABORT, PGN, reason=250), True,
                    pgn=PGN_ETP_CM)]
    assert "etp-size: 1" in violations(etp_small)[1]
    tp_big = [_rts(1.0, 1786), cm(1.01, 0x90, 0x80, CmFrame(Control.ABORT, PGN,
                                                                     reason=250), True)]
    assert "tp-size: 1" in violations(tp_big)[1]
    tp_small = [_rts(1.0, 8), cm(1.01, 0x90, 0x80, CmFrame(Control.ABORT, PGN, reason=250),
                                 True)]
    assert "tp-size: 1" in violations(tp_small)[1]


def test_a_receiving_dut_without_eoma_or_a_sender_that_never_aborts_fails() -> None:
    # the rig sends to the DUT; the DUT's CTS, all packets, then silence: no EndOfMsgAck
    rts = cm(1.0, 0x80, 0x90, CmFrame(Control.RTS, PGN, size=14, packets=2, max_per_cts=255),
             rx=False)
    cts = cm(1.01, 0x90, 0x80, CmFrame(Control.CTS, PGN, packets=2, next_packet=1), rx=True)
    log = [rts, cts, dt(1.02, 0x80, 0x90, 1, rx=False), dt(1.03, 0x80, 0x90, 2, rx=False),
           frame(4.0, 0xFE42, 0x90, bytes(8))]
    value, note = violations(log)
    assert value == 1 and "missing-eoma: 1" in note
    # the DUT sends an RTS, no CTS comes, and it never aborts (T3)
    hung = [_rts(1.0, 20), frame(4.0, 0xFE42, 0x90, bytes(8))]
    value, note = violations(hung)
    assert value == 1 and "not-closed: 1" in note
    # ... but a log that ends before T3 + Tr cannot tell
    assert violations([_rts(1.0, 20), frame(2.0, 0xFE42, 0x90, bytes(8))])[0] == 0
    # a DUT as receiver that asks for more than the RTS allows, and asks again mid-window
    greedy = [cm(1.0, 0x80, 0x90, CmFrame(Control.RTS, PGN, size=70, packets=10,
                                         max_per_cts=4), rx=False),
              cm(1.01, 0x90, 0x80, CmFrame(Control.CTS, PGN, packets=5, next_packet=1), rx=True),
              cm(1.02, 0x90, 0x80, CmFrame(Control.CTS, PGN, packets=4, next_packet=1), rx=True),
              cm(1.03, 0x90, 0x80, CmFrame(Control.ABORT, PGN, reason=250), rx=True)]
    note = violations(greedy)[1]
    assert "cts-beyond-limit: 1" in note and "cts-during-transfer: 1" in note


def test_a_cyclic_pgn_off_its_declared_period_fails() -> None:
    wire, _r, _d = bench(period_s=2.5)
    wire.run_until(12.0)
    m = judge(log_of(wire))["isobus.pgn.rate"][0]
    assert m.outcome is Outcome.FAIL and m.value == pytest.approx(25.0)
    assert "ISO 11783-10" in m.note


@pytest.mark.parametrize("size", [9, 1785, 1786, 5000])
@pytest.mark.parametrize("dut_sends", [True, False])
def test_our_stack_at_tp_and_etp_boundaries_has_no_violations(size: int,
                                                             dut_sends: bool) -> None:
    wire, r, d = bench()
    wire.run_until(0.5)
    (d if dut_sends else r).send(PGN, bytes(range(256)) * (size // 256) + bytes(size % 256),
                                 destination=0x80 if dut_sends else 0x90)
    wire.run_until(4.0)
    m = judge(log_of(wire))["isobus.transport.violations"][0]
    assert m.outcome is Outcome.PASS and m.note == "1 TP/ETP session(s) followed", m.note


def _etp(t: float, source: int, dest: int, control: Control, rx: bool, **fields):
    return cm(t, source, dest, CmFrame(control, PGN, **fields), rx, pgn=PGN_ETP_CM)


def _etp_dt(t: float, seq: int):
    return frame(t, 0xC700, 0x90, data_packet(seq, b"\x02" * 7), 0x80, True, priority=7)


def test_an_etp_sender_whose_dpo_does_not_fit_the_cts_fails() -> None:
    head = [_etp(1.0, 0x90, 0x80, Control.ETP_RTS, True, size=2000),
            _etp(1.01, 0x80, 0x90, Control.ETP_CTS, False, packets=3, next_packet=1)]
    good = [*head, _etp(1.02, 0x90, 0x80, Control.ETP_DPO, True, packets=3, offset=0),
            _etp_dt(1.03, 1), _etp_dt(1.04, 2), _etp_dt(1.05, 3),
            _etp(1.06, 0x90, 0x80, Control.ABORT, True, reason=250)]
    assert violations(good)[0] == 0
    bad = [*head, _etp(1.02, 0x90, 0x80, Control.ETP_DPO, True, packets=4, offset=5),
           _etp_dt(1.03, 1), _etp_dt(1.04, 3),
           _etp(1.06, 0x90, 0x80, Control.ABORT, True, reason=250)]
    value, note = violations(bad)
    assert value == 3
    assert "dpo-exceeds-cts: 1" in note and "dpo-offset: 1" in note and "sequence: 1" in note
    no_dpo = [*head, _etp_dt(1.03, 1), _etp(1.06, 0x90, 0x80, Control.ABORT, True, reason=250)]
    assert "data-without-dpo: 1" in violations(no_dpo)[1]


def test_our_tc_client_talking_to_our_tc_passes_with_its_client_task_every_2_s() -> None:
    from hil.isobus import ddi
    from hil.isobus.ddop.samples import section_control_pool
    from hil.isobus.tc import TaskControllerServer, TriggerPlan, constant_setpoints
    from hil.isobus.tc_client import ClientState, TaskControllerClient

    implement = IsobusName(identity_number=7, manufacturer_code=200, function=130,
                           device_class=5)
    rig, dut = IsobusNetwork(name="rig"), IsobusNetwork(name="dut")
    tc_port = rig.add(IsobusName(identity_number=2, manufacturer_code=100, function=130), 0xF7)
    tc_port.run(TaskControllerServer(tc_port, triggers=TriggerPlan(), setpoints=(
        constant_setpoints({ddi.SETPOINT_MASS_PER_AREA_RATE: 25_000}))))
    port = dut.add(implement, 0x81)
    client = TaskControllerClient(port, section_control_pool(sections=4, name=implement.value),
                                  on_setpoint=lambda *a: None, read_value=lambda *a: 0,
                                  distance_mm=lambda t: 0.0, on_connection=lambda *a: None)
    port.run(client)
    wire = VirtualWire([rig, dut])
    wire.run_until(12.0)
    assert client.state is ClientState.CONNECTED
    found = judge(log_of(wire))
    assert all(m.outcome is Outcome.PASS for ms in found.values() for m in ms), found
    assert "session(s) followed" in found["isobus.transport.violations"][0].note
    assert found["isobus.transport.violations"][0].note[0] != "0"     # the DDOP went by TP
    assert [m.conditions["message"] for m in found["isobus.pgn.rate"]] == ["TC client task"]


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.integers(9, 4000), st.booleans(), st.booleans(),
                          st.floats(0.3, 3.0)), min_size=1, max_size=5))
def test_our_stack_passes_under_any_mix_of_transfers(transfers) -> None:
    """Random sizes, both directions, BAMs and peer-to-peer, overlapping in time: no false
    alarm from the transport check on a stack that follows the standard."""
    wire, r, d = bench()
    for size, dut_sends, broadcast, at_s in sorted(transfers, key=lambda t: t[3]):
        wire.run_until(at_s)
        port, peer = (d, 0x80) if dut_sends else (r, 0x90)
        if broadcast and size <= 1785:
            port.send(0xFE42, bytes(size))
        else:
            port.send(PGN, bytes(size), destination=peer)
    wire.run_until(12.0)
    found = judge(log_of(wire))
    assert all(m.outcome is Outcome.PASS for ms in found.values() for m in ms), found
