"""Application-map metrics: each passes a good synthetic run and fails the bad one it names."""

from __future__ import annotations

import doctest
import math

import numpy as np
import pytest

from hil.metrics import application_map
from hil.metrics.application_map import (
    after_rate_change,
    cell_accuracy,
    grid_cells,
    section_switching,
    transition_distances,
)

# one straight 120 m run of 2 sections (0.75 m each), a sample every 0.1 m; zones along it
D = np.arange(0.0, 120.0, 0.1)
DIST = np.column_stack([D, D])
ZONE = np.where(D < 40.0, 0, np.where(D < 80.0, 1, 2))
RATES = np.array([160.0, 240.0, 200.0])
PRESCRIBED = np.column_stack([RATES[ZONE], RATES[ZONE]])
CELLS = np.column_stack([ZONE, ZONE])
ON = np.ones_like(DIST, dtype=bool)
WIDTHS = [0.75, 0.75]
LIMIT_PCT = 5.0          # the kind of limit a suite sets: within 5 % of the prescription
LIMIT_M = 3.0            # ... settled within 3 m of a boundary
SWITCH_LIMIT_M = 0.5     # ... sections switched within 0.5 m


def _lagged(target: np.ndarray, lag_m: float) -> np.ndarray:
    """A first-order lag in distance: what a rate controller with a lag of ``lag_m`` applies."""
    out = np.empty_like(target)
    out[0] = target[0]
    alpha = 1.0 - math.exp(-0.1 / lag_m)
    for k in range(1, target.shape[0]):
        out[k] = out[k - 1] + alpha * (target[k] - out[k - 1])
    return out


# ------------------------------------------------------------------------- cell accuracy ---

def test_cell_accuracy_hand_computed() -> None:
    # cell 0: 1 m at 100 and 3 m at 200 applied against 150 prescribed: 175 vs 150 -> +16.7 %
    d = np.array([0.0, 1.0, 4.0, 5.0])
    r = cell_accuracy([0, 0, 1, 1], d, [1.0], [True, True, True, False],
                      [100.0, 200.0, 150.0, 0.0], [150.0, 150.0, 150.0, 150.0])
    assert [c.cell for c in r.cells] == [0, 1]
    assert r.cells[0].applied == pytest.approx(175.0)
    assert r.cells[0].error_pct == pytest.approx(100.0 / 6.0)
    assert r.cells[1].area_m2 == pytest.approx(1.0) and r.cells[1].error_pct == 0.0
    assert r.worst_abs_error_pct == pytest.approx(100.0 / 6.0)
    assert r.mean_abs_error_pct == pytest.approx(100.0 / 6.0 * 4.0 / 5.0)


def test_a_controller_that_follows_the_map_passes() -> None:
    rng = np.random.default_rng(3)
    applied = _lagged(PRESCRIBED, 0.5) * (1.0 + 0.01 * rng.standard_normal(PRESCRIBED.shape))
    r = cell_accuracy(CELLS, DIST, WIDTHS, ON, applied, PRESCRIBED,
                      exclude=after_rate_change(DIST, PRESCRIBED, 3.0))
    assert len(r.cells) == 3 and r.worst_abs_error_pct < 1.0 < LIMIT_PCT


def test_a_controller_that_ignores_the_map_fails() -> None:
    applied = np.full_like(PRESCRIBED, 200.0)
    r = cell_accuracy(CELLS, DIST, WIDTHS, ON, applied, PRESCRIBED)
    assert r.worst_abs_error_pct == pytest.approx(25.0, abs=0.1)   # 200 vs 160
    assert r.worst_abs_error_pct > LIMIT_PCT
    assert [round(c.error_pct, 1) for c in r.cells] == [25.0, -16.7, 0.0]


def test_cells_outside_the_prescription_and_slivers() -> None:
    pres = PRESCRIBED.copy()
    pres[ZONE == 2] = 0.0
    r = cell_accuracy(CELLS, DIST, WIDTHS, ON, PRESCRIBED, pres)
    assert len(r.cells) == 2 and r.unprescribed_area_m2 == pytest.approx(2 * 0.75 * 40.0, 0.01)
    r = cell_accuracy(CELLS, DIST, WIDTHS, ON, PRESCRIBED, PRESCRIBED, min_area_m2=100.0)
    assert r.cells == () and math.isnan(r.worst_abs_error_pct)


def test_grid_cells_and_settling_mask() -> None:
    ids = grid_cells([0.5, 4.9, 5.1, -0.1, 0.5], [0.5, 0.5, 0.5, 0.5, 5.5], 5.0)
    assert ids[0] == ids[1] and len(set(ids.tolist())) == 4
    mask = after_rate_change(DIST, PRESCRIBED, 3.0)
    assert mask[:, 0].sum() == 2 * 30          # 3 m after each of the two changes


def test_cell_accuracy_refuses_mismatched_arrays() -> None:
    with pytest.raises(ValueError, match="shapes differ"):
        cell_accuracy(CELLS, DIST[:-1], WIDTHS, ON, PRESCRIBED, PRESCRIBED)
    with pytest.raises(ValueError, match="width_m"):
        cell_accuracy(CELLS, DIST, [0.75], ON, PRESCRIBED, PRESCRIBED)
    with pytest.raises(ValueError, match="must not decrease"):
        cell_accuracy(CELLS, DIST[::-1], WIDTHS, ON, PRESCRIBED, PRESCRIBED)


# ------------------------------------------------------------------------- transitions ----

def test_transition_distance_of_a_first_order_lag() -> None:
    # a lag of 1 m: within 5 % of the new rate after ln(|Δ| / (0.05 new)) m
    r = transition_distances(DIST, ON, _lagged(PRESCRIBED, 1.0), PRESCRIBED)
    assert len(r.transitions) == 4
    first = r.transitions[0]
    assert (first.section, first.from_rate, first.to_rate) == (0, 160.0, 240.0)
    assert first.at_m == pytest.approx(40.0)
    assert first.distance_m == pytest.approx(math.log(80.0 / 12.0), abs=0.1)
    assert r.worst_m < LIMIT_M


def test_a_slow_controller_fails_the_transition_limit() -> None:
    r = transition_distances(DIST, ON, _lagged(PRESCRIBED, 2.0), PRESCRIBED)
    assert r.worst_m > LIMIT_M
    assert r.worst_m == pytest.approx(2.0 * math.log(80.0 / 12.0), abs=0.2)


def test_a_controller_that_ignores_the_map_never_settles() -> None:
    r = transition_distances(DIST, ON, np.full_like(PRESCRIBED, 200.0), PRESCRIBED)
    # 200 is within 5 % of neither 240 nor... it is exactly the third zone's rate
    assert [t.distance_m for t in r.transitions[:2]] == [math.inf, 0.0]
    assert r.worst_m == math.inf


def test_a_transition_must_stay_in_the_band() -> None:
    applied = PRESCRIBED.copy()
    applied[(D > 45.0) & (D < 46.0)] = 300.0          # a spike 5 m after the boundary
    r = transition_distances(DIST, ON, applied, PRESCRIBED)
    assert r.transitions[0].distance_m == pytest.approx(6.0, abs=0.11)


def test_leaving_the_band_just_before_the_next_boundary_is_not_this_transition() -> None:
    # the next change anticipated by 0.3 m (a look-ahead): the first transition is unchanged
    applied = np.column_stack([RATES[np.where(D < 40.0, 0, np.where(D < 79.7, 1, 2))]] * 2)
    r = transition_distances(DIST, ON, applied, PRESCRIBED)
    assert r.transitions[0].distance_m == 0.0
    assert r.transitions[2].distance_m == 0.0


def test_boundaries_crossed_while_off_or_by_small_steps_are_not_judged() -> None:
    on = ON.copy()
    on[(D > 38.0) & (D < 42.0), 1] = False
    pres = PRESCRIBED.copy()
    pres[D >= 80.0] = 241.0                           # +0.4 %: below min_step_pct
    r = transition_distances(DIST, on, pres, pres)
    assert [(t.section, t.at_m) for t in r.transitions] == [(0, pytest.approx(40.0))]
    assert transition_distances(DIST, ~ON, PRESCRIBED, PRESCRIBED).transitions == ()
    assert math.isnan(transition_distances(DIST, ~ON, PRESCRIBED, PRESCRIBED).worst_m)


# ------------------------------------------------------------------------- sections ------

# a pass: work area from 10 m to 110 m (headlands); the second section's half of 50..70 m was
# covered by an earlier pass
INSIDE = np.column_stack([(D >= 10.0) & (D < 110.0)] * 2)
NEEDED = INSIDE.copy()
NEEDED[(D >= 50.0) & (D < 70.0), 1] = False


def test_ideal_switching_passes() -> None:
    r = section_switching(DIST, NEEDED, NEEDED, inside_work_area=INSIDE)
    assert (r.overlap_m, r.skip_m, r.worst_error_m, r.spurious_switches) == (0.0, 0.0, 0.0, 0)
    kinds = sorted((e.section, e.kind, e.direction) for e in r.events)
    assert kinds == [(0, "headland", "off"), (0, "headland", "on"),
                     (1, "coverage", "off"), (1, "coverage", "on"),
                     (1, "headland", "off"), (1, "headland", "on")]


def test_never_switching_sections_fails() -> None:
    r = section_switching(DIST, ON, NEEDED, inside_work_area=INSIDE)
    # 2 sections x 2 headlands of 10 m (the last sample holds no distance) + 20 m overlap
    assert r.overlap_m == pytest.approx(2 * 2 * 10.0 + 20.0 - 2 * 0.1)
    assert r.worst_error_m == math.inf and r.coverage_overlap_m == math.inf
    # on all along: every "on" came far too early, every "off" never; all of it overlap
    assert {(e.direction, e.error_m) for e in r.events} == {("on", -math.inf),
                                                            ("off", math.inf)}
    assert r.headland_skip_m == 0.0 and r.coverage_skip_m == 0.0
    assert r.overlap_m > SWITCH_LIMIT_M


def test_late_switching_fails_with_the_lateness_as_error() -> None:
    late = np.vstack([np.zeros((10, 2), dtype=bool), NEEDED[:-10]])   # 1 m late
    r = section_switching(DIST, late, NEEDED, inside_work_area=INSIDE)
    assert r.worst_error_m == pytest.approx(1.0)
    assert r.worst_error_m > SWITCH_LIMIT_M
    assert all(e.error_m == pytest.approx(1.0) for e in r.events)
    assert r.headland_skip_m == pytest.approx(2.0) and r.headland_overlap_m == pytest.approx(2.0)
    assert r.coverage_skip_m == pytest.approx(1.0) and r.coverage_overlap_m == pytest.approx(1.0)
    assert r.overlap_m == pytest.approx(3.0, abs=0.01) and r.skip_m == pytest.approx(3.0, abs=0.01)


def test_early_switching_is_a_negative_error_and_extra_switches_are_spurious() -> None:
    early = np.vstack([NEEDED[5:], np.zeros((5, 2), dtype=bool)])     # 0.5 m early
    flicker = early.copy()
    flicker[300:302, 0] = ~flicker[300:302, 0]
    r = section_switching(DIST, flicker, NEEDED)
    assert all(e.error_m == pytest.approx(-0.5) and e.kind == "coverage" for e in r.events)
    assert r.spurious_switches == 2


def test_sections_that_never_switch_on_skip() -> None:
    r = section_switching(DIST, ~ON, NEEDED, inside_work_area=INSIDE)
    assert {(e.direction, e.error_m) for e in r.events} == {("on", math.inf),
                                                            ("off", -math.inf)}
    assert r.headland_skip_m == math.inf and r.headland_overlap_m == 0.0
    assert r.skip_m == pytest.approx(100.0 + 80.0, abs=0.11) and r.overlap_m == 0.0


def test_docstring_example() -> None:
    assert doctest.testmod(application_map).failed == 0


def test_a_held_transition_ends_where_the_rate_enters_the_band_for_good_enough() -> None:
    d = np.arange(0.0, 30.0, 0.5)
    p = np.where(d < 10.0, 100.0, 200.0)
    a = p.copy()
    a[(d >= 10.0) & (d < 13.0)] = 150.0           # 3 m to reach the new rate
    a[(d >= 20.0) & (d < 20.5)] = 180.0           # one noisy sample later on
    on = np.ones_like(d, dtype=bool)
    strict = transition_distances(d, on, a, p)
    held = transition_distances(d, on, a, p, hold_m=2.0)
    assert strict.worst_m == pytest.approx(10.5)   # stays in the band only after the blip
    assert held.worst_m == pytest.approx(3.0)
    never = transition_distances(d, on, np.where(d < 10.0, 100.0, 150.0), p, hold_m=2.0)
    assert never.worst_m == math.inf
