"""The piecewise PID core of [F] (eq. 11-13) against hand-computed answers (contract section 1)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from reference_controllers.fertilizer.piecewise_pid import (
    OpenLoop,
    PiecewisePid,
    PiecewisePidParams,
    feedforward_volts,
    segment_of,
)
from reference_controllers.params import ParamError, override

PAPER = PiecewisePidParams.paper_literal()
# explicit gains, so these tests do not move when the tuned defaults do
# (no settle gate, and a first-update integral gain equal to the medium band's, so that the
# band arithmetic below is the plain law; the gate and the learning have tests of their own)
PHYS = PiecewisePidParams(mode="physical", kp1=0.1, kp2=0.2, kp3=0.3, ki1=0.4, ki2=0.5,
                          kd=0.6, e1=0.02, e2=0.10, settle_periods=0.0, ki_first=0.5)


def ff(q: float) -> float:
    return (q / 4.586) ** (1.0 / 0.6537) / 6.0


def test_feedforward_inverts_the_meter_map_and_clamps() -> None:
    assert feedforward_volts(23.0, PAPER) == pytest.approx(1.96393, abs=1e-5)   # 11.78 r/min
    assert feedforward_volts(23.0, PAPER) == pytest.approx(ff(23.0), rel=1e-15)
    assert feedforward_volts(0.0, PAPER) == 0.0
    assert feedforward_volts(-3.0, PAPER) == 0.0
    assert feedforward_volts(500.0, PAPER) == 10.0                 # beyond 60 r/min: v_max


@pytest.mark.parametrize(("abs_error", "segment"), [
    (0.0, 1), (0.999, 1), (1.0, 2), (4.999, 2), (5.0, 3), (50.0, 3)])
def test_segment_boundaries_belong_to_the_upper_band(abs_error: float, segment: int) -> None:
    assert segment_of(abs_error, 1.0, 5.0) == segment


def test_paper_literal_first_update_has_no_derivative_kick() -> None:
    pid = PiecewisePid(PAPER)
    volts, segment = pid.step(23.0, 20.0, True, True)      # e = 3: medium, Δu = Ki2·e
    assert segment == 2
    assert volts == pytest.approx(0.1 * 0.015 * 3.0, abs=1e-15)


def test_paper_literal_increment_and_clamp() -> None:
    pid = PiecewisePid(PAPER)
    assert pid.step(23.0, 13.0, True, True) == (0.0, 3)    # e = 10, coarse, Ki = 0: Δu = 0
    assert pid.step(23.0, 15.0, True, True) == (0.0, 3)    # Δu = 212.016·(-2) + … < 0: u = 0
    volts, segment = pid.step(23.0, 11.0, True, True)      # e = 12
    du = 212.016 * (12 - 8) + 1.317 * (12 - 2 * 8 + 10)   # 855.966 > v_max / km = 100
    assert du > 100 and (volts, segment) == (10.0, 3)
    # one more: Δu from the clamped state, not from the unclamped sum (anti-windup)
    volts, _ = pid.step(23.0, 22.5, True, True)            # e = 0.5: fine
    du = 0.038 * (0.5 - 12) + 0.167 * 0.5 + 1.317 * (0.5 - 2 * 12 + 8)
    assert volts == pytest.approx(0.1 * (100.0 + du), abs=1e-12)


def test_state_holds_between_reports_and_without_measurement() -> None:
    pid = PiecewisePid(PAPER)
    first = pid.step(23.0, 20.0, True, True)
    assert pid.step(23.0, 5.0, True, False) == first        # no new report
    assert pid.step(23.0, 5.0, False, True) == first        # a report but no valid row
    assert pid.step(30.0, 5.0, False, False) == first       # paper-literal: no feedforward


def test_target_zero_resets_everything() -> None:
    pid = PiecewisePid(PAPER)
    pid.step(23.0, 20.0, True, True)
    pid.step(23.0, 21.0, True, True)
    assert pid.step(0.0, 21.0, True, True) == (0.0, 0)
    assert pid.step(23.0, 0.0, True, False) == (0.0, 0)     # no update yet: segment 0
    volts, segment = pid.step(23.0, 20.0, True, True)       # as from scratch
    assert (volts, segment) == (pytest.approx(0.0045, abs=1e-15), 2)


def test_physical_update_position_form_with_integral() -> None:
    pid = PiecewisePid(PHYS)
    q = 23.0
    p1 = q * (1 - 0.05)                                     # r = 0.05: medium
    volts, segment = pid.step(q, p1, True, True)
    r1 = (q - p1) / q
    i1 = 0.5 * r1
    c1 = 0.2 * r1 + i1                                      # first update: r_prev = r
    assert segment == 2
    assert volts == pytest.approx(ff(q) * (1 + c1), rel=1e-14)
    p2 = q * (1 - 0.01)                                     # r = 0.01: fine
    volts, segment = pid.step(q, p2, True, True)
    r2 = (q - p2) / q
    i2 = i1 + 0.4 * r2
    c2 = 0.1 * r2 + i2 + 0.6 * (r2 - r1)
    assert segment == 1
    assert volts == pytest.approx(ff(q) * (1 + c2), rel=1e-14)
    # between reports the correction is held
    volts, segment = pid.step(q, 0.0, True, False)
    assert (volts, segment) == (pytest.approx(ff(q) * (1 + c2), rel=1e-14), 1)
    # a target jump acts through the feedforward at once and keeps only I
    volts, segment = pid.step(34.0, 0.0, True, False)
    assert (volts, segment) == (pytest.approx(ff(34.0) * (1 + i2), rel=1e-14), 1)


def test_physical_coarse_band_has_no_integral_and_leaves_no_frozen_step() -> None:
    pid = PiecewisePid(dataclasses.replace(PHYS, ki_first=0.0))
    q = 30.0
    pid.step(q, q * 0.5, True, True)                        # r = 0.5: coarse, c = Kp3·r
    assert pid.integral == 0.0 and pid.correction == pytest.approx(0.15)
    volts, segment = pid.step(q, q, True, True)             # r = 0: the P kick is gone
    assert segment == 1
    assert pid.correction == pytest.approx(0.6 * (0.0 - 0.5))   # only D remains: -0.3
    volts, _ = pid.step(q, q, True, True)
    assert volts == pytest.approx(ff(q), rel=1e-14)         # c = 0: feedforward alone


def test_physical_clamps_integral_correction_and_volts() -> None:
    pid = PiecewisePid(PHYS)
    q = 30.0
    for _ in range(40):                                     # r = 0.08 forever: I winds up …
        pid.step(q, q * 0.92, True, True)
    assert pid.integral == 0.5 and pid.correction == 0.5    # … to c_max and no further
    for _ in range(3):                                      # and unwinds at once
        pid.step(q, q * 1.08, True, True)
    assert pid.integral == pytest.approx(0.5 - 3 * 0.5 * 0.08)


def test_physical_does_not_wind_up_against_the_output_limit() -> None:
    pid = PiecewisePid(PHYS)
    q = 60.0                                                # ff(60) = 8.5 V
    volts = 0.0
    for _ in range(40):                                     # r = 0.08 forever
        volts, _ = pid.step(q, q * 0.92, True, True)
    assert volts == 10.0                                    # the command sits at v_max …
    # … and I stopped growing once it got there (never to c_max)
    assert pid.integral < 10.0 / ff(q) - 1.0 + 0.5 * 0.08 + 1e-12
    for _ in range(3):                                      # and unwinds at once
        before = pid.integral
        pid.step(q, q * 1.08, True, True)
        assert pid.integral == pytest.approx(before - 0.5 * 0.08)


def test_physical_ignores_reports_for_settle_periods_after_a_jump() -> None:
    params = dataclasses.replace(PHYS, settle_periods=3.0, ki_first=0.8)
    pid = PiecewisePid(params)
    for _ in range(3):                                      # windows still hold the old flow
        volts, segment = pid.step(23.0, 2.0, True, True)
        assert (volts, segment) == (pytest.approx(ff(23.0), rel=1e-14), 0)
    volts, _ = pid.step(23.0, 23.0 * 0.96, True, True)      # r = 0.04, the first clean report
    assert pid.integral == pytest.approx(0.8 * 0.04)        # learns the meter factor
    assert volts == pytest.approx(ff(23.0) * (1 + 0.2 * 0.04 + 0.8 * 0.04), rel=1e-12)
    # a jump of the target keeps I (the meter factor), drops P and D, and waits again
    volts, _ = pid.step(44.0, 23.0, True, True)
    assert pid.correction == pid.integral
    assert volts == pytest.approx(ff(44.0) * (1 + 0.8 * 0.04), rel=1e-12)
    # a slow change (at most e2 per period, as speed changes in the field) is no jump
    pid.step(44.0, 44.0, True, True)
    pid.step(44.0, 44.0, True, True)
    pid.step(44.0, 44.0, True, True)
    assert pid.since_jump == 3
    pid.step(44.0 * 1.05, 44.0, True, True)
    assert pid.since_jump == 4


def test_open_loop_ignores_the_sensor() -> None:
    law = OpenLoop(PHYS)
    assert law.step(23.0, 999.0, True, True) == (feedforward_volts(23.0, PHYS), 0)
    assert law.step(0.0, 999.0, True, True) == (0.0, 0)


def test_parameters_check_and_override() -> None:
    with pytest.raises(ValueError, match="mode"):
        PiecewisePidParams(mode="pid", kp1=0, kp2=0, kp3=0, ki1=0, ki2=0, kd=0, e1=1, e2=2)
    with pytest.raises(ValueError, match="e1 < e2"):
        override(PAPER, {"e1": 6.0})
    with pytest.raises(ParamError, match="'kp4'"):
        override(PAPER, {"kp4": 1.0})
    with pytest.raises(ParamError, match="not finite"):
        override(PAPER, {"kp1": "nan"})
    assert override(PAPER, {"kp1": "0.5"}).kp1 == 0.5
    phys = PiecewisePidParams.physical()
    assert (phys.mode, phys.e1, phys.e2, phys.c_max) == ("physical", 0.02, 0.10, 0.5)
    assert all(math.isfinite(getattr(phys, k)) for k in ("kp1", "kp2", "kp3", "ki1", "ki2",
                                                         "kd"))


@pytest.mark.parametrize(("name", "value"), [("ff_coeff", 1e308), ("ff_coeff", 4390.0),
                                             ("v_max", 12.0), ("ff_exponent", 3.0),
                                             ("shaft_rpm_per_v", 6000.0), ("km", 0.0)])
def test_parameters_out_of_physical_range_are_refused_by_name(name: str, value: float) -> None:
    """A value no meter has (a unit mistake: g for kg, mV for V) is refused, naming the key."""
    with pytest.raises(ValueError, match=rf"^{name} must be > 0 and <= "):
        override(PAPER, {name: value})
    override(PAPER, {name: {"km": 0.1}.get(name, getattr(PAPER, name))})
