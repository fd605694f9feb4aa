"""``hil gate campaign.json`` on the stated requirement (issue 29), on synthetic campaigns
written the way ``hil campaign`` writes them (:class:`hil.campaign.engine.Campaign`):
pass, fail and inconclusive each with its exit code, an early decision judged complete only
when its samples settle it, a record's verdict never taken on its word, and the compact
baseline giving the shift test what the whole record gives it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from hil.campaign.engine import Campaign, CampaignPlan
from hil.cli.main import main
from hil.dut.profile import load_profile
from hil.gate.campaign import compare_campaigns
from hil.gate.campaign_baseline import compact_baseline
from hil.gate.tolerance import Band, Tolerances
from tests.fuzz.cli import run_cli
from tests.fuzz.mutate import json_mutations

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
TOL = Tolerances(default=Band(abs=1.0))


def _sample(i: int, verdict: str, value: float = 99.0) -> dict:
    return {"index": i, "seed": i, "overrides": {}, "verdict": verdict, "error": None,
            "failed_tests": [], "worker": "w", "wall_s": 1.0, "measurements": [
                {"name": "flow.field.accuracy", "conditions": {"speed_kmh": 4},
                 "value": value, "unit": "%", "low": 97.5, "high": None,
                 "outcome": "pass" if verdict == "pass" else "fail"}]}


def _campaign(tmp: Path, verdicts: list[str], *, total: int = 300, rule: str = "curtailed",
              values: list[float] | None = None) -> tuple[Campaign, bool]:
    plan = CampaignPlan(profile=load_profile(REFERENCE), samples=total, rule=rule)
    campaign = Campaign(plan, tmp, engine={"kind": "local", "workers": 2})
    decided = False
    for i, v in enumerate(verdicts):
        decided = campaign.add(_sample(i, v, values[i] if values else 99.0))
        if decided:
            break
    campaign.status = "complete"
    campaign.close()
    campaign.write()
    return campaign, decided


def _gate(path: Path, *extra: str) -> int:
    return main(["gate", str(path), *extra])


def test_a_failing_build_stops_early_and_the_gate_fails_it(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    _, decided = _campaign(tmp_path, ["fail"] * 300)
    doc = json.loads((tmp_path / "campaign.json").read_text())
    assert decided and len(doc["samples"]) == 13
    d = doc["decision"]
    assert d["rule"] == "curtailed" and d["early"] and d["verdict"] == "fail"
    assert (d["samples_run"], d["samples_saved"]) == (13, 287)
    assert doc["summary"]["verdict"] == "fail" and "decided after 13 of 300" in \
        doc["summary"]["reason"]
    assert _gate(tmp_path / "campaign.json") == 1
    out = capsys.readouterr().out
    assert "FAIL" in out and "decided after 13 of 300 samples" in out


@pytest.mark.parametrize("failed", [[], ["isobus.claim.frames_before"]])
def test_a_rerun_failing_bus_conformance_fails_a_passing_campaign(
        tmp_path: Path, failed: list[str]) -> None:
    """The samples keep no bus log, so their reruns with full recording judge the bus
    conformance: a failure there fails the campaign, whose samples all passed, and its gate;
    without one the campaign passes."""
    campaign, _ = _campaign(tmp_path, ["pass"] * 300, rule="fixed")
    campaign.reruns.append({"index": 4, "seed": 4, "why": ["worst x"], "dir": "samples/0004",
                            "report": "samples/0004/report.html", "command": "hil qualify",
                            "verdict": "fail" if failed else "pass", "error": None,
                            "reproduced": True, "conformance_failed": failed})
    campaign.write()
    doc = json.loads((tmp_path / "campaign.json").read_text())
    if failed:
        assert doc["summary"]["verdict"] == "fail"
        assert doc["summary"]["reason"].startswith(
            "bus conformance failed in the rerun of sample 4 with full recording: "
            "isobus.claim.frames_before")
        assert _gate(tmp_path / "campaign.json") == 1
    else:
        assert doc["summary"]["verdict"] == "pass"
        assert _gate(tmp_path / "campaign.json") == 0


def test_a_short_record_the_rule_has_not_settled_has_no_verdict(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]
                                                                ) -> None:
    _campaign(tmp_path, ["fail"] * 12)          # 12 failures: 288 passes could still save it
    assert _gate(tmp_path / "campaign.json") == 2
    assert "no verdict" in capsys.readouterr().err
    # the same 13 failures as a decided campaign, but interrupted: no verdict either
    doc_path = tmp_path / "c2"
    _campaign(doc_path, ["fail"] * 300)
    doc = json.loads((doc_path / "campaign.json").read_text())
    doc["status"] = "interrupted"
    (doc_path / "campaign.json").write_text(json.dumps(doc))
    assert _gate(doc_path / "campaign.json") == 2


def test_pass_fail_inconclusive_have_their_exit_codes(tmp_path: Path) -> None:
    # 300 samples for 0.975: 2 failures pass, 5 are inconclusive, 13 fail
    for failures, code in ((2, 0), (5, 3), (13, 1)):
        out = tmp_path / f"f{failures}"
        verdicts = ["fail"] * failures + ["pass"] * (300 - failures)
        _campaign(out, verdicts[::-1], rule="fixed")      # failures last: nothing stops it
        assert _gate(out / "campaign.json") == code, failures


def test_a_record_claiming_a_pass_is_judged_by_its_samples(tmp_path: Path) -> None:
    _campaign(tmp_path, ["pass"] * 290 + ["fail"] * 10, rule="fixed")
    path = tmp_path / "campaign.json"
    doc = json.loads(path.read_text())
    assert doc["summary"]["verdict"] == "inconclusive"
    doc["summary"]["verdict"] = "pass"
    path.write_text(json.dumps(doc))
    assert _gate(path) == 3
    # nor is a requirement out of its range taken: exit 2 naming the key
    doc["requirement"]["pass_probability"] = 1.5
    path.write_text(json.dumps(doc))
    assert _gate(path) == 2


def test_sequential_record_is_checked_in_index_order(tmp_path: Path) -> None:
    _, decided = _campaign(tmp_path, ["fail", "fail"] + ["pass"] * 298,
                                  rule="sequential")
    doc = json.loads((tmp_path / "campaign.json").read_text())
    assert decided and doc["decision"]["verdict"] == "fail" and len(doc["samples"]) == 2
    assert doc["decision"]["sprt"]["beta"] == pytest.approx(0.05)
    assert _gate(tmp_path / "campaign.json") == 1
    # a sequential record missing sample 1 has not decided: no verdict
    doc["samples"] = [s if s["index"] == 0 else {**s, "index": 5} for s in doc["samples"]]
    (tmp_path / "campaign.json").write_text(json.dumps(doc))
    assert _gate(tmp_path / "campaign.json") == 2


def test_compact_baseline_gives_the_shift_test_what_the_record_gives(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(7)
    base_values = list(rng.normal(99.3, 0.5, 40))
    _campaign(tmp_path / "base", ["pass"] * 40, total=40, rule="fixed", values=base_values)
    base_path = tmp_path / "base" / "campaign.json"
    base = json.loads(base_path.read_text())
    compact = compact_baseline(base, created_at="now")
    assert compact["n"] == 40 and len(json.dumps(compact)) < len(json.dumps(base)) / 5
    m = compact["measurements"]["flow.field.accuracy[speed_kmh=4]"]
    assert m["n"] == 40 and m["passed"] == 40
    assert m["mean"] == pytest.approx(np.mean(base_values))
    assert m["quantiles"]["0.5"] == pytest.approx(np.median(base_values))
    # 30 samples cannot demonstrate 0.975: inconclusive, unless a shift fails the build
    for shift, expected in ((0.0, "inconclusive"), (-1.0, "fail")):
        values = list(rng.normal(99.3 + shift, 0.5, 30))
        new_dir = tmp_path / f"new{shift}"
        _campaign(new_dir, ["pass"] * 30, total=30, rule="fixed", values=values)
        new = json.loads((new_dir / "campaign.json").read_text())
        full = compare_campaigns(new, base, TOL)
        small = compare_campaigns(new, compact, TOL)
        assert full.verdict == small.verdict == expected
        assert [r.p_value for r in small.rows] == pytest.approx([r.p_value for r in full.rows])
    # written by the gate, and read back by it
    store = tmp_path / "ci" / "campaign-x.json"
    # (an inconclusive campaign may be a baseline: it says nothing against the build)
    assert _gate(base_path, "--baseline", str(store), "--update-baseline") == 3
    assert json.loads(store.read_text())["schema"] == "agrihil.campaign-baseline/1"
    assert "n = 40" in capsys.readouterr().out
    tolerance = tmp_path / "tol.toml"
    tolerance.write_text("[default]\nabs = 1.0\n")     # TOL, as a file
    assert _gate(new_dir / "campaign.json", "--baseline", str(store),
                 "--tolerance", str(tolerance)) == 1


COMPACT = ROOT / "ci" / "baselines" / "campaign-fertilizer-piecewise-pid-daemon.json"


@given(case=json_mutations(COMPACT))
@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_a_damaged_compact_baseline_is_refused_or_judged_never_a_traceback(
        case: tuple[str, bytes], tmp_path_factory: pytest.TempPathFactory) -> None:
    """The stored compact baseline, mutated (a key deleted, retyped, a NaN, truncation ...):
    ``hil gate`` refuses it in one line naming the file (exit 2) or judges with it."""
    what, content = case
    tmp = tmp_path_factory.mktemp("compact")
    record = tmp / "camp"
    _campaign(record, ["pass"] * 5, total=5, rule="fixed")
    path = tmp / "baseline.json"
    path.write_bytes(content)
    outcome = run_cli("gate", str(record / "campaign.json"), "--baseline", str(path))
    assert "Traceback" not in outcome.stderr and "internal error" not in outcome.stderr, \
        (what, outcome.stderr)
    assert outcome.code in (0, 1, 2, 3), (what, outcome)
    if outcome.code == 2:
        assert len(outcome.error_lines()) == 1 and path.name in outcome.stderr, (what, outcome)


FUZZ_RECORD = ROOT / "tests" / "fuzz" / "data" / "campaign.json"


@pytest.mark.parametrize(("where", "value", "key"), [
    ("requirement", "x", "[requirement]"),
    ("requirement", {"pass_probability": 2, "confidence": 0.9},
     "[requirement.pass_probability] pass_probability must be a number 0 < x < 1"),
    ("decision", [], "[decision]"),
    ("decision", {"rule": "zz"}, "[decision.rule]"),
    ("decision", {"rule": "sequential"}, "[requirement.sequential_good_probability]"),
    ("samples.0.index", None, "[samples[0].index]"),
])
def test_a_damaged_requirement_or_decision_is_refused_naming_the_key(
        tmp_path: Path, where: str, value: object, key: str) -> None:
    doc = json.loads(FUZZ_RECORD.read_text())
    if where == "samples.0.index":
        del doc["samples"][0]["index"]
    else:
        doc[where] = value
    path = tmp_path / "campaign.json"
    path.write_text(json.dumps(doc))
    outcome = run_cli("gate", str(path))
    assert outcome.code == 2 and key in outcome.stderr and str(path) in outcome.stderr, outcome
    assert len(outcome.error_lines()) == 1
