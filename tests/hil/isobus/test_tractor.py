"""The emulated tractor (hil.isobus.tractor) with the TC client as the implement, in virtual time:
the example field driven over its three-zone map by an implement of four sections. The
set-points follow the zones under the boom, sections go off in the headland turns and over the
overlap pass, and the as-applied record is what the implement reported."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.isobus import ddi
from hil.isobus import process_data as pd
from hil.isobus.ddop import ElementType, ObjectPool
from hil.isobus.ddop.samples import section_control_pool
from hil.isobus.field import load_field, load_prescription
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.process_data import AckError, Command
from hil.isobus.tc_client import TaskControllerClient
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.wire import VirtualWire

FIELDS = Path(__file__).resolve().parents[3] / "plant_emulators" / "fertilizer" / "fields"
IMPLEMENT_NAME = IsobusName(identity_number=9, manufacturer_code=300, function=130,
                            device_class=5)
DRIVE_AFTER_S = 3.0

# one drive of the whole example field (131 s of run time): about 8 s of CPU, most of it the
# tractor's section control (coverage probes every 10 ms TC tick)
pytestmark = pytest.mark.slow
SECTIONS = 4


class Planter:
    """An ideal implement: applies what it is told at once and reports it."""

    def __init__(self, pool: ObjectPool) -> None:
        self.pool = pool
        self.bin = next(e.element_number for e in pool.elements
                        if e.element_type == ElementType.BIN)
        self.boom = next(e.element_number for e in pool.elements
                         if e.element_type == ElementType.FUNCTION)
        self.rate = 0
        self.states = [0] * SECTIONS
        self.rates: list[tuple[float, int]] = []
        self.commands: list[tuple[float, list[int]]] = []

    def on_setpoint(self, element: int, ddi_: int, value: int, t: float) -> AckError | None:
        if (element, ddi_) == (self.bin, ddi.SETPOINT_MASS_PER_AREA_RATE):
            self.rate = value
            self.rates.append((t, value))
        elif (element, ddi_) == (self.boom, 290):
            self.states = ddi.unpack_condensed_work_state(value & 0xFFFFFFFF)[:SECTIONS]
            self.commands.append((t, list(self.states)))
        return None

    def read_value(self, element: int, ddi_: int, t: float) -> int | None:
        if (element, ddi_) == (self.bin, ddi.ACTUAL_MASS_PER_AREA_RATE):
            return self.rate if any(s == 1 for s in self.states) else 0
        if (element, ddi_) == (self.boom, 161):
            return ddi.pack_condensed_work_state(self.states + [3] * (16 - SECTIONS))
        if (element, ddi_) == (self.boom, ddi.ACTUAL_WORKING_WIDTH):
            return 3000
        return 0


@pytest.fixture(scope="module")
def drive() -> tuple[Tractor, Planter, TaskControllerClient, VirtualWire]:
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    tractor = Tractor(TractorSetup(fld, rx, drive_after_s=DRIVE_AFTER_S))
    pool = section_control_pool(sections=SECTIONS, section_width_mm=750,
                                name=IMPLEMENT_NAME.value)
    planter = Planter(pool)
    dut = IsobusNetwork(name="implement")
    port = dut.add(IMPLEMENT_NAME, 0x85, "planter")
    client = TaskControllerClient(port, pool, on_setpoint=planter.on_setpoint,
                                  read_value=planter.read_value)
    port.run(client)
    wire = VirtualWire([tractor.network, dut])
    wire.run_until(DRIVE_AFTER_S + fld.path.duration_s + 1.0)
    return tractor, planter, client, wire


def _held(events: list[tuple[float, list[int]]], t: float) -> list[int] | None:
    """The last of ``events`` at or before ``t``."""
    held = None
    for at, value in events:
        if at > t:
            break
        held = value
    return held


def test_the_implement_connects_before_the_tractor_drives(drive) -> None:
    tractor, _, client, _ = drive
    connected = next(e.time_s for e in client.events if e.detail == "connected")
    assert client.connected and client.connections == 1
    assert connected < DRIVE_AFTER_S
    assert tractor.tc.sessions[0x85].pool is not None


def test_set_points_follow_the_zones_under_the_boom(drive) -> None:
    tractor, planter, _, _ = drive
    rx = tractor.setup.prescription
    implement = tractor._implements[0x85]
    zone_values = {int(rx.setpoint_ddi_value(z.rate)) for z in rx.zones}
    assert zone_values == {16_000, 24_000, 20_000}
    assert zone_values <= {v for _, v in planter.rates}, "every zone's rate arrived"
    pure: list[tuple[float, int]] = []       # set-points sent with the whole boom in one zone
    for t, value in planter.rates:
        pose = tractor.pose(t)
        centre = implement.boom.section_lines(pose.east_m, pose.north_m, pose.heading_deg)[1][0]
        under = rx.setpoint_ddi_value(rx.rate_at_local(centre[:, 0], centre[:, 1]))
        # a set-point is never outside the rates under the sections, and is the zone's own
        # where the whole boom is in one zone
        assert under.min() <= value <= under.max(), (t, value, under)
        if under.min() == under.max():
            assert value == under[0]
            pure.append((t, value))
    assert len(pure) >= 8
    # along each pass, the rate goes through the zones in the order they lie on the ground:
    # 160 kg/ha in the south, the 240 band, 200 in the north
    spans = tractor.leg_spans("pass") + tractor.leg_spans("overlap")
    assert len(spans) == 4
    for start, end in spans:
        held = [v for t, v in pure if t <= start][-1]
        seen = [held] + [v for t, v in pure if start < t <= end]
        runs = [v for i, v in enumerate(seen) if i == 0 or v != seen[i - 1]]
        heading = tractor.pose((start + end) / 2).heading_deg
        northbound = heading < 90 or heading > 270
        assert runs == ([16_000, 24_000, 20_000] if northbound else [20_000, 24_000, 16_000]), (
            start, heading, runs)


def test_sections_switch_off_in_the_headland_turns_and_over_the_overlap(drive) -> None:
    tractor, planter, _, _ = drive
    step = 0.05

    def on_share(spans: list[tuple[float, float]]) -> np.ndarray:
        samples = [_held(planter.commands, t) for a, b in spans
                   for t in np.arange(a, b, step)]
        arr = np.array([s if s is not None else [0] * SECTIONS for s in samples])
        return (arr == 1).mean(axis=0)

    turns = on_share(tractor.leg_spans("turn"))
    assert turns.max() < 0.15, turns          # off in the headlands (look-ahead at the ends)
    passes = on_share(tractor.leg_spans("pass"))
    assert passes.min() > 0.7, passes          # on over the work area
    overlap = on_share(tractor.leg_spans("overlap"))
    # two of the four rows run over the third pass's ground: off; the other two apply
    assert sorted(overlap)[:2] == pytest.approx([0.0, 0.0], abs=0.05), overlap
    assert sorted(overlap)[2:] > [0.7, 0.7], overlap


def test_the_as_applied_record_is_what_the_implement_reported(drive) -> None:
    tractor, _, _, wire = drive
    reported: dict[int, list[tuple[float, int]]] = {ddi.ACTUAL_MASS_PER_AREA_RATE: [], 161: []}
    for f in wire.frames:
        cid = f.frame.arbitration_id
        if (cid >> 8) & 0x3FF00 != pd.PROCESS_DATA_PGN or cid & 0xFF != 0x85:
            continue
        m = pd.decode(bytes(f.frame.data))
        if isinstance(m, pd.ElementCommand) and m.command == Command.VALUE \
                and m.ddi in reported:
            reported[m.ddi].append((f.time_s, m.value))
    assert len(reported[161]) >= 10 and len(reported[ddi.ACTUAL_MASS_PER_AREA_RATE]) >= 10
    record = tractor.as_applied()
    assert record is not None
    a = record.arrays()
    assert len(a.t_s) > 1000
    mismatches = 0
    for k, t in enumerate(a.t_s):
        # what the implement had reported by the sample (a report at the same instant may
        # arrive before or after it)
        candidates = []
        for before in (True, False):
            states = [(at, v) for at, v in reported[161] if (at < t if before else at <= t)]
            rates = [(at, v) for at, v in reported[ddi.ACTUAL_MASS_PER_AREA_RATE]
                     if (at < t if before else at <= t)]
            s = ddi.unpack_condensed_work_state(states[-1][1] & 0xFFFFFFFF)[:SECTIONS] \
                if states else [0] * SECTIONS
            applying = [x == 1 for x in s]
            rate = rates[-1][1] / 100.0 if rates else 0.0
            candidates.append((applying, [rate if on else 0.0 for on in applying]))
        got = (list(a.applying[k]), list(a.rate[k]))
        if not any(got[0] == c[0] and np.allclose(got[1], c[1]) for c in candidates):
            mismatches += 1
    assert mismatches == 0
    # and it applied: the three zones' rates are in the record
    assert {160.0, 200.0, 240.0} <= set(np.round(a.rate[a.applying], 3))
