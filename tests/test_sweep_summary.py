"""scripts/sweep_summary.py: a campaign's samples summarised, and bad input refused by name."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from hil.dut.build import PROJECT_ROOT

SCRIPT = PROJECT_ROOT / "scripts" / "sweep_summary.py"


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=60, check=False)


def _sample(seed: int, value: float) -> dict:
    return {"seed": seed, "verdict": "pass" if value <= 5.0 else "fail",
            "measurements": [{"name": "flow.step.overshoot", "conditions": {"target_gps": 23},
                              "value": value, "unit": "%", "low": None, "high": 5.0,
                              "outcome": "pass" if value <= 5.0 else "fail"}]}


def test_a_summary_counts_and_names_the_failures(tmp_path: Path) -> None:
    path = tmp_path / "samples.jsonl"
    path.write_text("".join(json.dumps(_sample(s, v)) + "\n"
                            for s, v in ((1, 2.0), (2, 5.5), (3, 3.0))))
    proc = _run(str(path))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("3 seeds, 2 pass, 1 not")
    assert "seed 2: flow.step.overshoot[target_gps=23] = 5.5 fail" in proc.stdout


def test_a_missing_or_broken_file_is_named_without_a_traceback(tmp_path: Path) -> None:
    proc = _run(str(tmp_path / "none.jsonl"))
    assert proc.returncode == 2
    assert "cannot read" in proc.stderr and "none.jsonl" in proc.stderr
    assert "Traceback" not in proc.stderr
    bad = tmp_path / "bad.jsonl"
    bad.write_text(json.dumps(_sample(1, 1.0)) + "\n{not json\n")
    proc = _run(str(bad))
    assert proc.returncode == 2 and "bad.jsonl:2: not a JSON sample" in proc.stderr
    assert "Traceback" not in proc.stderr
