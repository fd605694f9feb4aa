"""The reference fertilizer controller's ISOBUS mode against the emulated tractor, in virtual time.

The controller (reference_controllers.fertilizer.isobus_mode) and the tractor
(hil.isobus.tractor: TECU + TC over the example field and its three-zone map) share a
VirtualWire; the rig's CANopen side is absent: SYNC comes from :class:`ControllerNode` every
100 ms, and an ideal meter reports each active row's last target flow on the flow module frames
(rows switched off report nothing, as a row clutch would leave them empty).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import can
import numpy as np
import pytest

from hil.isobus import ddi
from hil.isobus import process_data as pd
from hil.isobus.field import load_field, load_prescription
from hil.isobus.process_data import Command
from hil.isobus.tc.records import EventKind
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.wire import VirtualWire
from hil.rig.device import Device
from plant_emulators.fertilizer.frames import FertilizerDatabase
from reference_controllers.fertilizer.isobus_mode import SPEED_TIMEOUT_S, IsobusFlowController
from reference_controllers.params import ParamError
from reference_controllers.registry import make_controller

FIELDS = Path(__file__).resolve().parents[2] / "plant_emulators" / "fertilizer" / "fields"
SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
DB = FertilizerDatabase()
DRIVE_AFTER_S = 3.0
ADDRESS = 0x81


@dataclass(frozen=True)
class Step:
    """What the controller did at one control step."""

    t: float
    target_gps: float
    volts: float
    rate_kg_ha: float
    sections: tuple[bool, ...]
    speed: tuple[str, float] | None
    metering: bool


class ControllerNode(Device):
    """The controller on the wire: a SYNC every period, an ideal meter's flow frames before it."""

    def __init__(self, controller: IsobusFlowController, *, meter: bool = True) -> None:
        self.ctl = controller
        self.meter = meter
        self.period_s = controller.adapter_params.period_s
        self.steps: list[Step] = []
        self._last_target = 0.0
        self._boot = controller.on_start()

    def next_due(self, time_s: float) -> float:
        return max(self.ctl.steps * self.period_s, math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        if self.meter:
            for row in sorted(self.ctl.rows.active):
                self.ctl.on_frame(DB.encode(f"FlowModule{row}", {
                    "Flow": self._last_target, "WindowMass": self._last_target, "Counter": 1,
                    "BaselineReady": 1, "SlidingWindow": 1, "AdcOverrange": 0,
                    "InterceptApplied": 0, "WindowLength": 1000}))
        out = self._boot + self.ctl.on_frame(SYNC)
        self._boot = []
        target = self.ctl.target_gps()
        self._last_target = target
        self.steps.append(Step(self.ctl.clock_s, target, self.ctl.volts, self.ctl.rate_kg_ha,
                               tuple(self.ctl.sections), self.ctl.ground_speed(),
                               self.ctl.metering()))
        return out

    def accepts(self, msg: can.Message) -> bool:
        return bool(msg.is_extended_id)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        return self.ctl.on_frame(msg)


def _tractor(*, slip: float = 0.0) -> Tractor:
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    return Tractor(TractorSetup(fld, rx, drive_after_s=DRIVE_AFTER_S, wheel_slip=slip))


def _run(end_s: float, *, slip: float = 0.0, **params: str | float,
         ) -> tuple[Tractor, ControllerNode, VirtualWire]:
    tractor = _tractor(slip=slip)
    node = ControllerNode(IsobusFlowController("physical", params))
    wire = VirtualWire([tractor.network, node])
    wire.run_until(end_s)
    return tractor, node, wire


def _plateaus(values: list[tuple[float, float]], min_s: float) -> list[float]:
    """The values held for at least ``min_s``, in order (repeats merged)."""
    out: list[float] = []
    i = 0
    while i < len(values):
        j = i
        while j + 1 < len(values) and values[j + 1][1] == values[i][1]:
            j += 1
        if values[j][0] - values[i][0] >= min_s and (not out or out[-1] != values[i][1]):
            out.append(values[i][1])
        i = j + 1
    return out


@pytest.fixture(scope="module")
def drive() -> tuple[Tractor, ControllerNode, VirtualWire]:
    """The whole example field: three passes, the headland turns, the overlapping fourth
    (131 s of run time, ~10-30 s of CPU: the tractor's coverage at every 10 ms TC tick)."""
    path = _tractor().setup.field.path
    return _run(DRIVE_AFTER_S + path.duration_s + 1.0)


# --------------------------------------------------------------------- building it
def test_registry_builds_it_and_rejects_bad_parameters() -> None:
    ctl = make_controller("fertilizer-piecewise-pid-isobus", {"mode": "paper-literal"})
    assert isinstance(ctl, IsobusFlowController)
    assert ctl.name == "fertilizer-piecewise-pid-paper-literal-isobus"
    name = ctl.implement_name
    assert (name.industry_group, name.device_class, name.function, name.self_configurable) \
        == (2, 5, 128, True)
    # the set-point latency is the plant's meter-to-furrow delay: 0.08 s + 0.35 s
    assert ctl.latency_ms == 430
    assert ctl.pool.property_value(ctl.elements.boom, ddi.PHYSICAL_SETPOINT_TIME_LATENCY) == 430
    widths = [ctl.pool.property_value(s, ddi.ACTUAL_WORKING_WIDTH) for s in ctl.elements.sections]
    offsets = [ctl.pool.property_value(s, ddi.DEVICE_ELEMENT_OFFSET_Y)
               for s in ctl.elements.sections]
    assert widths == [750] * 4 and offsets == [-1125, -375, 375, 1125]
    for bad in ({"speed": "radar"}, {"ddop": "odd"}, {"width_m": 0}, {"address": 254},
                {"gain": 1}):
        with pytest.raises(ParamError):
            make_controller("fertilizer-piecewise-pid-isobus", bad)


# --------------------------------------------------------------------- the field drive
@pytest.mark.slow
def test_it_claims_connects_and_its_ddop_is_activated(drive) -> None:
    tractor, node, wire = drive
    client = node.ctl.client
    assert client.connected and client.connections == 1 and client.refusal is None
    connected = next(e.time_s for e in client.events if e.detail == "connected")
    assert connected < DRIVE_AFTER_S
    # the claim went on the wire first: no frame from 0x81 before its address claimed
    ours = [f for f in wire.frames if f.sender == 1 and f.frame.is_extended_id]
    assert ours[0].frame.arbitration_id >> 8 & 0x3FF00 == 0xEE00
    assert ours[0].frame.arbitration_id & 0xFF == ADDRESS
    session = tractor.tc.sessions[ADDRESS]
    assert session.pool is not None and session.pool.to_bytes() == node.ctl.pool.to_bytes()
    assert any(e.kind == EventKind.ACTIVATED for e in tractor.tc.events
               if e.address == ADDRESS)


@pytest.mark.slow
def test_its_target_rate_follows_the_zones_and_its_flow_follows_eq_1(drive) -> None:
    tractor, node, _ = drive
    rates = [s.rate_kg_ha for s in node.steps]
    assert {160.0, 200.0, 240.0} <= set(rates)
    # along each pass the rate holds each zone's value while the boom is inside it, in the
    # order the zones lie on the ground (160 south, the 240 band, 200 north); where the boom
    # straddles a boundary the TC sends the mean under the sections, briefly
    for start, end in tractor.leg_spans("pass") + tractor.leg_spans("overlap"):
        plateaus = _plateaus([(s.t, s.rate_kg_ha) for s in node.steps if start <= s.t < end],
                             min_s=3.0)
        assert plateaus in ([160.0, 240.0, 200.0], [200.0, 240.0, 160.0]), (start, plateaus)
    row_width = 3.0 / 4
    metering = [s for s in node.steps if s.metering]
    assert len(metering) > 600
    for s in metering:
        assert s.speed is not None and s.speed[0] == "ground"
        assert s.target_gps == pytest.approx(0.1 * s.rate_kg_ha * row_width * s.speed[1])
        assert s.volts > 0.0
    # nothing is metered before the pool is active and the tractor moves off
    assert all(s.volts == 0.0 for s in node.steps if s.t < DRIVE_AFTER_S)


@pytest.mark.slow
def test_sections_switch_rows_off_over_the_overlap_and_in_the_turns(drive) -> None:
    tractor, node, _ = drive

    def on_share(spans: list[tuple[float, float]]) -> np.ndarray:
        states = [s.sections for s in node.steps if s.metering is not None
                  and any(a <= s.t < b for a, b in spans)]
        metering = np.array([[on and s.metering for on in s.sections]
                             for s in node.steps if any(a <= s.t < b for a, b in spans)])
        assert states
        return metering.mean(axis=0)

    overlap = on_share(tractor.leg_spans("overlap"))
    assert sorted(overlap)[:2] == pytest.approx([0.0, 0.0], abs=0.05), overlap
    assert min(sorted(overlap)[2:]) > 0.7, overlap
    passes = on_share(tractor.leg_spans("pass"))
    assert passes.min() > 0.7, passes
    turns = on_share(tractor.leg_spans("turn"))
    assert turns.max() < 0.15, turns
    # over the overlap the per-row target does not change with two rows switched off: each
    # active row still covers its 0.75 m
    (a, b), = tractor.leg_spans("overlap")
    two = [s for s in node.steps if a <= s.t < b and s.metering and sum(s.sections) == 2]
    assert len(two) > 50
    for s in two:
        assert s.speed is not None
        assert s.target_gps == pytest.approx(0.1 * s.rate_kg_ha * 0.75 * s.speed[1])


@pytest.mark.slow
def test_actual_rate_and_rows_reported_to_the_tc_are_what_it_meters(drive) -> None:
    tractor, node, wire = drive
    actual: list[tuple[float, int]] = []
    for f in wire.frames:
        cid = f.frame.arbitration_id
        if f.sender != 1 or (cid >> 8) & 0x3FF00 != pd.PROCESS_DATA_PGN:
            continue
        m = pd.decode(bytes(f.frame.data))
        if isinstance(m, pd.ElementCommand) and m.command == Command.VALUE \
                and m.ddi == ddi.ACTUAL_MASS_PER_AREA_RATE:
            actual.append((f.time_s, m.value))
    assert len(actual) > 50
    # nothing is reported applied while the meter is stopped (turns, before the drive)
    by_time = {round(s.t, 6): s for s in node.steps}
    stopped = [v for t, v in actual if (s := by_time.get(round(t, 6))) and not s.metering]
    assert len(stopped) > 5 and set(stopped) == {0}
    record = tractor.as_applied()
    assert record is not None
    a = record.arrays()
    applied = np.round(a.rate[a.applying], 0)
    # the ideal meter delivers what was asked one step later; at constant speed that is the
    # zone's rate, reported back as kg/ha through Q = 0.1·M·D·v
    for zone in (160.0, 200.0, 240.0):
        assert np.count_nonzero(np.abs(applied - zone) <= 0.02 * zone) > 50, zone


# --------------------------------------------------------------------- speed
def test_it_uses_ground_based_speed_under_wheel_slip() -> None:
    slip = 0.2
    tractor, node, _ = _run(DRIVE_AFTER_S + 8.0, slip=slip)
    steps = [s for s in node.steps if s.metering and s.t > DRIVE_AFTER_S + 2.0]
    assert len(steps) > 25
    for s in steps:
        truth = tractor.pose(s.t).speed_m_s
        assert s.speed is not None and s.speed[0] == "ground"
        # the TECU's 100 ms cycle: the speed in use is at most one message old
        assert s.speed[1] == pytest.approx(truth, abs=0.05)
        assert s.target_gps == pytest.approx(0.1 * s.rate_kg_ha * 0.75 * truth, rel=0.03)


def test_it_never_reads_the_wall_clock(monkeypatch: pytest.MonkeyPatch) -> None:
    """Lockstep: its time is the SYNC count; any clock read would raise here."""
    import time

    def no_clock() -> float:
        raise AssertionError("the wall clock was read")

    tractor = _tractor()
    node = ControllerNode(IsobusFlowController("physical"))
    wire = VirtualWire([tractor.network, node])
    with monkeypatch.context() as m:
        for name in ("time", "monotonic", "perf_counter", "time_ns", "monotonic_ns"):
            m.setattr(time, name, no_clock)
        wire.run_until(DRIVE_AFTER_S + 6.0)
    assert node.ctl.client.connected and node.steps[-1].metering
    assert node.ctl.clock_s == pytest.approx((node.ctl.steps - 1) * 0.1)


def test_the_wheel_speed_variant_over_meters_by_the_slip() -> None:
    """The check above fails for a controller that reads PGN 65096 (the must-fail variant)."""
    slip = 0.2
    tractor, node, _ = _run(DRIVE_AFTER_S + 8.0, slip=slip, speed="wheel")
    steps = [s for s in node.steps if s.metering and s.t > DRIVE_AFTER_S + 2.0]
    assert len(steps) > 25
    ratios = [s.target_gps / (0.1 * s.rate_kg_ha * 0.75 * tractor.pose(s.t).speed_m_s)
              for s in steps]
    assert all(s.speed is not None and s.speed[0] == "wheel" for s in steps)
    assert np.median(ratios) == pytest.approx(1 / (1 - slip), rel=0.01)


def test_speed_falls_back_to_wheel_based_only_without_ground_based_and_stops_when_lost() -> None:
    ctl = IsobusFlowController("physical")
    db = ctl._speed_messages
    _, ground_msg, _ = db[0xFE49]
    _, wheel_msg, _ = db[0xFE48]

    def frame(pgn: int, message, signal: str, v: float) -> can.Message:
        data = message.encode({s.name: 0 for s in message.signals} | {signal: v})
        return can.Message(arbitration_id=(3 << 26) | (pgn << 8) | 0x80, data=data,
                           is_extended_id=True)

    ctl.on_frame(frame(0xFE48, wheel_msg, "WheelBasedMachineSpeed", 2.0))
    assert ctl.ground_speed() == ("wheel", 2.0)       # only the wheel-based one is there
    ctl.on_frame(frame(0xFE49, ground_msg, "GroundBasedMachineSpeed", 1.6))
    assert ctl.ground_speed() == ("ground", 1.6)
    # steps go by, only the wheel-based speed keeps coming: the ground-based one is lost
    for _ in range(round(SPEED_TIMEOUT_S / 0.1) + 2):
        ctl.on_frame(SYNC)
        ctl.on_frame(frame(0xFE48, wheel_msg, "WheelBasedMachineSpeed", 2.0))
    assert ctl.ground_speed() == ("wheel", 2.0)
    for _ in range(round(SPEED_TIMEOUT_S / 0.1) + 2):
        ctl.on_frame(SYNC)
    assert ctl.ground_speed() is None and not ctl.metering() and ctl.target_gps() == 0.0
    # a "not available" speed (0xFFFF) is no speed
    ctl.on_frame(can.Message(arbitration_id=(3 << 26) | (0xFE49 << 8) | 0x80,
                             data=b"\xff" * 8, is_extended_id=True))
    assert ctl.ground_speed() is None


def test_the_tecu_going_silent_stops_the_meter() -> None:
    tractor = _tractor()
    silent_from = DRIVE_AFTER_S + 10.0
    node = ControllerNode(IsobusFlowController("physical"))
    tecu = tractor.network.functions[0]
    assert tecu.label == "TECU"
    wire = VirtualWire([tractor.network, node],
                       drop=lambda f, sender: sender == 0 and f.timestamp >= silent_from
                       and (f.arbitration_id >> 8) & 0x3FFFF in (0xFE48, 0xFE49, 0xF022))
    wire.run_until(silent_from + 2.0)
    before = [s for s in node.steps if silent_from - 3.0 < s.t < silent_from]
    after = [s for s in node.steps if s.t > silent_from + SPEED_TIMEOUT_S + 0.1 + 1e-9]
    assert before and all(s.volts > 0 for s in before)
    assert after and all(s.volts == 0.0 and s.speed is None for s in after)


# --------------------------------------------------------------------- the TC
def test_a_tc_restart_stops_the_meter_until_the_pool_is_active_again() -> None:
    tractor = _tractor()
    node = ControllerNode(IsobusFlowController("physical"))
    wire = VirtualWire([tractor.network, node])
    restart_at = DRIVE_AFTER_S + 10.0
    wire.run_until(restart_at)
    tractor.tc.restart(restart_at, down_s=8.0)
    wire.run_until(restart_at + 12.0)
    client = node.ctl.client
    lost = next(e.time_s for e in client.events if e.kind == "lost")
    back = [e.time_s for e in client.events if e.detail == "connected"][-1]
    # the standard's 6 s without a TC status: until then the last set-points hold
    assert restart_at + 4.0 <= lost <= restart_at + 6.0 + 0.1
    assert client.connections == 2 and restart_at + 8.0 <= back < restart_at + 9.0
    assert all(s.metering and s.volts > 0 for s in node.steps
               if restart_at - 2.0 <= s.t < lost)
    between = [s for s in node.steps if lost <= s.t < back]
    assert len(between) > 20 and all(s.volts == 0.0 and s.target_gps == 0.0 for s in between)
    after = [s for s in node.steps if s.t > back + 0.5]
    assert after and all(s.metering and s.volts > 0 for s in after)


# --------------------------------------------------------------------- a refused pool
def test_a_broken_ddop_is_refused_and_nothing_is_metered() -> None:
    tractor, node, _ = _run(DRIVE_AFTER_S + 6.0, ddop="broken")
    client = node.ctl.client
    assert not client.connected and client.refusal is not None
    actual_rate = node.ctl.pool.process_data(node.ctl.elements.boom,
                                             ddi.ACTUAL_MASS_PER_AREA_RATE)
    assert actual_rate is not None
    # the TC names the faulty object, and the client keeps what it was told
    assert client.refusal.object_id == actual_rate.object_id
    refused = [e for e in tractor.tc.events if e.address == ADDRESS
               and e.kind == EventKind.REFUSED]
    assert len(refused) == 1 and "presentation object 32767 does not exist" in refused[0].detail
    assert not any(e.kind == EventKind.ACTIVATED for e in tractor.tc.events)
    moving = [s for s in node.steps if s.t > DRIVE_AFTER_S + 1.0]
    assert moving and all(s.speed is not None for s in moving)     # the TECU is heard
    assert all(s.volts == 0.0 and s.target_gps == 0.0 for s in node.steps)
