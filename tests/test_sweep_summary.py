"""scripts/sweep_summary.py: a campaign's samples summarised, and bad input refused by name."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from hil.dut.build import PROJECT_ROOT

SCRIPT = PROJECT_ROOT / "scripts" / "sweep_summary.py"


@pytest.fixture
def run(capsys: pytest.CaptureFixture[str]):
    """The script's ``main`` in this process (its output captured), as ``python SCRIPT``."""
    spec = importlib.util.spec_from_file_location("sweep_summary", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)

    def _run(*args: str) -> SimpleNamespace:
        code = module.main(list(args))
        out = capsys.readouterr()
        return SimpleNamespace(returncode=code, stdout=out.out, stderr=out.err)
    return _run


def _sample(seed: int, value: float) -> dict:
    return {"seed": seed, "verdict": "pass" if value <= 5.0 else "fail",
            "measurements": [{"name": "flow.step.overshoot", "conditions": {"target_gps": 23},
                              "value": value, "unit": "%", "low": None, "high": 5.0,
                              "outcome": "pass" if value <= 5.0 else "fail"}]}


def test_a_summary_counts_and_names_the_failures(tmp_path: Path, run) -> None:
    path = tmp_path / "samples.jsonl"
    path.write_text("".join(json.dumps(_sample(s, v)) + "\n"
                            for s, v in ((1, 2.0), (2, 5.5), (3, 3.0))))
    proc = run(str(path))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("3 seeds, 2 pass, 1 not")
    assert "seed 2: flow.step.overshoot[target_gps=23] = 5.5 fail" in proc.stdout


def test_a_missing_or_broken_file_is_named_without_a_traceback(tmp_path: Path, run) -> None:
    proc = run(str(tmp_path / "none.jsonl"))
    assert proc.returncode == 2
    assert "cannot read" in proc.stderr and "none.jsonl" in proc.stderr
    assert "Traceback" not in proc.stderr
    bad = tmp_path / "bad.jsonl"
    bad.write_text(json.dumps(_sample(1, 1.0)) + "\n{not json\n")
    proc = run(str(bad))
    assert proc.returncode == 2 and "bad.jsonl:2: not a JSON sample" in proc.stderr
    assert "Traceback" not in proc.stderr
