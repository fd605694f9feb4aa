"""One rule for every record kind: an interrupted or incomplete record is never a pass (exit 2,
saying why), with or without a baseline (issue 30)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.cli.main import main
from hil.gate.completeness import incomplete_reason


def campaign_doc(status: str = "complete", *, samples: int = 3, requested: int = 3,
                 verdict: str = "pass", rig: str = "fertilizer", name: str = "x") -> dict:
    sample = [{"index": i, "seed": i, "verdict": "pass", "measurements": [
        {"name": "flow.field.accuracy", "conditions": {"speed_kmh": 4}, "value": 99.0 + i / 10,
         "low": 97.5, "high": None, "outcome": "pass"}]} for i in range(samples)]
    return {"schema": "agrihil.campaign/1", "status": status, "dut": {"name": name},
            "rig": {"name": rig}, "samples": sample, "samples_requested": requested,
            "summary": {"verdict": verdict, "reason": "r"}, "measurements": {}, "reruns": []}


def qualification_doc(verdict: str = "pass", complete: bool = True) -> dict:
    return {"schema": "agrihil.qualification/1", "run_id": "r", "verdict": verdict,
            "complete": complete, "dut": {"name": "x"}, "measurements": []}


def _write(tmp_path: Path, name: str, doc: dict) -> str:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return str(path)


INCOMPLETE = {"campaign-interrupted": campaign_doc("interrupted"),
              "campaign-running": campaign_doc("running"),
              "campaign-short": campaign_doc("complete", samples=2, requested=3),  # says complete
              "qual-interrupted": qualification_doc("interrupted", complete=False),
              "qual-incomplete": qualification_doc("pass", complete=False)}


@pytest.mark.parametrize("kind", sorted(INCOMPLETE))
@pytest.mark.parametrize("with_baseline", [False, True])
def test_incomplete_records_never_gate_green(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            kind: str, with_baseline: bool) -> None:
    doc = INCOMPLETE[kind]
    record = _write(tmp_path, "record.json", doc)
    argv = ["gate", record]
    if with_baseline:   # a campaign's baseline is a campaign; a qualification's, a baseline
        base = (_write(tmp_path, "base.json", campaign_doc())
                if doc["schema"] == "agrihil.campaign/1" else str(tmp_path / "none.json"))
        argv += ["--baseline", base]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "hil: error:" in err and record in err
    assert "no verdict" in err


def test_a_complete_campaign_still_passes(tmp_path: Path) -> None:
    assert main(["gate", _write(tmp_path, "c.json", campaign_doc())]) == 0
    base = _write(tmp_path, "b.json", campaign_doc())
    assert main(["gate", _write(tmp_path, "c.json", campaign_doc()), "--baseline", base]) == 0


def test_an_interrupted_baseline_is_refused(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    base = _write(tmp_path, "b.json", campaign_doc("interrupted"))
    assert main(["gate", _write(tmp_path, "c.json", campaign_doc()), "--baseline", base]) == 2
    assert "--baseline" in capsys.readouterr().err


def test_the_rule_is_one_function_of_the_document() -> None:
    assert incomplete_reason(campaign_doc(), path="c") is None
    assert incomplete_reason(qualification_doc(), path="q") is None
    assert incomplete_reason(qualification_doc("fail", complete=False), path="q") is None
    assert "interrupted" in (incomplete_reason(campaign_doc("interrupted"), path="c") or "")
    assert "2 of 3" in (incomplete_reason(campaign_doc(samples=2), path="c") or "")


def test_baseline_of_another_rig_is_exit_2_naming_both(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = _write(tmp_path, "c.json", campaign_doc())
    base = _write(tmp_path, "b.json", campaign_doc(rig="sowing-depth", name="y"))
    assert main(["gate", record, "--baseline", base]) == 2
    err = capsys.readouterr().err
    assert "--baseline" in err and "sowing-depth" in err and "fertilizer" in err


@pytest.mark.parametrize("value", ["-1", "nan", "inf", "0", "1.5"])
def test_shift_fraction_out_of_range_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                               value: str) -> None:
    record = _write(tmp_path, "c.json", campaign_doc())
    assert main(["gate", record, f"--shift-fraction={value}"]) == 2
    assert "--shift-fraction" in capsys.readouterr().err
