"""Every shipped must-fail profile fails a campaign, in every sample, on what its header names.

A must-fail's defect is in its code, not in its luck: whatever the seed, each sample of a
campaign of the fast and robustness suites must fail, and each measurement its ``# must-fail:``
header names that the campaign measured must fail (or be not computed) in at least one
condition of every sample. ``tests/test_discrimination.py`` and
``tests/test_suites_depth_discrimination.py`` check the same profiles at one seed, on the
exact conditions; this checks them the way a release campaign meets them, at seeds none of
those use. Two samples each on two local workers: ~10 minutes for all of them, so ``slow``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from hil.dut.profile import load_profile, must_fail_claims
from hil.limits import is_conformance

ROOT = Path(__file__).resolve().parents[1]
MUST_FAIL = ROOT / "dut_profiles" / "must_fail"
#: seeds no discrimination test uses (they run at each scenario's own seed)
SEED = 7_700_000
NOT_PASSED = {"fail", "error"}
PROFILES = sorted(p for p in MUST_FAIL.glob("*.toml") if "-bus-" not in p.stem)


def test_every_non_bus_must_fail_profile_is_here() -> None:
    """The glob finds the profiles (a moved folder must not make this file vacuous), and
    each names what it fails."""
    assert len(PROFILES) >= 20
    for path in PROFILES:
        assert must_fail_claims(path), f"{path.name} has no '# must-fail:' header"


@pytest.mark.slow
@pytest.mark.parametrize("profile", PROFILES, ids=[p.stem for p in PROFILES])
def test_must_fail_fails_every_sample_of_a_campaign(tmp_path: Path, profile: Path) -> None:
    out = tmp_path / "camp"
    named = must_fail_claims(profile)
    # a campaign's samples keep no bus log: the bus conformance its header may name alone is
    # judged in the reruns with full recording, and one failing there fails the campaign
    bus_only = all(is_conformance(n) for n in named)
    proc = subprocess.run(
        [sys.executable, "-m", "hil", "campaign", str(profile), "--samples", "2",
         "--seed", str(SEED), "--bus", "inline", "--dispersion", "none",
         "--suite", "isobus" if load_profile(profile).wiring.isobus else "fast,robustness",
         "--workers", "2", "--max-reruns", "1" if bus_only else "0",
         "--no-progress", "--out", str(out)],
        capture_output=True, text=True, cwd=ROOT, timeout=1800)
    assert (out / "campaign.json").exists(), proc.stdout + proc.stderr
    doc = json.loads((out / "campaign.json").read_text())
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert doc["summary"]["verdict"] == "fail", doc["summary"]
    samples = doc["samples"]
    assert len(samples) == 2
    if bus_only:
        [rerun] = doc["reruns"]
        assert named & set(rerun["conformance_failed"]), rerun
        # the campaign fails on the conformance its header names, or earlier when the defect
        # also fails the samples (a VT client maintaining every 2 s also gets its pool active
        # late): the rerun above still shows the named conformance failing
        assert doc["summary"]["reason"].startswith(
            ("bus conformance failed", f"{len(samples)} of {len(samples)} samples failed")
        ), doc["summary"]
        return
    for sample in samples:
        assert sample["verdict"] == "fail", (sample["seed"], sample.get("error"))
        measured = {m["name"] for m in sample["measurements"]}
        checked = named & measured
        # the busload suite is not in this campaign; everything else a header names is
        assert checked and all(n.split(".")[1] == "busload" for n in named - measured), (
            f"seed {sample['seed']}: header names {sorted(named - measured)}, not measured")
        for name in sorted(checked):
            outcomes = [m["outcome"] for m in sample["measurements"] if m["name"] == name]
            assert NOT_PASSED & set(outcomes), (
                f"{profile.stem}, seed {sample['seed']}: {name} passed every condition "
                f"({outcomes})")


@pytest.mark.slow
def test_ignoring_the_calibration_test_fails_the_dispersed_campaign(tmp_path: Path) -> None:
    """On the shipped dispersion every sample draws its own lot and the terminal sends the
    operator's test of it (MeterCalibration): a controller that ignores the test fails every
    sample on the tested lot's step, what its header names."""
    profile = MUST_FAIL / "fertilizer-ignores-calibration-daemon.toml"
    out = tmp_path / "camp"
    proc = subprocess.run(
        [sys.executable, "-m", "hil", "campaign", str(profile), "--samples", "2",
         "--seed", str(SEED + 100), "--bus", "inline", "--suite", "fast,robustness",
         "--workers", "2", "--max-reruns", "0", "--no-progress", "--out", str(out)],
        capture_output=True, text=True, cwd=ROOT, timeout=1800)
    assert (out / "campaign.json").exists(), proc.stdout + proc.stderr
    doc = json.loads((out / "campaign.json").read_text())
    assert proc.returncode == 1 and doc["summary"]["verdict"] == "fail", doc["summary"]
    assert doc["dispersion"]["parameters"], doc.get("dispersion")
    for sample in doc["samples"]:
        assert sample["verdict"] == "fail", (sample["seed"], sample.get("error"))
        outcomes = [m["outcome"] for m in sample["measurements"]
                    if m["name"] == "flow.lot.calibrated.overshoot"]
        assert outcomes and NOT_PASSED & set(outcomes), (sample["seed"], outcomes)
