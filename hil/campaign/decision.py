"""Early decisions: when a campaign may stop before its N samples, and why.

Two rules, both pure functions of the outcomes so far (the campaign applies them as samples
arrive, the gate applies them again to the record's samples and trusts nothing else):

* **Curtailment** of the fixed-N exact test (the default with a ``[campaign]`` requirement):
  the campaign stops as soon as its verdict at N samples is settled, whatever the samples not
  yet run give (pass, fail or error). The verdict is monotone in the outcomes (a pass raises
  both exact bounds, a fail lowers both), so it is settled when the all-fail and the all-pass
  futures give the same verdict. The early verdict *is* the fixed-N verdict: no error rate
  changes. A build failing every sample of a 300-sample campaign for 0.975 at 95 % is decided
  after 13 samples (the upper bound of 287 passes in 300 is below 0.975).
* **Wald's sequential probability ratio test** (``hil campaign --sequential``) between a bad
  build at ``pass_probability`` and a good one at ``sequential_good_probability``: the log
  likelihood ratio of the good build over the bad one gains ``log(p1/p0)`` per pass and
  ``log((1-p1)/(1-p0))`` per failure; the campaign passes when it reaches
  ``log((1-alpha)/beta)`` and fails when it falls to ``log(alpha/(1-beta))``, with ``beta =
  1 - confidence`` the risk of passing a build at ``pass_probability`` and ``alpha`` that of
  failing one at the good probability (Wald 1945; the risks hold to within Wald's
  approximation, ``alpha' + beta' <= alpha + beta``). The outcomes are taken in sample order
  (index 0, 1, 2 ...), not in the order Dask returns them: a sample that fails quickly must not
  weigh more than one that passes slowly. A test that reaches N samples without a decision is
  inconclusive.

Error samples (the machinery's or the bench's failures, not the DUT's) count for neither side.
A campaign stops early on a settled **pass** or **fail** only: a campaign too short to
demonstrate its requirement is settled as inconclusive from its first sample, and still runs its
samples for the distributions they show (the gate accepts any settled verdict).

>>> settled(0, 13, 287, pass_probability=0.975, confidence=0.95)
'fail'
>>> settled(0, 12, 288, pass_probability=0.975, confidence=0.95) is None
True
>>> Sprt(0.975, 0.995, alpha=0.05, beta=0.05).decide(0, 2)
'fail'
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from hil.campaign.stats import lower_bound, upper_bound

#: sample verdicts that are a DUT result; the others count for neither side
JUDGED = ("pass", "fail")


def settled(passed: int, failed: int, remaining: int, *, pass_probability: float,
            confidence: float) -> str | None:
    """The fixed-N verdict (``pass``, ``fail`` or ``inconclusive``) when the ``remaining``
    samples cannot change it, else None.

    Parameters
    ----------
    passed, failed : int
        Judged samples so far (error samples are not counted).
    remaining : int
        Samples of the N not yet run (each may still pass, fail or be an error).
    pass_probability, confidence : float
        The requirement.
    """
    if min(passed, failed, remaining) < 0:
        raise ValueError(f"counts must be >= 0, got {passed}, {failed}, {remaining}")
    n = passed + failed
    if n == 0:       # every sample so far an error: remaining errors would leave no verdict
        return None
    total = n + remaining
    p, c = pass_probability, confidence
    if lower_bound(passed, total, c) >= p:            # passes even if every other one fails
        return "pass"
    if upper_bound(passed + remaining, total, c) < p:  # fails even if every other one passes
        return "fail"
    if lower_bound(passed + remaining, total, c) < p and upper_bound(passed, total, c) >= p:
        return "inconclusive"
    return None


@dataclass(frozen=True)
class Sprt:
    """Wald's SPRT of a bad build (pass probability ``p_bad``) against a good one
    (``p_good``): ``beta`` is the risk of passing the bad one, ``alpha`` of failing the good
    one."""

    p_bad: float
    p_good: float
    alpha: float
    beta: float

    def __post_init__(self) -> None:
        if not 0 < self.p_bad < self.p_good < 1:
            raise ValueError(f"need 0 < p_bad < p_good < 1, got {self.p_bad}, {self.p_good}")
        if not (0 < self.alpha < 1 and 0 < self.beta < 1 and self.alpha + self.beta < 1):
            raise ValueError(f"need 0 < alpha, beta and alpha + beta < 1, got {self.alpha}, "
                             f"{self.beta}")

    @property
    def step_pass(self) -> float:
        """What one pass adds to the log likelihood ratio (> 0)."""
        return math.log(self.p_good / self.p_bad)

    @property
    def step_fail(self) -> float:
        """What one failure adds (< 0)."""
        return math.log((1 - self.p_good) / (1 - self.p_bad))

    @property
    def pass_at(self) -> float:
        """The log likelihood ratio at which the good build is accepted."""
        return math.log((1 - self.alpha) / self.beta)

    @property
    def fail_at(self) -> float:
        """The log likelihood ratio at which the bad build is accepted (the build fails)."""
        return math.log(self.alpha / (1 - self.beta))

    def llr(self, passed: int, failed: int) -> float:
        return passed * self.step_pass + failed * self.step_fail

    def decide(self, passed: int, failed: int) -> str | None:
        """``pass``, ``fail`` or None (not yet) after these outcomes."""
        value = self.llr(passed, failed)
        if value >= self.pass_at:
            return "pass"
        if value <= self.fail_at:
            return "fail"
        return None

    def unreachable(self, passed: int, failed: int, remaining: int) -> bool:
        """True when neither boundary can be reached in ``remaining`` more samples (the test
        ends inconclusive at N whatever they give)."""
        value = self.llr(passed, failed)
        return (value + remaining * self.step_pass < self.pass_at
                and value + remaining * self.step_fail > self.fail_at)

    def to_dict(self) -> dict[str, float]:
        return {"p_bad": self.p_bad, "p_good": self.p_good, "alpha": self.alpha,
                "beta": self.beta, "step_pass": self.step_pass, "step_fail": self.step_fail,
                "pass_at": self.pass_at, "fail_at": self.fail_at}


@dataclass(frozen=True)
class Decision:
    """Where a rule stands: its verdict once decided (None: keep sampling), the samples it
    used, and why."""

    verdict: str | None
    used: int
    reason: str


def curtailed(outcomes: list[str], total: int, *, pass_probability: float,
              confidence: float) -> Decision:
    """Curtailment over the outcomes so far (any order: only the counts matter)."""
    passed, failed = outcomes.count("pass"), outcomes.count("fail")
    remaining = total - len(outcomes)
    verdict = settled(passed, failed, remaining, pass_probability=pass_probability,
                      confidence=confidence)
    need = f"{pass_probability:.4g} at {confidence:.0%} confidence"
    if verdict is None:
        return Decision(None, len(outcomes), f"{remaining} samples could still change the "
                                             f"verdict")
    what = {"pass": f"the lower bound stays >= {need} even if all {remaining} remaining "
                    f"samples fail",
            "fail": f"the upper bound stays < {need} even if all {remaining} remaining "
                    f"samples pass",
            "inconclusive": f"neither bound can cross {need} in the {remaining} remaining "
                            f"samples"}[verdict]
    return Decision(verdict, len(outcomes), f"{passed}/{passed + failed} passed: {what}")


def sequential(outcomes: list[str], total: int, sprt: Sprt) -> Decision:
    """The SPRT over ``outcomes`` in sample order (index 0 first; a gap must not be given):
    its verdict at the first boundary crossed, ``inconclusive`` at ``total`` samples or when
    no boundary can be reached any more."""
    passed = failed = 0
    for used, outcome in enumerate(outcomes, start=1):
        if outcome == "pass":
            passed += 1
        elif outcome == "fail":
            failed += 1
        else:
            continue
        verdict = sprt.decide(passed, failed)
        if verdict is not None:
            bound = sprt.pass_at if verdict == "pass" else sprt.fail_at
            return Decision(verdict, used,
                            f"{passed}/{passed + failed} passed: log likelihood ratio "
                            f"{sprt.llr(passed, failed):.3f} {'>=' if verdict == 'pass' else '<='}"
                            f" {bound:.3f} (Wald's SPRT of {sprt.p_good:g} against "
                            f"{sprt.p_bad:g}, alpha {sprt.alpha:g}, beta {sprt.beta:g})")
    remaining = total - len(outcomes)
    if remaining <= 0 or sprt.unreachable(passed, failed, remaining):
        return Decision("inconclusive", len(outcomes),
                        f"{passed}/{passed + failed} passed: Wald's SPRT reached neither "
                        f"boundary (log likelihood ratio {sprt.llr(passed, failed):.3f}, "
                        f"bounds {sprt.fail_at:.3f} and {sprt.pass_at:.3f})"
                        + (f" and cannot in the {remaining} remaining samples"
                           if remaining > 0 else f" in {total} samples"))
    return Decision(None, len(outcomes), "no boundary crossed yet")


def sprt_of(requirement: dict[str, Any]) -> Sprt:
    """The SPRT a ``[campaign]`` requirement states (``sequential_good_probability``,
    ``sequential_alpha``; beta is ``1 - confidence``)."""
    return Sprt(p_bad=requirement["pass_probability"],
                p_good=requirement["sequential_good_probability"],
                alpha=requirement["sequential_alpha"],
                beta=1.0 - requirement["confidence"])


def in_order(samples: list[dict[str, Any]]) -> list[str]:
    """The verdicts of the contiguous run of samples from index 0 (what the SPRT may use)."""
    by_index = {s["index"]: s["verdict"] for s in samples}
    out = []
    while len(out) in by_index:
        out.append(by_index[len(out)])
    return out


#: the stopping rules a campaign record names (``decision.rule``)
RULES = ("fixed", "curtailed", "sequential")


def decide(rule: str, samples: list[dict[str, Any]], total: int,
           requirement: dict[str, Any] | None) -> Decision:
    """Where ``rule`` stands after ``samples`` (each with ``index`` and ``verdict``) of a
    campaign of ``total``: the one function the campaign stops by and the gate checks by.

    ``fixed`` never decides early (the campaign's own verdict comes at ``total``);
    ``curtailed`` and ``sequential`` need a requirement."""
    if rule == "fixed":
        return Decision(None, len(samples), "every sample is run")
    if rule not in RULES:
        raise ValueError(f"unknown stopping rule {rule!r} (known: {', '.join(RULES)})")
    if requirement is None:
        raise ValueError(f"the {rule} rule needs a [campaign] requirement")
    if rule == "curtailed":
        return curtailed([s["verdict"] for s in samples], total,
                         pass_probability=requirement["pass_probability"],
                         confidence=requirement["confidence"])
    return sequential(in_order(samples), total, sprt_of(requirement))
