"""Exact binomial statistics and campaign verdicts (hil.campaign.stats)."""

from __future__ import annotations

import pytest
from scipy.stats import binomtest

from hil.campaign.stats import clopper_pearson, lower_bound, samples_needed, upper_bound, verdict


@pytest.mark.parametrize(("k", "n"), [(0, 10), (3, 10), (10, 10), (290, 300), (1, 1)])
def test_clopper_pearson_matches_scipy_binomtest(k: int, n: int) -> None:
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    lo, hi = clopper_pearson(k, n, 0.95)
    assert lo == pytest.approx(ci.low, abs=1e-12)
    assert hi == pytest.approx(ci.high, abs=1e-12)


def test_300_passes_demonstrate_99_percent_at_95() -> None:
    # the design note's figure: zero failures in 300 samples supports 99 % at 95 %
    assert lower_bound(300, 300, 0.95) > 0.99
    assert lower_bound(297, 297, 0.95) < 0.99
    assert samples_needed(0.99, 0.95) == 299
    assert lower_bound(299, 299, 0.95) >= 0.99 > lower_bound(298, 298, 0.95)


def test_samples_needed_with_failures_is_the_smallest_that_demonstrates() -> None:
    for failures in (0, 1, 3):
        n = samples_needed(0.95, 0.9, failures)
        assert lower_bound(n - failures, n, 0.9) >= 0.95
        assert lower_bound(n - 1 - failures, n - 1, 0.9) < 0.95


def test_bounds_are_ordered_and_clamped() -> None:
    assert lower_bound(0, 5) == 0.0 and upper_bound(5, 5) == 1.0
    assert lower_bound(7, 10) < 0.7 < upper_bound(7, 10)
    with pytest.raises(ValueError):
        clopper_pearson(11, 10)
    with pytest.raises(ValueError):
        lower_bound(1, 2, confidence=1.0)


def test_verdicts() -> None:
    # without a requirement: pass when none failed, and the demonstrated probability is stated
    v = verdict(20, 20, pass_probability=None)
    assert v.verdict == "pass" and "0.86" in v.reason
    assert verdict(19, 20, pass_probability=None).verdict == "fail"
    # with one: too few samples even with none failing -> inconclusive, with the count needed
    v = verdict(50, 50, pass_probability=0.99, confidence=0.95)
    assert v.verdict == "inconclusive" and v.samples_needed == 299
    assert verdict(300, 300, pass_probability=0.99, confidence=0.95).verdict == "pass"
    # clearly below the requirement -> fail
    assert verdict(80, 100, pass_probability=0.99, confidence=0.95).verdict == "fail"
    # one failure among 100: not demonstrated, not refuted; needs more samples than 299
    v = verdict(99, 100, pass_probability=0.99, confidence=0.95)
    assert v.verdict == "inconclusive" and v.samples_needed is not None \
        and v.samples_needed > 299
    assert verdict(0, 0, pass_probability=None, errors=3).verdict == "error"
