"""The cross-row plausibility check (reference_controllers/fertilizer/cross_row.py): a row that
disagrees with the others for the dwell is left out and comes back once it agrees as long; a
healthy spread, a short transient and a pair of rows are left alone. The C build
(firmware/core/cross_row.c) runs the same cases in firmware/tests/test_cross_row.c, and the
RC-400 and ISOBUS vectors hold the two builds to the same frames."""

from __future__ import annotations

from reference_controllers.fertilizer.cross_row import (
    DWELL_S,
    CrossRowCheck,
    median,
)
from reference_controllers.fertilizer.rows import FlowRows

PERIOD_S = 0.1
DWELL = round(DWELL_S / PERIOD_S)


def test_median_is_the_middle_or_the_mean_of_the_middle_two() -> None:
    assert median([3.0, 1.0, 2.0]) == 2.0
    assert median([4.0, 1.0, 3.0, 2.0]) == 2.5


def test_a_stuck_row_is_excluded_after_the_dwell_and_readmitted_after_as_long() -> None:
    check = CrossRowCheck(PERIOD_S)
    stuck = {1: 34.0, 2: 20.4, 3: 33.5, 4: 34.6}
    for _ in range(DWELL - 1):
        assert check.excluded(stuck) == set()
    assert check.excluded(stuck) == {2}
    healthy = {1: 34.0, 2: 33.8, 3: 33.5, 4: 34.6}
    for _ in range(DWELL - 1):
        assert check.excluded(healthy) == {2}
    assert check.excluded(healthy) == set()


def test_a_healthy_spread_and_a_short_transient_are_not_excluded() -> None:
    check = CrossRowCheck(PERIOD_S)
    spread = {1: 34.0 * 1.08, 2: 34.0 * 0.95, 3: 34.0, 4: 34.0 * 0.97}   # 8 % off: inside
    lagging = {1: 34.0, 2: 23.0, 3: 34.0, 4: 34.0}    # a module one step behind, 2 s
    for _ in range(5 * DWELL):
        assert check.excluded(spread) == set()
    for _ in range(DWELL - 1):
        assert check.excluded(lagging) == set()
    assert check.excluded(spread) == set()


def test_noise_that_agrees_as_often_as_not_keeps_a_row_in() -> None:
    check = CrossRowCheck(PERIOD_S)
    far, near = {1: 34.0, 2: 45.0, 3: 34.0}, {1: 34.0, 2: 35.0, 3: 34.0}
    for k in range(10 * DWELL):
        assert check.excluded(far if k % 2 else near) == set()


def test_two_rows_or_a_standstill_exclude_nothing() -> None:
    check = CrossRowCheck(PERIOD_S)
    for _ in range(2 * DWELL):
        assert check.excluded({1: 34.0, 2: 10.0}) == set()
        assert check.excluded({1: 0.3, 2: 0.0, 3: 0.9, 4: 0.1}) == set()


def test_a_row_that_drops_out_starts_afresh() -> None:
    check = CrossRowCheck(PERIOD_S)
    stuck = {1: 34.0, 2: 20.4, 3: 33.5, 4: 34.6}
    for _ in range(DWELL):
        check.excluded(stuck)
    assert check.excluded({1: 34.0, 3: 33.5, 4: 34.6}) == set()
    for _ in range(DWELL - 1):
        assert check.excluded(stuck) == set()
    assert check.excluded(stuck) == {2}


def test_flow_rows_leave_the_excluded_row_out_of_the_mean() -> None:
    rows = FlowRows(stale_after_s=2.5, period_s=PERIOD_S)
    flows = {1: 34.0, 2: 20.4, 3: 33.0, 4: 35.0}
    for step in range(DWELL + 1):
        for row, flow in flows.items():
            rows.report(row, flow, True, False, step)
        m = rows.measure(34.0, step)
    assert rows.excluded == {2}
    assert m.valid_rows == 3 and m.measured_gps == (34.0 + 33.0 + 35.0) / 3
    # without the check (the must-fail variant) the stuck row is averaged in
    rows.cross_row = None
    rows.report(1, 34.0, True, False, DWELL + 1)
    assert rows.measure(34.0, DWELL + 1).measured_gps == sum(flows.values()) / 4
