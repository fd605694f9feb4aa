"""The campaign gate's statistic on synthetic campaigns (the real ones: test_campaign_gate_real)."""

from __future__ import annotations

import numpy as np
import pytest

from hil.gate.campaign import compare_campaigns, welch_shift_p, worseness
from hil.gate.tolerance import Band, Tolerances

TOL = Tolerances(default=Band(abs=1.0))


def _campaign(values: list[float], *, start: int = 0, verdict: str = "pass") -> dict:
    samples = [{"index": start + i, "verdict": "pass", "measurements": [
        {"name": "flow.field.accuracy", "conditions": {"speed_kmh": 4}, "value": v,
         "low": 97.5, "high": None, "outcome": "pass"}]} for i, v in enumerate(values)]
    return {"schema": "agrihil.campaign/1", "status": "complete", "dut": {"name": "x"},
            "samples": samples, "samples_requested": len(values),
            "summary": {"verdict": verdict, "reason": "r"}}


def test_welch_offset_test() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.normal(1.0, 0.4, 30), rng.normal(0.0, 0.4, 30)
    assert welch_shift_p(a, b, 0.0) < 1e-6          # 1.0 worse: beyond a zero band
    assert welch_shift_p(a, b, 0.5) < 1e-3          # and beyond 0.5
    assert welch_shift_p(a, b, 1.5) > 0.5           # not beyond 1.5
    assert welch_shift_p(np.full(3, 2.0), np.full(3, 1.0), 0.5) == 0.0   # no spread at all


def test_worseness_direction() -> None:
    assert list(worseness([1.0, 2.0], None, 5.0)) == [1.0, 2.0]
    assert list(worseness([1.0, 2.0], 0.0, None)) == [-1.0, -2.0]
    assert list(worseness([1.0, 9.0], 0.0, 10.0)) == [4.0, 4.0]
    assert worseness([1.0], None, None) is None


@pytest.mark.parametrize("seed", range(20))
def test_seed_noise_is_not_a_regression(seed: int) -> None:
    rng = np.random.default_rng(seed)
    base = _campaign(list(rng.normal(99.3, 0.5, 30)))
    new = _campaign(list(rng.normal(99.3, 0.5, 30)), start=1000)
    result = compare_campaigns(new, base, TOL)
    assert result.verdict == "pass", [r for r in result.rows if r.status != "ok"]


def test_a_one_point_drop_is_a_regression_and_a_gain_is_not() -> None:
    rng = np.random.default_rng(3)
    base = _campaign(list(rng.normal(99.3, 0.5, 30)))
    worse = _campaign(list(rng.normal(98.3, 0.5, 30)), start=1000)
    better = _campaign(list(rng.normal(99.9, 0.3, 30)), start=1000)
    r = compare_campaigns(worse, base, TOL)
    assert r.verdict == "fail" and [x.status for x in r.rows] == ["regression"]
    assert compare_campaigns(better, base, TOL).verdict == "pass"
    assert compare_campaigns(worse, base, TOL, allow_regressions=True).verdict == "pass"


def test_own_verdict_and_missing_measurements() -> None:
    base = _campaign([99.0, 99.1, 99.2])
    assert compare_campaigns(_campaign([99.0], verdict="fail"), None).verdict == "fail"
    inconclusive = compare_campaigns(_campaign([99.0], verdict="inconclusive"), None)
    assert inconclusive.verdict == "inconclusive" and inconclusive.exit_code == 3
    assert compare_campaigns(_campaign([99.0], verdict="error"), None).exit_code == 2
    other = _campaign([99.0])
    other["samples"][0]["measurements"][0]["name"] = "flow.bench.accuracy"
    r = compare_campaigns(other, base, TOL)
    assert r.verdict == "fail" and [x.status for x in r.rows if x.status == "missing"]
