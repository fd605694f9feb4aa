"""The reference ISOBUS implement operated on the rig's VT: master key, calibration, a row's alarm.

The tractor (TECU + TC over the example field) with the VT added to its network, and the
reference controller with its operator interface (reference_controllers.fertilizer.isobus_vt)
on a virtual wire; SYNC every 100 ms and an ideal meter's flow frames as in
tests/reference_controllers/test_refctl_isobus.py (a row can be made silent: its flow lost).
"""

from __future__ import annotations

import math
from pathlib import Path

import can
import pytest

from hil.isobus.field import load_field, load_prescription
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.vt.operator import Operator
from hil.isobus.vt.server import VirtualTerminalServer, add_vt
from hil.isobus.wire import VirtualWire
from hil.rig.device import Device
from plant_emulators.fertilizer.frames import FertilizerDatabase
from reference_controllers.fertilizer.calibration import ff_coeff_from_test
from reference_controllers.fertilizer.isobus_vt import ALARM_AFTER_S, IsobusVtFlowController
from reference_controllers.fertilizer.operator_pool import IDS

FIELDS = Path(__file__).resolve().parents[4] / "plant_emulators" / "fertilizer" / "fields"
SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
DB = FertilizerDatabase()


class Node(Device):
    """The controller on the wire: SYNC every period, an ideal meter's flow frames before it;
    the rows in ``silent`` report nothing (their flow is lost)."""

    def __init__(self, controller: IsobusVtFlowController) -> None:
        self.ctl = controller
        self.period_s = controller.adapter_params.period_s
        self.silent: set[int] = set()
        self.metering: list[tuple[float, bool, float]] = []
        self._target = 0.0
        self._boot = controller.on_start()

    def next_due(self, time_s: float) -> float:
        return max(self.ctl.steps * self.period_s, math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        for row in sorted(self.ctl.rows.active - self.silent):
            self.ctl.on_frame(DB.encode(f"FlowModule{row}", {
                "Flow": self._target, "WindowMass": self._target, "Counter": 1,
                "BaselineReady": 1, "SlidingWindow": 1, "AdcOverrange": 0,
                "InterceptApplied": 0, "WindowLength": 1000}))
        out = self._boot + self.ctl.on_frame(SYNC)
        self._boot = []
        self._target = self.ctl.target_gps()
        self.metering.append((self.ctl.clock_s, self.ctl.metering(), self._target))
        return out

    def accepts(self, msg: can.Message) -> bool:
        return bool(msg.is_extended_id)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        return self.ctl.on_frame(msg)


def setup(defect: str = "") -> tuple[Tractor, VirtualTerminalServer, Node, VirtualWire]:
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    tractor = Tractor(TractorSetup(fld, rx, drive_after_s=3.0))
    vt = add_vt(tractor.network)
    params = {"vt_defect": defect} if defect else {}
    node = Node(IsobusVtFlowController("physical", params))
    return tractor, vt, node, VirtualWire([tractor.network, node])


Run = tuple[Tractor, VirtualTerminalServer, Node, VirtualWire]


def scenario(defect: str = "") -> Run:
    """Calibrate at 6-7.5 s, Master on at 8 s, row 3 silent from 14 s, acknowledge at 19 s,
    Master off at 20 s; the VT restarts (down 5 s) at 22 s; ends at 34 s."""
    tractor, vt, node, wire = setup(defect)
    operator = Operator(vt)
    operator.press("Calib.", 6.0)
    operator.enter(IDS.cal_grams_in, 95.0, 7.0)
    operator.press("Back", 7.5)
    operator.press("Master", 8.0)
    wire.run_until(14.0)
    node.silent = {3}                       # row 3's flow is lost from 14 s
    operator.acknowledge(19.0)
    operator.press("Master", 20.0)          # master off
    wire.run_until(22.0)
    vt.restart(22.0, down_s=5.0)
    wire.run_until(34.0)
    return tractor, vt, node, wire


# --- the checks a suite makes (each must fail its must-fail implement) ---------------------

def pool_active_within(run: Run, limit_s: float) -> bool:
    """The implement's pool became active on the VT within ``limit_s`` of power-up."""
    return any(e.kind == "activated" and e.time_s <= limit_s for e in run[1].events)


def nothing_before_master(run: Run) -> bool:
    """No target flow before the operator's Master (8 s)."""
    before = [q for t, _, q in run[2].metering if t < 8.0]
    return bool(before) and all(q == 0.0 for q in before)


def master_off_stops(run: Run) -> bool:
    """Zero target from 0.3 s after Master off (20 s) to the VT's restart (22 s)."""
    after = [q for t, _, q in run[2].metering if 20.3 <= t < 22.0]
    return bool(after) and all(q == 0.0 for q in after)


def alarm_shown_within(run: Run, limit_s: float) -> bool:
    """Row 3's alarm mask on the screen within ``limit_s`` of its flow stopping (14 s)."""
    return any(c.function == 0xAD and c.object_id == IDS.alarm and c.error == 0
               and 14.0 <= c.time_s <= 14.0 + limit_s for c in run[1].commands)


def reloaded_after_restart(run: Run) -> bool:
    """After the VT's restart the pool is active again, loaded from storage."""
    return any(e.kind == "activated" and e.time_s > 27.0 and "loaded version" in e.detail
               for e in run[1].events)


ALARM_LIMIT_S = 2.5 + ALARM_AFTER_S + 0.5     # the adapter's staleness, the alarm's delay


@pytest.fixture(scope="module")
def run() -> Run:
    return scenario()


def test_the_reference_passes_every_check(run: Run) -> None:
    assert pool_active_within(run, 6.0)
    assert nothing_before_master(run)
    assert master_off_stops(run)
    assert alarm_shown_within(run, ALARM_LIMIT_S)
    assert reloaded_after_restart(run)
    assert run[0].tc.sessions and run[2].ctl.rate_kg_ha > 0.0   # the TC sent a rate all along


def test_master_on_meters(run: Run) -> None:
    during = [(m, q) for t, m, q in run[2].metering if 8.5 <= t < 14.0]
    assert during and all(m and q > 0.0 for m, q in during)


def test_calibration_entered_on_the_vt_changes_the_feedforward(run: Run) -> None:
    node = run[2]
    p = node.ctl.core_params
    assert node.ctl.calibration == (95.0, 21.0)
    assert p.ff_coeff == ff_coeff_from_test(95.0, 21.0, p.ff_exponent, p.ff_linear_below_rpm)


def test_the_alarm_text_then_ack_returns_to_run(run: Run) -> None:
    vt = run[1]
    alarm = [c for c in vt.commands if c.function == 0xAD and c.object_id == IDS.alarm]
    stale_s = run[2].ctl.adapter_params.stale_after_s
    assert len(alarm) == 1
    assert 14.0 + stale_s + ALARM_AFTER_S <= alarm[0].time_s <= 14.0 + ALARM_LIMIT_S
    text = [c for c in vt.commands if c.function == 0xB3 and "Row 3: flow lost" in c.detail]
    assert text and text[0].time_s <= alarm[0].time_s
    back = [c for c in vt.commands if c.function == 0xAD and c.object_id == IDS.run
            and c.time_s > alarm[0].time_s]
    assert back and 19.0 < back[0].time_s < 19.5


def test_the_run_mask_shows_rate_and_rows(run: Run) -> None:
    numbers = [c for c in run[1].commands if c.function == 0xA8 and c.error == 0]
    assert any(c.object_id == IDS.rate_var for c in numbers)
    rows = {c.object_id for c in numbers} - {IDS.rate_var}
    assert rows == {IDS.row_var(r) for r in range(1, run[2].ctl.row_count + 1)}


MUST_FAIL = {
    "ignores-master": master_off_stops,
    "no-alarm": lambda r: alarm_shown_within(r, ALARM_LIMIT_S),
    "bad-pool": lambda r: pool_active_within(r, 6.0),
    "no-reconnect": reloaded_after_restart,
    "meters-without-vt": nothing_before_master,
}


@pytest.mark.parametrize("defect", [
    "ignores-master",
    pytest.param("no-alarm", marks=pytest.mark.slow),
    pytest.param("bad-pool", marks=pytest.mark.slow),
    pytest.param("no-reconnect", marks=pytest.mark.slow),
    pytest.param("meters-without-vt", marks=pytest.mark.slow)])
def test_each_must_fail_implement_fails_its_check(defect: str) -> None:
    result = scenario(defect)
    assert not MUST_FAIL[defect](result)
    if defect == "bad-pool":
        refusal = result[2].ctl.vt.refusal
        assert refusal is not None and refusal.object_id == IDS.rate_out


@pytest.mark.slow
def test_two_lockstep_runs_of_the_scenario_give_identical_bus_logs(run: Run) -> None:
    again = scenario()
    first = [(f.time_s, f.sender, f.frame.arbitration_id, bytes(f.frame.data))
             for f in run[3].frames]
    second = [(f.time_s, f.sender, f.frame.arbitration_id, bytes(f.frame.data))
              for f in again[3].frames]
    assert len(first) > 1_000 and first == second
