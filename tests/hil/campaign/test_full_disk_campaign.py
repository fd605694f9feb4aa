"""A full disk during ``hil campaign`` (issue 30): exit 2 with one line naming the path and the
reason, no traceback, no staging directory left, the previous campaign's record and samples
kept (``campaign.json`` says the new one did not finish, so no gate passes it).

Two disks that fill up, as in tests/hil/reliability/test_full_disk_run.py: a 300 kB tmpfs as
``--out`` (root only: "No space left on device" as the record is written), and a 100 kB
file-size limit (``RLIMIT_FSIZE``, any user: "File too large"), which the samples' records
pass and the rerun's traces and ``report.html`` do not.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from tests.hil.reliability.test_full_disk_run import LIMIT, small_disk

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"
HIL = [sys.executable, "-m", "hil"]
PREVIOUS = {"schema": "agrihil.campaign/1", "status": "complete", "run": "previous"}
PREVIOUS_SAMPLES = '{"index": 0, "previous": true}\n'


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def _campaign(out: Path, *, limited: bool) -> subprocess.CompletedProcess[str]:
    out.mkdir(parents=True)
    (out / "campaign.json").write_text(json.dumps(PREVIOUS))
    (out / "samples.jsonl").write_text(PREVIOUS_SAMPLES)
    return subprocess.run(
        [*HIL, "campaign", str(REFERENCE), "--samples", "2", "--bus", "inline", "--workers",
         "1", "--dispersion", "none", "-k", "test_flow_step and 23", "--max-reruns", "1",
         "--no-progress", "--out", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
        preexec_fn=_limit_file_size if limited else None)


def _assert_named_and_kept(done: subprocess.CompletedProcess[str], out: Path,
                           reason: str) -> None:
    assert done.returncode == 2, done.stderr[-3000:]
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    line = done.stderr.strip().splitlines()[-1]
    assert line.startswith("hil: error: ") and reason in line and str(out) in line, line
    assert not [p.name for p in out.iterdir() if p.name.startswith(".campaign-")]
    assert json.loads((out / "campaign.previous.json").read_text()) == PREVIOUS
    assert (out / "samples.jsonl").read_text() == PREVIOUS_SAMPLES
    assert json.loads((out / "campaign.json").read_text())["status"] != "complete"


@pytest.mark.slow
def test_a_full_tmpfs_names_the_path_and_keeps_the_previous_campaign(tmp_path: Path) -> None:
    with small_disk(tmp_path / "disk") as disk:
        out = disk / "c"
        done = _campaign(out, limited=False)
        _assert_named_and_kept(done, out, "No space left on device")


@pytest.mark.slow
def test_a_file_size_limit_names_the_path_and_keeps_the_previous_campaign(
        tmp_path: Path) -> None:
    out = tmp_path / "c"
    done = _campaign(out, limited=True)
    _assert_named_and_kept(done, out, "File too large")
