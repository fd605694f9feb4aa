"""The ``isobus`` suite's Virtual Terminal tests: an implement operated from the tractor's VT
(issue 39).

The tractor has a VT beside its TC (``[tractor] vt = true``) and the scenario's operator acts
on it (``[[operator]]``): the implement uploads its pool to the VT, the operator switches its
master key (the soft key or button labelled ``Master``) on and off, and the rig breaks a row's
flow or the VT itself. Every measurement reads the truth: grams at the meters and the
openers, the masks the VT really showed, the pool the VT really activated (the run's record,
``truth.field_run.vt``), never what the implement reported. The limits are derived in
:mod:`hil.limits`.

- ``isobus-vt-operator``: key-on to the pool active on the VT; nothing laid before the
  operator's Master; the meters stopped after Master off; a lost row's alarm on the screen;
- ``isobus-vt-restart``: the VT loses power mid-pass and comes back: the pool active again,
  loaded from the VT's storage rather than uploaded;
- ``isobus-vt-calibration``: the lot's calibration test entered on the VT (grams per
  revolution, shaft speed) is what meters in the first 1.5 s after Master, before the flow
  modules can correct anything.

Each test first runs ``isobus-vt-probe`` (6 s, key on, the tractor standing): an implement
that never addresses the VT there (no get memory, no pool, no stored version asked for: an
implement without a VT client; a working set master message alone is a TC client's too) has
these tests skipped, saying so, without their longer runs; one that tries and fails (its pool
refused, never active) fails them. (A VT client that would first address the VT later than
6 s, the time its pool must be active by, is taken for none.)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from hil.isobus.vt.fieldvt import alarm_masks
from hil.rig import RunResult
from test_suites.fertilizer.traces import transport_s

pytestmark = [pytest.mark.hil_rig("fertilizer"), pytest.mark.hil_suite("isobus")]

#: the label of the implement's master key the suite's scenarios press
MASTER = "Master"
#: the fault the operator scenario breaks a row's flow with
ROW_LOST_FAULT = "flow_sensor_silent"
#: a row's flow at the meters below this share of what they metered before Master off is
#: stopped (a fluted roller at rest delivers nothing; a coasting one is still turning)
STOPPED_FRACTION = 0.05
#: the flow before Master off is averaged over this long
BEFORE_OFF_S = 2.0
#: the first metering judged against the entered calibration: from the drive's ramp after
#: Master on, for 1.5 s (four and a half flute periods of the meter at the run's ~15 r/min, and
#: before the flow modules' 1 s window can have corrected anything)
CALIBRATION_WINDOW_S = (0.2, 1.7)


def vt_of(result: RunResult) -> dict[str, Any]:
    """The VT's part of a field run's record (``truth.field_run.vt``).

    Raises
    ------
    ValueError
        The run had no VT (its scenario lacks ``[tractor] vt = true``).
    """
    run = (result.record.get("truth") or {}).get("field_run") or {}
    if "vt" not in run:
        raise ValueError(f"{result.out_dir}: the run had no Virtual Terminal ([tractor] vt)")
    return dict(run["vt"])


#: the short run that tells a VT client from an implement without one
PROBE = "isobus-vt-probe"
#: the VT's events that only a VT client's messages make (its connection procedure: get
#: memory first, then the pool or a stored version); a working set master message alone is
#: not one (a TC client sends it too: ISO 11783-7)
VT_CLIENT_EVENTS = frozenset({"memory", "out of memory", "transferred", "activated", "refused",
                              "stored", "store refused", "load refused", "deleted",
                              "out of order"})


def skip_unless_vt_client(hil_run: Any) -> None:
    """Skip (saying why) when the implement never addressed the VT in :data:`PROBE`."""
    vt = vt_of(hil_run(PROBE, label="probe"))     # its own directory beside the test's run
    if not any(e.get("kind") in VT_CLIENT_EVENTS for e in vt.get("events", [])):
        pytest.skip(f"the implement never addressed the tractor's VT in {PROBE} (6 s key "
                    "on: no get memory, no pool, no stored version asked for): no VT "
                    "client, nothing to judge")


def master_releases(vt: dict[str, Any]) -> list[float]:
    """When the operator released the master key, press by press (on, off, ...)."""
    return [float(s["at_s"]) + float(s.get("hold_s", 0.2)) for s in vt.get("operator", [])
            if s.get("press") == MASTER]


def fault_start(result: RunResult, name: str) -> float:
    """When the run's fault ``name`` was injected."""
    for event in result.record.get("events", []) or []:
        if event.get("kind") == "fault" and name in str(event.get("detail", "")):
            return float(event["t"])
    raise ValueError(f"{result.out_dir}: the run's record has no {name} fault")


def rows_sum(result: RunResult, prefix: str, suffix: str) -> tuple[np.ndarray, np.ndarray]:
    """Time and the sum over rows of the traces ``<prefix><row><suffix>`` (row a number:
    ``delivered_total_g`` is not a row)."""
    traces, _ = result.traces()
    names = sorted(k for k in traces if k.startswith(prefix) and k.endswith(suffix)
                   and k[len(prefix):len(k) - len(suffix)].isdigit())
    if not names:
        raise ValueError(f"{result.out_dir}: no {prefix}*{suffix} traces")
    return traces["time_s"], np.sum([traces[k] for k in names], axis=0)


def delivered_between(result: RunResult, t0: float, t1: float) -> float:
    """Grams laid at the openers by all rows in ``[t0, t1)``."""
    t, total = rows_sum(result, "delivered_", "_g")
    if t1 <= t0:
        return 0.0
    return float(np.interp(t1, t, total) - np.interp(t0, t, total))


def operator_run(hil_run: Any) -> tuple[RunResult, dict[str, Any]]:
    skip_unless_vt_client(hil_run)
    result = hil_run("isobus-vt-operator")
    return result, vt_of(result)


# --------------------------------------------------------------------- the operator
def test_vt_connection(hil_run, hil_measure) -> None:
    result, vt = operator_run(hil_run)
    active = [ws for ws in vt.get("working_sets", []) if ws.get("activated_s") is not None]
    refused = [e for e in vt.get("events", []) if e.get("kind") == "refused"]
    note = (f"pool of {active[0]['pool_bytes']:,} bytes ({active[0]['objects']} objects) "
            f"active at {active[0]['activated_s']:.2f} s" if active else
            "the pool never became active on the VT"
            + (f": refused ({refused[0]['detail']})" if refused else ""))
    hil_measure("isobus.vt.connect.time_to_active",
                float(active[0]["activated_s"]) if active else math.inf, run=result, note=note)


def test_vt_nothing_before_master(hil_run, hil_measure) -> None:
    result, vt = operator_run(hil_run)
    presses = master_releases(vt)
    if not presses:
        raise ValueError("isobus-vt-operator presses no Master key")
    until = presses[0] + transport_s(result)
    grams = delivered_between(result, 0.0, until)
    hil_measure("isobus.vt.before_master.delivered", grams, run=result,
                note=f"laid before the operator's Master (released at {presses[0]:g} s) "
                     f"reached the openers ({until:.2f} s)")


def test_vt_master_off(hil_run, hil_measure) -> None:
    result, vt = operator_run(hil_run)
    presses = master_releases(vt)
    if len(presses) < 2:
        raise ValueError("isobus-vt-operator does not press Master twice (on, then off)")
    off = presses[1]
    t, flow = rows_sum(result, "flow_at_meter_", "_gps")
    before = flow[(t >= off - BEFORE_OFF_S) & (t < off)]
    if before.size == 0 or float(before.mean()) <= 0.1:
        raise ValueError(f"isobus-vt-operator: nothing was metered before Master off at "
                         f"{off:g} s: the run cannot judge the stop")
    threshold = STOPPED_FRACTION * float(before.mean())
    after = t >= off
    running = np.flatnonzero(after & (flow > threshold))
    stop = off if running.size == 0 else (float(t[running[-1] + 1])
                                          if running[-1] + 1 < t.size else math.inf)
    hil_measure("isobus.vt.master_off.stop_time", stop - off, run=result,
                note=(f"the meters below {100 * STOPPED_FRACTION:g} % of their "
                      f"{before.mean():.1f} g/s at {stop:.2f} s" if math.isfinite(stop) else
                      f"the meters still at {flow[-1]:.1f} g/s at the end of the run")
                     + f"; Master released at {off:g} s")


def test_vt_alarm_on_row_loss(hil_run, hil_measure) -> None:
    result, vt = operator_run(hil_run)
    lost = fault_start(result, ROW_LOST_FAULT)
    shown = [(t, mask) for t, mask in alarm_masks(vt) if t >= lost]
    hil_measure("isobus.vt.alarm.time_to_shown", shown[0][0] - lost if shown else math.inf,
                run=result,
                note=(f"alarm mask {shown[0][1]} shown at {shown[0][0]:.2f} s" if shown else
                      "no alarm mask was shown")
                     + f"; the row's flow module silent from {lost:g} s")


# --------------------------------------------------------------------- the VT fails
def test_vt_restart(hil_run, hil_measure) -> None:
    skip_unless_vt_client(hil_run)
    result = hil_run("isobus-vt-restart")
    vt = vt_of(result)
    down = [d for d in vt.get("vt_down", []) if d[1] is not None]
    if not down:
        raise ValueError("isobus-vt-restart: the VT never came back (no vt_down cleared)")
    back = float(down[0][1])
    again = [ws for ws in vt.get("working_sets", [])
             if ws.get("activated_s") is not None and float(ws["activated_s"]) >= back]
    hil_measure("isobus.vt.restart.reconnect_time",
                float(again[0]["activated_s"]) - back if again else math.inf, run=result,
                note=(f"pool active again at {again[0]['activated_s']:.2f} s, "
                      + ("loaded from the VT's storage" if again[0].get("loaded_from_storage")
                         else "uploaded again") if again else
                      "the pool never became active again")
                     + f"; the VT back at {back:g} s")
    uploaded = sum(int(ws.get("pool_bytes") or 0) for ws in again
                   if not ws.get("loaded_from_storage"))
    hil_measure("isobus.vt.restart.uploaded_bytes", uploaded, run=result,
                note=("no activation after the VT came back" if not again else
                      f"{len(again)} activation(s) after the VT came back"))


# --------------------------------------------------------------------- the calibration
def test_vt_calibration(hil_run, hil_measure) -> None:
    skip_unless_vt_client(hil_run)
    result = hil_run("isobus-vt-calibration")
    vt = vt_of(result)
    entered = [s for s in vt.get("operator", []) if "enter" in s]
    presses = master_releases(vt)
    if not entered or not presses:
        raise ValueError("isobus-vt-calibration enters no calibration or presses no Master")
    traces, _ = result.traces()
    t, flow = rows_sum(result, "flow_at_meter_", "_gps")
    rows = sum(1 for k in traces if k.startswith("flow_at_meter_"))
    # what the openers need when this flow reaches them (the map's rate under them then)
    target = rows * np.interp(t + transport_s(result), t, traces["target_flow_row_gps"])
    start, end = presses[0] + CALIBRATION_WINDOW_S[0], presses[0] + CALIBRATION_WINDOW_S[1]
    window = (t >= start) & (t < end)
    asked = float(target[window].mean()) if window.any() else 0.0
    if asked <= 0.0:
        raise ValueError(f"isobus-vt-calibration: the map asks nothing from {start:g} s to "
                         f"{end:g} s: the run cannot judge the calibration")
    metered = float(flow[window].mean())
    hil_measure("isobus.vt.calibration.initial_error", 100.0 * abs(metered / asked - 1.0),
                run=result,
                note=f"{metered:.1f} g/s metered for {asked:.1f} g/s from {start:.1f} to "
                     f"{end:.1f} s; entered on the VT: "
                     + ", ".join(f"{s['value']:g} into {s['enter']}" for s in entered))
