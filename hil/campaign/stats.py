"""Exact binomial statistics of a campaign: Clopper-Pearson bounds, verdicts, sample sizes.

>>> round(lower_bound(300, 300, 0.95), 4)      # 300 passes, none failing
0.9901
>>> samples_needed(0.99, 0.95)
299
>>> lo, hi = clopper_pearson(290, 300)
>>> round(lo, 3), round(hi, 3)
(0.94, 0.984)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.stats import beta


def clopper_pearson(passed: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided exact (Clopper-Pearson) interval of a pass probability.

    Parameters
    ----------
    passed, n : int
        passes and samples (``0 <= passed <= n``; ``n = 0`` gives ``(0, 1)``).
    confidence : float
        coverage of the interval, e.g. 0.95.
    """
    _check(passed, n, confidence)
    if n == 0:
        return 0.0, 1.0
    alpha = 1.0 - confidence
    lo = 0.0 if passed == 0 else float(beta.ppf(alpha / 2, passed, n - passed + 1))
    hi = 1.0 if passed == n else float(beta.ppf(1 - alpha / 2, passed + 1, n - passed))
    return lo, hi


def lower_bound(passed: int, n: int, confidence: float = 0.95) -> float:
    """One-sided exact lower confidence bound of the pass probability (what the samples
    demonstrate at ``confidence``)."""
    _check(passed, n, confidence)
    if n == 0 or passed == 0:
        return 0.0
    return float(beta.ppf(1.0 - confidence, passed, n - passed + 1))


def upper_bound(passed: int, n: int, confidence: float = 0.95) -> float:
    """One-sided exact upper confidence bound of the pass probability."""
    _check(passed, n, confidence)
    if n == 0 or passed == n:
        return 1.0
    return float(beta.ppf(confidence, passed + 1, n - passed))


def samples_needed(pass_probability: float, confidence: float, failures: int = 0) -> int:
    """Fewest samples that demonstrate ``pass_probability`` at ``confidence`` when
    ``failures`` of them fail (299 samples for 99 % at 95 % with none failing)."""
    if not 0 < pass_probability < 1 or not 0 < confidence < 1:
        raise ValueError("pass_probability and confidence must lie in (0, 1)")
    n = max(failures + 1, math.ceil(math.log(1 - confidence) / math.log(pass_probability)))
    while lower_bound(n - failures, n, confidence) < pass_probability:
        n += max(1, n // 50)
    while n > failures + 1 and lower_bound(n - 1 - failures, n - 1, confidence) \
            >= pass_probability:
        n -= 1
    return n


@dataclass(frozen=True)
class Verdict:
    """A campaign's verdict: ``pass``, ``fail``, ``inconclusive`` or ``error``, why, and
    (inconclusive) how many samples would settle it if no more failed."""

    verdict: str
    reason: str
    samples_needed: int | None = None


def verdict(passed: int, n: int, *, pass_probability: float | None,
            confidence: float = 0.95, errors: int = 0) -> Verdict:
    """The campaign verdict.

    With a requirement (``pass_probability`` at ``confidence``): ``pass`` when the one-sided
    lower bound clears it; ``fail`` when the upper bound is below it; else ``inconclusive`` with
    the samples needed (with no further failure). Without one: ``pass`` when no sample failed.
    No judged sample at all (every one an error) is ``error``.
    """
    failed = n - passed
    if n == 0:
        return Verdict("error", f"no sample completed ({errors} errors)")
    demonstrated = lower_bound(passed, n, confidence)
    note = f" ({errors} error samples not counted)" if errors else ""
    if pass_probability is None:
        if failed:
            return Verdict("fail", f"{failed} of {n} samples failed{note}")
        return Verdict("pass", f"all {n} samples passed: pass probability >= "
                               f"{demonstrated:.4f} (one-sided {confidence:.0%} lower "
                               f"bound){note}")
    need = f"{pass_probability:.4g} at {confidence:.0%} confidence"
    if demonstrated >= pass_probability:
        return Verdict("pass", f"{passed}/{n} passed: lower bound {demonstrated:.4f} >= "
                               f"{need}{note}")
    top = upper_bound(passed, n, confidence)
    if top < pass_probability:
        return Verdict("fail", f"{failed} of {n} samples failed: upper bound {top:.4f} < "
                               f"{need}{note}")
    more = samples_needed(pass_probability, confidence, failed)
    return Verdict("inconclusive",
                   f"{passed}/{n} passed: lower bound {demonstrated:.4f} does not reach {need};"
                   f" {more} samples with no further failure would{note}", more)


def _check(passed: int, n: int, confidence: float) -> None:
    if not 0 <= passed <= n:
        raise ValueError(f"need 0 <= passed <= n, got passed={passed}, n={n}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
