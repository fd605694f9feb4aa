"""A VT client's bus behaviour judged from frames: a good client passes, each breach is found."""

from __future__ import annotations

import can

from hil.conformance.isobus import IsobusFrame, isobus_frames
from hil.isobus.can_id import encode_id
from hil.isobus.vt.bench import IMPLEMENT_ADDRESS, VtBench
from hil.isobus.vt.conformance import vt_client_conformance, vt_client_findings
from hil.isobus.vt.messages import pad

from .pools import implement_pool

VT = 0x26


def frames(bench: VtBench) -> list[tuple[float, can.Message]]:
    return [(f.time_s, f.frame) for f in bench.wire.frames]


def frame(pgn: int, source: int, destination: int, data: bytes) -> can.Message:
    return can.Message(arbitration_id=encode_id(6, pgn, source, destination), data=data,
                       is_extended_id=True)


def test_a_good_client_has_no_finding() -> None:
    bench = VtBench([implement_pool().to_bytes()])
    bench.run_until(8.0)
    assert bench.client is not None and bench.client.state == "connected"
    assert vt_client_findings(frames(bench), end_s=8.0) == []


def test_late_maintenance_and_a_pool_before_get_memory() -> None:
    bench = VtBench(client=False)
    cf = bench.implement_cf
    bench.run_until(0.5)
    for t in (0.5, 1.5, 3.8):                     # 2.3 s gap
        bench.run_until(t)
        cf.send(0xE700, pad([0xFF, 0, 4]), VT, 5)
    cf.send(0xE700, bytes([0x11]) + implement_pool().to_bytes(), VT, 5)
    bench.run_until(6.0)
    found = vt_client_findings(frames(bench), end_s=6.0)
    kinds = [(f.kind, f.address) for f in found]
    assert ("pool-before-memory", IMPLEMENT_ADDRESS) in kinds
    late = [f for f in found if f.kind == "maintenance"]
    assert len(late) == 2                        # the 2.3 s gap, and silence to the end
    assert "2.30 s between two" in late[0].detail and abs(late[0].time_s - 3.8) < 0.02


def test_two_transfers_at_once() -> None:
    rts = bytes([16, 100, 0, 15, 0xFF, 0x00, 0xE7, 0x00])      # TP RTS, 100 bytes of 0xE700
    eoma = bytes([19, 100, 0, 15, 0xFF, 0x00, 0xE7, 0x00])
    good = [(0.0, frame(0xEC00, 0x84, VT, rts)), (0.2, frame(0xEC00, VT, 0x84, eoma)),
            (0.3, frame(0xEC00, 0x84, VT, rts))]
    assert vt_client_findings(good) == []
    bad = [(0.0, frame(0xEC00, 0x84, VT, rts)), (0.1, frame(0xEC00, 0x84, VT, rts))]
    (finding,) = vt_client_findings(bad)
    assert finding.kind == "two-transfers" and "opened at 0.00 s" in finding.detail


# --------------------------------------------------------------------- as measurements
def rows(pairs: list[tuple[float, can.Message]]) -> list[IsobusFrame]:
    return isobus_frames([(t, m, True) for t, m in pairs])


def status(t: float) -> tuple[float, can.Message]:
    return (t, frame(0xE600, VT, 0xFF, pad([0xFE, 0x84, 0xFF, 0xFF, 0xFF, 0xFF, 0])))


def maintenance(t: float) -> tuple[float, can.Message]:
    return (t, frame(0xE700, 0x84, VT, pad([0xFF, 0, 4])))


def test_the_conformance_measurements_per_kind_fail_a_late_maintenance() -> None:
    late = [status(t) for t in range(10)] + [maintenance(t) for t in (0.5, 1.5, 4.5, 5.5)]
    found = vt_client_conformance(rows(sorted(late, key=lambda p: p[0])), end_s=6.0,
                                  conditions={"run": "r"})
    by_kind = {m.conditions["kind"]: m for m in found}
    assert set(by_kind) == {"maintenance", "pool-before-memory", "two-transfers"}
    assert all(m.name == "isobus.vt_client.violations" and m.high == 0.0 for m in found)
    assert by_kind["maintenance"].value == 1.0
    assert by_kind["maintenance"].outcome.value == "fail"
    assert "3.00 s between two" in by_kind["maintenance"].note
    assert by_kind["two-transfers"].outcome.value == "pass"


def test_a_gap_across_the_vts_own_silence_is_not_the_clients() -> None:
    """The VT silent from 3 s to 9 s (a restart): the client stops its maintenance when it has
    lost the VT and starts again when it is back; that gap is not a breach."""
    pairs = [status(t) for t in (0, 1, 2, 3, 9, 10, 11)] + [
        maintenance(t) for t in (0.5, 1.5, 2.5, 3.5, 5.5, 9.5, 10.5)]
    found = vt_client_conformance(rows(sorted(pairs, key=lambda p: p[0])), end_s=11.0)
    (late,) = [m for m in found if m.conditions["kind"] == "maintenance"]
    assert late.value == 0.0 and "1 silence" in late.note
    # the same gap with the VT up all along is one
    pairs = [status(t) for t in range(12)] + [
        maintenance(t) for t in (0.5, 1.5, 2.5, 3.5, 5.5, 9.5, 10.5)]
    found = vt_client_conformance(rows(sorted(pairs, key=lambda p: p[0])), end_s=11.0)
    (late,) = [m for m in found if m.conditions["kind"] == "maintenance"]
    assert late.value == 2.0 and late.outcome.value == "fail"


def test_no_vt_on_the_bus_no_vt_measurement() -> None:
    assert vt_client_conformance(rows([maintenance(0.5), maintenance(4.0)]), end_s=5.0) == []
