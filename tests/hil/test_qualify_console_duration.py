"""``hil qualify`` prints one duration, the command's wall time (issue 31.7)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PROFILE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"


def test_qualify_prints_one_duration_and_it_is_the_wall_time(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "hil", "qualify", str(PROFILE), "--bus", "inline",
         "--out", str(tmp_path / "q"), "-k", "flow_step and 23"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    text = done.stdout + done.stderr
    durations = re.findall(r"\bin \d+(?:\.\d+)?\s?s\b", text)
    assert len(durations) == 1, durations
    assert re.search(r"PASS \(.*\) in \d+\.\d s \(wall time", text)
    assert "passed" in text      # pytest's count line stays, without its own time
