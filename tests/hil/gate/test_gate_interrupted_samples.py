"""``hil gate`` on a campaign interrupted in part: a campaign that ran to its end while some
of its samples were interrupted (a worker stopped under them: their own qualification cut
short) says ``complete``, and the gate answered inconclusive (3) or fail (1) on the samples
that ran without a word about the others (issue 43). Those samples did not run: they count as
missing, the gate says how many and which, and only a verdict the samples that ran settle
whatever the missing ones would give is one (else no verdict, exit 2)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.campaign.engine import Campaign, CampaignPlan
from hil.cli.main import main
from hil.dut.profile import load_profile

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"


def _sample(i: int, verdict: str) -> dict:
    measured = [] if verdict == "interrupted" else [
        {"name": "flow.field.accuracy", "conditions": {"speed_kmh": 4}, "value": 99.0,
         "unit": "%", "low": 97.5, "high": None,
         "outcome": "pass" if verdict == "pass" else "fail"}]
    return {"index": i, "seed": i, "overrides": {}, "verdict": verdict,
            "error": "interrupted" if verdict == "interrupted" else None, "failed_tests": [],
            "worker": "w", "wall_s": 1.0, "measurements": measured}


def _campaign(out: Path, verdicts: list[str]) -> Path:
    """A fixed-rule campaign of 300 samples that ran to its end, as ``hil campaign`` writes
    it (the profile asks 0.975 at 95 % confidence)."""
    plan = CampaignPlan(profile=load_profile(REFERENCE), samples=len(verdicts), rule="fixed")
    campaign = Campaign(plan, out, engine={"kind": "local", "workers": 2})
    for i, verdict in enumerate(verdicts):
        campaign.add(_sample(i, verdict))
    campaign.status = "complete"
    campaign.close()
    campaign.write()
    return out / "campaign.json"


def test_an_undecided_campaign_with_interrupted_samples_has_no_verdict_and_says_why(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # 280 passes and 5 failures are inconclusive for 0.975; 15 samples did not run
    path = _campaign(tmp_path, ["pass"] * 280 + ["fail"] * 5 + ["interrupted"] * 15)
    doc = json.loads(path.read_text())
    assert doc["status"] == "complete"
    # the campaign's own summary says it too
    assert "15 of the samples not counted were interrupted" in doc["summary"]["reason"]
    assert main(["gate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "interrupted in part" in err and "285 of 300 samples run" in err, err
    assert "15 interrupted: 285, 286" in err and "no verdict" in err, err


def test_a_failure_the_missing_samples_cannot_undo_fails_and_says_they_are_missing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # 13 failures fail 0.975 over 300 samples whatever the 17 interrupted ones give
    path = _campaign(tmp_path, ["fail"] * 13 + ["pass"] * 270 + ["interrupted"] * 17)
    assert main(["gate", str(path)]) == 1
    out = capsys.readouterr().out
    assert "FAIL" in out
    assert "interrupted in part: 17 of 300 samples were interrupted (283, 284" in out, out


def test_a_campaign_without_interrupted_samples_is_judged_as_before(tmp_path: Path) -> None:
    path = _campaign(tmp_path, ["pass"] * 280 + ["fail"] * 5 + ["error"] * 15)
    assert main(["gate", str(path)]) == 3
