"""Early decisions (issue 29): how many of a 300-sample campaign's samples a decision takes.

    python benchmarks/bench_campaign_decision.py              # two must-fail builds per rig
    python benchmarks/bench_campaign_decision.py --all        # every must-fail profile
    python benchmarks/bench_campaign_decision.py --simulate-only

Two parts, each printed as a table; nothing is asserted (figures, not tests: the tests are
tests/hil/campaign/test_early_decisions.py and the slow test_early_decision_real.py).

1. **Measured**: real ``hil campaign --samples 300`` runs (fast suite, in process, 2 workers,
   the rig's shipped dispersion, no reruns) of must-fail profiles held to their rig's reference
   requirement (:mod:`hil.campaign.held`), once with the default curtailment and once with
   ``--sequential``: samples run, verdict, wall time, and the share of the 300 a fixed-N
   campaign would run. The goal of issue 29: a clearly failing build decided in <= 5 % (15).
2. **Simulated** (the same decision functions on Bernoulli streams, 2000 per row, no rig): the
   samples used and the verdicts for builds at a few true pass probabilities around each
   requirement, including one just below it, where neither rule can decide quickly.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hil.campaign.decision import Sprt, settled, sprt_of  # noqa: E402
from hil.campaign.held import held_to  # noqa: E402
from hil.dut.profile import load_profile  # noqa: E402

N = 300
REFERENCE = {"fertilizer": ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml",
             "sowing_depth": ROOT / "dut_profiles/sowing-depth-fuzzy-pid-daemon.toml"}
DEFAULT = ("fertilizer-no-integral-daemon", "fertilizer-dies-after-10s-daemon",
           "sowing-depth-inverted-polarity-daemon", "sowing-depth-never-engages-daemon")


def run_campaign(profile: Path, out: Path, *extra: str) -> dict:
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "hil", "campaign", str(profile), "--samples",
                           str(N), "--bus", "inline", "--workers", "2", "--suite", "fast",
                           "--max-reruns", "0", "--no-progress", "--out", str(out), *extra],
                          capture_output=True, text=True, check=False)
    doc = json.loads((out / "campaign.json").read_text())
    return {"exit": done.returncode, "wall_s": time.perf_counter() - t0,
            "run": len(doc["samples"]), "verdict": doc["summary"]["verdict"],
            "failed": doc["summary"]["failed"], "errors": doc["summary"]["errors"]}


def measured(names: list[str]) -> None:
    print(f"\n1. measured: {N}-sample campaigns of must-fail builds held to their rig's "
          f"requirement (fast suite, inline, 2 workers, shipped dispersion)")
    print(f"{'profile':<44} {'rule':<11} {'verdict':<8} {'run':>4} {'of 300':>7} "
          f"{'failed':>6} {'wall':>7}")
    worst = 0.0
    with tempfile.TemporaryDirectory(prefix="bench-decision-") as tmp:
        for name in names:
            path = ROOT / "dut_profiles/must_fail" / f"{name}.toml"
            rig = load_profile(path).dut.rig
            copy = held_to(path, REFERENCE[rig], Path(tmp) / name)
            for rule, extra in (("curtailed", ()), ("sequential", ("--sequential",))):
                r = run_campaign(copy, Path(tmp) / name / rule, *extra)
                share = r["run"] / N
                worst = max(worst, share)
                print(f"{name:<44} {rule:<11} {r['verdict']:<8} {r['run']:>4} {share:>7.1%} "
                      f"{r['failed']:>6} {r['wall_s']:>6.1f}s", flush=True)
    print(f"largest share of the {N} samples run before the decision: {worst:.1%} "
          f"(goal: <= 5 %)")


def _first(hits: np.ndarray) -> np.ndarray:
    return np.where(hits.any(1), hits.argmax(1), N)


def simulate(p_req: float, confidence: float, sprt: Sprt, p_true: float,
             rng: np.random.Generator, runs: int = 2000) -> tuple[list[float], list[float]]:
    """(mean samples, P(pass), P(fail)) for curtailment and the SPRT at ``p_true``."""
    # curtailment's thresholds from the function itself: the failures that settle a fail,
    # the passes that settle a pass (at N = 300 they do not depend on the samples run)
    fail_at = next(f for f in range(N + 1)
                   if settled(0, f, N - f, pass_probability=p_req, confidence=confidence)
                   == "fail")
    pass_at = next(s for s in range(N + 1)
                   if settled(s, 0, N - s, pass_probability=p_req, confidence=confidence)
                   == "pass")
    x = rng.random((runs, N)) < p_true
    passes, fails = np.cumsum(x, 1), np.cumsum(~x, 1)
    stop_fail, stop_pass = _first(fails >= fail_at), _first(passes >= pass_at)
    used = np.minimum(np.minimum(stop_fail, stop_pass) + 1, N)
    curt = [float(used.mean()), float((stop_pass < stop_fail).mean()),
            float((stop_fail < stop_pass).mean())]
    llr = np.cumsum(np.where(x, sprt.step_pass, sprt.step_fail), 1)
    up, down = _first(llr >= sprt.pass_at), _first(llr <= sprt.fail_at)
    seq = [float(np.minimum(np.minimum(up, down) + 1, N).mean()), float((up < down).mean()),
           float((down < up).mean())]
    return curt, seq


def simulated() -> None:
    print(f"\n2. simulated: the decision functions on 2000 Bernoulli streams of {N} per row "
          f"(no rig); inconclusive = neither pass nor fail")
    print(f"{'rig':<13} {'required':>8} {'true p':>7} | {'curtailed: mean n':>17} {'pass':>6} "
          f"{'fail':>6} | {'SPRT: mean n':>12} {'pass':>6} {'fail':>6}")
    rng = np.random.default_rng(29)
    for rig, ref in REFERENCE.items():
        req = load_profile(ref).campaign
        assert req is not None
        sprt = sprt_of({"pass_probability": req.pass_probability,
                        "confidence": req.confidence,
                        "sequential_good_probability": req.sequential_good_probability,
                        "sequential_alpha": req.sequential_alpha})
        p = req.pass_probability
        for p_true in (0.0, 0.5, 0.9, round(p - 0.01, 3), p, 0.995, 0.998):
            curt, seq = simulate(p, req.confidence, sprt, p_true, rng)
            print(f"{rig:<13} {p:>8g} {p_true:>7g} | {curt[0]:>17.1f} {curt[1]:>6.1%} "
                  f"{curt[2]:>6.1%} | {seq[0]:>12.1f} {seq[1]:>6.1%} {seq[2]:>6.1%}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--all", action="store_true", help="every must-fail profile")
    parser.add_argument("--simulate-only", action="store_true", help="part 2 only")
    parser.add_argument("profiles", nargs="*", help="must-fail profile names (default: "
                                                    f"{', '.join(DEFAULT)})")
    args = parser.parse_args()
    print(f"load average at start: {os.getloadavg()}")
    if not args.simulate_only:
        names = (sorted(p.stem for p in (ROOT / "dut_profiles/must_fail").glob("*.toml"))
                 if args.all else args.profiles or list(DEFAULT))
        measured(names)
    simulated()
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
