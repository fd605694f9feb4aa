"""Early decisions (issue 29) on synthetic outcome streams: curtailment gives the fixed-N
verdict whatever the remaining samples do, Wald's SPRT keeps its stated risks, and a build that
fails every sample is decided within 5 % of a 300-sample campaign under each reference profile's
stated requirement."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.campaign.decision import (
    Sprt,
    curtailed,
    decide,
    in_order,
    sequential,
    settled,
    sprt_of,
)
from hil.campaign.stats import verdict
from hil.dut.profile import load_profile

ROOT = Path(__file__).resolve().parents[3]
REFERENCES = sorted((ROOT / "dut_profiles").glob("*.toml"))


def _full_verdict(outcomes: tuple[str, ...], p: float, c: float) -> str:
    judged = [o for o in outcomes if o != "error"]
    return verdict(judged.count("pass"), len(judged), pass_probability=p, confidence=c).verdict


@pytest.mark.parametrize(("n", "p", "c"), [(7, 0.5, 0.8), (7, 0.4, 0.6), (6, 0.6, 0.7)])
def test_a_settled_verdict_is_the_verdict_of_every_completion(n: int, p: float,
                                                              c: float) -> None:
    """Every stream of pass/fail/error of length n, every prefix: when curtailment settles,
    every way of completing the prefix ends with that verdict (brute force)."""
    decided = {"pass": 0, "fail": 0, "inconclusive": 0}
    for k in range(1, n):
        for prefix in itertools.product(("pass", "fail", "error"), repeat=k):
            s = settled(prefix.count("pass"), prefix.count("fail"), n - k,
                        pass_probability=p, confidence=c)
            if s is None:
                continue
            decided[s] += 1
            finals = {_full_verdict(prefix + rest, p, c)
                      for rest in itertools.product(("pass", "fail", "error"), repeat=n - k)}
            assert finals == {s}, (prefix, s, finals)
    # and it does settle, each way: the check above is not vacuous
    assert all(decided.values()), decided


def test_settled_is_none_while_the_remaining_samples_could_change_it() -> None:
    # 300 samples for 0.975 at 95 %: 12 failures can still end inconclusive, 13 cannot
    assert settled(0, 12, 288, pass_probability=0.975, confidence=0.95) is None
    assert settled(0, 13, 287, pass_probability=0.975, confidence=0.95) == "fail"
    assert settled(280, 0, 20, pass_probability=0.975, confidence=0.95) is None
    assert settled(300, 0, 0, pass_probability=0.975, confidence=0.95) == "pass"


@pytest.mark.parametrize("profile", REFERENCES, ids=lambda p: p.stem)
def test_a_build_failing_every_sample_is_decided_within_5_percent(profile: Path) -> None:
    """Under each reference profile's stated requirement, a 300-sample campaign of a build that
    fails every sample stops after at most 15 samples, with its fixed-N verdict (fail); the
    SPRT the profile states fails it sooner still."""
    req = load_profile(profile).campaign
    assert req is not None, f"{profile.name} states no [campaign] requirement"
    stated = {"pass_probability": req.pass_probability, "confidence": req.confidence,
              "sequential_good_probability": req.sequential_good_probability,
              "sequential_alpha": req.sequential_alpha}
    for rule in ("curtailed", "sequential"):
        samples: list[dict] = []
        for i in range(300):
            samples.append({"index": i, "verdict": "fail"})
            d = decide(rule, samples, 300, stated)
            if d.verdict is not None:
                break
        assert d.verdict == "fail" and len(samples) <= 15, (rule, len(samples))
    # the same build interleaved with error samples is decided on its judged samples
    samples = [{"index": i, "verdict": "fail" if i % 3 else "error"} for i in range(40)]
    d = decide("curtailed", samples, 300, stated)
    assert d.verdict == "fail"


def test_a_good_build_is_not_stopped_early_by_curtailment() -> None:
    outcomes = ["pass"] * 250 + ["fail"]
    d = curtailed(outcomes, 300, pass_probability=0.975, confidence=0.95)
    assert d.verdict is None


@given(p_true=st.floats(0.5, 0.999), seed=st.integers(0, 2**32 - 1))
@settings(max_examples=25, deadline=None)
def test_curtailed_verdict_equals_the_fixed_n_verdict(p_true: float, seed: int) -> None:
    """Random Bernoulli streams of 300: where curtailment stops, the full stream's verdict is
    the one it gave."""
    rng = np.random.default_rng(seed)
    outcomes = ["pass" if x else "fail" for x in rng.random(300) < p_true]
    full = _full_verdict(tuple(outcomes), 0.975, 0.95)
    for k in range(1, 301):
        d = curtailed(outcomes[:k], 300, pass_probability=0.975, confidence=0.95)
        if d.verdict is not None:
            assert d.verdict == full, (k, d, full)
            break


def _sprt_runs(sprt: Sprt, p_true: float, runs: int, total: int,
               rng: np.random.Generator) -> tuple[float, float, float]:
    """Fraction passed, fraction failed and mean samples used, vectorised over ``runs``."""
    x = rng.random((runs, total)) < p_true
    llr = np.cumsum(np.where(x, sprt.step_pass, sprt.step_fail), axis=1)
    up, down = llr >= sprt.pass_at, llr <= sprt.fail_at
    first_up = np.where(up.any(1), up.argmax(1), total)
    first_down = np.where(down.any(1), down.argmax(1), total)
    passed = (first_up < first_down).mean()
    failed = (first_down < first_up).mean()
    used = np.minimum(np.minimum(first_up, first_down) + 1, total).mean()
    return float(passed), float(failed), float(used)


def test_sprt_keeps_its_stated_risks() -> None:
    """Simulated: a build at the required probability passes at most ~beta of the time, a
    good one fails at most ~alpha (Wald: alpha' + beta' <= alpha + beta), a bad one is failed
    in a few samples; the loose test (alpha = beta = 0.3) shows the simulation can see a risk
    above 5 %."""
    rng = np.random.default_rng(29)
    sprt = Sprt(0.975, 0.995, alpha=0.05, beta=0.05)
    passed_bad, _, _ = _sprt_runs(sprt, 0.975, 4000, 3000, rng)
    _, failed_good, used_good = _sprt_runs(sprt, 0.995, 4000, 3000, rng)
    _, failed_awful, used_awful = _sprt_runs(sprt, 0.5, 2000, 300, rng)
    assert passed_bad <= 0.06 and failed_good <= 0.06, (passed_bad, failed_good)
    assert passed_bad + failed_good <= 0.10
    assert failed_awful == 1.0 and used_awful < 8
    loose = Sprt(0.975, 0.995, alpha=0.3, beta=0.3)
    passed_loose, _, _ = _sprt_runs(loose, 0.975, 4000, 3000, rng)
    assert passed_loose > 0.1
    assert 100 < used_good < 400


def test_sprt_boundaries_and_truncation() -> None:
    sprt = Sprt(0.975, 0.995, alpha=0.05, beta=0.05)
    assert sequential(["pass"] * 145, 300, sprt).verdict is None
    assert sequential(["pass"] * 146, 300, sprt).verdict == "pass"
    assert sequential(["fail", "fail"], 300, sprt).verdict == "fail"
    assert sequential(["fail", "error", "fail"], 300, sprt).used == 3
    # one failure early costs ~79 passes: not decided at 146
    assert sequential(["fail"] + ["pass"] * 146, 300, sprt).verdict is None
    # at N without a boundary: inconclusive
    assert sequential(["fail"] + ["pass"] * 99, 100, sprt).verdict == "inconclusive"
    with pytest.raises(ValueError):
        Sprt(0.99, 0.98, alpha=0.05, beta=0.05)
    with pytest.raises(ValueError):
        Sprt(0.9, 0.99, alpha=0.6, beta=0.5)


def test_sprt_takes_samples_in_index_order() -> None:
    """A failing sample that finished first counts in its place, not first; a gap stops the
    sequence the test may read."""
    arrived = [{"index": 2, "verdict": "fail"}, {"index": 0, "verdict": "fail"}]
    assert in_order(arrived) == ["fail"]
    req = {"pass_probability": 0.975, "confidence": 0.95,
           "sequential_good_probability": 0.995, "sequential_alpha": 0.05}
    assert decide("sequential", arrived, 300, req).verdict is None
    arrived.append({"index": 1, "verdict": "fail"})
    d = decide("sequential", arrived, 300, req)
    assert d.verdict == "fail" and d.used == 2
    assert sprt_of(req).beta == pytest.approx(0.05)
    with pytest.raises(ValueError):
        decide("curtailed", arrived, 300, None)
    assert decide("fixed", arrived, 300, req).verdict is None


def test_sequential_needs_the_profile_to_state_its_test(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    """Exit 2 naming the profile and the missing key, before any worker starts."""
    from hil.cli.main import main

    must_fail = ROOT / "dut_profiles/must_fail/fertilizer-no-integral-daemon.toml"
    reference = ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"
    partial = tmp_path / reference.name
    partial.write_text("\n".join(line for line in reference.read_text().splitlines()
                                 if not line.startswith("sequential_")) + "\n")
    for profile, key in ((must_fail, "[campaign]"),
                         (partial, "[campaign.sequential_good_probability]")):
        code = main(["campaign", str(profile), "--samples", "5", "--bus", "inline",
                     "--sequential", "--out", str(tmp_path / "c"), "--no-progress"])
        err = capsys.readouterr().err
        assert code == 2 and key in err and str(profile) in err, err
        assert not (tmp_path / "c").exists()
