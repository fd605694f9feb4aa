"""``hil run`` stages its run and promotes it, as ``hil qualify`` does (issue 30).

A run refused at setup (here: a DUT command that cannot be executed) leaves ``--out`` exactly as
it was; a run that completes replaces the previous run's files, keeps its record as
``record.previous.json`` and leaves no staging directory behind.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests.hil.reliability.conftest import dying_profile_text

ROOT = Path(__file__).resolve().parents[3]
HIL = [sys.executable, "-m", "hil"]
#: a short run of the builtin controller on the inline bus (about a second)
RUN = ["run", "--rig", "fertilizer", "--dut", "builtin:pi", "--scenario", "bench-step-23",
       "--bus", "inline"]
PREVIOUS = {"run_id": "old", "verdict": "pass", "error": None, "measurements": []}


def hil(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*HIL, *argv], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)


def previous_run(out: Path) -> dict[str, bytes]:
    """A previous run's files in ``out`` (their bytes, to compare with afterwards)."""
    out.mkdir(parents=True, exist_ok=True)
    files = {"record.json": json.dumps(PREVIOUS).encode(), "bus.log": b"(0.0) can0 710#00\n",
             "traces.npz": b"previous traces", "notes.txt": b"the user's own file"}
    for name, data in files.items():
        (out / name).write_bytes(data)
    return files


def contents(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in out.iterdir()}


def test_a_run_refused_at_setup_leaves_out_as_it_was(tmp_path: Path) -> None:
    """Before: the DUT's command was found not executable inside the run, after the recorder
    had replaced record.json (verdict error) and emptied bus.log and traces.npz."""
    binary = tmp_path / "dut-fw"
    binary.write_text("#!/bin/sh\nexit 0\n")
    binary.chmod(0o644)                                       # chmod -x
    profile = tmp_path / "toy.toml"
    profile.write_text(dying_profile_text("toy", "x").replace(
        'command = ["{python}", ', f'command = ["{binary}", "--bus", "{{bus}}"] # ', 1))
    out = tmp_path / "run"
    files = previous_run(out)
    done = hil("run", "--dut", str(profile), "--scenario", "bench-step-23", "--out", str(out))
    assert done.returncode == 2, done.stderr
    line = done.stderr.strip().splitlines()[-1]
    assert str(binary) in line and "launch.command" in line, line
    assert "Traceback" not in done.stderr
    assert contents(out) == files


def test_a_finished_run_replaces_the_previous_one_and_keeps_its_record(tmp_path: Path) -> None:
    out = tmp_path / "run"
    previous_run(out)
    done = hil(*RUN, "--out", str(out))
    assert done.returncode == 0, done.stderr
    record = json.loads((out / "record.json").read_text())
    assert record["verdict"] == "no-measurements" and record["run_id"] != "old"
    assert json.loads((out / "record.previous.json").read_text()) == PREVIOUS
    for name in record["artifacts"]:                           # every file the record lists
        assert (out / name).is_file(), name
    assert (out / "traces.npz").read_bytes() != b"previous traces"
    assert (out / "notes.txt").read_bytes() == b"the user's own file"
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]
