"""The flow modules as the controller sees them: each row's latest report and its validity.

Section 1, "CAN adapter", of the contract: a row is valid when its latest report has
BaselineReady = 1, AdcOverrange = 0, arrived within ``stale_after_s`` and its Flow is
plausible, ``Flow <= 3·Q + 5`` g/s, and it agrees with the other valid rows (the cross-row
check of :mod:`reference_controllers.fertilizer.cross_row`). The core gets the mean flow of
the valid rows, whether any row is valid, and whether a valid row reported since the previous
step.

Time is counted in control steps (the controller's own clock, as a firmware's tick counter):
a report that arrives between step n-1 and step n is 0 s old at step n.
"""

from __future__ import annotations

from dataclasses import dataclass

from reference_controllers.fertilizer.cross_row import CrossRowCheck


@dataclass
class RowReport:
    flow_gps: float
    baseline_ready: bool
    overrange: bool
    arrived_step: int
    fresh: bool = True


@dataclass(frozen=True)
class Measurement:
    """What the core gets from the sensors at one step."""

    measured_gps: float
    has_measurement: bool
    new_report: bool
    valid_rows: int


class FlowRows:
    """Latest report per row; :meth:`measure` evaluates validity and clears the fresh flags."""

    def __init__(self, stale_after_s: float, period_s: float) -> None:
        self.stale_after_steps = stale_after_s / period_s
        self.reports: dict[int, RowReport] = {}
        self.cross_row: CrossRowCheck | None = CrossRowCheck(period_s)
        #: the rows the cross-row check left out at the last step
        self.excluded: set[int] = set()

    def report(self, row: int, flow_gps: float, baseline_ready: bool, overrange: bool,
               step: int) -> None:
        """A FlowModule frame of ``row`` arrived before step ``step``."""
        self.reports[row] = RowReport(flow_gps, baseline_ready, overrange, step)

    def valid(self, r: RowReport, target_gps: float, step: int) -> bool:
        return (r.baseline_ready and not r.overrange
                and step - r.arrived_step <= self.stale_after_steps + 1e-9
                and r.flow_gps <= 3.0 * target_gps + 5.0)

    def measure(self, target_gps: float, step: int,
                active_rows: int | None = None) -> Measurement:
        """The core's sensor inputs at step ``step`` (rows in ascending order). With
        ``active_rows`` = N (FertSetpoint.ActiveRows) only rows 1..N count: the others'
        clutches are out and their modules read the 0 g/s of a stopped roller. Of the rows
        that pass :meth:`valid`, those the cross-row check excludes do not count either."""
        passed = [(row, r) for row, r in sorted(self.reports.items())
                  if (active_rows is None or row <= active_rows)
                  and self.valid(r, target_gps, step)]
        self.excluded = (self.cross_row.excluded({row: r.flow_gps for row, r in passed})
                         if self.cross_row is not None else set())
        total = 0.0
        count = 0
        new = False
        for row, r in passed:
            if row not in self.excluded:
                total += r.flow_gps
                count += 1
                new = new or r.fresh
        for r in self.reports.values():
            r.fresh = False
        mean = total / count if count else 0.0
        return Measurement(mean, count > 0, new, count)
