"""A SIGINT at every phase of ``hil run`` (issue 30), injected at an exact point rather than by
timing: set up (before ``--out`` is touched), staged, in the middle of the run (the controller
sends it at its 100th frame), while the recorder writes the run's files, once the run is
written, while it is promoted. Whatever the phase the signal is not lost (exit 130, no
traceback, no staging left), and what ``--out`` holds says what it is: untouched, an
``aborted`` record (the previous one kept as ``record.previous.json``), or, when the signal
came after the run was complete, the complete run.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import can
import pytest

from plant_emulators.fertilizer.controllers import PiFlowController
from tests.hil.reliability.test_run_staging import PREVIOUS, RUN, contents, previous_run
from tests.hil.test_pytest_plugin import PROFILE

ROOT = Path(__file__).resolve().parents[3]
HIL = [sys.executable, "-m", "hil"]

#: phases marked by hil.cli.phases in hil run, in order
PHASES = ("run:built", "run:staged", "run:written", "run:promote")
#: hil run with Recorder.close sending SIGINT first: the signal lands as the recorder starts
#: writing the run's files (Recorder has no phase mark of its own)
IN_RECORDER = """
import os, signal, sys
from hil.record.recorder import Recorder
close = Recorder.close
def interrupted_close(self):
    os.kill(os.getpid(), signal.SIGINT)
    return close(self)
Recorder.close = interrupted_close
from hil.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


class SigintAtFrame(PiFlowController):
    """The builtin controller, sending its own process SIGINT at its ``at_frame``-th frame: a
    Ctrl-C in the middle of a lockstep run, at the same simulated moment every time."""

    name = "sigint-at-frame"

    def __init__(self, at_frame: int = 100) -> None:
        super().__init__()
        self.at_frame = at_frame
        self.frames = 0

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        self.frames += 1
        if self.frames == self.at_frame:
            os.kill(os.getpid(), signal.SIGINT)
        return super().on_frame(msg)


#: the plugin tests' in-process profile, with this controller
MID_RUN_PROFILE = PROFILE.replace("plant_emulators.fertilizer.controllers:PiFlowController",
                                  "tests.hil.reliability.test_signals_run:SigintAtFrame")


def _hil(argv: list[str], env: dict[str, str] | None = None,
         driver: str | None = None) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-c", driver] if driver else HIL
    return subprocess.run([*command, *argv], cwd=ROOT, capture_output=True, text=True,
                          timeout=300, env={**os.environ, **(env or {})})


def _assert_not_lost(done: subprocess.CompletedProcess[str], out: Path) -> dict:
    assert done.returncode == 130, done.stderr[-3000:]
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    assert done.stderr.strip().splitlines()[-1].startswith("hil: interrupted"), done.stderr
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]
    return json.loads((out / "record.json").read_text())


def _assert_aborted(record: dict, out: Path) -> None:
    assert record["run_id"] != "old" and record["verdict"] == "aborted", record
    assert json.loads((out / "record.previous.json").read_text()) == PREVIOUS
    for name in record.get("artifacts", []):       # what the record lists is there
        assert (out / name).is_file(), name


@pytest.mark.parametrize("at", PHASES)
def test_a_sigint_at_each_phase_of_a_run_is_never_lost(tmp_path: Path, at: str) -> None:
    out = tmp_path / "run"
    files = previous_run(out)
    done = _hil([*RUN, "--out", str(out)], env={"HIL_TEST_SIGNAL_AT": at})
    record = _assert_not_lost(done, out)
    if at == "run:built":
        assert contents(out) == files                 # --out untouched
    elif at in ("run:written", "run:promote"):
        # the run was complete and written: it is kept as it is, and the exit says 130
        assert record["run_id"] != "old" and record["verdict"] == "no-measurements", record
        assert record["error"] is None and (out / "traces.npz").stat().st_size > 1000
    else:
        _assert_aborted(record, out)


def test_a_sigint_in_the_middle_of_a_run(tmp_path: Path) -> None:
    profile = tmp_path / "toy-pi-inprocess.toml"
    profile.write_text(MID_RUN_PROFILE)
    out = tmp_path / "run"
    previous_run(out)
    done = _hil(["run", "--dut", str(profile), "--scenario", "bench-step-23", "--bus", "inline",
                 "--out", str(out)])
    record = _assert_not_lost(done, out)
    _assert_aborted(record, out)
    assert 0 < record["sim_s"] < 23.0, record["sim_s"]      # cut short, what ran is recorded
    assert "traces.npz" in record["artifacts"]


def test_a_sigint_while_the_recorder_writes(tmp_path: Path) -> None:
    """Before: the KeyboardInterrupt left Recorder.close before record.json was written, and
    --out kept the previous run's record beside the new run's partial files."""
    out = tmp_path / "run"
    previous_run(out)
    done = _hil([*RUN, "--out", str(out)], driver=IN_RECORDER)
    record = _assert_not_lost(done, out)
    _assert_aborted(record, out)
