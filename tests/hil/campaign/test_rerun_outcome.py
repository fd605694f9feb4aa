"""A rerun that could not run says so: never "NOT reproduced" (issue 30: a rerun that hit a
file-size limit was reported as not reproducing its sample)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.cli.campaign import _report
from hil.report.campaign_page import _reproduced


def _doc(rerun: dict[str, object]) -> dict[str, object]:
    return {"dut": {"name": "d"}, "wall_s": 1.0, "decision": None, "reruns": [rerun],
            "summary": {"pass_rate": 1.0, "verdict": "pass", "reason": "all passed",
                        "passed": 3, "judged": 3, "ci95": [0.3, 1.0], "errors": 0}}


def _rerun(verdict: str, reproduced: bool | None, error: str | None = None) -> dict[str, object]:
    return {"index": 2, "seed": 7, "why": ["worst x"], "dir": "samples/0002",
            "report": "samples/0002/report.html", "command": "hil qualify p.toml --seed 7",
            "verdict": verdict, "error": error, "reproduced": reproduced}


@pytest.mark.parametrize(("rerun", "says", "never"), [
    (_rerun("pass", True), "hil qualify p.toml --seed 7\n", "NOT"),
    (_rerun("pass", False), "NOT reproduced", "rerun failed"),
    (_rerun("error", None, "samples/0002/record.json: File too large"),
     "the rerun failed: samples/0002/record.json: File too large", "NOT reproduced"),
])
def test_the_console_tells_a_failed_rerun_from_one_that_did_not_reproduce(
        rerun: dict[str, object], says: str, never: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    _report(_doc(rerun), tmp_path)
    err = capsys.readouterr().err
    assert says in err and never not in err, err


def test_the_report_tells_them_apart_too() -> None:
    assert _reproduced(_rerun("pass", True)) == "yes"
    assert _reproduced(_rerun("pass", False)) == "<b>NO</b>"
    cell = _reproduced(_rerun("error", None, "a <disk> full"))
    assert cell.startswith("<b>rerun failed</b>") and "a &lt;disk&gt; full" in cell
