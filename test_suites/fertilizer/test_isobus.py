"""The ``isobus`` suite: an ISOBUS implement under the rig's Task Controller (issue 27).

The DUT claims an address, connects to the rig's TC and takes its rate from a prescription map
(TC-GEO), its section states from the TC's coverage (TC-SC) and its speed from the tractor ECU.
Every measurement reads what really landed where (:mod:`test_suites.fertilizer.field_truth`),
never what the DUT reported; the limits are derived in :mod:`hil.limits`.

- ``isobus-field``: power-up to an active pool; the rate laid per zone of the map at steady
  speed; the distance from each zone boundary to the new rate; the section switches at the
  headlands and over the overlapping pass (the field's wheels slip 5 %, so a controller on
  the wheel-based speed over-applies);
- ``isobus-tc-restart``: the TC restarts mid-pass: nothing laid once the implement must have
  noticed, and the time to reconnect when it is back;
- ``isobus-tc-refused``: the TC refuses the pool: nothing laid;
- ``isobus-speed-loss``: the TECU falls silent as the tractor slows: no over-application.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from hil.isobus.field.laid import SAMPLE_S
from hil.metrics.application_map import cell_accuracy, section_switching, transition_distances
from hil.metrics.rows import applied_per_row
from hil.rig import RunResult
from test_suites.fertilizer.field_truth import FieldArrays, FieldTruth
from test_suites.fertilizer.traces import transport_s

pytestmark = [pytest.mark.hil_rig("fertilizer"), pytest.mark.hil_suite("isobus")]

#: the rate is judged from this far past a change (a zone boundary, the start of the ground to
#: cover): the transition's own limit (isobus.zone.transition_distance)
SETTLE_AFTER_M = 2.5
#: ... and up to this far before one (the TC's look-ahead lands the new rate early by up to
#: the switch error's limit)
SETTLE_BEFORE_M = 0.5
#: a transition is over when the rate stays in the 5 % band for this much travel
HOLD_M = 2.0
#: ISO 11783-10: a client considers the TC lost after 6 s without its status
TC_TIMEOUT_S = 6.0
#: after a loss of the TECU's speed, the time a controller gets to notice it (three missed
#: 100 ms messages) and act (one step), before what lands is judged (the transport is added)
SPEED_LOSS_GRACE_S = 0.5


def _fault_times(result: RunResult, name: str) -> tuple[float, float]:
    """When the run's fault ``name`` was injected and cleared (inf: never cleared)."""
    start, end = math.inf, math.inf
    for event in result.record.get("events", []) or []:
        if name in str(event.get("detail", "")):
            if event.get("kind") == "fault":
                start = float(event["t"])
            elif event.get("kind") == "fault-cleared":
                end = float(event["t"])
    if not math.isfinite(start):
        raise ValueError(f"{result.out_dir}: the run's record has no {name} fault")
    return start, end


def _near_changes(distance: np.ndarray, signal: np.ndarray, before_m: float,
                  after_m: float) -> np.ndarray:
    """(k, s) True within ``before_m`` before and ``after_m`` after each change of ``signal``
    along each column's track."""
    out = np.zeros(signal.shape, dtype=bool)
    for j in range(signal.shape[1]):
        d = distance[:, j]
        for k in np.flatnonzero(signal[1:, j] != signal[:-1, j]) + 1:
            out[:, j] |= (d >= d[k] - before_m) & (d < d[k] + after_m)
    return out


def _delivered_between(result: RunResult, t0: float, t1: float) -> float:
    """Grams delivered by all rows in ``[t0, t1)`` (trace samples)."""
    traces, _ = result.traces()
    t = traces["time_s"]
    rows = sorted(k for k in traces if k.startswith("delivered_") and k.endswith("_g"))
    total = np.sum([traces[k] for k in rows], axis=0)
    if t1 <= t0:
        return 0.0
    return float(np.interp(t1, t, total) - np.interp(t0, t, total))


# --------------------------------------------------------------------- the field run
def test_connection(hil_run, hil_measure) -> None:
    result = hil_run("isobus-field")
    truth = FieldTruth(result)
    active = truth.events("activated")
    refused = [e for e in truth.run["tc_events"] if e["kind"] == "refused"]
    note = (f"pool active at {active[0]:.1f} s" if active else
            "the pool never became active" + (f": refused ({refused[0]['detail']})"
                                             if refused else ""))
    hil_measure("isobus.connect.time_to_active", active[0] if active else math.inf,
                run=result, note=note)


def test_rate_per_zone(hil_run, hil_measure) -> None:
    result = hil_run("isobus-field")
    truth = FieldTruth(result)
    if truth.prescription is None:
        raise ValueError("isobus-field has no prescription map")
    a = truth.arrays
    zone_of = np.where(a.needed, a.prescribed, -1.0)
    judged = a.needed & a.steady[:, None] & ~_near_changes(
        a.distance_m, zone_of, SETTLE_BEFORE_M, SETTLE_AFTER_M)
    # the ground that needed it: a row that laid nothing there counts as 0 kg/ha
    cells = cell_accuracy(a.cell, a.distance_m, a.width_m, judged, a.applied, a.prescribed)
    by_zone = {c.cell: c for c in cells.cells}
    for index, zone in enumerate(truth.prescription.zones):
        cell = by_zone.get(index)
        if cell is None:
            continue            # the path crosses no steady stretch of this zone
        hil_measure("isobus.field.rate_accuracy", 100.0 - abs(cell.error_pct),
                    conditions={"zone": zone.name, "rate_kg_ha": zone.rate}, run=result,
                    note=f"{cell.applied:.1f} kg/ha laid of {cell.prescribed:.1f} on "
                         f"{cell.area_m2:.0f} m2")


def test_zone_transitions(hil_run, hil_measure) -> None:
    result = hil_run("isobus-field")
    a = FieldTruth(result).arrays
    # where the ground under the openers' middle needed applying: a controller that lays
    # nothing there never reaches the new rate (inf)
    needed = a.needed.any(axis=1, keepdims=True)
    found = transition_distances(a.boom_distance_m, needed, a.boom_applied_smooth,
                                 a.boom_prescribed, hold_m=HOLD_M)
    if not found.transitions:
        raise ValueError("isobus-field crossed no zone boundary on ground that needed applying")
    worst = max(found.transitions, key=lambda t: t.distance_m)
    hil_measure("isobus.zone.transition_distance", worst.distance_m, run=result,
                note=f"worst of {len(found.transitions)} boundaries: {worst.from_rate:g} -> "
                     f"{worst.to_rate:g} kg/ha at {worst.at_m:.1f} m of travel; all: "
                     + ", ".join(f"{t.distance_m:.2f}" for t in found.transitions))


def test_section_switching(hil_run, hil_measure) -> None:
    result = hil_run("isobus-field")
    a: FieldArrays = FieldTruth(result).arrays
    sw = section_switching(a.distance_m, a.applying, a.needed, inside_work_area=a.inside_work_area)
    kinds: dict[str, list[Any]] = {}
    for event in sw.events:
        kinds.setdefault(event.kind, []).append(event)
    if not kinds:
        raise ValueError("isobus-field has no section switch to judge")
    switches = len(sw.events)
    totals = (f"{switches} switches asked for; {sw.spurious_switches} switches where none "
              f"was needed")
    hil_measure("isobus.section.overlap_per_switch", sw.overlap_m / switches, run=result,
                note=f"{sw.overlap_m:.2f} m applied where not needed; {totals}")
    hil_measure("isobus.section.skip_per_switch", sw.skip_m / switches, run=result,
                note=f"{sw.skip_m:.2f} m not applied where needed; {totals}")
    for kind, events in sorted(kinds.items()):
        worst = max(events, key=lambda e: abs(e.error_m))
        hil_measure("isobus.section.switch_error", abs(worst.error_m),
                    conditions={"kind": kind}, run=result,
                    note=f"worst of {len(events)} {kind} switches: row {worst.section + 1} "
                         f"{worst.direction} {worst.error_m:+.2f} m; run totals: overlap "
                         f"{sw.overlap_m:.2f} m, skip {sw.skip_m:.2f} m, "
                         f"{sw.spurious_switches} switches where none was needed")


def test_rows(hil_run, hil_measure) -> None:
    """Each row against its own share of the map where its ground needed applying: the
    switched rows' measurement of the terminal's runs (hil.metrics.rows), with the TC's
    sections as the rule of which rows should meter."""
    result = hil_run("isobus-field")
    truth = FieldTruth(result)
    a, laid = truth.arrays, truth.laid
    delivered = np.vstack([np.zeros((1, truth.rows)), np.cumsum(laid.mass_g[:-1], axis=0)])
    # g/s each row should lay: the map's kg/ha over the strip it crosses per sample
    target = np.where(a.needed, a.prescribed / 10.0 * laid.area_m2 / SAMPLE_S, 0.0)
    rows = applied_per_row(a.t_s, delivered, target, a.needed, transport_s=0.0,
                           row_gain=np.asarray(result.record["truth"]["row_gain"]))
    for row, (accuracy, off) in enumerate(zip(rows.accuracy_pct, rows.off_delivery_g,
                                              strict=True), start=1):
        hil_measure("flow.rows.applied_accuracy", accuracy,
                    conditions={"scenario": "isobus-field", "row": row}, run=result,
                    note=f"{off:.1f} g laid where its ground did not need it")


# --------------------------------------------------------------------- the TC fails
def test_tc_restart(hil_run, hil_measure) -> None:
    result = hil_run("isobus-tc-restart")
    truth = FieldTruth(result)
    down, back = _fault_times(result, "tc_down")
    noticed = down + TC_TIMEOUT_S + transport_s(result)
    grams = _delivered_between(result, noticed, back)
    hil_measure("isobus.tc.loss.delivered", grams, run=result,
                note=f"laid from {noticed:.2f} s (6 s without the TC's status, plus the "
                     f"transport) until the TC was back at {back:g} s")
    again = [t for t in truth.events("activated") if t >= back]
    hil_measure("isobus.tc.restart.reconnect_time", (again[0] - back) if again else math.inf,
                run=result, note=(f"pool active again at {again[0]:.1f} s" if again else
                                  "the pool never became active again"))


def test_tc_refuses_the_pool(hil_run, hil_measure) -> None:
    result = hil_run("isobus-tc-refused")
    truth = FieldTruth(result)
    refused = [e for e in truth.run["tc_events"] if e["kind"] == "refused"]
    active = truth.events("activated")
    if active and not refused:
        raise ValueError("isobus-tc-refused: the TC accepted the pool (it is small enough for "
                         "the TC's memory): the run cannot judge a refusal")
    total = float(sum(result.record["truth"]["delivered_g"]))
    hil_measure("isobus.tc.refused.delivered", total, run=result,
                note=(f"refused at {refused[0]['t']:.1f} s: {refused[0]['detail']}"
                      if refused else "the implement never asked for a transfer"))


# --------------------------------------------------------------------- the TECU fails
def test_speed_loss(hil_run, hil_measure) -> None:
    result = hil_run("isobus-speed-loss")
    a = FieldTruth(result).arrays
    lost, _ = _fault_times(result, "tecu_silent")
    window = a.t_s >= lost + SPEED_LOSS_GRACE_S + transport_s(result)
    area = np.vstack([np.diff(a.distance_m, axis=0), np.zeros((1, a.distance_m.shape[1]))])
    area = area * a.width_m[None, :]
    # per row over the whole window: a fluted roller's pulsation swings a 0.1 s sample by
    # +-15 %, which a sum of per-sample excesses would count as over-application
    asked_by_row = np.where(a.needed, a.prescribed * area / 10.0, 0.0)[window].sum(axis=0)
    laid_by_row = a.mass_g[window].sum(axis=0)
    over = float(np.sum(np.maximum(0.0, laid_by_row - asked_by_row)))
    asked = float(np.sum(asked_by_row))
    if asked <= 0:
        raise ValueError("isobus-speed-loss: the map prescribed nothing after the speed loss")
    hil_measure("isobus.tecu.speed_loss.overapplication", 100.0 * over / asked, run=result,
                note=f"{over:.0f} g laid beyond the map's {asked:.0f} g after the TECU fell "
                     f"silent at {lost:g} s")
