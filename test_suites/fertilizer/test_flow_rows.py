"""Switched rows: what each row laid while the terminal had it on.

The terminal's FertSetpoint.ActiveRows = N says that rows 1..N share the total target (eq. 1's
``0.1·M·D·v / N`` each) and the rig takes the others' clutches out (their rollers stand and
their flow modules read 0). Two field runs switch rows: a headland section pattern (rows off
one by one down to row 1 alone, the working width following them, and back on) and a blocked
row (row 4 off for 20 s, the width kept: three rows share the whole target). Each row's mass
laid while it is on is judged against its share of the target there (the metering rows'
total split by their rollers' gains, the meter's own spread, which no controller governs;
[F] eq. 15,
``flow.rows.applied_accuracy``, condition ``row``), with :func:`hil.metrics.rows.applied_per_row`,
the function the ISOBUS suite's section control shares.

A controller that averages the stopped rows' modules into its measured flow over-meters the
rows left (2x with half the rows off); one that divides the target by all the rows whatever
ActiveRows says under-meters them when the width is kept.
"""

from __future__ import annotations

import numpy as np
import pytest

from hil.metrics.rows import RowsApplied, applied_per_row
from hil.rig import RunResult
from test_suites.fertilizer.traces import transport_s

pytestmark = [pytest.mark.hil_rig("fertilizer"), pytest.mark.hil_suite("robustness")]

ROW_SCENARIOS = ("field-rows-headland", "field-rows-blocked")


def rows_applied(result: RunResult) -> RowsApplied:
    """Per row, what it laid while its clutch was in (the terminal's ActiveRows) against its
    target there: the traced per-row target (0 with the clutch out) and delivered mass."""
    traces, _ = result.traces()
    rows = len(result.record["truth"]["delivered_g"])
    on = np.column_stack([traces[f"clutch_{r + 1}"] > 0.5 for r in range(rows)])
    target = np.where(on, traces["target_flow_row_gps"][:, None], 0.0)
    delivered = np.column_stack([traces[f"delivered_{r + 1}_g"] for r in range(rows)])
    return applied_per_row(traces["time_s"], delivered, target, on,
                           transport_s=transport_s(result),
                           row_gain=np.asarray(result.record["truth"]["row_gain"]))


@pytest.mark.parametrize("scenario", ROW_SCENARIOS)
def test_switched_rows(hil_run, hil_measure, scenario: str) -> None:
    result = hil_run(scenario)
    applied = rows_applied(result)
    for row, accuracy in enumerate(applied.accuracy_pct, start=1):
        hil_measure("flow.rows.applied_accuracy", accuracy,
                    conditions={"row": row, "scenario": scenario}, run=result,
                    note=f"laid {applied.laid_g[row - 1]:.1f} g of "
                         f"{applied.target_g[row - 1]:.1f} g over {applied.on_s[row - 1]:.1f} s "
                         f"on; {applied.off_delivery_g[row - 1]:.2f} g over "
                         f"{applied.off_s[row - 1]:.1f} s off (clutch out)")
