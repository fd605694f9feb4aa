"""A real campaign of a clearly failing build, held to the reference's requirement, is decided in
at most 5 % of its 300 samples (issue 29); the gate agrees and accepts the short record.
The decision logic itself is proved on synthetic streams in test_early_decisions.py."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.campaign.held import held_to
from hil.cli.main import main

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"
MUST_FAIL = ROOT / "dut_profiles/must_fail/fertilizer-no-integral-daemon.toml"


@pytest.mark.slow
@pytest.mark.parametrize(("extra", "most"), [((), 15), (("--sequential",), 4)])
def test_a_failing_build_is_decided_in_5_percent_of_300(tmp_path: Path, extra: tuple[str, ...],
                                                        most: int,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    profile = held_to(MUST_FAIL, REFERENCE, tmp_path / "profile")
    out = tmp_path / "camp"
    code = main(["campaign", str(profile), "--samples", "300", "--bus", "inline", "--workers",
                 "2", "-k", "test_flow_step and 23", "--dispersion", "none", "--max-reruns",
                 "0", "--no-progress", "--out", str(out), *extra])
    doc = json.loads((out / "campaign.json").read_text())
    decision = doc["decision"]
    assert code == 1 and doc["status"] == "complete" and doc["summary"]["verdict"] == "fail"
    assert decision["early"] and decision["samples_run"] == len(doc["samples"]) <= most
    assert decision["samples_saved"] == 300 - len(doc["samples"])
    assert doc["summary"]["failed"] >= 2 and doc["summary"]["passed"] == 0
    err = capsys.readouterr().err
    assert f"decided after {len(doc['samples'])} of 300 samples" in err
    # the gate checks the rule again from the samples and fails the build (not "incomplete")
    assert main(["gate", str(out / "campaign.json")]) == 1
