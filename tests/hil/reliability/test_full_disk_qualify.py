"""A file-size limit during ``hil qualify`` (issue 30): the disk refusing a run's traces or bus
log is a storage error like a refused record: exit 2 with one line naming ``--out`` and the
reason, no staging left, the previous record kept.

A file-size limit (``RLIMIT_FSIZE``, 100 kB) refuses writes for any user with "File too large".
Before, the recorder only noted the refusal in the run's ``recorder_problems``, and qualify went
on to judge the truncated run ("ERROR (no measurements)") without naming the disk. The 300 kB
tmpfs case is tests/hil/reliability/test_qualify_setup_errors.py's.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

from tests.hil.reliability.test_qualify_setup_errors import PREVIOUS, PROFILE, _previous

ROOT = Path(__file__).resolve().parents[3]
LIMIT = 100 * 1024


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def test_a_file_size_limit_names_the_path_and_keeps_the_previous_record(tmp_path: Path) -> None:
    out = tmp_path / "q"
    _previous(out)
    done = subprocess.run(
        [sys.executable, "-m", "hil", "qualify", str(PROFILE), "--bus", "inline", "--suite",
         "fast", "-k", "flow_step and 23", "--quiet", "--out", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=300, preexec_fn=_limit_file_size)
    assert done.returncode == 2, done.stdout[-2000:] + done.stderr[-2000:]
    assert "Traceback" not in done.stderr, done.stderr
    line = done.stderr.strip().splitlines()[-1]
    assert line.startswith("hil: error: ") and "File too large" in line and str(out) in line, \
        line
    left = sorted(p.name for p in out.iterdir())
    assert not [n for n in left if n.startswith(".qualify-")], left
    assert json.loads((out / "record.previous.json").read_text()) == PREVIOUS
    assert json.loads((out / "record.json").read_text())["verdict"] != "pass"
