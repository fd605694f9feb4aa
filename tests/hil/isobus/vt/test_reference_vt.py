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


def setup() -> tuple[Tractor, VirtualTerminalServer, Node, VirtualWire]:
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    tractor = Tractor(TractorSetup(fld, rx, drive_after_s=3.0))
    vt = add_vt(tractor.network)
    node = Node(IsobusVtFlowController("physical"))
    return tractor, vt, node, VirtualWire([tractor.network, node])


@pytest.fixture(scope="module")
def run() -> tuple[Tractor, VirtualTerminalServer, Node, VirtualWire]:
    tractor, vt, node, wire = setup()
    operator = Operator(vt)
    wire.run_until(6.0)
    assert node.ctl.vt.state == "connected"
    operator.press("Calib.", 6.0)
    operator.enter(IDS.cal_grams_in, 95.0, 7.0)
    operator.press("Back", 7.5)
    operator.press("Master", 8.0)
    wire.run_until(14.0)
    node.silent = {3}                       # row 3's flow is lost from 14 s
    wire.run_until(19.0)
    operator.acknowledge(19.0)
    wire.run_until(20.0)
    operator.press("Master", 20.0)          # master off
    wire.run_until(22.0)
    assert operator.missed == []
    return tractor, vt, node, wire


def test_the_pool_is_active_and_nothing_is_metered_before_master(
        run: tuple[Tractor, VirtualTerminalServer, Node, VirtualWire]) -> None:
    _, vt, node, _ = run
    activated = [e for e in vt.events if e.kind == "activated"]
    assert len(activated) == 1 and activated[0].time_s < 6.0
    before = [(t, m, q) for t, m, q in node.metering if 6.0 <= t < 8.0]
    assert before and not any(m for _, m, _ in before)
    assert all(q == 0.0 for _, _, q in before)
    # the TC was connected and sending a rate all the while: only the master held it
    assert node.ctl.client.connected and node.ctl.rate_kg_ha > 0.0


def test_master_on_meters_master_off_stops(
        run: tuple[Tractor, VirtualTerminalServer, Node, VirtualWire]) -> None:
    _, vt, node, _ = run
    during = [(t, m, q) for t, m, q in node.metering if 8.5 <= t < 14.0]
    assert during and all(m and q > 0.0 for _, m, q in during)
    after = [(t, m, q) for t, m, q in node.metering if t >= 20.3]
    assert after and not any(m for _, m, _ in after) and all(q == 0.0 for _, _, q in after)
    ws = next(iter(vt.sessions.values()))
    assert ws.text(ws.obj(IDS.master_out)) == "OFF"         # type: ignore[arg-type]


def test_calibration_entered_on_the_vt_changes_the_feedforward(
        run: tuple[Tractor, VirtualTerminalServer, Node, VirtualWire]) -> None:
    _, _, node, _ = run
    p = node.ctl.core_params
    assert node.ctl.calibration == (95.0, 21.0)
    assert p.ff_coeff == ff_coeff_from_test(95.0, 21.0, p.ff_exponent, p.ff_linear_below_rpm)


def test_a_lost_row_raises_its_alarm_and_ack_returns(
        run: tuple[Tractor, VirtualTerminalServer, Node, VirtualWire]) -> None:
    _, vt, node, _ = run
    alarm = [c for c in vt.commands if c.function == 0xAD and c.object_id == IDS.alarm]
    # silent from 14 s: stale after the adapter's 2.5 s, lost for 1 s, then on the screen
    stale_s = node.ctl.adapter_params.stale_after_s
    assert len(alarm) == 1 and 14.0 + stale_s + ALARM_AFTER_S <= alarm[0].time_s \
        <= 14.0 + stale_s + ALARM_AFTER_S + 0.5
    text = [c for c in vt.commands if c.function == 0xB3 and "Row 3: flow lost" in c.detail]
    assert text and text[0].time_s <= alarm[0].time_s
    back = [c for c in vt.commands if c.function == 0xAD and c.object_id == IDS.run
            and c.time_s > alarm[0].time_s]
    assert back and 19.0 < back[0].time_s < 19.5


def test_the_run_mask_shows_rate_and_rows(
        run: tuple[Tractor, VirtualTerminalServer, Node, VirtualWire]) -> None:
    _, vt, node, _ = run
    numbers = [c for c in vt.commands if c.function == 0xA8 and c.error == 0]
    shown_rate = [c for c in numbers if c.object_id == IDS.rate_var]
    assert shown_rate
    rows = {c.object_id for c in numbers} - {IDS.rate_var}
    assert rows == {IDS.row_var(r) for r in range(1, node.ctl.row_count + 1)}
