"""The fertilizer lot against the controller's calibration (robustness suite, issue 42).

Every drill and spreader manual asks for a calibration ("rotation") test whenever the product
or the lot changes: the rig runs it on the run's lot and the terminal sends it
(``MeterCalibration``; ``plant_emulators/fertilizer/calibration_test.py``). Two questions:

* **a tested lot** (``bench-lot-calibrated``): the lot 8 points denser than the lot the
  controller's own calibration was made on, the test sent. A controller that uses it lands its
  feedforward where the lot delivers, and the step's first second (before any flow module can
  report) is [F]'s: ``flow.lot.calibrated.overshoot`` <= 5 %. One that ignores it overshoots by
  the lot's 8 points more.
* **an untested lot** (``bench-lot-uncalibrated-*``, 4 points denser or lighter, no test): the
  first second is the lot's, which no controller can see; what closed-loop correction must
  deliver is judged instead: the 50 s run's applied accuracy ([F] eq. 15,
  ``flow.lot.uncalibrated.accuracy``) and the time from the enable until the true flow's error
  is brought under the true steady-state limit (``flow.lot.uncalibrated.correction_time``: from
  then on it stays under it for a whole judging window; later excursions are the steady state's,
  which ``flow.step.true_steady_state_error`` judges, not the correction's). The limits are
  derived in ``hil/limits.py``.

A controller on its own database whose binding does not carry the calibration
(``calibration_grams_per_rev``, optional in the contract) cannot be told of a test: the tested
lot is skipped with that reason, the untested ones are judged as for any controller.

The true flow is the rows' mean at the meters. The overshoot takes the step test's filter (whole
flute periods, ~1 s); the correction time a mean over whole flute periods of at least 5 s: the
flute-to-flute fill noise of a 1 s mean (~0.9 % SD at 34 g/s) would cross a 2.2 % band by chance
many times in 50 s, a 5 s mean's (~0.4 %) does not, while a lot left uncorrected (4 %) stays out.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.dut.profile import DutProfile
from hil.metrics import accuracy_theta, judged_recovery, step_response
from hil.rig import RunResult
from test_suites.fertilizer.traces import (
    ENABLE_S,
    STEADY_WINDOW_S,
    delivered_and_target_g,
    flow_filter,
    flutes,
    row_mean,
    trace,
)

pytestmark = pytest.mark.hil_rig("fertilizer")

#: the judging window of the correction time: whole flute periods of at least this
CORRECTION_WINDOW_S = 5.0
#: the true flow's steady-state limit the correction must bring the error under, a fraction
#: of the target (flow.step.true_steady_state_error's 2.2 %, hil/limits.py)
STEADY_BAND = 0.022
#: the untested lots: how much more they deliver than the controller's calibration
UNTESTED_LOTS = {"denser": 4.0, "lighter": -4.0}


def _correction_filter(result: RunResult) -> dict[str, float | str]:
    t, shaft = trace(result, "shaft_speed_rpm")
    turning = shaft[(t >= ENABLE_S) & (shaft > 0.5)]
    if turning.size == 0:
        return {"filter_kind": "mean", "filter_s": CORRECTION_WINDOW_S}
    period_s = 60.0 / (flutes(result) * float(np.median(turning)))
    periods = max(1, math.ceil(CORRECTION_WINDOW_S / period_s - 1e-9))
    return {"filter_kind": "mean", "filter_s": periods * period_s}


def correction_time(t: np.ndarray, flow: np.ndarray, *, t0: float, target: float,
                    window_s: float) -> float:
    """Seconds from ``t0`` to the first sample from which the centred ``window_s`` mean of
    ``flow`` stays within ``STEADY_BAND`` of ``target`` for ``window_s``; nan: never.

    The mean is judged only where its window is whole; the rise through the band (a lot
    denser than the controller's calibration passes it on the way up) lasts far less than a
    window and does not count.
    """
    dt = float(np.median(np.diff(t)))
    half = max(1, round(window_s / dt / 2.0))
    kernel = np.ones(2 * half + 1) / (2 * half + 1)
    mean = np.full(flow.shape, np.nan)
    mean[half:-half] = np.convolve(flow, kernel, mode="valid")
    inside = np.abs(mean / target - 1.0) < STEADY_BAND
    hold = 2 * half + 1
    start = int(np.searchsorted(t, t0))
    for i in np.flatnonzero(inside[start:]) + start:
        if i + hold <= inside.size and inside[i:i + hold].all():
            return float(t[i] - t0)
    return math.nan


def _lot_note(result: RunResult) -> str:
    test = result.record["truth"].get("calibration_test")
    lot = 100.0 * float(result.record["truth"]["lot_frac"])
    if not test:
        return f"lot {lot:+.2f} % against the map, not tested"
    return (f"lot {lot:+.2f} % against the map; test: {test['weighed_kg']:.1f} kg over "
            f"{test['revolutions']} revolutions, {test['grams_per_rev_row']:.2f} g/rev "
            f"({100.0 * test['error_frac']:+.2f} % off the lot)")


def _hears_calibration(profile: DutProfile) -> bool:
    """Whether the binding in force carries the calibration test to the DUT."""
    from hil.contract.binding import load_binding
    from hil.contract.registry import rig_contract

    contract = rig_contract(profile.dut.rig, profile.rig_config, str(profile.path or ""))
    return "calibration_grams_per_rev" in load_binding(contract.binding_file).carriers


@pytest.mark.hil_suite("robustness")
def test_lot_calibrated(hil_run, hil_rig, hil_profile, hil_measure) -> None:
    if not _hears_calibration(hil_profile):
        pytest.skip("the DUT's binding carries no calibration test (calibration_grams_per_rev):"
                    " the terminal cannot tell it of the lot")
    result = hil_run("bench-lot-calibrated")
    target = float(hil_rig.load_scenario("bench-lot-calibrated").initial["target_flow_gps"])
    t, true_flow = row_mean(result, "flow_at_meter")
    m = step_response(t, true_flow, t0=ENABLE_S, target=target, y0=0.0,
                      **flow_filter(result, ENABLE_S), steady_window_s=STEADY_WINDOW_S)
    hil_measure("flow.lot.calibrated.overshoot", m.overshoot_pct, run=result,
                note=_lot_note(result))


@pytest.mark.hil_suite("robustness")
@pytest.mark.parametrize("lot", sorted(UNTESTED_LOTS))
def test_lot_uncalibrated(hil_run, hil_rig, hil_measure, lot: str) -> None:
    scenario = f"bench-lot-uncalibrated-{lot}"
    result = hil_run(scenario)
    conditions = {"lot_offset_pct": UNTESTED_LOTS[lot]}
    note = _lot_note(result)
    delivered, target_g = delivered_and_target_g(result)
    hil_measure("flow.lot.uncalibrated.accuracy", accuracy_theta(target_g, delivered),
                conditions=conditions, run=result,
                note=f"weighed {delivered:.1f} g of {target_g:.1f} g; {note}")
    target = float(hil_rig.load_scenario(scenario).initial["target_flow_gps"])
    t, true_flow = row_mean(result, "flow_at_meter")
    window = float(_correction_filter(result)["filter_s"])
    correction, never = judged_recovery(
        correction_time(t, true_flow, t0=ENABLE_S, target=target, window_s=window), t,
        t0=ENABLE_S, band=STEADY_BAND, min_hold_s=window)
    hil_measure("flow.lot.uncalibrated.correction_time", correction, conditions=conditions,
                run=result, note="; ".join(n for n in (never, note) if n))
