"""Cross-row plausibility: a flow module that disagrees with the other rows is left out.

The rows of the meter are driven by one shaft through identical rollers, so their flows agree
within the rig's roller spread, and their modules read them within their calibration spread
and noise. A module whose number leaves that band while its status bits stay good (frozen at a
mid-range reading, a sensitivity step, a drift) cannot be told by its own report: only by the
other rows. Each control step the rows that passed the single-row checks are compared with
their median; a row farther from it than ``THRESHOLD_FRAC`` of the median plus ``FLOOR_GPS``
for ``DWELL_S`` (net of the steps it agrees) is excluded from the mean, and readmitted once it
has agreed for as long again. With fewer than ``MIN_ROWS`` rows to compare nothing is excluded
(two rows that disagree cannot say which one is wrong).

Where the numbers come from: the shipped dispersion (plant_emulators/fertilizer/dispersion.toml)
at its widest, roller spread 2.5 % SD (drawn about the rows' mean) and module calibration
spread 0.8 % SD (truncated at 2 SD), on rig.toml's flute charge (4 % per flute), transit jitter
(2.5 %) and baseline wander; measured with the reference on every nominal bench and field
scenario (steps, constant speeds, 4 and 8 km/h, headland, stop-go, rows switched off and on):

* ``THRESHOLD_FRAC`` = 12 %: how far a healthy row stays from the median for 3 s on end, beyond
  the 1 g/s floor: at most 6.7 % over 30 seeds x 13 scenarios with sliding reports, 5.7 % over
  12 seeds x 7 scenarios in [F]'s block mode. Most of it is the row's roller and module (a
  fixed offset; the windows' noise, ~3 % SD a report, averages out over 3 s); 30 seeds give
  120 rows (the largest ~2.6 SD), 300 dispersed samples 1,200 (~3.3 SD): ~8 %. 12 % leaves
  half as much again. The faults read 40 % (stuck at 60 %), 30 % (gain step) and, at 2 %/s,
  beyond 12 % + 1 g/s (15 % at 34 g/s) 7.5 s after the drift starts.
* ``FLOOR_GPS`` = 1 g/s: near a stopped or starting meter the median is near 0, and the
  modules' baseline wander (0.05 fF SD x 18.655 g/pF x 90 conversions a window = 0.08 g) and
  the frame's vibration move a report by tenths of a g/s: a relative band alone would exclude
  rows at a standstill.
* ``DWELL_S`` = 3 s: a healthy row leaves the band for longer than its noise only while its
  module reports a change later than the others: a window and a report period, 2 s in block
  mode (the start, a step, a row switched back on that still reads its stopped roller). Over
  2 s such a row was 13.8 % off the median (field-rows-blocked, block mode), over 3 s 4.4 %.

Not one healthy row was excluded in any of those runs. A row counts up on each step it
disagrees and down on each step it agrees, so the dwell is net: a stuck row is out 3 s after it
freezes, and back 3 s after it reads right again.
"""

from __future__ import annotations

THRESHOLD_FRAC = 0.12
FLOOR_GPS = 1.0
DWELL_S = 3.0
MIN_ROWS = 3


def median(values: list[float]) -> float:
    """The median of ``values`` (not empty): the middle one, or the mean of the middle two,
    ``(a + b) / 2`` as the C build computes it."""
    ordered = sorted(values)
    n = len(ordered)
    mid = n // 2
    return ordered[mid] if n % 2 else (ordered[mid - 1] + ordered[mid]) / 2.0


class CrossRowCheck:
    """Per row, a count of control steps in disagreement with the other rows, up on each step
    it disagrees and down on each step it agrees (between 0 and the dwell): a row is excluded
    when its count reaches the dwell and readmitted when it is back at 0, so a single noisy
    report neither excludes a healthy row nor readmits a faulty one."""

    def __init__(self, period_s: float) -> None:
        #: ``DWELL_S`` in whole control steps
        self.dwell_steps = max(1, round(DWELL_S / period_s))
        self.count: dict[int, int] = {}
        self.out: set[int] = set()

    def excluded(self, flows: dict[int, float]) -> set[int]:
        """The rows of ``flows`` (row -> reported g/s, the rows that passed the single-row
        checks this step) to leave out of the mean. A row not in ``flows`` starts afresh."""
        for row in list(self.count):
            if row not in flows or len(flows) < MIN_ROWS:
                del self.count[row]
                self.out.discard(row)
        if len(flows) < MIN_ROWS:
            return set()
        med = median(list(flows.values()))
        band = THRESHOLD_FRAC * med + FLOOR_GPS
        for row, flow in flows.items():
            count = self.count.get(row, 0)
            if abs(flow - med) > band:
                count = min(count + 1, self.dwell_steps)
            else:
                count = max(count - 1, 0)
            self.count[row] = count
            if count == self.dwell_steps:
                self.out.add(row)
            elif count == 0:
                self.out.discard(row)
        return set(self.out)
