"""A full disk during ``hil run`` (issue 30): exit 2 with one line naming the path and the
reason, no traceback, no staging directory left, the previous run's record and files kept.

Two disks that fill up: a 300 kB tmpfs mounted as ``--out`` (a real "No space left on
device"; mounting needs root, as in the qualify test of tests/hil/reliability/
test_qualify_setup_errors.py), and, for any user, a file-size limit (``RLIMIT_FSIZE``, 100 kB:
the kernel refuses the write beyond it with "File too large", through the same write paths).
Before staging, the run wrote into ``--out`` directly: on the small tmpfs it left truncated
bus logs and an empty traces.npz over the previous run's; under the limit it exited 0 with
truncated files and the failure only in the record's ``recorder_problems``.
"""

from __future__ import annotations

import contextlib
import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from tests.hil.reliability.test_qualify_setup_errors import _tiny_disk
from tests.hil.reliability.test_run_staging import PREVIOUS, RUN, previous_run

ROOT = Path(__file__).resolve().parents[3]
HIL = [sys.executable, "-m", "hil"]
LIMIT = 100 * 1024


def small_disk(where: Path) -> contextlib.AbstractContextManager[Path]:
    """A 300 kB tmpfs at ``where`` (the qualify test's); skips where it cannot be mounted."""
    if os.geteuid() != 0:
        pytest.skip("mounting a 300 kB tmpfs needs root")
    return _tiny_disk(where)


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def _run(out: Path, *, limited: bool) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*HIL, *RUN, "--out", str(out)], cwd=ROOT, capture_output=True,
                          text=True, timeout=300,
                          preexec_fn=_limit_file_size if limited else None)


def _assert_named_and_kept(done: subprocess.CompletedProcess[str], out: Path,
                           files: dict[str, bytes], reason: str) -> None:
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    line = done.stderr.strip().splitlines()[-1]
    assert line.startswith("hil: error: ") and reason in line and str(out) in line, line
    assert not [p.name for p in out.iterdir() if p.name.startswith(".run-")]
    # the previous run's files as they were; its record kept, and record.json says the new
    # run did not finish
    for name in ("bus.log", "traces.npz", "notes.txt"):
        assert (out / name).read_bytes() == files[name], name
    assert json.loads((out / "record.previous.json").read_text()) == PREVIOUS
    record = json.loads((out / "record.json").read_text())
    assert record["run_id"] != "old" and record["verdict"] == "aborted", record


def test_a_full_tmpfs_names_the_path_and_keeps_the_previous_run(tmp_path: Path) -> None:
    with small_disk(tmp_path / "disk") as disk:
        out = disk / "run"
        files = previous_run(out)
        done = _run(out, limited=False)
        _assert_named_and_kept(done, out, files, "No space left on device")


def test_a_file_size_limit_names_the_path_and_keeps_the_previous_run(tmp_path: Path) -> None:
    out = tmp_path / "run"
    files = previous_run(out)
    done = _run(out, limited=True)
    _assert_named_and_kept(done, out, files, "File too large")
