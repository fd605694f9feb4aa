"""Lockstep does not constrain the order of a DUT's frames within its step (issue 31 item 1).

The DUT here is the reference fertilizer daemon with each answer to SYNC reordered, the
command frame first and its status and heartbeat after it (``command_first_dut.py``), over the
embedded software bus as a process. Marking its steps with the step-end frame
(``--mark-steps``), it passes every bus conformance measurement in lockstep, and its bus log is
the same bytes run after run, also with every CPU kept busy. Without the step-end
frame its run ends with an error naming the frame, the cause and the fix.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from hil.conformance import run_conformance
from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import DutProfile, load_profile
from hil.measurements import Outcome
from hil.rig import RunOptions, RunResult, load_rig, run_scenario
from hil.rig.scenario import Event

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
DUT = Path(__file__).with_name("command_first_dut.py")
REFERENCE_COMMAND = ('command = ["{python}", "-m", "reference_controllers.daemon", '
                     '"--controller", "fertilizer-piecewise-pid", "--bus", "{bus}", "{params}"]')


def _profile(tmp_path: Path, *, mark_steps: bool) -> DutProfile:
    """The reference daemon's profile, launching the command-first DUT as a process."""
    text = REFERENCE.read_text()
    assert REFERENCE_COMMAND in text
    words = ['"{python}"', f'"{DUT}"', '"0x220"', '"--controller"',
             '"fertilizer-piecewise-pid"', '"--bus"', '"{bus}"']
    if mark_steps:
        words.append('"--mark-steps"')
    text = text.replace(REFERENCE_COMMAND, f"command = [{', '.join(words)}, \"{{params}}\"]")
    text = "\n".join(line for line in text.splitlines() if not line.startswith("inprocess"))
    text = text.replace('name = "fertilizer-piecewise-pid-daemon"',
                        'name = "fertilizer-command-first-daemon"')
    path = tmp_path / "fertilizer-command-first-daemon.toml"
    path.write_text(text)
    return load_profile(path)


def _run(profile: DutProfile, out: Path, *, restart: bool = False) -> RunResult:
    """A short bench step (enabled at 3 s, 5 s long; with a DUT power cycle at 4 s)."""
    rig = load_rig(profile.dut.rig)
    scenario = rig.load_scenario("bench-step-23")
    events = tuple(e for e in scenario.events if e.at_s < 5.0)
    if restart:
        events += (Event(at_s=4.0, dut="restart"),)
    scenario = dataclasses.replace(scenario, duration_s=5.0, events=events)
    dut, _ = make_dut(profile, bus="softbus", clock="lockstep", log_dir=out)
    return run_scenario(rig, scenario, dut, RunOptions(
        out_dir=out, clock="lockstep", bus="softbus", step_timeout_s=10.0,
        **profile_run_options(profile)))


#: a CPU hog at the lowest priority: it keeps its CPU busy, so every wake-up of the rig, the bus
#: or the DUT has to preempt it, without starving them (or the machine's other work)
HOG = "import os\nos.nice(19)\nwhile True:\n    pass\n"


@contextmanager
def _busy_cpus() -> Iterator[None]:
    """Every CPU of the machine kept busy by a process spinning at nice 19."""
    hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(os.cpu_count() or 2)]
    try:
        yield
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()


def test_a_command_first_dut_that_marks_its_steps_passes_conformance_byte_for_byte(
        tmp_path: Path) -> None:
    """One run (with a power cycle) passes every conformance measurement; a second one, with
    every CPU busy, writes the same bus log, byte for byte."""
    profile = _profile(tmp_path, mark_steps=True)
    out = tmp_path / "run"
    result = _run(profile, out, restart=True)
    assert result.record["verdict"] != "error", result.record["error"]
    # the DUT announced after each of its 2 boot-ups and ended each of the 51 steps with the
    # step-end frame (SYNC at 0.0, 0.1 … 5.0 s)
    assert result.record["frames"]["step_ends"] == 51 + 2
    found = run_conformance(result.record, out, profile,
                            physics_period_s=load_rig("fertilizer").physics_period_s)
    names = {m.name for m in found.measurements}
    assert {"bus.undeclared_frames", "bus.heartbeat.period", "bus.cycle_time.median",
            "bus.bootup.unexpected"} <= names
    bad = [(m.name, m.value, m.note) for m in found.measurements
           if m.outcome is not Outcome.PASS]
    assert not bad
    # the order is the DUT's: each step's command frame, then its heartbeat, at the SYNC's time
    lines = (out / "bus.log").read_text().splitlines()
    sync = lines.index("(2.500000) can0 080# T")
    assert lines[sync + 1].startswith("(2.500000) can0 220#")
    assert lines[sync + 2] == "(2.500000) can0 710#05 R"
    with _busy_cpus():
        again = _run(profile, tmp_path / "loaded", restart=True)
    assert again.record["verdict"] != "error", again.record["error"]
    assert (tmp_path / "loaded" / "bus.log").read_bytes() == (out / "bus.log").read_bytes()


@pytest.mark.slow
def test_its_bus_log_stays_the_same_over_many_loaded_reruns(tmp_path: Path) -> None:
    """Eight runs with a power cycle, all with every CPU busy: one bus log."""
    profile = _profile(tmp_path, mark_steps=True)
    logs = set()
    with _busy_cpus():
        for n in range(8):
            out = tmp_path / f"run{n}"
            result = _run(profile, out, restart=True)
            assert result.record["verdict"] != "error", result.record["error"]
            logs.add((out / "bus.log").read_bytes())
    assert len(logs) == 1


def test_without_the_step_end_frame_the_error_names_the_cause_and_the_fix(
        tmp_path: Path) -> None:
    result = _run(_profile(tmp_path, mark_steps=False), tmp_path / "run")
    error = result.record["error"] or ""
    assert result.record["verdict"] == "error"
    assert "straddle lockstep steps" in error
    assert "after its command frame 0x220" in error
    assert "send the command frame last" in error and "step-end frame" in error
    assert "0x1FFFFFF0" in error and "docs/guide/clocks.md" in error
    assert "heartbeat" not in error


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
