"""A SIGINT at every phase boundary of ``hil campaign`` (issue 30), injected through
``HIL_TEST_SIGNAL_AT`` (:mod:`hil.cli.phases`) rather than by timing: the campaign started,
after a sample, with its record written, as the reruns start, while it is promoted. Sent to
the whole process group, as a terminal's Ctrl-C is, so the Dask workers get it too. Whatever
the phase: exit 130, a console without tracebacks, a record that says what it is (never a
gate pass unless it completed), the previous campaign kept and nothing staged left behind."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"
HIL = [sys.executable, "-m", "hil"]
PREVIOUS = {"schema": "agrihil.campaign/1", "status": "complete", "run": "previous"}
PHASES = ["campaign:started", "campaign:sample@1", "campaign:written", "campaign:rerun",
          "campaign:promote"]


def _campaign(out: Path, at: str) -> subprocess.CompletedProcess[str]:
    out.mkdir(parents=True)
    (out / "campaign.json").write_text(json.dumps(PREVIOUS))
    return subprocess.run(
        [*HIL, "campaign", str(REFERENCE), "--samples", "3", "--bus", "inline", "--workers",
         "2", "--dispersion", "none", "-k", "test_flow_step and 23", "--max-reruns", "1",
         "--no-progress", "--out", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=600, start_new_session=True,
        env={**os.environ, "HIL_TEST_SIGNAL_AT": f"{at}/group"})


@pytest.mark.slow
@pytest.mark.parametrize("at", PHASES)
def test_ctrl_c_at_each_phase_of_a_campaign(tmp_path: Path, at: str) -> None:
    out = tmp_path / "c"
    done = _campaign(out, at)
    assert done.returncode == 130, done.stderr[-3000:]
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr, \
        done.stderr[-3000:]
    assert done.stderr.strip().splitlines()[-1].startswith("hil: interrupted")
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]
    assert json.loads((out / "campaign.previous.json").read_text()) == PREVIOUS
    doc = json.loads((out / "campaign.json").read_text())
    gate = subprocess.run([*HIL, "gate", str(out / "campaign.json")], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    if at == "campaign:promote":    # held while it moved in: a finished campaign, then 130
        assert doc["status"] == "complete" and len(doc["samples"]) == 3
        assert gate.returncode == 3, gate.stdout + gate.stderr   # 3 samples: inconclusive
    else:
        assert doc["status"] == "interrupted", doc["status"]
        assert gate.returncode == 2 and "no verdict" in gate.stderr, gate.stderr
        lines = (out / "samples.jsonl").read_text().splitlines()
        assert len(lines) == len(doc["samples"]) < 3 or at in ("campaign:written",
                                                              "campaign:rerun")
