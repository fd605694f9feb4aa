"""Limits, regression and the verdict, on synthetic records (no files)."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import pytest

from hil.gate import (
    Band,
    Status,
    Tolerances,
    Verdict,
    baseline_from_record,
    compare,
    parse_record,
    worse_by,
)
from hil.measurements import Measurement

from .records import bench_accuracy, depth_mean, good, lateness, overshoot, record, step_time

NOW = datetime(2026, 11, 22, 12, 0, tzinfo=UTC)
#: every measurement gets an absolute band of 0.1 in its unit
TIGHT = Tolerances(default=Band(abs=0.1))


def _rec(measurements, **kw):
    return parse_record(record(measurements, **kw), path="record.json")


def _baseline(measurements):
    return baseline_from_record(_rec(measurements, run_id="base00000000"), created_at=NOW,
                                path="baseline.json")


def _row(result, key):
    (row,) = [r for r in result.rows if r.key == key]
    return row


STEP23 = "flow.step.response_time[sensor=sliding,target_gps=23]"
ACC = "flow.bench.accuracy[target_g=1700]"
DEPTH = "depth.field.mean[speed_band=3-5]"


def test_worse_follows_the_limits() -> None:
    assert worse_by(1.3, 1.1, low=None, high=1.5) == pytest.approx(0.2)      # larger is worse
    assert worse_by(95.0, 97.0, low=90.0, high=None) == pytest.approx(2.0)   # smaller is worse
    assert worse_by(27.0, 31.0, low=20.0, high=40.0) == pytest.approx(2.0)   # 3 mm off vs 1 mm
    assert worse_by(31.0, 29.0, low=20.0, high=40.0) == pytest.approx(0.0)   # as far, other side
    assert worse_by(99.0, 1.0, low=None, high=None) is None


def test_a_good_build_passes_on_limits_alone() -> None:
    result = compare(_rec(good()), None)
    assert result.verdict is Verdict.PASS and result.exit_code == 0
    assert result.counts() == {Status.PASS: 5, Status.INFO: 1}
    assert _row(result, STEP23).baseline is None and _row(result, STEP23).delta is None


def test_a_value_outside_its_limit_fails() -> None:
    result = compare(_rec([step_time(1.62), overshoot(3.0)]), None)
    assert result.verdict is Verdict.FAIL and result.exit_code == 1
    row = _row(result, STEP23)
    assert row.status is Status.FAIL and row.value == 1.62 and row.high == 1.5
    assert result.rows[0] is row                                  # worst first
    assert result.reasons == ("1 measurement outside limits",)


def test_an_errored_measurement_fails() -> None:
    result = compare(_rec([bench_accuracy(math.nan), overshoot(3.0)]), None)
    assert _row(result, ACC).status is Status.ERROR
    assert result.verdict is Verdict.FAIL
    assert "1 measurement could not be computed" in result.reasons


def test_a_regression_within_limits_fails_unless_allowed() -> None:
    base = _baseline(good())
    now = good()
    now[0] = step_time(1.35)                  # limit 1.5: still passes; 0.25 s slower
    result = compare(_rec(now), base, TIGHT)
    row = _row(result, STEP23)
    assert row.status is Status.REGRESSION
    assert (row.baseline, row.band) == (1.10, 0.1) and row.delta == pytest.approx(0.25)
    assert result.verdict is Verdict.FAIL and result.reasons == ("1 regression beyond tolerance",)
    allowed = compare(_rec(now), base, TIGHT, allow_regressions=True)
    assert allowed.verdict is Verdict.PASS and allowed.exit_code == 0
    assert allowed.warnings == ("1 regression beyond tolerance (allowed: --allow-regressions)",)
    assert _row(allowed, STEP23).status is Status.REGRESSION


def test_within_the_band_is_neither_regression_nor_improvement() -> None:
    base = _baseline(good())
    now = good()
    now[0] = step_time(1.19)                  # +0.09 s, band 0.1 s
    now[3] = bench_accuracy(96.91)            # -0.09 points, band 0.1
    result = compare(_rec(now), base, TIGHT)
    assert _row(result, STEP23).status is Status.PASS
    assert _row(result, ACC).status is Status.PASS
    assert result.verdict is Verdict.PASS


def test_an_improvement_is_reported_and_passes() -> None:
    base = _baseline(good())
    now = good()
    now[3] = bench_accuracy(98.5)             # low limit: larger is better
    now[4] = depth_mean(30.0)                 # both limits: closer to 30 mm is better (0.2 -> 0)
    result = compare(_rec(now), base, Tolerances(default=Band(abs=0.1)))
    assert _row(result, ACC).status is Status.IMPROVED
    assert _row(result, ACC).delta == pytest.approx(1.5)
    assert _row(result, DEPTH).status is Status.IMPROVED
    assert result.verdict is Verdict.PASS


def test_getting_farther_from_the_middle_of_a_two_sided_band_regresses() -> None:
    base = _baseline(good())                  # depth 30.2 mm in 20..40
    now = good()
    now[4] = depth_mean(29.5)                 # 0.5 mm off instead of 0.2: worse by 0.3 mm
    result = compare(_rec(now), base, TIGHT)
    assert _row(result, DEPTH).status is Status.REGRESSION


def test_a_measurement_without_limits_never_regresses() -> None:
    base = _baseline(good())
    now = good()
    now[5] = lateness(900.0)                  # 12 us -> 900 us, but no limits: information
    result = compare(_rec(now), base, TIGHT)
    row = _row(result, "rig.timing.lateness_p99")
    assert row.status is Status.INFO and row.delta == pytest.approx(888.0)
    assert result.verdict is Verdict.PASS


def test_a_missing_measurement_fails_and_a_new_one_is_information() -> None:
    base = _baseline(good())
    now = [m for m in good() if m.name != "depth.field.mean"]
    now.append(step_time(1.2, target=34))
    result = compare(_rec(now), base, TIGHT)
    missing = _row(result, DEPTH)
    assert missing.status is Status.MISSING and missing.value is None
    assert missing.baseline == 30.2 and (missing.low, missing.high) == (20.0, 40.0)
    new = _row(result, "flow.step.response_time[sensor=sliding,target_gps=34]")
    assert new.status is Status.NEW and new.baseline is None
    assert result.verdict is Verdict.FAIL
    assert result.reasons == ("1 baseline measurement missing from the record",)
    # when the baseline is being rewritten, the missing check is accepted (but still shown)
    accepted = compare(_rec(now), base, TIGHT, accept_changes=True)
    assert accepted.verdict is Verdict.PASS and _row(accepted, DEPTH).status is Status.MISSING


def test_a_failing_value_is_a_fail_even_when_it_improved() -> None:
    base = _baseline([step_time(1.9)])
    result = compare(_rec([step_time(1.6)]), base, TIGHT)
    assert _row(result, STEP23).status is Status.FAIL and result.exit_code == 1


def test_marginal_passes_with_a_warning() -> None:
    result = compare(_rec([step_time(1.495)]), None)       # within 1 % of 1.5
    assert _row(result, STEP23).status is Status.MARGINAL
    assert result.verdict is Verdict.PASS
    assert result.warnings == ("1 measurement marginal (close to a limit)",)


@pytest.mark.parametrize(("verdict", "expected"), [("invalid-bench", Verdict.INVALID_BENCH),
                                                   ("error", Verdict.ERROR)])
def test_invalid_bench_and_error_give_no_verdict_on_the_dut(verdict, expected) -> None:
    # even with a failing measurement: the bench, not the DUT, was at fault
    result = compare(_rec([step_time(1.9)], verdict=verdict), None)
    assert result.verdict is expected and result.exit_code == 2


def test_the_records_fail_verdict_fails_the_gate_without_a_failed_measurement() -> None:
    rec = _rec([step_time(1.1)], verdict="fail",
               tests=[{"nodeid": "test_suites/x.py::test_restart", "outcome": "failed",
                       "duration_s": 1.0, "message": "boom"}])
    result = compare(rec, None)
    assert result.verdict is Verdict.FAIL
    assert result.reasons == ("the record's verdict is fail (tests: "
                              "test_suites/x.py::test_restart (failed))",)


def test_an_empty_record_does_not_pass() -> None:
    result = compare(_rec([], verdict="pass"), None)
    assert result.verdict is Verdict.FAIL
    assert result.reasons == ("the record has no measurements: nothing was checked",)


def test_a_changed_unit_is_not_compared() -> None:
    base = _baseline([Measurement("flow.step.response_time", 1100.0, "ms", high=1500.0)])
    result = compare(_rec([Measurement("flow.step.response_time", 1.2, "s", high=1.5)]), base)
    row = result.rows[0]
    assert row.status is Status.PASS and row.delta is None
    assert any("unit changed from 'ms' to 's'" in n for n in row.notes)
